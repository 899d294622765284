"""A whole simulation: 10 s of the car manoeuvre (catalog.car) with the axle reactions
sampled at 1 kHz (10 001 output times), NumPy vs C backend.

    .venv/bin/python benchmarks/car_simulation.py [--t-end 10] [--rate 1000]

Times exclude derivation and compilation (shown separately). The integrator is
appell.simulate (DOP853 with projection drift control) at two tolerance settings.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import appell
from appell.examples.catalog import car
from appell import numeric_model


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=1000.0, help="output samples per second")
    ap.add_argument("--json")
    ap.add_argument("--markdown", help="also write the table (Markdown) here")
    args = ap.parse_args()
    from appell.simulation.simulate import simulate

    t0 = time.perf_counter()
    d = appell.derive(car())
    t_derive = time.perf_counter() - t0
    t0 = time.perf_counter()
    models = {"numpy": numeric_model(d)}
    t_numpy = time.perf_counter() - t0
    t0 = time.perf_counter()
    models["c"] = numeric_model(d, "c")
    t_c = time.perf_counter() - t0
    t_eval = np.linspace(0.0, args.t_end, int(round(args.t_end * args.rate)) + 1)
    print(f"car manoeuvre, {args.t_end:g} s, reactions at {len(t_eval)} times")
    print(f"derive {t_derive:.2f} s; NumPy functions {t_numpy:.2f} s; C library {t_c:.2f} s "
          f"({'compiled now' if getattr(models['c'], 'freshly_compiled', False) else 'from cache'})")
    print(f"{'backend':<8} {'rtol':>7} {'wall [s]':>9} {'f evals':>8} {'steps':>6} "
          f"{'max|lambda_rear|':>17} {'max|lambda_front|':>18} {'max|phi|':>9}")
    out, ref, rows = {}, None, []
    for rtol, atol in ((1e-9, 1e-12), (1e-6, 1e-9)):
        for name, model in models.items():
            t0 = time.perf_counter()
            sol = simulate(model, args.t_end, t_eval=t_eval, rtol=rtol, atol=atol, complete=True, progress=False)
            wall = time.perf_counter() - t0
            lam = sol.multipliers
            phi = max(float(np.nanmax(np.abs(v))) for v in sol.velocity_residuals.values())
            st = sol.statistics
            nfev = getattr(st, "nfev", getattr(st, "function_evaluations", "?"))
            steps = getattr(st, "steps", getattr(st, "naccepted", "?"))
            print(f"{name:<8} {rtol:7.0e} {wall:9.3f} {nfev!s:>8} {steps!s:>6} {np.max(np.abs(lam['rear'])):17.3f} "
                  f"{np.max(np.abs(lam['front'])):18.3f} {phi:9.1e}  status {sol.status}")
            if ref is None:
                ref = lam
            rows.append([name, f"{rtol:.0e}", f"{wall:.3f} s", str(nfev), str(steps),
                         f"{np.max(np.abs(lam['rear'])):.1f} N / {np.max(np.abs(lam['front'])):.1f} N"])
            out[f"{name}:{rtol:g}"] = {"seconds": wall, "status": sol.status,
                                        "max_dev_from_first": max(float(np.max(np.abs(lam[k] - ref[k]))) for k in lam)}
    if args.markdown:
        import sys

        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from harness import markdown_table

        Path(args.markdown).write_text(
            f"Derivation {t_derive:.2f} s, C library {t_c:.2f} s (not in the wall times).\n\n"
            + markdown_table(["backend", "rtol", "wall time", "RHS evaluations", "steps",
                              "max abs. reaction rear / front"], rows) + "\n")
    if args.json:
        Path(args.json).write_text(json.dumps({"derive": t_derive, "numpy_functions": t_numpy,
                                               "c_library": t_c, "runs": out}, indent=1))


if __name__ == "__main__":
    main()
