"""Linear models against a peer (issue 23): SymPy's ``Linearizer`` (``KanesMethod.linearize``,
A and B solved, then ``lambdify(cse=True, modules="math")``, SymPy's best practice) and
:func:`appell.linearise` on the same system, a thin disc rolling upright on a level plane
(``benchmarks/models.py``; appell's is the bundled ``rolling_disc`` with its contact and
free joint).

    python benchmarks/linearise_peers.py [--spins N]

Prints, with the machine and date: the time from the model to the first A; one more A at
a new spin rate (median of interleaved rounds, CPU time); eigenvalues at N spin rates with
the critical one located; and the critical spin rate of each route against the closed form
sqrt(g / (3 r)). The routes differ in what they need: SymPy's operating point is given in
closed form (upright, contact at rest, 3 coordinates), appell finds the steady motion of
its 6-coordinate model with the contact force as a multiplier at each spin rate.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

sys.path.insert(0, str(Path(__file__).resolve().parent))
import appell  # noqa: E402
from appell.examples.mechanism_examples import rolling_disc  # noqa: E402
from harness import interleaved, load, machine, median, today, version  # noqa: E402
from models import rolling_disc_sympy_linear  # noqa: E402

R, MASS, G = 0.25, 1.5, 9.81
FREE = ["float_x_dot", "float_y_dot", "float_z_dot", "float_z"]
IGNORE = ["float_x", "float_y", "float_rz", "float_ry"]


def guess(spin: float) -> dict[str, float]:
    return {"alpha": 0.0, "float_z": R, "float_ry_dot": spin, "float_x_dot": -R * spin}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--spins", type=int, default=1001, help="spin rates of the sweep")
    args = parser.parse_args()
    spins = np.linspace(1.0, 8.0, args.spins)
    exact = np.sqrt(G / (3 * R))

    t0 = time.perf_counter()
    stages, sympy_A = rolling_disc_sympy_linear()
    np.linalg.eigvals(np.array(sympy_A(6.0, R, MASS, G), float))
    sympy_first = time.perf_counter() - t0

    t0 = time.perf_counter()
    d = appell.derive(rolling_disc())
    derive_s = time.perf_counter() - t0
    point = appell.steady_motion(d, guess(6.0), free=FREE, ignore=IGNORE)
    appell.linearise(d, point, ignore=IGNORE).eigenvalues()
    appell_first = time.perf_counter() - t0

    times = interleaved(
        {
            "sympy": lambda: np.array(sympy_A(6.5, R, MASS, G), float),
            "appell": lambda: appell.linearise(d, point, ignore=IGNORE),
        },
        rounds=15,
    )

    t0 = time.perf_counter()
    growth = [np.max(np.linalg.eigvals(np.array(sympy_A(s, R, MASS, G), float)).real) for s in spins]
    k = next(i for i in range(len(spins) - 1) if growth[i] > 1e-9 >= growth[i + 1])

    # the lean-yaw block (q2, u1, u3) has eigenvalues 0 and +-mu with mu^2 = trace(A^2) / 2,
    # a smooth function of the spin rate: its root, bracketed by the sweep
    def mu2(s):
        a = np.array(sympy_A(s, R, MASS, G), float)[np.ix_([1, 3, 5], [1, 3, 5])]
        return np.trace(a @ a) / 2

    sympy_crit = brentq(mu2, spins[k], spins[k + 1], xtol=1e-14)
    sympy_sweep = time.perf_counter() - t0

    t0 = time.perf_counter()
    sweep = appell.stability_sweep(
        d, "float_ry_dot", spins, at={"alpha": 0.0, "float_z": R, "float_x_dot": R}, free=FREE, ignore=IGNORE
    )
    appell_sweep = time.perf_counter() - t0
    appell_crit = sweep.crossings[0].value

    print(
        f"rolling disc about upright rolling, {today()}, {machine()}, load {load()}; "
        f"SymPy {version('sympy')}, appell {version('appell')}"
    )
    print("| stage | SymPy Linearizer | appell.linearise |\n|---|---|---|")
    print(f"| equations of motion | {stages['equations']:.2f} s (Kane) | {derive_s:.2f} s (derive) |")
    print(
        f"| model to first eigenvalues | {sympy_first:.2f} s (Kane, linearize {stages['linearise']:.2f} s, "
        f"lambdify {stages['compile'] * 1e3:.0f} ms) | {appell_first:.2f} s (derive, compile, steady motion, "
        f"linearise) |"
    )
    print(
        f"| one more A (median of 15 rounds) | {median(times['sympy']) * 1e6:.1f} us (A from the closed form) | "
        f"{median(times['appell']) * 1e3:.2f} ms (exact Jacobians, split, chart) |"
    )
    print(
        f"| {args.spins} spin rates, eigenvalues, critical rate located | {sympy_sweep:.2f} s (operating point "
        f"given) | {appell_sweep:.2f} s (steady motion solved at each) |"
    )
    print(
        f"| critical spin rate, error against sqrt(g/(3r)) = {exact:.12f} | {abs(sympy_crit - exact):.1e} | "
        f"{abs(appell_crit - exact):.1e} |"
    )


if __name__ == "__main__":
    main()
