"""One evaluation of the accelerations and the loop-closure reaction of the n-link pendulum
(tip on a vertical line), appell against its peers, all at the same state.

    python benchmarks/evaluation.py [--sizes 4,10,20,40] [--setup-limit 120] [--json F] [--markdown F]

Times are CPU time of the process (harness.CLOCK; the C loop: CLOCK_PROCESS_CPUTIME_ID).
From Python (interleaved rounds; a ratio is the median of per-round ratios peer / appell C):
  appell C            CompiledNumericModel.evaluate (one call into the generated C)
  appell NumPy        NumericModel.evaluate
  Pinocchio           computeAllTerms + tip Jacobian row + drift + forwardDynamics (KKT)
  SymPy Kane          KanesMethod + lambdify(cse=True, modules="math") of [M -J^T; J 0], [f; -c]
                      + numpy.linalg.solve
  PyDy Cython         generate_ode_function(generator="cython") on the same augmented system
  dense C, O(n) C     benchmarks/reference/nlink.c and nlink_recursive.c through ctypes
From a C loop (benchmarks/reference/bench_eval.c, candidates interleaved):
  appell_evaluate (appell's generated code), the dense hand-written C, the O(n) recursion.

Before timing, every candidate's accelerations and reaction are compared with the O(n)
recursion (an independent derivation: rod tensions); one that differs by more than 1e-9
relative is not timed (it would compare different physics). A peer that is not installed,
or whose set-up exceeds --setup-limit seconds, is reported as such.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from appell import numeric_model

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import appell  # noqa: E402
from appell.core.derive import derive  # noqa: E402 (the derivation itself, not appell.derive's cache)
from appell.numerics.codegen import compile_c  # noqa: E402
from harness import interleaved, markdown_table, median, optional, ratio, target, us  # noqa: E402
from models import (
    nlink_appell,
    nlink_kane,
    nlink_parameters,
    nlink_pinocchio_function,  # noqa: E402
    nlink_state,
    pinocchio_state,
)

TOLERANCE = 1e-9
APPELL_EVALUATE = re.compile(
    r"int appell_evaluate\(double t, const double \*y, const double \*p, "
    r"const double \*bias, const int \*dep,\s*double cond_max, double \*dy, double \*lam\)"
)


class Timeout(Exception):
    pass


def with_limit(seconds: float, fn):
    """``fn()``, or Timeout after ``seconds`` (SIGALRM interrupts SymPy's Python loops)."""

    def handler(signum, frame):
        raise Timeout()

    old = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        return fn()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def build_reference(workdir: Path):
    """The hand-written references as one shared library, and the C timing loop."""
    cc = shutil.which("cc")
    if cc is None:
        return None, None
    ref = HERE / "reference"
    so, exe = workdir / "nlink.so", workdir / "bench_eval"
    sources = [str(ref / "nlink.c"), str(ref / "nlink_recursive.c")]
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(so), *sources, "-lm"], check=True)
    subprocess.run([cc, "-O2", "-o", str(exe), str(ref / "bench_eval.c"), *sources, "-lm", "-ldl"], check=True)
    return so, exe


def c_function(lib, name: str, n: int, pv: np.ndarray):
    fn = getattr(lib, name)
    fn.argtypes = [ctypes.c_int] + [ctypes.c_void_p] * 4
    dy, lam = np.empty(2 * n), np.empty(1)
    pp = np.ascontiguousarray(pv, dtype=float)

    def call(y):
        yy = np.ascontiguousarray(y, dtype=float)
        fn(n, yy.ctypes.data, pp.ctypes.data, dy.ctypes.data, lam.ctypes.data)
        return dy[n:].copy(), float(lam[0])

    return call


