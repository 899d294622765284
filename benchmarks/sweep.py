"""A 64-run sweep of the car against a plain loop of the same 64 runs, on this machine.

    .venv/bin/python benchmarks/sweep.py [--repeats 3] [--workers 2] [--t-end 10]

The runs: the car model file (examples/car.toml) with its own solver settings (Radau,
rtol 1e-9, output every 0.05 s, projection), over F = 600..1000 N x M = 1000..1400 kg
(8 x 8 = 64 grid points). The model is derived and compiled once, before any timing.

* loop: ``simulate`` of each grid point in this process, with the same compiled model (C)
  and the same options as the sweep's workers: like against like;
* sweep (kept cluster): ``appell.sweep`` on a cluster kept across sweeps
  (``appell.sweep_cluster``: ``--workers`` worker processes with one thread each, started
  once, outside the timing; the workers keep the model between repeats);
* sweep (new cluster): ``appell.sweep`` starting its own local cluster of the same size,
  cluster start and the workers' imports included.

Both sweeps also write their HDF5 dataset and JSON summary (the loop writes nothing). The
three are interleaved in every repeat; the ratios are sweep / loop of the same repeat.
On a machine shared with other work the wall-time ratios are noisy: the load average is
printed, and so is the CPU time each spent (this process, plus the workers of the kept
cluster, plus the reaped worker processes of a new cluster): a sweep's CPU time over the
loop's is its overhead, which other work on the machine hardly changes.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from appell import numeric_model


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2, help="worker processes (one thread each)")
    ap.add_argument("--t-end", type=float, default=None, help="final time of every run (default: the model's, 10 s)")
    ap.add_argument(
        "--grid",
        default="F=600:1000:8,M=1000:1400:8",
        help="the sweep specs, comma-separated between axes (default 64 runs)",
    )
    args = ap.parse_args()

    import appell
    from appell.examples import example_path
    from appell.simulation.simulate import simulate
    from appell.simulation.sweep import parameter_grid, sweep, sweep_cluster
    from appell.workflows import command_options

    system = appell.load_model(example_path("car"))
    derivation = appell.derive(system)
    model = numeric_model(derivation, "c")
    options = command_options(system, args.t_end)
    t_end, t_eval = options.t_end, options.output_times()
    opts = {"method": options.method, "rtol": options.rtol, **options.changes(but=("t_end", "t_eval"))}
    specs = _specs(args.grid)
    grid = parameter_grid(specs)
    print(
        f"car, {len(grid)} runs of {t_end:g} s ({opts['method']}, rtol {opts['rtol']:g}, {len(t_eval)} output "
        f"times each); sweep on {args.workers} worker process(es) x 1 thread; {os.cpu_count()} cores; "
        f"load average {', '.join(f'{x:.2f}' for x in os.getloadavg())}; {time.strftime('%Y-%m-%d %H:%M %Z')}"
    )

    def loop():
        out = []
        for params in grid:
            t0 = time.perf_counter()
            sol = simulate(model, t_end, t_eval=t_eval, params=params, progress=False, **opts)
            out.append((time.perf_counter() - t0, sol.status))
        assert all(status == 0 for _, status in out), "a run of the loop failed"
        return [w for w, _ in out]

    def swept(directory, **where):
        result = sweep(
            derivation,
            specs,
            t_end,
            t_eval=t_eval,
            output=Path(directory) / "car-sweep.h5",
            backend="c",
            progress=False,
            **where,
            **opts,
        )
        assert not result.failed, result.summary_text()
        return [r.wall_time for r in result.runs]

    def cpu(client=None) -> float:
        """CPU seconds of this process, its reaped children, and the workers of ``client``."""
        own = resource.getrusage(resource.RUSAGE_SELF)
        children = resource.getrusage(resource.RUSAGE_CHILDREN)
        total = own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime
        if client is not None:
            total += sum(client.run(time.process_time).values())
        return total

    rows, cpu_rows = [], []
    with tempfile.TemporaryDirectory() as directory, sweep_cluster(args.workers) as client:
        swept(directory, client=client)  # the kept cluster's workers build the model once
        for rep in range(args.repeats):
            timings, per_run, cpus = {}, {}, {}
            for name, job, workers in (
                ("loop", loop, None),
                ("sweep, kept cluster", lambda: swept(directory, client=client), client),
                ("sweep, new cluster", lambda: swept(directory, n_workers=args.workers), None),
            ):
                c0 = cpu(workers)
                t0 = time.perf_counter()
                per_run[name] = job()
                timings[name] = time.perf_counter() - t0
                cpus[name] = cpu(workers) - c0
            rows.append(timings)
            cpu_rows.append(cpus)
            print(
                f"repeat {rep + 1} (load {os.getloadavg()[0]:.1f}): "
                + "; ".join(
                    f"{name} {t:.2f} s, CPU {cpus[name]:.2f} s (mean run {1e3 * np.mean(per_run[name]):.0f} ms)"
                    for name, t in timings.items()
                )
                + "; ratios "
                + ", ".join(
                    f"{name} / loop {timings[name] / timings['loop']:.2f}" for name in timings if name != "loop"
                ),
                flush=True,
            )
    print(f"median over the {len(rows)} repeats (wall time; CPU time):")
    for name in rows[0]:
        line = (
            f"  {name:<20} {statistics.median(r[name] for r in rows):7.2f} s; "
            f"{statistics.median(r[name] for r in cpu_rows):7.2f} s"
        )
        if name != "loop":
            ratios = [r[name] / r["loop"] for r in rows]
            cpu_ratio = statistics.median(r[name] / r["loop"] for r in cpu_rows)
            line += (
                f"   ratio to the loop {statistics.median(ratios):.2f} "
                f"(repeats: {', '.join(f'{x:.2f}' for x in ratios)}); CPU time ratio {cpu_ratio:.2f}"
            )
        print(line)
    print(f"load average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")


def _specs(text: str) -> list[str]:
    """'F=600:1000:8,M=1000:1400:8' -> ['F=600:1000:8', 'M=1000:1400:8'] (a comma inside an
    axis of listed values, 'F=1,2', stays with its axis)."""
    out = []
    for part in text.split(","):
        if "=" in part or not out:
            out.append(part)
        else:
            out[-1] += "," + part
    return out


if __name__ == "__main__":
    main()
