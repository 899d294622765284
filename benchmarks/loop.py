"""The whole simulation loop against compiled code: ``simulate`` vs a fixed-step RK4 in C.

    .venv/bin/python benchmarks/loop.py [--repeats 15] [--chain 4 10] [--json out.json]

Car (catalog.car, Do Shan's example 1): 10 s with both axle reactions recorded at 1 kHz
(10 001 output times). Four candidates, run in turn (A B C A B C ...) so that a drift of
the machine's speed touches all of them alike; each ratio is taken pair by pair and its
median printed:

* ``simulate`` with its default DOP853 on the C backend: the compiled loop
  (appell.numerics.compiled_loop; projection onto the constraints when a residual exceeds
  1e-10, done inside the loop, so that the run is one C call; rtol 1e-9, atol 1e-12);
* the same with every projection in Python (``compiled_loop.PROJECT_IN_LOOP = False``: the
  loop hands each step that needs one back to Python, the driver before issue 46 §5);
* ``simulate`` with SciPy's ``DOP853`` class (the reference path: the same steps, Python
  driving SciPy, the outputs recorded in batches);
* the yardstick: classical RK4 with the fixed step 1 ms written in C around the same
  compiled model (``benchmarks/reference/rk4_loop.c``), recording the same quantities at
  the same times (state, accelerations, multipliers, residuals) into preallocated arrays,
  called once through ctypes. Its results agree with ``simulate``'s (printed).

Wall and CPU time (``time.process_time``, this process only) are both printed: on a shared
machine the CPU time is the steadier of the two. The n-link chain with its tip on a line (``--chain``; benchmarks/models.py) is timed the
same way, 10 s at 1 kHz. Times exclude derivation and compilation.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.integrate as si

import appell
import appell.numerics.compiled_loop as compiled_loop
from appell import numeric_model
from appell.examples.catalog import car, nlink_pendulum
from appell.numerics.codegen import build_library, find_compiler, load_library
from appell.numerics.numeric import KEEP_CONDITION
from appell.simulation.simulate import simulate

HERE = Path(__file__).resolve().parent


def rk4_library():
    source = (HERE / "reference" / "rk4_loop.c").read_text()
    compiler = find_compiler()
    path, _ = build_library(source, compiler)
    lib, _, _ = load_library(path, source, compiler)
    P = ctypes.c_void_p
    lib.rk4_run.argtypes = [
        P,
        P,
        P,
        P,
        ctypes.c_double,
        ctypes.c_int,
        ctypes.c_int,
        ctypes.c_int,
        ctypes.c_double,
        P,
        ctypes.c_double,
        ctypes.c_long,
        P,
        P,
        P,
        P,
        P,
    ]
    lib.rk4_run.restype = ctypes.c_int
    return lib


def rk4(lib, model, y0, t_end: float, h: float):
    """The RK4 yardstick: rows at 0, h, ..., t_end (state, accelerations, multipliers, F, phi)."""
    nq, n, s = len(model.coordinate_names), len(model.speed_names), len(model.constraint_names)
    steps = int(round(t_end / h))
    Y, A = np.empty((steps + 1, nq + n)), np.empty((steps + 1, n))
    L, F, PHI = np.empty((steps + 1, s)), np.empty((steps + 1, s)), np.empty((steps + 1, s))
    y0 = np.ascontiguousarray(y0, dtype=float)
    mlib = model._lib
    status = lib.rk4_run(
        ctypes.cast(mlib.appell_evaluate, ctypes.c_void_p).value,
        ctypes.cast(mlib.appell_residuals, ctypes.c_void_p).value,
        model.default_parameters.ctypes.data,
        model._default_dep.ctypes.data,
        KEEP_CONDITION,
        nq,
        n,
        s,
        0.0,
        y0.ctypes.data,
        h,
        steps,
        Y.ctypes.data,
        A.ctypes.data,
        L.ctypes.data,
        F.ctypes.data,
        PHI.ctypes.data,
    )
    if status:
        raise RuntimeError("the compiled split refused a state in the RK4 yardstick")
    return Y, A, L


def python_projection(run):
    """``run()`` with every projection of the compiled loop in Python."""
    compiled_loop.PROJECT_IN_LOOP = False
    try:
        return run()
    finally:
        compiled_loop.PROJECT_IN_LOOP = True


def compare(name, model, initial, t_end, rate, repeats, lib):
    t_eval = np.linspace(0.0, t_end, int(round(t_end * rate)) + 1)
    kw = dict(t_eval=t_eval, initial=initial, complete=initial is None, progress=False, rtol=1e-9, atol=1e-12)
    loop_sol = simulate(model, t_end, method="DOP853", **kw)
    scipy_sol = simulate(model, t_end, method=si.DOP853, **kw)
    y0 = np.array([loop_sol.states[n][0] for n in model.state_names])
    Y, _, L = rk4(lib, model, y0, t_end, 1.0 / rate)
    lam_loop = np.column_stack([loop_sol.multipliers[c] for c in model.constraint_names])
    lam_scipy = np.column_stack([scipy_sol.multipliers[c] for c in model.constraint_names])
    scale = np.max(np.abs(lam_loop))
    candidates = (
        ("simulate (compiled loop)", lambda: simulate(model, t_end, method="DOP853", **kw)),
        ("  projection in Python", lambda: python_projection(lambda: simulate(model, t_end, method="DOP853", **kw))),
        ("simulate (SciPy DOP853)", lambda: simulate(model, t_end, method=si.DOP853, **kw)),
        ("RK4 in C", lambda: rk4(lib, model, y0, t_end, 1.0 / rate)),
    )
    wall = {key: [] for key, _ in candidates}
    cpu = {key: [] for key, _ in candidates}
    for _ in range(repeats):
        for key, run in candidates:
            w0, c0 = time.perf_counter(), time.process_time()
            run()
            cpu[key].append(time.process_time() - c0)
            wall[key].append(time.perf_counter() - w0)
    st = loop_sol.statistics
    print(
        f"\n{name}: {t_end:g} s, {len(t_eval)} output times; compiled loop {st.steps} steps, {st.nfev} evaluations, "
        f"{st.projections} projections"
    )
    old_sol = python_projection(lambda: simulate(model, t_end, method="DOP853", **kw))
    lam_old = np.column_stack([old_sol.multipliers[c] for c in model.constraint_names])
    print(
        f"  max |lambda| difference: projection in the loop vs in Python {np.max(np.abs(lam_loop - lam_old)) / scale:.1e}"
    )
    print(
        f"  max |lambda| difference: compiled loop vs SciPy path {np.max(np.abs(lam_loop - lam_scipy)) / scale:.1e}, "
        f"vs RK4 {np.max(np.abs(lam_loop - L)) / scale:.1e} (relative to max |lambda| = {scale:.4g})"
    )
    print(
        f"  {'candidate':<26} {'wall median [ms]':>17} {'ratio to RK4':>13} {'CPU median [ms]':>16} "
        f"{'ratio to RK4':>13}"
    )
    result = {}
    for key, _ in candidates:
        w, c = np.array(wall[key]), np.array(cpu[key])
        rw = float(np.median(w / np.array(wall["RK4 in C"])))
        rc = float(np.median(c / np.array(cpu["RK4 in C"])))
        result[key] = {
            "wall_median_s": float(np.median(w)),
            "cpu_median_s": float(np.median(c)),
            "wall_ratio_to_rk4": rw,
            "cpu_ratio_to_rk4": rc,
        }
        print(f"  {key:<26} {1e3 * np.median(w):17.2f} {rw:13.2f} {1e3 * np.median(c):16.2f} {rc:13.2f}")
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--chain", type=int, nargs="*", default=[4, 10], help="chain sizes (none: car only)")
    ap.add_argument("--json")
    args = ap.parse_args()
    lib = rk4_library()
    print(f"Python {sys.version.split()[0]}, {args.repeats} interleaved repeats")
    out = {"car": compare("car", numeric_model(appell.derive(car()), "c"), None, 10.0, 1000.0, args.repeats, lib)}
    sys.path.insert(0, str(HERE))
    from models import nlink_state

    for n in args.chain:
        th, w = nlink_state(n)
        out[f"chain{n}"] = compare(
            f"{n}-link chain, tip on a line",
            numeric_model(appell.derive(nlink_pendulum(n)), "c"),
            np.concatenate([th, w]),
            10.0,
            1000.0,
            max(3, args.repeats // 3),
            lib,
        )
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
