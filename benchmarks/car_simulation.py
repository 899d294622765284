"""A whole simulation: 10 s of the car manoeuvre (catalog.car) with the axle reactions
sampled at 1 kHz (10 001 output times), NumPy vs C backend.

    .venv/bin/python benchmarks/car_simulation.py [--t-end 10] [--rate 1000]

Times exclude derivation and compilation (shown separately). The integrator is
appell.simulate (DOP853 with projection drift control) at two tolerance settings. Then the
target of issue 46 §5: the C backend's run (rtol 1e-9; the compiled loop, one C call with
its projections inside) against the yardstick of benchmarks/loop.py, a fixed-step RK4 in C
around the same compiled model recording the same samples, run in turn ``--repeats`` times
with the ratio taken pair by pair (wall and CPU time of this process; target at most 1.5).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import appell
from appell import numeric_model
from appell.examples.catalog import car


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=1000.0, help="output samples per second")
    ap.add_argument("--json")
    ap.add_argument("--markdown", help="also write the table (Markdown) here")
    ap.add_argument("--repeats", type=int, default=15, help="interleaved runs against the RK4 yardstick")
    args = ap.parse_args()
    from appell.simulation.simulate import simulate

    t0 = time.perf_counter()
    d = appell.derive(car())
    t_derive = time.perf_counter() - t0
    t0 = time.perf_counter()
    models = {"numpy": numeric_model(d, "numpy")}
    t_numpy = time.perf_counter() - t0
    t0 = time.perf_counter()
    models["c"] = numeric_model(d, "c")
    t_c = time.perf_counter() - t0
    t_eval = np.linspace(0.0, args.t_end, int(round(args.t_end * args.rate)) + 1)
    print(f"car manoeuvre, {args.t_end:g} s, reactions at {len(t_eval)} times")
    print(
        f"derive {t_derive:.2f} s; NumPy functions {t_numpy:.2f} s; C library {t_c:.2f} s "
        f"({'compiled now' if getattr(models['c'], 'freshly_compiled', False) else 'from cache'})"
    )
    print(
        f"{'backend':<8} {'rtol':>7} {'wall [s]':>9} {'f evals':>8} {'steps':>6} "
        f"{'max|lambda_rear|':>17} {'max|lambda_front|':>18} {'max|phi|':>9}"
    )
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
            print(
                f"{name:<8} {rtol:7.0e} {wall:9.3f} {nfev!s:>8} {steps!s:>6} {np.max(np.abs(lam['rear'])):17.3f} "
                f"{np.max(np.abs(lam['front'])):18.3f} {phi:9.1e}  status {sol.status}"
            )
            if ref is None:
                ref = lam
            rows.append(
                [
                    name,
                    f"{rtol:.0e}",
                    f"{wall:.3f} s",
                    str(nfev),
                    str(steps),
                    f"{np.max(np.abs(lam['rear'])):.1f} N / {np.max(np.abs(lam['front'])):.1f} N",
                ]
            )
            out[f"{name}:{rtol:g}"] = {
                "seconds": wall,
                "status": sol.status,
                "max_dev_from_first": max(float(np.max(np.abs(lam[k] - ref[k]))) for k in lam),
            }
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    out["rk4"] = against_rk4(models["c"], t_eval, args.t_end, args.repeats)
    if args.markdown:
        from harness import markdown_table

        Path(args.markdown).write_text(
            f"Derivation {t_derive:.2f} s, C library {t_c:.2f} s (not in the wall times). The C backend's "
            f"run (rtol 1e-9) / a fixed-step RK4 in C recording the same samples: {out['rk4']['wall_ratio']:.2f} "
            f"(wall), {out['rk4']['cpu_ratio']:.2f} (CPU), medians of {args.repeats} interleaved pairs "
            "(target <= 1.5).\n\n"
            + markdown_table(
                ["backend", "rtol", "wall time", "RHS evaluations", "steps", "max abs. reaction rear / front"], rows
            )
            + "\n"
        )
    if args.json:
        Path(args.json).write_text(
            json.dumps({"derive": t_derive, "numpy_functions": t_numpy, "c_library": t_c, "runs": out}, indent=1)
        )


def against_rk4(model, t_eval, t_end: float, repeats: int) -> dict:
    """The C backend's ``simulate`` (rtol 1e-9, atol 1e-12) against benchmarks/loop.py's RK4
    in C with the step of the output times, in turn; the medians of the pair-by-pair ratios."""
    from appell.simulation.simulate import simulate
    from loop import rk4, rk4_library

    lib = rk4_library()
    kw = dict(t_eval=t_eval, rtol=1e-9, atol=1e-12, complete=True, progress=False)
    y0 = np.array([simulate(model, t_end, **kw).states[n][0] for n in model.state_names])
    h = float(t_eval[1] - t_eval[0])
    runs = {"simulate": lambda: simulate(model, t_end, **kw), "RK4 in C": lambda: rk4(lib, model, y0, t_end, h)}
    wall, cpu = {k: [] for k in runs}, {k: [] for k in runs}
    for _ in range(repeats):
        for key, run in runs.items():
            w0, c0 = time.perf_counter(), time.process_time()
            run()
            cpu[key].append(time.process_time() - c0)
            wall[key].append(time.perf_counter() - w0)
    w = np.array(wall["simulate"]) / np.array(wall["RK4 in C"])
    c = np.array(cpu["simulate"]) / np.array(cpu["RK4 in C"])
    print(f"\nagainst a fixed-step RK4 in C recording the same samples ({repeats} interleaved repeats, medians):")
    for key in runs:
        print(f"  {key:<9} wall {1e3 * np.median(wall[key]):7.2f} ms   CPU {1e3 * np.median(cpu[key]):7.2f} ms")
    print(
        f"  ratio simulate / RK4: wall {np.median(w):.2f} (repeats {np.min(w):.2f}-{np.max(w):.2f}), "
        f"CPU {np.median(c):.2f} (repeats {np.min(c):.2f}-{np.max(c):.2f}); target <= 1.5"
    )
    return {
        "wall_ratio": float(np.median(w)),
        "cpu_ratio": float(np.median(c)),
        "simulate_wall_s": float(np.median(wall["simulate"])),
        "rk4_wall_s": float(np.median(wall["RK4 in C"])),
    }


if __name__ == "__main__":
    main()
