"""The 3-D view of a motion (issue 24): frames per second in headless Chromium and page sizes.

    python benchmarks/viewer.py [--quick] [--markdown FILE]

For each model the page of ``appell animate`` is opened in Debian's headless Chromium
(software WebGL: SwiftShader, no GPU) with ``#bench=N``: the viewer sets and renders N
frames back to back (``setFrame`` + ``renderer.render`` + ``gl.finish``, what playing
costs per frame) and writes the rate into the page, read back with ``--dump-dom``. The
rate is measured for three runs; the table gives min / median / max. Also the size of the
page and of ``appell report``'s page for the car (target: under 1.5 MB with the viewer).
Target of the issue: at least 30 frames per second for the URDF arm.
"""

from __future__ import annotations

import argparse
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import appell  # noqa: E402
from appell.examples import example_path  # noqa: E402
from appell.io.modelfile import load_model  # noqa: E402
from appell.io.viewer import view_motion  # noqa: E402
from harness import load, machine, today  # noqa: E402

CHROMIUM = shutil.which("chromium")
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-extensions",
    "--disable-background-networking",
    "--window-size=1000,760",
]


def fps(page: Path, frames: int, profile: Path) -> float:
    out = subprocess.run(
        [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", "--dump-dom", f"{page.as_uri()}#bench={frames}"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    found = re.search(r'data-viewer-fps="([0-9.]+)"', out.stdout)
    if not found:
        raise RuntimeError(f"no rate in the page: {out.stderr[-500:]}")
    return float(found.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="one run per model")
    ap.add_argument("--markdown", help="also write the table as Markdown to this file")
    args = ap.parse_args()
    if CHROMIUM is None:
        sys.exit("headless Chromium is not installed (Debian: apt-get install chromium)")
    runs = 1 if args.quick else 3
    models = [
        ("URDF arm", example_path("four_bar").parent / "arm.urdf", 2.0),
        ("four-bar", example_path("four_bar"), 3.0),
        ("car", example_path("car"), 10.0),
    ]
    head = f"{machine()}, {today()}; Chromium headless, SwiftShader (software WebGL), 1000 x 760 window"
    print(head)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, path, t_end in models:
            system = load_model(path)
            solution = appell.simulate(appell.derive(system), t_end=t_end)
            motion = view_motion(system, solution)
            page = tmp / f"{path.stem}.html"
            motion.save(page)
            rates = [fps(page, 600, tmp / f"profile{k}") for k in range(runs)]
            meshes = sum(len(b["shapes"]) + max(len(b["links"]), 1) * 2 for b in motion.scene["bodies"])
            row = (
                name,
                len(motion.scene["t"]),
                meshes,
                page.stat().st_size / 1e6,
                min(rates),
                statistics.median(rates),
                max(rates),
            )
            rows.append(row)
            print(
                f"{name:10s} frames {row[1]:4d}  parts ~{row[2]:3d}  page {row[3]:.2f} MB  "
                f"fps min {row[4]:.0f} median {row[5]:.0f} max {row[6]:.0f}",
                flush=True,
            )
        report = tmp / "car-report.html"
        subprocess.run(
            [sys.executable, "-m", "appell", "report", "car", "-o", str(report)], check=True, capture_output=True
        )
        size = report.stat().st_size / 1e6
        print(f"appell report car: {size:.2f} MB (target < 1.5 MB)")
    if args.markdown:
        out = [head, "", "| model | frames | page | frames per second (min / median / max) |", "|---|---|---|---|"]
        out += [f"| {r[0]} | {r[1]} | {r[3]:.2f} MB | {r[4]:.0f} / {r[5]:.0f} / {r[6]:.0f} |" for r in rows]
        out += ["", f"`appell report car`: {size:.2f} MB with the viewer (target under 1.5 MB)."]
        Path(args.markdown).write_text("\n".join(out) + "\n")


if __name__ == "__main__":
    load()
    main()
