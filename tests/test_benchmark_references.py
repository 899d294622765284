"""The references and peers of the benchmarks compute the same physics as appell.

A benchmark that times different physics is worthless, so the independent routes the
benchmarks compare against are checked here against appell's split solution (1.4)/(1.5)
of the n-link pendulum with its tip on a vertical line (``benchmarks/models.py``):

* the O(n) C reference (``benchmarks/reference/nlink_recursive.c``): rod tensions of a
  chain of point masses on massless rods, a tridiagonal system (Newton's laws per mass);
* the dense hand-written C (``benchmarks/reference/nlink.c``): the augmented multiplier
  system [M -J^T; J 0][a; lam] = [Q - h; -c] written out by hand;
* SymPy's KanesMethod with the tip force as an unknown load (the augmented system): it
  does give the reaction;
* Pinocchio's constrained forward dynamics (skipped when ``pin`` is not installed);
* the chain written as an appell model file.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import appell
from appell import numeric_model

BENCH = Path(__file__).resolve().parent.parent / "benchmarks"
sys.path.insert(0, str(BENCH))

from models import (
    nlink_appell,
    nlink_kane_function,
    nlink_model_file,
    nlink_parameters,  # noqa: E402
    nlink_pinocchio_function,
    nlink_state,
    pinocchio_state,
)


@pytest.fixture(scope="module")
def references(tmp_path_factory):
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler")
    so = tmp_path_factory.mktemp("ref") / "nlink.so"
    subprocess.run(
        [
            cc,
            "-O2",
            "-shared",
            "-fPIC",
            "-o",
            str(so),
            str(BENCH / "reference" / "nlink.c"),
            str(BENCH / "reference" / "nlink_recursive.c"),
            "-lm",
        ],
        check=True,
    )
    return ctypes.CDLL(str(so))


def appell_solution(n: int):
    th, w = nlink_state(n)
    ev = numeric_model(appell.derive(nlink_appell(n))).evaluate(0.0, np.concatenate([th, w]))
    return th, w, ev.derivative[n:], float(ev.multipliers[0])


def call_reference(lib, name: str, n: int, th, w):
    fn = getattr(lib, name)
    fn.argtypes = [ctypes.c_int] + [ctypes.c_void_p] * 4
    y = np.concatenate([th, w])
    p = np.array(list(nlink_parameters(n).values()))
    dy, lam = np.empty(2 * n), np.empty(1)
    assert fn(n, y.ctypes.data, p.ctypes.data, dy.ctypes.data, lam.ctypes.data) == 0
    return dy, float(lam[0])


@pytest.mark.parametrize("n", [2, 3, 7])
@pytest.mark.parametrize("name", ["nlink_recursive", "nlink_evaluate"])
def test_c_references_give_appells_accelerations_and_tip_reaction(references, name, n):
    th, w, acc, lam = appell_solution(n)
    dy, lam_ref = call_reference(references, name, n, th, w)
    np.testing.assert_allclose(dy[:n], w, rtol=0, atol=0)
    # independent routes (a tridiagonal or a dense augmented solve against the split): rounding
    # times the condition of the chain's solves, growing with n (measured 7e-15 at n = 7)
    np.testing.assert_allclose(dy[n:], acc, rtol=1e-11, atol=1e-11)
    assert lam_ref == pytest.approx(lam, rel=1e-11, abs=1e-11)


def test_recursive_reference_single_link_on_the_line_is_at_rest(references):
    """n = 1: the tip on x = d fixes the link, so the mass is in equilibrium under gravity,
    the rod tension T along the rod and the line's force lam: T cos(th) = m g and
    lam = T sin(th), i.e. lam = m g tan(th) (statics by hand), and a = 0."""
    p = nlink_parameters(1)
    th = np.array([np.arcsin(p["d"] / p["l1"])])
    dy, lam = call_reference(references, "nlink_recursive", 1, th, np.zeros(1))
    # a = -g sin(th) + (m g sin(th)/cos(th)) cos(th)/m cancels to rounding: a few ulps of
    # g sin(th) = 2.9 (ulp 4e-16), as is lam against m g tan(th) with libm's sin, cos and tan
    assert dy[1] == pytest.approx(0.0, abs=1e-14)
    assert lam == pytest.approx(p["m1"] * p["g"] * np.tan(th[0]), rel=1e-14, abs=0)


def test_sympy_kane_augmented_system_gives_the_reaction():
    """SymPy's route (KanesMethod + lambdify of [M -J^T; J 0], [f; -c]) yields lam too."""
    n = 3
    th, w, acc, lam = appell_solution(n)
    evaluate = nlink_kane_function(n)
    a, lam_kane = evaluate(th, w, list(nlink_parameters(n).values()))
    # the augmented system solved by NumPy against the split: rounding times their condition
    np.testing.assert_allclose(a, acc, rtol=1e-11, atol=1e-11)
    assert lam_kane == pytest.approx(lam, rel=1e-11)


