"""Shared tools of the benchmarks: interleaved timing, the machine, optional peers, tables.

Every comparison is a ratio taken in one run with the candidates interleaved: each round
times every candidate once, in turn, and a ratio is the median of the per-round ratios, so
that a change of the machine's speed during the run (other processes on a shared machine)
moves all candidates alike.

In-process timings read :data:`CLOCK`, the CPU time of this process
(``time.process_time``, CLOCK_PROCESS_CPUTIME_ID): every candidate is single-threaded,
so on a quiet machine it equals the wall time, and on a machine shared with other work it
does not count the time other processes hold the cores.
"""

from __future__ import annotations

import datetime
import importlib
import os
import platform
import re
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
CLOCK = time.process_time
CLOCK_NAME = "CPU time of the process"


def batch_size(fn: Callable[[], object], seconds: float = 0.01) -> int:
    """Calls of ``fn`` that take about ``seconds`` (at least 1)."""
    number = 1
    while True:
        t0 = CLOCK()
        for _ in range(number):
            fn()
        elapsed = CLOCK() - t0
        if elapsed >= seconds or number >= 1 << 24:
            return max(1, int(number * seconds / max(elapsed, 1e-9)))
        number *= 4


def interleaved(
    candidates: Mapping[str, Callable[[], object]], rounds: int = 15, seconds: float = 0.01, batch: bool = True
) -> dict[str, list[float]]:
    """Per-call times [s] of each candidate, one entry per round; the candidates run in turn
    inside each round (``batch``: a batch of calls of about ``seconds`` each, else one call)."""
    sizes = {k: batch_size(fn, seconds) if batch else 1 for k, fn in candidates.items()}
    times: dict[str, list[float]] = {k: [] for k in candidates}
    for _ in range(rounds):
        for name, fn in candidates.items():
            number = sizes[name]
            t0 = CLOCK()
            for _ in range(number):
                fn()
            times[name].append((CLOCK() - t0) / number)
    return times


def median(values) -> float:
    return statistics.median(values)


def ratio(times: Mapping[str, list[float]], a: str, b: str) -> float:
    """Median over rounds of time(a) / time(b), paired round by round."""
    return statistics.median(x / y for x, y in zip(times[a], times[b]))


def spread(values) -> str:
    """'min-max' of a list of ratios or times, for the noise column."""
    return f"{min(values):.2f}-{max(values):.2f}"


def optional(module: str):
    """The module, or None when it is not installed (an optional peer)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        return None


def version(dist: str) -> str:
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def machine() -> str:
    """CPU model (lscpu), cores, memory, OS, Python."""
    model = "unknown CPU"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        model = next(line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("Model name"))
    except (OSError, StopIteration):
        pass
    mem = ""
    try:
        kb = int(re.search(r"MemTotal:\s+(\d+)", Path("/proc/meminfo").read_text()).group(1))
        mem = f", {kb / 2**20:.0f} GiB"
    except (OSError, AttributeError):
        pass
    return (
        f"{model}, {os.cpu_count()} cores{mem}, {platform.system()} {platform.release()}, "
        f"Python {platform.python_version()}"
    )


def compiler() -> str:
    try:
        out = subprocess.run(["cc", "--version"], capture_output=True, text=True).stdout
        return out.splitlines()[0]
    except (OSError, IndexError):
        return "no C compiler"


def load() -> str:
    try:
        return "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "load average unknown"


def versions() -> str:
    names = ("appell", "sympy", "numpy", "scipy", "pin", "pydy", "cython")
    return ", ".join(f"{n} {version(n)}" for n in names)


def today() -> str:
    return datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--", "src"], capture_output=True, text=True
        ).stdout.strip()
        return out.stdout.strip() + (" (src modified)" if dirty else "")
    except OSError:
        return "unknown"


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def us(seconds: float | None) -> str:
    """A time per call in microseconds, three significant digits."""
    if seconds is None:
        return "—"
    v = seconds * 1e6
    if v >= 1000:
        return f"{v / 1000:.3g} ms"
    return f"{v:.3g} µs" if v >= 1 else f"{v * 1e3:.0f} ns"


def replace_between_markers(text: str, name: str, body: str) -> str:
    """``text`` with what lies between ``<!-- bench:NAME -->`` and ``<!-- /bench:NAME -->``
    replaced by ``body`` (the markers are kept); the markers must be present."""
    begin, end = f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        raise KeyError(f"markers {begin} ... {end} not found")
    return text[: i + len(begin)] + "\n" + body.strip() + "\n" + text[j:]


def target(label: str, value: float | None, limit: float, unit: str = "×", below: bool = True) -> str:
    """A bullet of the targets of issue 13: the measured value against its limit."""
    if value is None:
        return f"- {label}: not measured"
    ok = value <= limit if below else value >= limit
    sign = "≤" if below else "≥"
    return f"- {label} (target {sign} {limit:g}{unit}): {value:.3g}{unit}, **{'met' if ok else 'not met'}**"


def robots_folder() -> Path | None:
    """The folder of ``example-robot-data``'s robot descriptions (the extra ``[bench]``), or None
    where it is not installed."""
    for base in map(Path, sys.path):
        folder = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if folder.is_dir():
            return folder
    return None
