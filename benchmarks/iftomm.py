"""The IFToMM benchmark problems on the command line (issue 19): the time a user waits for
``appell derive``, ``check``, ``simulate`` and ``report`` on the bundled model files, each
command a fresh process with an empty compiled-code cache (the derivation, the C compiler
and the integration all counted), and its peak memory.

    python benchmarks/iftomm.py [--quick] [--markdown FILE]

Targets of the issue: A02 with N = 40 four-bars simulated over the library's 20 s within
60 s; ``derive`` and ``report`` of A02 (N = 10) and of Bricard's mechanism (A04) within 60 s
each; the stiff flyball governor (A05) over its 10 s with every ``--method``. ``--quick``
leaves out N = 40. Issue 22 adds the benchmark bicycle (Meijaard et al. 2007): ``derive``,
``check`` and ``report`` within 30 s each (``--model benchmark_bicycle``).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from appell.examples import example_path  # noqa: E402
from appell.simulation.simulate import METHODS  # noqa: E402
from harness import load, machine, today  # noqa: E402

#: (model file, commands) in the order run
CASES = [
    ("iftomm_a02_n10", ("derive", "check", "simulate", "report")),
    ("bricard", ("derive", "check", "simulate", "report")),
    ("iftomm_a02_n40", ("simulate",)),
    ("iftomm_a05_governor", ("derive", "check", "report") + tuple(f"simulate --method {m}" for m in METHODS)),
    ("benchmark_bicycle", ("derive", "check", "report")),
]


def run(command: str, model: str, folder: Path) -> tuple[float, float, int, str]:
    """(wall seconds, peak MB of the process, exit code, last line) of one command."""
    path = example_path(model)
    command, *options = command.split()
    argv = [sys.executable, "-m", "appell", command, str(path), *options]
    if command == "simulate":
        argv += ["--out", str(folder / f"{model}{''.join(options)}.h5")]
    elif command == "report":
        argv += ["-o", str(folder / f"{model}.html")]
    env = {**os.environ, "APPELL_CACHE_DIR": str(folder / f"cache-{model}-{command}")}
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    proc = subprocess.run(argv, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    lines = (proc.stdout + proc.stderr).strip().splitlines()
    # ru_maxrss of the children is the largest so far: a smaller process reads as the earlier peak
    return wall, max(peak, before) / 1024.0, proc.returncode, (lines[-1] if lines else "")[:90]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="leave out A02 with N = 40")
    ap.add_argument("--model", action="append", help="run only this model file (repeatable)")
    ap.add_argument("--markdown", help="also write the table as Markdown to this file")
    args = ap.parse_args()
    head = f"machine: {machine()}; date: {today()}; {load()} at the start"
    print(head)
    rows = []
    with tempfile.TemporaryDirectory(prefix="appell_iftomm_") as tmp:
        folder = Path(tmp)
        for model, commands in CASES:
            if (args.quick and model == "iftomm_a02_n40") or (args.model and model not in args.model):
                continue
            for command in commands:
                wall, peak, code, last = run(command, model, folder)
                rows.append((model, command, wall, peak, code, last))
                print(
                    f"{model:16s} {command:30s} {wall:7.1f} s  peak <= {peak:6.0f} MB  exit {code}  {last}", flush=True
                )
    if args.markdown:
        out = [
            head,
            "",
            "| model file | command | wall time | peak memory (largest so far) | exit |",
            "|---|---|---|---|---|",
        ]
        out += [f"| {m} | `appell {c}` | {w:.1f} s | {p:.0f} MB | {code} |" for m, c, w, p, code, _ in rows]
        out += [
            "",
            "Each command a fresh process with an empty compiled-code cache (derivation, C compiler and "
            "integration included); `simulate` writes HDF5, `report` the HTML report.",
        ]
        Path(args.markdown).write_text("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