def measure(n: int, args, lib, exe, notes: list[str]) -> dict:
    """Set up every candidate at size n, check it against the O(n) recursion, time them."""
    values = nlink_parameters(n)
    pv = np.array(list(values.values()))
    th, w = nlink_state(n)
    y = np.concatenate([th, w])
    out = {"n": n, "setup": {}, "check": {}, "python": {}, "ratio": {}, "spread": {}, "status": {}, "cloop": None}
    ref_a, ref_lam = c_function(lib, "nlink_recursive", n, pv)(y) if lib else (None, None)
    if ref_a is None:  # no compiler: appell NumPy is the reference
        ev = numeric_model(appell.derive(nlink_appell(n))).evaluate(0.0, y)
        ref_a, ref_lam = ev.derivative[n:], float(ev.multipliers[0])
    scale = max(np.max(np.abs(ref_a)), abs(ref_lam))
    calls = {}

    def add(name, setup, fn, result):
        """Keep ``fn`` for timing if ``result()`` = (accelerations, lam) agrees with the reference."""
        if isinstance(setup, str):
            out["status"][name] = setup
            return
        out["setup"][name] = setup
        a, lam = result()
        diff = float(max(np.max(np.abs(np.asarray(a) - ref_a)), abs(lam - ref_lam)) / scale)
        out["check"][name] = diff
        if diff > TOLERANCE:
            out["status"][name] = f"differs from the O(n) recursion by {diff:.1e} (not timed)"
            return
        calls[name] = fn

    t0 = time.perf_counter()
    d = derive(nlink_appell(n))
    t_derive = time.perf_counter() - t0
    t0 = time.perf_counter()
    cm = compile_c(d, "c") if lib else None
    t_c = time.perf_counter() - t0
    if cm is not None:
        add(
            "appell C",
            t_derive + t_c,
            lambda: cm.evaluate(0.0, y),
            lambda: (cm.evaluate(0.0, y).derivative[n:], float(cm.evaluate(0.0, y).multipliers[0])),
        )
    t0 = time.perf_counter()
    nm = numeric_model(d)
    t_np = time.perf_counter() - t0
    add(
        "appell NumPy",
        t_derive + t_np,
        lambda: nm.evaluate(0.0, y),
        lambda: (nm.evaluate(0.0, y).derivative[n:], float(nm.evaluate(0.0, y).multipliers[0])),
    )

    if optional("pinocchio") is None:
        add("Pinocchio", "not installed (pip install pin)", None, None)
    else:
        t0 = time.perf_counter()
        pin_eval = nlink_pinocchio_function(n)
        setup = time.perf_counter() - t0
        qp, vp = pinocchio_state(th, w)
        # Pinocchio works in relative angles: theta'' = cumsum(ddq) (outside the timed call)
        add(
            "Pinocchio",
            setup,
            lambda: pin_eval(qp, vp),
            lambda: (np.cumsum(pin_eval(qp, vp)[0]), float(pin_eval(qp, vp)[1])),
        )

    kane = None
    try:
        t0 = time.perf_counter()
        kane = with_limit(args.setup_limit, lambda: nlink_kane(n))
        t_kane = time.perf_counter() - t0
    except Timeout:
        add("SymPy Kane", f"KanesMethod > {args.setup_limit:g} s", None, None)
        add("PyDy Cython", f"KanesMethod > {args.setup_limit:g} s", None, None)
    if kane is not None:
        import sympy as sp

        KM, A, b, params, q, u = kane
        pl = [values[s.name] for s in params]
        try:
            t0 = time.perf_counter()
            entries = with_limit(
                args.setup_limit, lambda: sp.lambdify([*q, *u, *params], list(A) + list(b), cse=True, modules="math")
            )
            t_l = time.perf_counter() - t0
            k = n + 1
            thl, wl = th.tolist(), w.tolist()

            def kane_call():
                e = np.array(entries(*thl, *wl, *pl))
                return np.linalg.solve(e[: k * k].reshape(k, k), e[k * k :])

            add("SymPy Kane", t_kane + t_l, kane_call, lambda: (kane_call()[:n], float(kane_call()[n])))
        except Timeout:
            add("SymPy Kane", f"lambdify > {args.setup_limit:g} s", None, None)
        if optional("pydy") is None or optional("Cython") is None:
            add("PyDy Cython", "not installed (pip install pydy cython)", None, None)
        else:
            from pydy.codegen.ode_function_generators import generate_ode_function
            from sympy.physics.mechanics import dynamicsymbols

            lam_state = dynamicsymbols("lam_state")  # stands for lam so that A [u'; lam] = b fits PyDy
            try:
                t0 = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    rhs = with_limit(
                        args.setup_limit,
                        lambda: generate_ode_function(
                            b,
                            q,
                            list(u) + [lam_state],
                            params,
                            mass_matrix=A,
                            coordinate_derivatives=sp.Matrix(u),
                            generator="cython",
                        ),
                    )
                t_p = time.perf_counter() - t0
                x = np.concatenate([th, w, [0.0]])
                pk = np.array(pl)
                add(
                    "PyDy Cython",
                    t_kane + t_p,
                    lambda: rhs(x, 0.0, pk),
                    lambda: (rhs(x, 0.0, pk)[n : 2 * n], float(rhs(x, 0.0, pk)[2 * n])),
                )
            except Timeout:
                add("PyDy Cython", f"Cython generation > {args.setup_limit:g} s", None, None)
            except Exception as exc:  # noqa: BLE001 (a failing peer is reported, not fatal)
                add("PyDy Cython", f"failed: {type(exc).__name__}: {str(exc)[:80]}", None, None)

    if lib is not None:
        dense, rec = c_function(lib, "nlink_evaluate", n, pv), c_function(lib, "nlink_recursive", n, pv)
        add("dense C (ctypes)", 0.0, lambda: dense(y), lambda: dense(y))
        add("O(n) C (ctypes)", 0.0, lambda: rec(y), lambda: rec(y))

    times = interleaved(calls, rounds=args.rounds)
    base = "appell C" if "appell C" in times else "appell NumPy"
    for name, ts in times.items():
        out["python"][name] = median(ts)
        out["ratio"][name] = ratio(times, name, base)
        out["spread"][name] = [min(t / b for t, b in zip(ts, times[base])), max(t / b for t, b in zip(ts, times[base]))]
    out["base"] = base

    if exe is not None and cm is not None:
        src = Path(cm.library_path).with_suffix(".c")
        text = src.read_text() if src.exists() else ""
        lib_arg = str(cm.library_path) if APPELL_EVALUATE.search(text) else "-"
        if lib_arg == "-":
            notes.append(f"n = {n}: appell_evaluate's C signature changed: update benchmarks/reference/bench_eval.c")
        iters = max(2000, int(2e6 / n**2))
        proc = subprocess.run(
            [
                str(exe),
                lib_arg,
                str(n),
                str(iters),
                str(d.partition.dependent[0]),
                *map(repr, y.tolist()),
                *map(repr, pv.tolist()),
            ],
            capture_output=True,
            text=True,
        )
        if proc.returncode == 0:
            out["cloop"] = json.loads(proc.stdout)
        else:
            notes.append(f"n = {n}: C loop failed: {proc.stderr.strip()[:200]}")
    return out


