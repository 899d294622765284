"""Derivation cost vs n: time and peak memory from the model to numeric functions giving
the accelerations and the loop-closure reaction of the n-link pendulum.

Each case runs in its own subprocess under a time limit, so that a blow-up shows as
``> limit``; once a method exceeds the limit its larger cases are not run. Peak memory is
the largest memory (proportional set size) of the case's process tree (the case, including the ~100 MB of
the interpreter with SymPy imported, plus the C compiler or the Cython build it runs),
sampled every 10 ms, and at least the case's own ``ru_maxrss``. The methods run in turn for each n.

    python benchmarks/derivation.py [--sizes 2,4,...] [--limit 60] [--file-sizes 50] [--markdown F]

Methods
-------
appell          derive + NumPy numeric functions (blocks M, h-Q, J, c; split solve numerically)
appell-c        derive + C library (blocks and split solve in C; empty cache, compiler included)
kane            KanesMethod + tip force lam + constraint row, lambdify(cse, modules="math") of
                the entries of A = [M -J^T; J 0], b = [f; -c] (SymPy's best practice)
pydy            the same KanesMethod + PyDy generate_ode_function(generator="cython") (Cython
                and the C compiler included)
lagrange        LagrangesMethod(hol_coneqs) + lambdify(cse) of the augmented M, F
kane-expl       KanesMethod + explicit symbolic solve A^-1 b + lambdify(cse)
appell-file     (--file-sizes) the model file (benchmarks.models.nlink_model_file) loaded,
                derived, compiled to C with an empty cache, and the first evaluation made
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from appell import numeric_model
from appell.core.derive import derive  # the derivation itself, not appell.derive's cache

HERE = Path(__file__).resolve().parent
METHODS = ("appell", "appell-c", "kane", "pydy", "lagrange", "kane-expl")
LABELS = {
    "appell": "appell (NumPy)",
    "appell-c": "appell (C, empty cache)",
    "kane": "SymPy Kane + lambdify",
    "pydy": "PyDy Cython",
    "lagrange": "SymPy Lagrange + lambdify",
    "kane-expl": "Kane explicit A⁻¹b",
    "appell-file": "appell: model file → first compiled evaluation",
}


def run_case(method: str, n: int) -> dict:
    """Derive in this process and return the elapsed time (imports excluded)."""
    import numpy as np
    import sympy as sp

    sys.path.insert(0, str(HERE))
    from models import file_parameters, nlink_appell, nlink_kane, nlink_lagrange, nlink_model_file, nlink_state

    if method == "appell-file":
        path = Path(tempfile.mkdtemp(prefix="appell_file_")) / f"pendulum{n}.toml"
        path.write_text(nlink_model_file(n))
        from appell.io.modelfile.loader import load_model
        from appell.numerics.codegen import compile_c

        th, w = nlink_state(n, params=file_parameters(n))
        t0 = time.perf_counter()
        cm = compile_c(derive(load_model(path)), "c")
        ev = cm.evaluate(0.0, np.concatenate([th, w]))
        seconds = time.perf_counter() - t0
        if not np.all(np.isfinite(ev.derivative)):
            raise RuntimeError("the first evaluation is not finite")
        return {"seconds": seconds}
    t0 = time.perf_counter()
    if method in ("appell", "appell-c"):
        d = derive(nlink_appell(n))
        if method == "appell":
            numeric_model(d)  # noqa: B018 (made on first access: the time measured)
        else:
            from appell.numerics.codegen import compile_c

            compile_c(d, "c")
    elif method == "lagrange":
        LM, M, F, params, q, qd = nlink_lagrange(n)
        sp.lambdify([q, qd, params], [M, F], cse=True)
    else:
        KM, A, b, params, q, u = nlink_kane(n)
        if method == "kane":
            sp.lambdify([*q, *u, *params], list(A) + list(b), cse=True, modules="math")
        elif method == "kane-expl":
            sp.lambdify([q, u, params], [A.LUsolve(b)], cse=True)
        else:
            import warnings

            from pydy.codegen.ode_function_generators import generate_ode_function
            from sympy.physics.mechanics import dynamicsymbols

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                generate_ode_function(
                    b,
                    q,
                    list(u) + [dynamicsymbols("lam_state")],
                    params,
                    mass_matrix=A,
                    coordinate_derivatives=sp.Matrix(u),
                    generator="cython",
                )
    return {"seconds": time.perf_counter() - t0}


def tree_rss_mb(pid: int) -> float:
    """Memory of a process and all its descendants now [MB]: the sum of their proportional
    set sizes (Linux /proc/PID/smaps_rollup; pages shared after a fork count once)."""
    total, stack = 0, [pid]
    while stack:
        p = stack.pop()
        try:
            rollup = Path(f"/proc/{p}/smaps_rollup").read_text()
            total += next(int(line.split()[1]) for line in rollup.splitlines() if line.startswith("Pss:"))
            for task in Path(f"/proc/{p}/task").iterdir():
                stack += [int(c) for c in (task / "children").read_text().split()]
        except (OSError, StopIteration, ValueError):
            continue
    return total / 1024


def measure(method: str, n: int, limit: float) -> dict:
    """One case in a subprocess; its peak memory is the largest sum of the resident memory
    of the case and its running descendants (the compiler), sampled every 10 ms, and at least
    the case's own ``ru_maxrss``."""
    env = dict(os.environ)
    env["APPELL_CACHE_DIR"] = tempfile.mkdtemp(prefix="appell_bench_")
    cmd = [sys.executable, __file__, "--case", method, "--n", str(n)]
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(
            cmd, stdout=out, stderr=err, text=True, env=env, cwd=tempfile.mkdtemp(prefix="appell_case_")
        )
        start, peak = time.monotonic(), 0.0
        while proc.poll() is None:
            if time.monotonic() - start > limit:
                proc.kill()
                proc.wait()
                return {"seconds": None, "rss_mb": None, "status": f"> {limit:g} s"}
            peak = max(peak, tree_rss_mb(proc.pid))
            time.sleep(0.01)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    if proc.returncode != 0:
        lines = stderr.strip().splitlines() or ["no output"]
        if "ModuleNotFoundError" in stderr:
            return {"seconds": None, "rss_mb": None, "status": "not installed"}
        return {"seconds": None, "rss_mb": None, "status": "error: " + lines[-1][:80]}
    r = json.loads(stdout.strip().splitlines()[-1])
    return r | {"status": "ok", "tree_peak_mb": peak, "rss_mb": max(peak, r["self_mb"])}


