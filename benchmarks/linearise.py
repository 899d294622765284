"""Linear models of the benchmark bicycle (issue 23): time from the builder to the first
eigenvalues by stage, one linearisation (median of repeated calls), and a sweep over the
forward speed with the steady motion solved at each speed.

    python benchmarks/linearise.py [--speeds N]

Prints a table: stage, seconds (or ms), with the machine and date. The stages are those
a user runs: derive (the symbolic split), the numeric model (NumPy, compiled once), the
first linearisation (compiling the blocks for the complex step), then each further one.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from appell import numeric_model

sys.path.insert(0, str(Path(__file__).resolve().parent))
from appell import linearise, load_model, stability_sweep, steady_motion  # noqa: E402
from appell.core.derive import derive  # noqa: E402 (the derivation itself, not appell.derive's cache)
from appell.examples import example_path  # noqa: E402
from appell.examples.mechanism_examples import benchmark_bicycle  # noqa: E402
from harness import load, machine, today  # noqa: E402

FREE = [
    "rear_x_dot",
    "rear_y_dot",
    "rear_z_dot",
    "rear_rz_dot",
    "rear_rx_dot",
    "rear_ry_dot",
    "front_spin_dot",
    "steer_dot",
    "rear_z",
    "rear_ry",
]
IGNORE = ["rear_x", "rear_y", "rear_rz", "rear_spin", "front_spin", "rear_spin_dot"]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--speeds", type=int, default=101, help="values of the speed sweep")
    args = parser.parse_args()
    rows = []
    t0 = time.perf_counter()
    system = benchmark_bicycle()
    d = derive(system)
    rows.append(("derive (9 coordinates, 6 constraints)", time.perf_counter() - t0))
    t1 = time.perf_counter()
    numeric_model(d)  # noqa: B018 (made on first access: the time measured)
    rows.append(("numeric model (NumPy)", time.perf_counter() - t1))
    t2 = time.perf_counter()
    point = steady_motion(
        d,
        {"rear_z": -0.3, "rear_x_dot": 5.0, "rear_spin_dot": -5.0 / 0.3, "front_spin_dot": -5.0 / 0.35},
        free=FREE,
        ignore=IGNORE[:5],
    )
    rows.append(("steady motion at 5 m/s", time.perf_counter() - t2))
    t3 = time.perf_counter()
    lm = linearise(d, point, ignore=IGNORE, coordinates=["rear_rx", "steer"])
    rows.append(("first linearisation (compiles the blocks)", time.perf_counter() - t3))
    rows.append(("builder to first eigenvalues", time.perf_counter() - t0))
    times = []
    for _ in range(50):
        s = time.perf_counter()
        linearise(d, point, ignore=IGNORE, coordinates=["rear_rx", "steer"])
        times.append(time.perf_counter() - s)
    rows.append(("one linearisation (median of 50)", statistics.median(times)))
    rates = -np.linspace(0.0, 10.0, args.speeds)[::-1] / 0.3
    s = time.perf_counter()
    sweep = stability_sweep(
        d,
        "rear_spin_dot",
        rates,
        at={"rear_z": -0.3, "rear_x_dot": 10.0, "front_spin_dot": -10.0 / 0.35},
        free=FREE,
        ignore=IGNORE,
        coordinates=["rear_rx", "steer"],
    )
    rows.append(
        (f"sweep of {args.speeds} speeds 0..10 m/s, steady motion at each, crossings located", time.perf_counter() - s)
    )
    # the bundled model file: its speeds follow the parameter v, no steady motion to solve
    t4 = time.perf_counter()
    df = derive(load_model(example_path("benchmark_bicycle")))
    first = linearise(df, df.system.initial_values, ignore=IGNORE[:5])
    first.eigenvalues()
    rows.append(("model file to first eigenvalues (load, derive, compile, linearise)", time.perf_counter() - t4))
    s = time.perf_counter()
    file_sweep = stability_sweep(df, "v", np.linspace(0.0, 10.0, args.speeds), ignore=IGNORE[:5])
    rows.append((f"sweep of {args.speeds} values of the file's v, crossings located", time.perf_counter() - s))
    print(
        f"benchmark bicycle, {today()}, {machine()}, load {load()}; eigenvalues at 5 m/s: "
        + ", ".join(f"{z.real:.6f}{z.imag:+.6f}i" for z in lm.eigenvalues())
    )
    print("crossings: " + ", ".join(f"{-0.3 * c.value:.11f} m/s ({c.kind})" for c in sweep.crossings))
    print("crossings over the file's v: " + ", ".join(f"{c.value:.11f} m/s ({c.kind})" for c in file_sweep.crossings))
    print("| stage | time |\n|---|---|")
    for name, sec in rows:
        print(f"| {name} | {sec * 1e3:.1f} ms |" if sec < 1 else f"| {name} | {sec:.1f} s |")


if __name__ == "__main__":
    main()
