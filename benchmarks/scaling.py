"""How appell's cost grows with the number of speeds n and of constraints s: derivation
(derive + NumPy functions), C generation + compilation, and one evaluation (NumPy and C,
called from Python) of the n-link pendulum with s = 1 (tip on a vertical line) and s = 2
(tip held at a point).

    .venv/bin/python benchmarks/scaling.py [--sizes 2,5,10,20]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import appell  # noqa: E402
from models import nlink_appell, nlink_state  # noqa: E402


def per_call(fn) -> float:
    timer = timeit.Timer(fn)
    number, _ = timer.autorange()
    return min(timer.repeat(5, number)) / number


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2,5,10,20")
    args = ap.parse_args()
    os.environ["APPELL_CACHE_DIR"] = tempfile.mkdtemp(prefix="appell_scaling_")
    print(f"{'n':>3} {'s':>2} {'derive [s]':>11} {'numpy fns [s]':>14} {'C gen+cc [s]':>13} {'C source [kB]':>14} "
          f"{'eval numpy [us]':>16} {'eval C [us]':>12}")
    for n in map(int, args.sizes.split(",")):
        for s in (1, 2):
            if s > n - 1:
                continue
            t0 = time.perf_counter()
            d = appell.derive(nlink_appell(n, s))
            t1 = time.perf_counter()
            nm = d.numeric
            t2 = time.perf_counter()
            cm = d.compiled("c")
            t3 = time.perf_counter()
            th, w = nlink_state(n)
            y = np.concatenate([th, w])
            e_np, e_c = per_call(lambda: nm.evaluate(0.0, y)), per_call(lambda: cm.evaluate(0.0, y))
            src = cm.library_path.with_suffix(".c").stat().st_size / 1024
            print(f"{n:>3} {s:>2} {t1 - t0:11.2f} {t2 - t1:14.2f} {t3 - t2:13.2f} {src:14.0f} "
                  f"{e_np * 1e6:16.1f} {e_c * 1e6:12.2f}", flush=True)


if __name__ == "__main__":
    main()
