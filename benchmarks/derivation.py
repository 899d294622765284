"""Derivation cost vs n: time and peak memory to go from the model to numeric functions
giving the accelerations and the loop-closure reaction of the n-link pendulum.

Each case runs in its own subprocess (peak memory = ``ru_maxrss`` of that process,
which includes the ~100 MB of the interpreter with SymPy imported) under a time limit,
so that a blow-up shows as ``> limit``. Once a method exceeds the limit its larger cases
are not run.

    .venv/bin/python benchmarks/derivation.py [--sizes 2,4,...] [--limit 60]

Methods
-------
appell          derive + NumPy numeric functions (blocks M, h-Q, J, c; split solve numerically)
appell-c        derive + C library (blocks and split solve in C; gcc -O2, empty cache)
lagrange        LagrangesMethod(hol_coneqs) + lambdify(cse) of the augmented M, F
lagrange-expl   ... + explicit symbolic solve M^-1 F (the ``rhs()`` route) + lambdify(cse)
kane            KanesMethod + tip force lam + constraint row, lambdify(cse) of A, b
kane-expl       ... + explicit symbolic solve A^-1 b + lambdify(cse)
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

HERE = Path(__file__).resolve().parent
METHODS = ("appell", "appell-c", "lagrange", "lagrange-expl", "kane", "kane-expl")


def run_case(method: str, n: int) -> dict:
    """Derive in this process and return the elapsed time (imports excluded)."""
    import sympy as sp

    sys.path.insert(0, str(HERE))
    import appell
    from models import nlink_appell, nlink_kane, nlink_lagrange

    t0 = time.perf_counter()
    if method in ("appell", "appell-c"):
        d = appell.derive(nlink_appell(n))
        if method == "appell":
            d.numeric
        else:
            from appell.numerics.codegen_c import compile_c

            compile_c(d, "c")
    elif method.startswith("lagrange"):
        LM, M, F, params, q, qd = nlink_lagrange(n)
        args = [q, qd, params]
        if method == "lagrange":
            sp.lambdify(args, [M, F], cse=True)
        else:
            sp.lambdify(args, [M.LUsolve(F)], cse=True)
    else:
        KM, A, b, params, q, u = nlink_kane(n)
        args = [q, u, params]
        if method == "kane":
            sp.lambdify(args, [A, b], cse=True)
        else:
            sp.lambdify(args, [A.LUsolve(b)], cse=True)
    return {"seconds": time.perf_counter() - t0}


def measure(method: str, n: int, limit: float) -> dict:
    env = dict(os.environ)
    if method == "appell-c":
        env["APPELL_CACHE_DIR"] = tempfile.mkdtemp(prefix="appell_bench_")
    cmd = [sys.executable, __file__, "--case", method, "--n", str(n)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=limit, env=env)
    except subprocess.TimeoutExpired:
        return {"seconds": None, "rss_mb": None, "status": f"> {limit:g} s"}
    if proc.returncode != 0:
        return {"seconds": None, "rss_mb": None, "status": "error: " + proc.stderr.strip().splitlines()[-1][:80]}
    return json.loads(proc.stdout.strip().splitlines()[-1]) | {"status": "ok"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2,4,6,8,10,12,15,20")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--limit", type=float, default=60.0, help="seconds per case")
    ap.add_argument("--json", help="also write the results here")
    ap.add_argument("--case", help=argparse.SUPPRESS)
    ap.add_argument("--n", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        out = run_case(args.case, args.n)
        out["rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(json.dumps(out))
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    methods = args.methods.split(",")
    results, dead = {}, set()
    print(f"derivation time [s] / peak RSS [MB] per case (limit {args.limit:g} s)")
    print(f"{'n':>3} " + " ".join(f"{m:>18}" for m in methods))
    for n in sizes:
        cells = []
        for m in methods:
            r = {"seconds": None, "rss_mb": None, "status": "skipped (smaller n over limit)"} if m in dead \
                else measure(m, n, args.limit)
            if r["status"] != "ok":
                dead.add(m)
                cells.append(f"{'> limit' if r['status'].startswith('>') or m in dead and 'skip' in r['status'] else r['status'][:18]:>18}")
            else:
                cells.append(f"{r['seconds']:8.2f} / {r['rss_mb']:6.0f}".rjust(18))
            results[f"{m}:{n}"] = r
        print(f"{n:>3} " + " ".join(cells), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
