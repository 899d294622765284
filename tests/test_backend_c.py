"""The C backend (appell.numerics.codegen) against the NumPy functions: identical blocks,
accelerations and multipliers on every catalog example and on an n-link pendulum with a
loop closure; the disk cache; the fallback without a compiler."""

import numpy as np
import pytest

import appell
from appell import numeric_model
from appell.examples import example_path
from appell.examples.catalog import CATALOG, nlink_pendulum
from appell.numerics.codegen import CompiledNumericModel, c_source, compile_c
from appell.numerics.numeric import compile_model

pytestmark = pytest.mark.skipif(__import__("shutil").which("cc") is None, reason="no C compiler")


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("APPELL_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "appell_cache"))


def nlink(n):
    """n-link pendulum with point masses, tip held on the line x = d (the benchmark family)."""
    return nlink_pendulum(n)


def close(x, y, rtol=1e-12):
    """The same expressions in C and NumPy, the same split by the C code's LU and by LAPACK:
    rounding only, a few eps times the solves' condition (measured at most 1.4e-14 of the scale)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    scale = max(1.0, float(np.max(np.abs(y)))) if y.size else 1.0
    assert np.max(np.abs(x - y), initial=0.0) <= rtol * scale


def states(derivation, count=4, seed=7):
    rng = np.random.default_rng(seed)
    nq, n = len(derivation.kinematics.coordinates), len(derivation.kinematics.speeds)
    for _ in range(count):
        yield rng.uniform(0, 2), rng.uniform(-1, 1, nq), rng.uniform(-1, 1, n)


@pytest.mark.numpy_model  # its reference is numeric_model(d): NumPy also under APPELL_TEST_BACKEND=c
@pytest.mark.parametrize("name", sorted(CATALOG) + ["pendulum5"])
def test_c_equals_numpy(name):
    """Blocks, accelerations (1.4), multipliers (1.5), rates and residuals agree to 1e-12."""
    d = appell.derive(nlink(5) if name == "pendulum5" else CATALOG[name]())
    nm, cm = numeric_model(d), numeric_model(d, "c")
    assert isinstance(cm, CompiledNumericModel)
    for t, q, w in states(d):
        for x, y in zip(cm.evaluate_blocks(t, q, w), nm.evaluate_blocks(t, q, w)):
            close(x, y)
        s1, s2 = nm.solve(t, q, w), cm.solve(t, q, w)
        close(s2.accelerations, s1.accelerations)
        close(s2.multipliers, s1.multipliers)
        close(s2.generalized_reactions, s1.generalized_reactions)
        e1, e2 = nm.evaluate(t, np.r_[q, w]), cm.evaluate(t, np.r_[q, w])
        close(e2.derivative, e1.derivative)
        close(e2.multipliers, e1.multipliers)
        for x, y in zip(cm.constraint_residuals(t, q, w), nm.constraint_residuals(t, q, w)):
            np.testing.assert_array_equal(np.isnan(x), np.isnan(y))
            close(np.nan_to_num(x), np.nan_to_num(y))


def test_c_matches_numpy_with_a_chosen_partition_and_a_baumgarte_bias():
    """The car at theta = 0.2 with (x'', y'') dependent given explicitly, and with a constraint
    bias (Baumgarte): the C code gives the NumPy route's accelerations, multipliers and rates.
    (No partition switch happens here: that is tested in test_events.py and test_core_crosscheck.py.)"""
    d = appell.derive(CATALOG["car"]())
    nm, cm = numeric_model(d), compile_c(d, "c")
    q, w = np.array([0.1, 0.2, 0.3]), np.array([1.0, 0.5, 0.2])
    s1 = nm.solve(0.0, q, w, dependent=(0, 1))
    s2 = cm.solve(0.0, q, w, dependent=(0, 1))
    close(s2.accelerations, s1.accelerations)
    close(s2.multipliers, s1.multipliers)
    bias = np.array([0.3, -0.2])
    close(cm.solve(1.0, q, w, bias=bias).multipliers, nm.solve(1.0, q, w, bias=bias).multipliers)
    close(cm.evaluate(1.0, np.r_[q, w], bias=bias).derivative, nm.evaluate(1.0, np.r_[q, w], bias=bias).derivative)


def test_cache_second_load_does_not_recompile(tmp_path, monkeypatch):
    monkeypatch.setenv("APPELL_CACHE_DIR", str(tmp_path))
    d = appell.derive(CATALOG["knife_edge"]())
    first = compile_c(d, "c")
    assert first.freshly_compiled and first.library_path.parent == tmp_path
    import subprocess

    def no_compiler(*args, **kwargs):
        raise AssertionError("compiled again")

    monkeypatch.setattr(subprocess, "run", no_compiler)
    second = compile_c(d, "c")
    assert not second.freshly_compiled and second.library_path == first.library_path
    assert [p.suffix for p in tmp_path.iterdir()].count(".so") == 1
    assert (tmp_path / first.library_path.name.replace(".so", ".c")).read_text() == c_source(d)


def test_auto_keeps_the_compiled_model_it_built(monkeypatch):
    """numeric_model(d, 'auto') builds the compiled model once and shares it with 'c'; a
    fallback to NumPy is not kept (its warning comes at every call)."""
    d = appell.derive(CATALOG["knife_edge"]())
    first = numeric_model(d, "auto")
    assert isinstance(first, CompiledNumericModel)
    assert numeric_model(d, "auto") is first and numeric_model(d, "c") is first
    monkeypatch.setenv("APPELL_CC", "/nonexistent/cc")
    other = appell.derive(CATALOG["pendulum"]())
    for _ in range(2):
        with pytest.warns(RuntimeWarning, match="no C compiler"):
            assert not isinstance(numeric_model(other, "auto"), CompiledNumericModel)


@pytest.mark.numpy_model  # without a compiler numeric_model(d) must be the NumPy model
def test_fallback_without_compiler(monkeypatch):
    """Without a compiler 'auto' falls back to NumPy with a warning; 'c' is refused (ModelError)."""
    monkeypatch.setenv("APPELL_CC", "/nonexistent/cc")
    d = appell.derive(CATALOG["pendulum"]())
    with pytest.warns(RuntimeWarning, match="no C compiler"):
        m = compile_c(d, "auto")
    assert not isinstance(m, CompiledNumericModel)
    close(
        m.solve(0, [0.6, -0.8], [0.1, 0.2]).multipliers, numeric_model(d).solve(0, [0.6, -0.8], [0.1, 0.2]).multipliers
    )
    with pytest.raises(appell.ModelError, match="needs a C compiler"):
        compile_c(d, "c")
    assert not isinstance(compile_model(d), CompiledNumericModel)


def test_simulation_with_c_backend():
    """The simulator integrates the compiled model like the NumPy one."""
    simulate = pytest.importorskip("appell.simulation.simulate").simulate
    d = appell.derive(CATALOG["car"]())
    t_eval = np.linspace(0, 2, 21)
    s1 = simulate(numeric_model(d), 2.0, t_eval=t_eval, progress=False, complete=True)
    s2 = simulate(numeric_model(d, "c"), 2.0, t_eval=t_eval, progress=False, complete=True)
    for k in s1.multipliers:
        # the same steps and projections: rounding only (measured 1e-14 relative); an output
        # between the paths' ends of a projected step would differ by ~1e-9 relative
        np.testing.assert_allclose(s2.multipliers[k], s1.multipliers[k], rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize(
    "call", ["short q", "long w", "dependent out of range", "repeated dependent", "short state", "short bias"]
)
def test_compiled_model_refuses_wrong_sizes_before_the_c_code_reads_them(call):
    """The C functions read exactly n_q, n, s entries: a wrong length or an index outside
    0..n-1 would be read out of bounds. Each is a ModelError naming the sizes instead."""
    d = appell.derive(CATALOG["car"]())
    m = numeric_model(d, "c")
    q, w = [0.0, 0.0, 0.3], [1.0, 0.2, 0.1]
    calls = {
        "short q": lambda: m.solve(0.0, q[:2], w),
        "long w": lambda: m.solve(0.0, q, w + [0.0]),
        "dependent out of range": lambda: m.solve(0.0, q, w, dependent=[0, 7]),
        "repeated dependent": lambda: m.solve(0.0, q, w, dependent=[1, 1]),
        "short state": lambda: m.evaluate(0.0, np.zeros(5)),
        "short bias": lambda: m.evaluate(0.0, np.zeros(6), bias=[0.0]),
    }
    with pytest.raises(appell.ModelError):
        calls[call]()
    # and a right call still agrees with the NumPy split: rounding only (measured 4e-16 relative)
    assert np.allclose(
        m.solve(0.0, q, w).multipliers, numeric_model(d).solve(0.0, q, w).multipliers, rtol=1e-12, atol=0
    )


def test_a_hostile_model_name_never_becomes_c_code():
    """A model file's name reaches the generated C only inside a comment, with every
    character that could end it (``*/``), start a line or a directive replaced (issue 20):
    before, a name holding ``*/`` put the rest of the name into the compiled library."""
    from appell.numerics.codegen import c_source

    text = (
        example_path("pendulum")
        .read_text()
        .replace('name = "pendulum"', 'name = "p */ int injected = 1; /* \\n#include <stdio.h>"')
    )
    derivation = appell.derive(appell.loads_model(text))
    first = c_source(derivation).splitlines()[0]
    assert first == "/* appell: generated C for system p ?? int injected ? 1? ?? ??include ?stdio.h?; n = 2, s = 1 */"
    model = numeric_model(derivation, "c")
    sol = appell.simulate(model, 0.5)
    assert sol.status == 0  # it compiles and runs as the pendulum it is
    assert "injected" not in " ".join(l for l in c_source(derivation).splitlines()[1:])


def test_a_library_built_in_the_background_is_the_one_compile_c_loads(tmp_path, monkeypatch):
    """``appell report`` starts the compiler while it checks the routes
    (:func:`appell.numerics.codegen.model.compile_in_background`): ``compile_c`` then takes up
    the source formed there and loads the library without compiling again, and it gives
    the NumPy model's accelerations and multipliers."""
    import subprocess

    from appell.numerics.codegen.model import compile_in_background

    monkeypatch.setenv("APPELL_CACHE_DIR", str(tmp_path))
    d = appell.derive(CATALOG["knife_edge"]())
    thread = compile_in_background(d)
    assert thread is not None
    thread.join()

    def no_compiler(*args, **kwargs):
        raise AssertionError("compiled again")

    monkeypatch.setattr(subprocess, "run", no_compiler)
    monkeypatch.setattr(subprocess, "Popen", no_compiler)
    compiled, reference = compile_c(d, "c"), compile_model(d)
    assert not compiled.freshly_compiled
    for t0, q, w in states(d):
        a, b = compiled.solve(t0, q, w), reference.solve(t0, q, w)
        close(a.accelerations, b.accelerations)
        close(a.multipliers, b.multipliers)


def test_a_background_build_that_fails_is_reported_by_compile_c(tmp_path, monkeypatch):
    """A compiler that fails in the background leaves no library and no temporary file; the
    failure reaches the user from ``compile_c``, with the compiler's message."""
    from appell.numerics.codegen.model import compile_in_background

    cache, cc = tmp_path / "cache", tmp_path / "broken-cc"
    cc.write_text("#!/bin/sh\necho 'broken-cc: no code today' >&2\nexit 1\n")
    cc.chmod(0o755)
    monkeypatch.setenv("APPELL_CACHE_DIR", str(cache))
    monkeypatch.setenv("APPELL_CC", str(cc))
    d = appell.derive(CATALOG["pendulum"](), cache=False)  # the folder holds only what the build leaves
    thread = compile_in_background(d)
    assert thread is not None
    thread.join()
    assert not [p for p in cache.iterdir() if p.suffix != ".lock"]
    with pytest.raises(appell.ComputationError, match="no code today"):
        compile_c(d, "c")
