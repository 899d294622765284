"""Parameter sweeps: many simulations over a grid of parameter values, run on Dask.

A sweep is the Cartesian product of one value list per parameter, each given as a spec
``NAME=START:STOP:NUM`` (NUM equally spaced values, both ends included), ``NAME=V1,V2,...``
or ``NAME=V``. Every grid point is one :func:`appell.simulation.simulate.simulate` run of the same
model. The model is derived and compiled once, in the calling process (the C library goes to
the shared cache); each worker process builds its numeric model once from the shipped
derivation, loading that library (:class:`_Shipment`). The runs go to a Dask cluster in tasks
of several grid points (:func:`chunks`): a local cluster started for the sweep by default, the
scheduler at ``scheduler`` (``tcp://host:8786``) to use many machines, or a ``client`` kept
across sweeps (:func:`sweep_cluster`).

Output: one HDF5 file (written to a temporary name, then renamed) with

* ``t`` (T) — the common output times;
* ``parameters/<name>`` (R) — the parameter values of each run;
* every column of a run's result in the groups of its own HDF5 file
  (:meth:`~appell.simulation.solution.Solution.grouped`): ``states/<name>``,
  ``accelerations/<name>``, ``multipliers/<name>``, ``outputs/<name>`` (joint forces and
  moments, contact forces), ``controls/<name>``, ``friction/<name>``,
  ``residuals/position|velocity|servo/<name>`` (R x T) — NaN where a run failed or ended early;
* ``status`` (R; 0 reached t_end, 1 terminal event, -1 integration failed, -2 raised),
  ``message`` (R), ``wall_time`` (R);

and a summary: per multiplier the extreme values over the successful runs (status 0 or 1)
with the parameters of the run where each occurs, the count of runs per status and the
list of failed runs. A failed run is recorded, never fatal to the other runs.

Faults of the environment: while the sweep runs, every finished run is appended to
``<output>.partial`` (JSON lines: a header, then one object per run with its arrays;
NaN written as ``NaN``), removed once the dataset is written. When the dataset cannot be
written (a full disk), :class:`~appell.errors.ResourceError` says so and names the partial
file with the runs it keeps; the runs are also on the exception (``.result``). Workers
lost during the sweep are replaced by Dask (the task they were running is computed again
elsewhere; a task's runs are recorded once, when it finishes, so none is lost or doubled);
when the cluster has had no worker at all for ``worker_timeout`` seconds the runs not yet
done are cancelled and recorded as failed. A scheduler that cannot be reached is a
ResourceError naming the address.

The package's modules: :mod:`.runs` (the grid, the runs on the workers, the dataset),
:mod:`.journal` (the partial file and ``resume``), :mod:`.cluster` (Dask); this module is the
driver, :func:`sweep`.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from appell.arguments import count, number, times
from appell.errors import ModelError, ResourceError
from appell.files import atomic_path, output_target
from appell.model import System
from appell.numerics.dynamics import system_of
from appell.simulation.resources import check_memory
from appell.simulation.sweep.cluster import (
    _compute_on,
    _distributed,
    _workers_without_interrupts,
    check_scheduler_address,
    sweep_cluster,
)
from appell.simulation.sweep.journal import RESUME_KEYS, _PartialFile, _resumed, model_fingerprint, read_partial
from appell.simulation.sweep.runs import (
    _MODELS,  # noqa: F401 (the models kept on a worker: tests read them here)
    MAX_RUNS,
    MAX_SAMPLES,
    RAISED,
    RunRecord,
    SweepResult,
    _assemble,
    _names,
    _prepare,
    _summary,
    _write_hdf5,
    chunks,
    parameter_grid,
    parse_spec,
)

__all__ = [
    "MAX_RUNS",
    "MAX_SAMPLES",
    "RAISED",
    "RESUME_KEYS",
    "RunRecord",
    "SweepResult",
    "check_scheduler_address",
    "chunks",
    "model_fingerprint",
    "parameter_grid",
    "parse_spec",
    "read_partial",
    "sweep",
    "sweep_cluster",
]


def _compute(
    shipment,
    todo,
    t_end,
    t_eval,
    simulate_options,
    on_result,
    *,
    client,
    scheduler,
    n_workers,
    processes,
    progress,
    worker_timeout,
    connect_timeout,
):
    """Run the grid points ``todo`` (``[(index, parameters), ...]``) on Dask: on ``client``
    (kept by the caller), else on a new local cluster or the scheduler at ``scheduler``
    (closed afterwards). The runs go in tasks of several grid points (:func:`chunks`, from
    the number of worker threads); every finished run goes to ``on_result``."""
    own = client is None
    with _workers_without_interrupts(own and processes and scheduler is None):
        _compute_on(
            shipment,
            todo,
            t_end,
            t_eval,
            simulate_options,
            on_result,
            client=client,
            scheduler=scheduler,
            n_workers=n_workers,
            processes=processes,
            progress=progress,
            worker_timeout=worker_timeout,
            connect_timeout=connect_timeout,
        )


def _checked_arguments(t_end, samples, n_workers, worker_timeout, connect_timeout, backend, scheduler, client):
    """The scalar arguments of :func:`sweep`, checked (:class:`ModelError` naming the culprit)
    before any model is derived: ``(t_end, samples, n_workers, worker_timeout,
    connect_timeout, scheduler)``."""
    from appell.numerics.codegen import BACKENDS

    if client is None:
        _distributed()  # a missing dask: the extra to install, before the model is derived
    t_end = number(t_end, "t_end", positive=True, hint="sweeps run from t = 0 to a finite t_end > 0")
    samples = count(samples, "samples", maximum=MAX_SAMPLES)
    if n_workers is not None:
        n_workers = count(n_workers, "n_workers", maximum=4096)
    worker_timeout = number(worker_timeout, "worker_timeout", positive=True)
    connect_timeout = number(connect_timeout, "connect_timeout", positive=True)
    if backend not in BACKENDS:
        raise ModelError(f"unknown numeric backend {backend!r}", hint="choose one of " + ", ".join(BACKENDS))
    if scheduler is not None:
        scheduler = check_scheduler_address(scheduler)
    if client is not None and (scheduler is not None or n_workers is not None):
        raise ModelError(
            "give a sweep either a client or a scheduler address / a number of workers, not both",
            hint="the client's cluster runs the sweep as it is",
        )
    if client is not None and not all(hasattr(client, a) for a in ("submit", "scheduler_info")):
        raise ModelError(
            f"client must be a dask.distributed Client, got {type(client).__name__}",
            hint="use 'with appell.sweep_cluster() as client: ...'",
        )
    return t_end, samples, n_workers, worker_timeout, connect_timeout, scheduler


def _checked_grid(model, specs) -> list:
    """The parameter grid of ``specs`` (:func:`parameter_grid`), refused when empty or when it
    names a parameter that ``model`` lacks."""
    grid = parameter_grid(specs)
    if not grid:
        raise ModelError("the sweep grid is empty")
    _, _, _, pnames = _names(model)
    unknown = sorted(set(grid[0]) - set(pnames))
    if unknown:
        raise ModelError(
            f"sweep over unknown parameter(s) {', '.join(unknown)}",
            hint="parameters of the model: " + ", ".join(pnames),
        )
    return grid


def _write_results(result: SweepResult, t_eval, groups, attributes: dict, partial) -> None:
    """Write ``result``'s HDF5 dataset and its summary JSON beside it (module docstring); a
    failed write is a :class:`ResourceError` carrying ``result`` and naming the kept partial file."""
    path, runs, summary = result.path, result.runs, result.summary
    summary_path = path.with_name(path.name + ".summary.json")
    try:
        _write_hdf5(
            path,
            t_eval,
            runs,
            groups,
            summary,
            attributes,
        )
        with atomic_path(summary_path, suffix=".tmp") as tmp:
            tmp.write_text(
                json.dumps(
                    {
                        "runs": [
                            r.__dict__ | {"message": r.message.splitlines()[0] if r.message else ""} for r in runs
                        ],
                        **summary,
                    },
                    indent=1,
                    default=str,
                )
            )
    except OSError as exc:
        error = ResourceError(
            f"cannot write the sweep's results to {exc.filename or path}: {exc.strerror or exc}",
            hint=partial.describe(),
        )
        error.result = result
        raise error from exc


def sweep(
    model,
    specs,
    t_end: float,
    *,
    output="sweep.h5",
    t_eval=None,
    samples: int = 501,
    scheduler: str | None = None,
    n_workers: int | None = None,
    processes: bool = True,
    client=None,
    backend: str = "auto",
    progress: bool = True,
    worker_timeout: float = 60.0,
    connect_timeout: float = 30.0,
    resume: bool = False,
    **simulate_options,
) -> SweepResult:
    """Simulate ``model`` at every point of a parameter grid, in parallel on Dask.

    Parameters
    ----------
    model : a :class:`~appell.model.System` or a :class:`~appell.core.equations.Derivation`
        (derived and compiled with ``backend`` once, here; the workers get the derivation and
        load the compiled library from the shared cache), a NumericModel (``numeric_model(d)``,
        ``numeric_model(d, 'c')``; shipped the same way) or another picklable
        :class:`~appell.numerics.dynamics.Dynamics`.
    specs : ``['NAME=START:STOP:NUM', ...]`` (see :func:`parse_spec`) or
        ``{name: values}``; names are model parameters.
    t_end : final time of every run; ``t_eval`` output times (default ``samples``
        equally spaced in [0, t_end]).
    output : the HDF5 file to write (module docstring); a summary JSON is written beside it
        (``<output>.summary.json``), and ``<output>.partial`` holds the finished runs while
        the sweep runs.
    scheduler : address of a Dask scheduler; default a local cluster with ``n_workers``
        workers (``processes=False``: threads in this process), started for this sweep.
    client : a ``distributed.Client`` kept by the caller across sweeps (:func:`sweep_cluster`);
        it is used as it is and left open (``scheduler``, ``n_workers`` and ``processes``
        are then not given). The runs go in tasks of several grid points (:func:`chunks`).
    backend : numeric backend on the workers: 'numpy', 'c' or 'auto'.
    progress : show a progress bar (tqdm) while runs complete.
    worker_timeout : seconds without any worker after which the runs not yet done are
        recorded as failed; ``connect_timeout`` seconds to reach the scheduler.
    resume : take the successful runs kept in ``<output>.partial`` by an earlier call with
        the same model, grid and output times (whose dataset could not be written), and
        compute only the others.
    simulate_options : passed to :func:`appell.simulation.simulate.simulate` (``rtol``, ``method``, ...).

    Returns
    -------
    SweepResult

    Raises
    ------
    ModelError : bad arguments (before any run); ResourceError : the scheduler cannot be
        reached, or the dataset cannot be written (the runs are on ``exc.result``).
    """
    t_end, samples, n_workers, worker_timeout, connect_timeout, scheduler = _checked_arguments(
        t_end, samples, n_workers, worker_timeout, connect_timeout, backend, scheduler, client
    )
    grid = _checked_grid(model, specs)
    t_eval = np.linspace(0.0, t_end, samples) if t_eval is None else times(t_eval, "t_eval", 0.0, t_end)
    states, multipliers, controls, _ = _names(model)
    # every column kept: states and their accelerations, per constraint its multiplier and two
    # residuals, the controls and the outputs
    system = model if isinstance(model, System) else getattr(model, "system", None) or system_of(model)
    outputs = len(system.outputs) if isinstance(system, System) else 0
    columns = 1 + 2 * len(states or ()) + 3 * len(multipliers or ()) + len(controls or ()) + outputs
    check_memory(
        len(grid) * len(t_eval),
        columns,
        f"the sweep's {len(grid):,} runs at {len(t_eval):,} output times",
        row_by_row=False,
        hint="sweep fewer runs or record fewer output times (--samples, t_eval)",
    )
    path = Path(output)
    output_target(path)  # a device, a FIFO, a directory: refused before the runs
    name = getattr(model, "name", None) or getattr(getattr(model, "system", None), "name", "model")
    spec_text = json.dumps(
        list(specs)
        if not isinstance(specs, Mapping)
        else {k: list(map(float, np.asarray(v, float).reshape(-1))) for k, v in specs.items()}
    )
    import appell

    if isinstance(model, System):  # derived once: for the fingerprint and for the runs
        from appell.core.derive import derive

        model = derive(model)
    options = json.dumps({k: simulate_options[k] for k in sorted(simulate_options)}, default=repr)
    header = {
        "appell_sweep_partial": 1,
        "model": str(name),
        "specs": spec_text,
        "t": t_eval,
        "content": model_fingerprint(model),
        "options": options,
        "backend": backend,
        "appell": appell.__version__,
    }
    partial_path = path.with_name(path.name + ".partial")
    earlier = _resumed(partial_path, header, len(grid)) if resume else []
    done = {r["index"] for r in earlier}
    todo = [(i, params) for i, params in enumerate(grid) if i not in done]
    shipment = _prepare(model, backend) if todo else None  # derived and compiled once, before any file
    # resuming appends to the partial file: the runs kept there are never at risk
    partial = _PartialFile(partial_path, header, kept=len(earlier) if earlier else None)
    results = list(earlier)

    def on_result(r):
        results.append(r)
        partial.add(r)

    try:
        if todo:
            _compute(
                shipment,
                todo,
                float(t_end),
                t_eval,
                simulate_options,
                on_result,
                client=client,
                scheduler=scheduler,
                n_workers=n_workers,
                processes=processes,
                progress=progress,
                worker_timeout=worker_timeout,
                connect_timeout=connect_timeout,
            )
    except BaseException:  # interrupted, or no cluster: keep the finished runs for --resume
        if partial.kept:
            partial.close()
        else:
            partial.remove()
        raise
    partial.close()
    results.sort(key=lambda r: r["index"])
    runs = tuple(RunRecord(r["index"], grid[r["index"]], r["status"], r["message"], r["wall_time"]) for r in results)
    groups = _assemble(results, grid, t_eval)
    summary = _summary(groups, runs)
    result = SweepResult(path, runs, summary)
    _write_results(
        result,
        t_eval,
        groups,
        {"model": str(name), "specs": spec_text, "t_end": float(t_end), "backend": backend},
        partial,
    )
    partial.remove()
    return result
