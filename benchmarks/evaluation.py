"""Cost of one numeric evaluation of the accelerations and the loop-closure reaction of
the n-link pendulum (default n = 10), all implementations at the same state.

    .venv/bin/python benchmarks/evaluation.py [--n 10] [--explicit-limit 120]

Rows (time per call, best of 5 repeats):
  appell numpy        NumericModel.evaluate  (lambdify(cse) blocks + split solve in NumPy/SciPy)
  appell C (Python)   CompiledNumericModel.evaluate  (one ctypes call: blocks + split solve in C)
  appell C (C loop)   appell_evaluate called from a C timing loop
  hand-written C      benchmarks/reference/nlink.c, from a C loop and through ctypes
  sympy lambdify M,F  LagrangesMethod, lambdify(cse) of the augmented M, F + numpy.linalg.solve
  sympy explicit      lambdify(cse) of the explicit symbolic solution M^-1 F (if derivable in time)
  pydy                PyDy generate_ode_function (cython, else lambdify) on Kane's augmented system
"""

from __future__ import annotations

import argparse
import ctypes
import json
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import timeit
import warnings
from pathlib import Path

import numpy as np
import sympy as sp

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import appell  # noqa: E402
from appell.numerics.codegen_c import compile_c  # noqa: E402
from models import nlink_kane, nlink_lagrange, nlink_parameters, nlink_state  # noqa: E402


def per_call(fn, repeat: int = 5) -> float:
    """Best time per call [s] (timeit autorange, best of ``repeat``)."""
    timer = timeit.Timer(fn)
    number, _ = timer.autorange()
    return min(timer.repeat(repeat, number)) / number


class Timeout(Exception):
    pass


