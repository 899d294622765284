"""Time of ``appell derive`` of every bundled example, this tree against a baseline tree,
and of the benchmark bicycle's ``appell derive`` and ``appell report``.

Each command runs in its own process (the derivation cache off: ``APPELL_NO_CACHE=1``), the
baseline's and this tree's in turn for each example, so that a change of the machine's load
moves both alike. A time is the CPU time (user + system) of the process and its children,
imports included: on a machine shared with other work it does not count the time other
processes hold the cores. The target of the printer's work: each example at most its
baseline time + 2 s; the bicycle's derive and report at most 30 s each.

    python benchmarks/derive_times.py --baseline OTHER/src [--examples car,pendulum] [--bicycle]

``OTHER/src`` is the ``src`` folder of another checkout (e.g. ``git archive main src | tar -x
-C /tmp/main``), put first on ``PYTHONPATH`` for its runs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"
#: the slack of the target: this tree's time may exceed the baseline's by this much
SLACK = 2.0
#: the bicycle's target (seconds, each of derive and report)
BICYCLE_LIMIT = 30.0


def cpu_seconds(args: list[str], src: Path, cwd: Path) -> tuple[float, int]:
    """CPU seconds (user + system) of ``python -m appell ARGS`` run with ``src`` first on the
    path, and its exit status."""
    env = {**os.environ, "PYTHONPATH": str(src), "APPELL_NO_CACHE": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "appell", *args], env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return usage.ru_utime + usage.ru_stime, proc.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, help="src folder of the baseline checkout")
    parser.add_argument("--examples", help="comma-separated example names (default: every bundled one)")
    parser.add_argument("--bicycle", action="store_true", help="also time the bicycle's derive and report")
    opts = parser.parse_args()
    sys.path.insert(0, str(SRC))
    from appell.examples import BUILDERS

    names = opts.examples.split(",") if opts.examples else sorted(BUILDERS)
    work = Path(tempfile.mkdtemp(prefix="appell_derive_times_"))
    if opts.baseline is not None:
        print(f"{'example':<30s} {'baseline s':>10s} {'this s':>8s} {'diff s':>8s}  within +{SLACK:g} s")
        worst = 0.0
        for name in names:
            base, rc_b = cpu_seconds(["derive", name], opts.baseline.resolve(), work)
            this, rc_t = cpu_seconds(["derive", name], SRC, work)
            worst = max(worst, this - base)
            flag = "yes" if this <= base + SLACK else "NO"
            fails = "" if rc_b == rc_t == 0 else f"  (exit {rc_b} / {rc_t})"
            print(f"{name:<30s} {base:10.2f} {this:8.2f} {this - base:+8.2f}  {flag}{fails}", flush=True)
        print(f"largest increase: {worst:+.2f} s")
    if opts.bicycle:
        for args in (
            ["derive", "benchmark_bicycle"],
            ["report", "benchmark_bicycle", "-o", str(work / "bicycle.html")],
        ):
            seconds, rc = cpu_seconds(args, SRC, work)
            flag = "yes" if seconds <= BICYCLE_LIMIT and rc == 0 else "NO"
            print(
                f"appell {args[0]} benchmark_bicycle: {seconds:.2f} s (exit {rc}); within {BICYCLE_LIMIT:g} s: {flag}"
            )


if __name__ == "__main__":
    main()