def cell(r: dict) -> str:
    if r["status"] != "ok":
        return r["status"]
    return f"{r['seconds']:.2f} s / {r['rss_mb']:.0f} MB"


def markdown(results: dict, sizes, methods, file_sizes) -> str:
    rows = []
    for n in sizes:
        row = [str(n)] + [cell(results[f"{m}:{n}"]) for m in methods]
        a, k = results.get(f"appell:{n}"), results.get(f"kane:{n}")
        ok = a and k and a["status"] == k["status"] == "ok"
        row.append(f"{a['seconds'] / k['seconds']:.2f}×" if ok else "—")
        rows.append(row)
    from harness import markdown_table

    text = markdown_table(["n"] + [LABELS[m] for m in methods] + ["appell (NumPy) / Kane"], rows)
    if file_sizes:
        from harness import target

        text += "\n\n" + markdown_table(
            ["n", LABELS["appell-file"]], [[str(n), cell(results[f"appell-file:{n}"])] for n in file_sizes]
        )
        goals = []
        for n in file_sizes:
            r = results[f"appell-file:{n}"]
            ok = r["status"] == "ok"
            if not ok and r["status"].startswith(">"):
                goals.append(f"- n = {n}, model file to first compiled step: {r['status']}, **not met**")
            elif n == 50:
                goals += [
                    target("n = 50, model file to first compiled step: time", r["seconds"] if ok else None, 60, " s"),
                    target("n = 50: peak memory with the compiler", r["rss_mb"] if ok else None, 1000, " MB"),
                ]
            elif n == 100:
                goals += [
                    target("n = 100: time", r["seconds"] if ok else None, 600, " s"),
                    target("n = 100: peak memory", r["rss_mb"] if ok else None, 4000, " MB"),
                ]
        if goals:
            text += "\n\nTargets (issue 13):\n\n" + "\n".join(goals)
    return text


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2,4,6,8,10,12,15,20")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--limit", type=float, default=60.0, help="seconds per case")
    ap.add_argument("--file-sizes", default="", help="sizes of the model-file case (e.g. 50)")
    ap.add_argument("--file-limit", type=float, default=600.0, help="seconds per model-file case")
    ap.add_argument("--json", help="also write the results here")
    ap.add_argument("--markdown", help="also write the table (Markdown) here")
    ap.add_argument("--case", help=argparse.SUPPRESS)
    ap.add_argument("--n", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        out = run_case(args.case, args.n)
        own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        out |= {"self_mb": own, "children_mb": children}
        print(json.dumps(out))
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    methods = args.methods.split(",")
    results, dead = {}, set()
    print(f"derivation time [s] / peak memory of the process tree [MB] per case (limit {args.limit:g} s)")
    print(f"{'n':>3} " + " ".join(f"{m:>18}" for m in methods))
    for n in sizes:
        cells = []
        for m in methods:
            r = (
                {"seconds": None, "rss_mb": None, "status": "> limit at smaller n"}
                if m in dead
                else measure(m, n, args.limit)
            )
            if r["status"] != "ok":
                dead.add(m)
            cells.append(cell(r)[:18].rjust(18))
            results[f"{m}:{n}"] = r
        print(f"{n:>3} " + " ".join(cells), flush=True)
    file_sizes = [int(s) for s in args.file_sizes.split(",") if s]
    for n in file_sizes:
        r = measure("appell-file", n, args.file_limit)
        results[f"appell-file:{n}"] = r
        print(
            f"model file -> first compiled evaluation, n = {n}: {cell(r)}"
            + (f" (own ru_maxrss {r['self_mb']:.0f} MB)" if r["status"] == "ok" else ""),
            flush=True,
        )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    if args.markdown:
        sys.path.insert(0, str(HERE))
        Path(args.markdown).write_text(markdown(results, sizes, methods, file_sizes) + "\n")


if __name__ == "__main__":
    main()