ORDER = ("appell C", "appell NumPy", "Pinocchio", "SymPy Kane", "PyDy Cython", "dense C (ctypes)", "O(n) C (ctypes)")


def markdown(results: list[dict]) -> str:
    head = ["implementation, called from Python (CPU time per call)"] + [f"n = {r['n']}" for r in results]
    rows = []
    for name in ORDER:
        cells = []
        for r in results:
            if name in r["python"]:
                cells.append(f"{us(r['python'][name])} ({r['ratio'][name]:.2f}×)")
            else:
                cells.append(r["status"].get(name, "—"))
        rows.append([name] + cells)
    rows.append(
        ["largest relative difference from the O(n) recursion"] + [f"{max(r['check'].values()):.0e}" for r in results]
    )
    py = markdown_table(head, rows)
    crow = []
    for r in results:
        c = r["cloop"]
        if c is None:
            continue
        appell_cell = us(c["appell_ns"] * 1e-9) if c["has_appell"] else "n/a"
        ratio_cell = f"**{c['appell_over_recursive']:.2f}×**" if c["has_appell"] else "n/a"
        crow.append(
            [
                str(r["n"]),
                appell_cell,
                us(c["dense_ns"] * 1e-9),
                us(c["recursive_ns"] * 1e-9),
                ratio_cell,
                f"{c['dense_over_recursive']:.2f}×",
                f"{max(c['max_abs_diff_appell'], c['max_abs_diff_dense']):.0e}",
            ]
        )
    cl = markdown_table(
        [
            "n",
            "appell generated C",
            "dense hand-written C",
            "O(n) recursion in C",
            "appell / O(n)",
            "dense / O(n)",
            "max abs. difference",
        ],
        crow,
    )
    goals = []
    for r in results:
        c, n = r["cloop"], r["n"]
        if c and c["has_appell"] and n in (10, 40):
            goals.append(
                target(f"C loop, n = {n}: appell / O(n) recursion", c["appell_over_recursive"], 1.5 if n == 10 else 3.0)
            )
    for r in results:
        if r["n"] in (10, 20, 40) and "Pinocchio" in r["ratio"] and r["base"] == "appell C":
            goals.append(
                target(
                    f"from Python, n = {r['n']}: Pinocchio / appell C (above 1: appell faster)",
                    r["ratio"]["Pinocchio"],
                    1.0,
                    below=False,
                )
            )
    return (
        py
        + "\n\nFrom a C loop (CPU time of one evaluation, candidates interleaved):\n\n"
        + cl
        + ("\n\nTargets (issue 13):\n\n" + "\n".join(goals) if goals else "")
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="4,10,20,40")
    ap.add_argument("--setup-limit", type=float, default=120.0, help="seconds allowed to set up one peer")
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--json", help="also write the results here")
    ap.add_argument("--markdown", help="also write the tables (Markdown) here")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="appell_eval_"))
    so, exe = build_reference(work)
    lib = ctypes.CDLL(str(so)) if so else None
    notes = [] if so else ["no C compiler: appell C and the C references are not built"]
    results = []
    for n in map(int, args.sizes.split(",")):
        r = measure(n, args, lib, exe, notes)
        results.append(r)
        print(f"n = {n}: time per call from Python (ratio to {r['base']}, median of paired rounds)")
        for name in ORDER:
            if name in r["python"]:
                print(
                    f"  {name:<18} {us(r['python'][name]):>10} {r['ratio'][name]:6.2f}x   "
                    f"set-up {r['setup'][name]:6.1f} s   diff {r['check'][name]:.0e}"
                )
            else:
                print(f"  {name:<18} {r['status'].get(name, '-')}")
        if r["cloop"]:
            c = r["cloop"]
            print(
                f"  C loop: appell {c['appell_ns']:.0f} ns, dense {c['dense_ns']:.0f} ns, O(n) "
                f"{c['recursive_ns']:.0f} ns; appell/O(n) {c['appell_over_recursive']:.2f}, "
                f"dense/O(n) {c['dense_over_recursive']:.2f}"
            )
        sys.stdout.flush()
    for note in notes:
        print("note:", note)
    if args.json:
        Path(args.json).write_text(json.dumps({"results": results, "notes": notes}, indent=1))
    if args.markdown:
        Path(args.markdown).write_text(markdown(results) + "".join(f"\n\nNote: {x}" for x in notes) + "\n")


if __name__ == "__main__":
    main()