def with_limit(seconds: float, fn):
    """Run ``fn()``; raise Timeout after ``seconds`` (SIGALRM interrupts SymPy's Python loops)."""
    def handler(signum, frame):
        raise Timeout()
    old = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        return fn()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def build_reference(workdir: Path) -> tuple[Path | None, Path | None]:
    """Compile the hand-written reference as a shared library and the C timing loop."""
    cc = shutil.which("cc")
    if cc is None:
        return None, None
    ref = HERE / "reference"
    so, exe = workdir / "nlink.so", workdir / "bench_eval"
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(so), str(ref / "nlink.c"), "-lm"], check=True)
    subprocess.run([cc, "-O2", "-o", str(exe), str(ref / "bench_eval.c"), str(ref / "nlink.c"), "-lm", "-ldl"],
                   check=True)
    return so, exe


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--explicit-limit", type=float, default=120.0,
                    help="seconds allowed to derive SymPy's explicit solution")
    ap.add_argument("--json", help="also write the results here")
    args = ap.parse_args()
    n = args.n
    work = Path(tempfile.mkdtemp(prefix="appell_eval_"))
    rows, notes = {}, []

    values = nlink_parameters(n)
    d = appell.derive(__import__("models").nlink_appell(n))
    pv = np.array([p.value for p in d.system.parameters])
    th, w = nlink_state(n)
    y = np.concatenate([th, w])
    nm = d.numeric
    cm = compile_c(d, "c")
    ev_np, ev_c = nm.evaluate(0.0, y), cm.evaluate(0.0, y)
    ref_out = np.concatenate([ev_np.derivative[n:], ev_np.multipliers])
    check = {}

    def record(name, seconds, out):
        rows[name] = seconds
        if out is not None:
            check[name] = float(np.max(np.abs(np.asarray(out) - ref_out)) / np.max(np.abs(ref_out)))

    record("appell numpy", per_call(lambda: nm.evaluate(0.0, y)), ref_out)
    record("appell C (Python)", per_call(lambda: cm.evaluate(0.0, y)),
           np.concatenate([ev_c.derivative[n:], ev_c.multipliers]))

    so, exe = build_reference(work)
    if so is not None:
        lib = ctypes.CDLL(str(so))
        lib.nlink_evaluate.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                                       ctypes.c_void_p]
        dy, lam = np.empty(2 * n), np.empty(1)

        def ref_call():
            yy = np.ascontiguousarray(y, dtype=float)
            pp = np.ascontiguousarray(pv, dtype=float)
            lib.nlink_evaluate(n, yy.ctypes.data, pp.ctypes.data, dy.ctypes.data, lam.ctypes.data)
            return dy, lam

        ref_call()
        record("hand-written C (Python)", per_call(ref_call), np.concatenate([dy[n:], lam]))
        dep = str(d.partition.dependent[0])
        out = subprocess.run([str(exe), str(cm.library_path), str(n), "200000", dep,
                              *map(repr, y.tolist()), *map(repr, pv.tolist())],
                             capture_output=True, text=True, check=True)
        loop = json.loads(out.stdout)
        rows["appell C (C loop)"] = loop["appell_c_ns"] * 1e-9
        rows["hand-written C (C loop)"] = loop["reference_ns"] * 1e-9
        check["C loop: appell vs hand-written (abs)"] = loop["max_abs_diff"]
    else:
        notes.append("no C compiler: hand-written reference not built")

    # SymPy LagrangesMethod: numeric solve of the lambdified augmented system
    t0 = time.perf_counter()
    LM, M, F, params, q, qd = nlink_lagrange(n)
    MF = sp.lambdify([q, qd, params], [M, F], cse=True)
    t_lag = time.perf_counter() - t0
    pl = [values[s.name] for s in params]

    def lag_call():
        Mn, Fn = MF(th, w, pl)
        return np.linalg.solve(Mn, Fn.ravel())

    sol = lag_call()
    # sympy's multiplier sign/scale: compare the reaction up to sign (same constraint x_tip - d)
    record("sympy lambdify M,F + solve", per_call(lag_call), np.concatenate([sol[:n], [sol[n] * np.sign(sol[n] * ref_out[n])]]))
    notes.append(f"LagrangesMethod derivation + lambdify: {t_lag:.1f} s")

    # SymPy explicit solution
    try:
        t0 = time.perf_counter()
        expl = with_limit(args.explicit_limit,
                          lambda: sp.lambdify([q, qd, params], [M.LUsolve(F)], cse=True))
        notes.append(f"explicit symbolic solve + lambdify: {time.perf_counter() - t0:.1f} s")
        out = np.asarray(expl(th, w, pl)[0], float).ravel()
        record("sympy explicit solution", per_call(lambda: expl(th, w, pl)),
               np.concatenate([out[:n], [out[n] * np.sign(out[n] * ref_out[n])]]))
    except Timeout:
        rows["sympy explicit solution"] = None
        notes.append(f"explicit symbolic solve + lambdify did not finish in {args.explicit_limit:g} s")

    # PyDy
    try:
        from pydy.codegen.ode_function_generators import generate_ode_function
        from sympy.physics.mechanics import dynamicsymbols

        KM, A, b, kparams, kq, ku = nlink_kane(n)
        lam_state = dynamicsymbols("lam_state")   # stands for lam so that A [u'; lam] = b fits PyDy
        made = None
        for gen in ("cython", "lambdify"):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t0 = time.perf_counter()
                    rhs = generate_ode_function(b, kq, list(ku) + [lam_state], kparams, mass_matrix=A,
                                                coordinate_derivatives=sp.Matrix(ku), generator=gen)
                    made = (gen, rhs, time.perf_counter() - t0)
                break
            except Exception as exc:  # noqa: BLE001 (report and try the next generator)
                notes.append(f"pydy generator {gen!r} failed: {type(exc).__name__}: {str(exc)[:100]}")
        if made:
            gen, rhs, t_gen = made
            x = np.concatenate([th, w, [0.0]])
            pk = np.array([values[s.name] for s in kparams])
            out = rhs(x, 0.0, pk)
            record(f"pydy ({gen})", per_call(lambda: rhs(x, 0.0, pk)),
                   np.concatenate([out[n:2 * n], [out[2 * n] * np.sign(out[2 * n] * ref_out[n])]]))
            notes.append(f"pydy code generation ({gen}): {t_gen:.1f} s")
    except ImportError:
        rows["pydy"] = None
        notes.append("pydy is not installed (pip install pydy)")

    import platform
    print(f"one evaluation of accelerations + reaction, n = {n} ({platform.python_version()}, {platform.machine()})")
    print(f"{'implementation':<30} {'time/call':>12} {'vs hand C (C loop)':>20} {'rel. diff vs appell':>20}")
    base = rows.get("hand-written C (C loop)")
    for name, sec in rows.items():
        if sec is None:
            print(f"{name:<30} {'n/a':>12}")
            continue
        ratio = f"{sec / base:.1f}x" if base else "-"
        diff = check.get(name)
        print(f"{name:<30} {sec * 1e6:10.2f} us {ratio:>20} {'' if diff is None else f'{diff:.1e}':>20}")
    for k, v in check.items():
        if k.startswith("C loop"):
            print(f"{k}: {v:.1e}")
    for note in notes:
        print("note:", note)
    if args.json:
        Path(args.json).write_text(json.dumps({"n": n, "seconds": rows, "check": check, "notes": notes}, indent=1))


if __name__ == "__main__":
    main()
