"""Run every benchmark and print the tables (reproduces docs/performance.md).

    .venv/bin/python benchmarks/run_all.py [--quick] [--out results.txt]

--quick: smaller sizes and a 20 s limit per derivation case (a few minutes in all).
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def machine() -> str:
    model = "unknown CPU"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        model = next(line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("Model name"))
    except (OSError, StopIteration):
        pass
    return f"{model}, {os.cpu_count()} cores, Python {platform.python_version()}, {platform.system()}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", help="also write everything printed to this file")
    args = ap.parse_args()
    py = sys.executable
    runs = [
        [py, HERE / "derivation.py"] + (["--sizes", "2,4,6,8,10", "--limit", "20"] if args.quick else ["--limit", "60"]),
        [py, HERE / "evaluation.py", "--n", "10"] + (["--explicit-limit", "30"] if args.quick else []),
        [py, HERE / "car_simulation.py"],
        [py, HERE / "loop.py"] + (["--repeats", "5", "--chain", "4"] if args.quick else []),
        [py, HERE / "scaling.py"] + (["--sizes", "2,5,10"] if args.quick else []),
    ]
    text = [f"machine: {machine()}"]
    print(text[0], flush=True)
    for cmd in runs:
        header = "\n$ " + " ".join(str(c) for c in cmd[1:])
        print(header, flush=True)
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
        print(proc.stdout, end="", flush=True)
        if proc.returncode:
            print(proc.stderr[-2000:], flush=True)
        text += [header, proc.stdout]
    if args.out:
        Path(args.out).write_text("\n".join(text))


if __name__ == "__main__":
    main()