def test_pinocchio_chain_gives_the_same_accelerations_and_reaction():
    pytest.importorskip("pinocchio")
    n = 5
    th, w, acc, lam = appell_solution(n)
    ddq, lam_pin = nlink_pinocchio_function(n)(*pinocchio_state(th, w))
    # Pinocchio's KKT solve in relative angles, summed: rounding only (measured 1e-13)
    np.testing.assert_allclose(np.cumsum(ddq), acc, rtol=1e-9, atol=1e-9)
    assert lam_pin == pytest.approx(lam, rel=1e-9)


def test_chain_model_file_is_the_same_system(tmp_path):
    from appell.io.modelfile.loader import load_model

    n = 4
    path = tmp_path / "pendulum4.toml"
    path.write_text(nlink_model_file(n))
    th, w, acc, lam = appell_solution(n)
    ev = numeric_model(appell.derive(load_model(path))).evaluate(0.0, np.concatenate([th, w]))
    # the same system from its file: the same formulas up to SymPy's ordering, rounding only
    np.testing.assert_allclose(ev.derivative[n:], acc, rtol=1e-12, atol=1e-12)
    assert float(ev.multipliers[0]) == pytest.approx(lam, rel=1e-12)


def test_markers_replace_only_their_section():
    from harness import replace_between_markers

    text = "a\n<!-- bench:x -->\nold\n<!-- /bench:x -->\nb\n<!-- bench:y -->\nkeep\n<!-- /bench:y -->\n"
    out = replace_between_markers(text, "x", "new table")
    assert out == "a\n<!-- bench:x -->\nnew table\n<!-- /bench:x -->\nb\n<!-- bench:y -->\nkeep\n<!-- /bench:y -->\n"
    with pytest.raises(KeyError):
        replace_between_markers(text, "z", "t")


def test_sympy_linearizer_of_the_rolling_disc_has_appells_eigenvalues():
    """The peer of ``benchmarks/linearise_peers.py``: SymPy's Linearizer (KanesMethod, the
    contact point at rest, speeds in the lean frame) and appell's linear model of the bundled
    disc (free joint, rolling contact, steady motion solved) about upright rolling give the
    same lean-yaw eigenvalues on both sides of the critical spin rate sqrt(g / (3 r))
    (the closed form of ``tests/test_linearise.py``)."""
    from appell.examples.mechanism_examples import rolling_disc
    from models import rolling_disc_sympy_linear

    _, sympy_A = rolling_disc_sympy_linear()
    d = appell.derive(rolling_disc())
    r, m, g = 0.25, 1.5, 9.81
    for spin in (2.0, 3.6, 3.7, 6.0):
        point = appell.steady_motion(
            d,
            {"alpha": 0.0, "float_z": r, "float_ry_dot": spin, "float_x_dot": -r * spin},
            free=["float_x_dot", "float_y_dot", "float_z_dot", "float_z"],
            ignore=["float_x", "float_y", "float_rz", "float_ry"],
        )
        mine = appell.linearise(d, point, ignore=["float_x", "float_y", "float_rz", "float_ry"]).eigenvalues()
        theirs = np.linalg.eigvals(np.array(sympy_A(spin, r, m, g), float))
        nonzero = lambda ev: sorted(ev[np.abs(ev) > 1e-9], key=lambda z: (z.real, z.imag))  # noqa: E731
        assert np.allclose(nonzero(mine), nonzero(theirs), rtol=1e-10, atol=1e-12)
        assert (np.max(theirs.real) > 1e-9) == (spin**2 < g / (3 * r))
