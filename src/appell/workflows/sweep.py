"""``appell sweep`` and ``appell cluster``: a parameter grid on Dask (:func:`sweep_model`) and a
local cluster kept for sweeps (:func:`keep_cluster`).
"""

from __future__ import annotations

import sys
from pathlib import Path

from appell.errors import ComputationError, ModelError
from appell.files import default_file_name, output_target
from appell.workflows.load import _print
from appell.workflows.simulate import command_options


def sweep_model(
    system,
    specs,
    t_end=None,
    out=None,
    *,
    scheduler=None,
    workers=None,
    worker_timeout: float = 60.0,
    resume: bool = False,
    backend: str = "auto",
    solver=None,
    progress: bool | None = None,
    echo=None,
):
    """``appell sweep``: :func:`appell.simulation.sweep.sweep` of ``system`` over the grid of
    ``specs`` with the model's ``[simulation]`` settings and the command's ``solver`` options
    (:func:`command_options`), written to ``out`` (default ``<model name>-sweep.h5``); the
    summary printed. Raises :class:`~appell.errors.ComputationError` when a run failed
    (after writing: the dataset records every run)."""
    from appell.simulation.sweep import parameter_grid, sweep

    echo = echo or _print
    if system.servo_constraints:
        raise ModelError(
            "sweeps of models with servo constraints are not supported yet",
            hint="sweep the plain constrained system, or loop over appell simulate --set",
        )
    parameter_grid(specs)  # bad specs are bad input, before a cluster starts
    opts = command_options(system, t_end, **(solver or {}))
    if opts.complete:  # missing values are computed; a run whose given values violate a constraint fails
        opts = opts.given(adjust=())  # (its changes could not be reported), instead of being changed silently
    path = Path(out) if out else default_file_name(system.name, "-sweep.h5")
    output_target(path)
    progress = sys.stderr.isatty() if progress is None else progress
    result = sweep(
        system,
        list(specs),
        opts.t_end,
        output=path,
        t_eval=opts.output_times(),
        scheduler=scheduler,
        n_workers=workers,
        backend=backend,
        progress=progress,
        worker_timeout=worker_timeout,
        resume=resume,
        **opts.changes(but=("t_end", "t_eval")),
    )
    echo(result.summary_text())
    if result.failed:
        which = (
            "every run"
            if len(result.failed) == len(result.runs)
            else f"{len(result.failed)} of {len(result.runs)} runs"
        )
        raise ComputationError(
            f"{which} of the sweep failed (listed above); the summary uses the successful runs only",
            hint="the dataset records every run with its status and message",
        )
    return result


def keep_cluster(workers=None, host: str = "127.0.0.1", port: int = 8786, echo=None) -> None:
    """``appell cluster``: a local Dask cluster (:func:`appell.simulation.sweep.sweep_cluster`)
    kept until Ctrl-C, its address printed."""
    import time

    from appell.simulation.sweep import sweep_cluster

    echo = echo or _print
    with sweep_cluster(workers, host=host, port=port) as client:
        address = client.scheduler.address
        echo(
            f"Dask scheduler at {address} with {len(client.scheduler_info()['workers'])} worker(s); "
            f"run sweeps with: appell sweep MODEL --param ... --scheduler {address}; Ctrl-C stops it"
        )
        sys.stdout.flush()
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            echo("stopping the cluster")
