"""CPU time of building a robot file's symbolic :class:`appell.System` (the joint tree, every
body's frame, velocity and acceleration, every joint's force and moment as outputs: what
:func:`appell.mechanism.mjcf.mjcf_system` and :func:`appell.mechanism.urdf.urdf_system` return,
before any derivation), this tree against a baseline tree.

Each build runs in its own process with the file's reading and the build timed inside it
(imports not counted), the baseline's and this tree's in turn for each file and round, so
that a change of the machine's load moves both alike; the table gives each side's median
over the rounds. Files: the MuJoCo Menagerie models in ``../shared/models/menagerie`` (read
with ``frictionloss='ignore'``, as ``--mjcf frictionloss=ignore``) and the bundled arm.urdf.

    python benchmarks/model_build.py --baseline OTHER/src [--rounds 3] [--files go2,gen3]

``OTHER/src`` is the ``src`` folder of another checkout (e.g. ``git archive main src | tar -x
-C /tmp/main``), put first on ``PYTHONPATH`` for its runs; without it, this tree alone.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"
MENAGERIE = HERE.parent.parent / "shared" / "models" / "menagerie"

#: the child's program: read and build, print the CPU seconds of that alone
CHILD = """
import sys, time, warnings
warnings.simplefilter("ignore")
path = sys.argv[1]
if path.endswith(".urdf"):
    from appell.mechanism.urdf import urdf_system as build
    options = {}
else:
    from appell.mechanism.mjcf import mjcf_system as build
    options = {"frictionloss": "ignore"}
start = time.process_time()
system = build(path, **options)
print(time.process_time() - start, len(system.coordinates), len(system.outputs))
"""


def files() -> dict[str, Path]:
    """``{short name: path}`` of the robot files measured."""
    found = {p.stem: p for p in sorted(MENAGERIE.glob("*/*.xml"))}
    found["arm"] = SRC / "appell" / "examples" / "arm.urdf"
    return found


def build_seconds(path: Path, src: Path) -> tuple[float, int, int]:
    """``(CPU seconds, coordinates, outputs)`` of one build in a fresh process with ``src``
    first on the path."""
    env = {**os.environ, "PYTHONPATH": str(src), "APPELL_NO_CACHE": "1"}
    done = subprocess.run([sys.executable, "-c", CHILD, str(path)], env=env, capture_output=True, text=True, check=True)
    seconds, coordinates, outputs = done.stdout.split()
    return float(seconds), int(coordinates), int(outputs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, help="src folder of the baseline checkout")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--files", help="comma-separated short names (default: every file)")
    opts = parser.parse_args()
    chosen = files()
    if opts.files:
        chosen = {k: v for k, v in chosen.items() if k in opts.files.split(",")}
    sides = {"this": SRC} if opts.baseline is None else {"baseline": opts.baseline.resolve(), "this": SRC}
    print(f"# {platform.node()}, {os.cpu_count()} cores, Python {platform.python_version()}, {datetime.date.today()}")
    print("# CPU seconds of reading the file and building its System (imports not counted), median of the rounds")
    head = "".join(f"{k + ' s':>12s}" for k in sides)
    print(f"{'file':<20s} {'q':>4s} {'outputs':>8s}{head}{'  this/baseline' if len(sides) == 2 else ''}")
    for name, path in chosen.items():
        times: dict[str, list[float]] = {k: [] for k in sides}
        size = (0, 0)
        for _ in range(opts.rounds):
            for side, src in sides.items():
                seconds, *size = build_seconds(path, src)
                times[side].append(seconds)
        medians = {k: statistics.median(v) for k, v in times.items()}
        ratio = f"  {medians['this'] / medians['baseline']:13.2f}" if len(sides) == 2 else ""
        cells = "".join(f"{v:12.2f}" for v in medians.values())
        print(f"{name:<20s} {size[0]:4d} {size[1]:8d}{cells}{ratio}", flush=True)


if __name__ == "__main__":
    main()
