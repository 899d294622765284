"""The code of lambdified blocks kept on disk (appell.numerics.lambdified): read back in another
process without forming it, numbers equal to code formed afresh; a bad entry is written again;
the key tells apart what prints differently."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

import appell
from appell._cache import cache_dir
from appell.core.derive import derive
from appell.numerics import lambdified


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("APPELL_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv(lambdified.NO_CACHE_ENV, raising=False)
    return tmp_path / "lambdified"


CHILD = """
import json, sys, numpy as np, appell
from appell.core.derive import derive
m = appell.numeric_model(derive(appell.load_model(sys.argv[1])), "numpy")
rng = np.random.default_rng(0)
q, w = rng.uniform(-1, 1, len(m.coordinate_names)), rng.uniform(-1, 1, len(m.speed_names))
print(json.dumps([b.tolist() for b in m.evaluate_blocks(0.3, q, w)]))
"""


@pytest.mark.parametrize("name", ["benchmark_bicycle", "rolling_disc"])
def test_blocks_turned_into_code_in_another_process_are_read_back(folder, monkeypatch, name):
    """The NumPy model of a derivation built in a child process: here its blocks' code is read
    from the entries (forming code raises), and every block at random states equals, to the
    last bit, the child's (the same code), and that of code formed afresh with the cache off
    (to rounding: the order of the shared subexpressions may differ)."""
    from appell import symbols

    child = subprocess.run(
        [sys.executable, "-c", CHILD, name],
        env={**os.environ, "APPELL_CACHE_DIR": str(folder.parent)},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert child.returncode == 0, child.stderr
    assert list(folder.glob("*.py"))
    d = derive(appell.load_model(name))
    form = symbols.lambdify_with_printer

    def refuse(args, exprs, modules="math", cse=None):
        if len(exprs):  # (an empty function gives the namespace of the module's code)
            raise AssertionError("code formed again: the stored code was not read")
        return form(args, exprs, modules, cse)

    with monkeypatch.context() as m:
        m.setattr(symbols, "lambdify_with_printer", refuse)
        cached = appell.numeric_model(d, "numpy")
        rng = np.random.default_rng(0)
        q, w = rng.uniform(-1, 1, len(cached.coordinate_names)), rng.uniform(-1, 1, len(cached.speed_names))
        read = cached.evaluate_blocks(0.3, q, w)
    monkeypatch.setenv(lambdified.NO_CACHE_ENV, "1")
    fresh = appell.numeric_model(derive(appell.load_model(name)), "numpy").evaluate_blocks(0.3, q, w)
    for a, b, c in zip(read, fresh, json.loads(child.stdout)):
        np.testing.assert_array_equal(a, np.array(c))
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13)


def test_a_changed_or_truncated_entry_is_written_again(folder):
    x, y = sp.symbols("x y")
    exprs = [sp.sin(x) * y + sp.sqrt(x**2 + 1), sp.cos(y) ** 2]
    f = lambdified.cached_lambdify([x, y], exprs)
    (entry,) = folder.glob("*.py")
    good = entry.read_bytes()
    expected = [np.sin(0.4) * 0.7 + np.sqrt(1.16), np.cos(0.7) ** 2]
    np.testing.assert_allclose(f(0.4, 0.7), expected, rtol=1e-15)
    entry.write_bytes(good.replace(b"sin(x)", b"cos(x)"))  # its checksum no longer holds
    np.testing.assert_allclose(lambdified.cached_lambdify([x, y], exprs)(0.4, 0.7), expected, rtol=1e-15)
    assert entry.read_bytes() == good
    entry.write_bytes(good[:40])
    np.testing.assert_allclose(lambdified.cached_lambdify([x, y], exprs)(0.4, 0.7), expected, rtol=1e-15)
    assert entry.read_bytes() == good


def test_the_key_tells_apart_what_prints_differently(folder):
    """Another last digit of a number, another argument order or name, another printer: another
    entry; the same expressions built again: the same entry, in another process too."""
    x, y = sp.symbols("x y")
    base = [x * sp.Float("0.1", 30) + y]
    lambdified.cached_lambdify([x, y], base)
    lambdified.cached_lambdify([x, y], [x * sp.Float("0.1", 30) + y])
    assert len(list(folder.glob("*.py"))) == 1
    lambdified.cached_lambdify([x, y], [x * sp.Float("0.1000000000000000000000000001", 30) + y])
    lambdified.cached_lambdify([y, x], base)
    lambdified.cached_lambdify([x, sp.Symbol("z")], [x * sp.Float("0.1", 30) + sp.Symbol("z")])
    lambdified.cached_lambdify([x, y], base, modules="numpy")
    assert len(list(folder.glob("*.py"))) == 5
    here = lambdified.structural_digest([sp.sin(x + y) ** 2, sp.Matrix([[x, 1], [sp.Rational(1, 3), y]])])
    there = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sympy as sp; from appell.numerics.lambdified import structural_digest as d; "
            "x, y = sp.symbols('x y'); print(d([sp.sin(x + y) ** 2, sp.Matrix([[x, 1], [sp.Rational(1, 3), y]])]))",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert there.stdout.strip() == here
    positive = sp.Symbol("x", positive=True)
    assert lambdified.structural_digest([positive + y]) != lambdified.structural_digest([x + y])
    assert cache_dir() / "lambdified" == folder
