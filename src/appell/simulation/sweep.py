"""Parameter sweeps: many simulations over a grid of parameter values, run on Dask.

A sweep is the Cartesian product of one value list per parameter, each given as a spec
``NAME=START:STOP:NUM`` (NUM equally spaced values, both ends included), ``NAME=V1,V2,...``
or ``NAME=V``. Every grid point is one :func:`appell.simulation.simulate.simulate` run of the same
model (any :class:`~appell.numerics.dynamics.Dynamics`, or a System / Derivation compiled once per
worker process). The runs go to a Dask cluster: a local one by default, or the scheduler
at ``scheduler`` (``tcp://host:8786``) to use many machines.

Output: one HDF5 file (written to a temporary name, then renamed) with

* ``t`` (T) — the common output times;
* ``parameters/<name>`` (R) — the parameter values of each run;
* ``states/<name>``, ``multipliers/<name>``, ``controls/<name>`` (R x T) — NaN where a run
  failed or ended early;
* ``status`` (R; 0 reached t_end, 1 terminal event, -1 integration failed, -2 raised),
  ``message`` (R), ``wall_time`` (R);

and a summary: per multiplier the extreme values across the sweep with the parameters of
the run where each occurs, and the count of runs per status. A failed run is recorded, never
fatal to the sweep.
"""

from __future__ import annotations

import itertools
import json
import time
import traceback
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from appell.errors import ModelError
from appell.io.files import atomic_path

#: run status for a run that raised (simulate's own codes are 0, 1 and -1)
RAISED = -2


def parse_spec(spec: str) -> tuple[str, np.ndarray]:
    """``'NAME=START:STOP:NUM'`` -> ``(NAME, linspace(START, STOP, NUM))``; also
    ``'NAME=V1,V2,...'`` and ``'NAME=V'``."""
    name, sep, values = spec.partition("=")
    name = name.strip()
    if not sep or not name.isidentifier() or not values.strip():
        raise ModelError(f"bad sweep spec {spec!r}", hint="write NAME=START:STOP:NUM, NAME=V1,V2,... or NAME=V")
    try:
        if ":" in values:
            parts = values.split(":")
            if len(parts) != 3:
                raise ValueError
            start, stop, num = float(parts[0]), float(parts[1]), int(parts[2])
            if num < 1:
                raise ValueError
            return name, np.linspace(start, stop, num)
        return name, np.array([float(v) for v in values.split(",")])
    except ValueError:
        raise ModelError(f"bad sweep spec {spec!r}: values must be numbers and NUM a positive integer",
                         hint="e.g. m=0.5:2:4 or L=1,1.5,2") from None


def parameter_grid(specs: Sequence[str] | Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """The Cartesian product of the specs, one ``{name: value}`` per run (last name fastest)."""
    axes = dict(parse_spec(s) for s in specs) if not isinstance(specs, Mapping) else \
        {k: np.asarray(v, float).reshape(-1) for k, v in specs.items()}
    names = list(axes)
    return [dict(zip(names, map(float, combo))) for combo in itertools.product(*(axes[n] for n in names))]


@dataclass(frozen=True)
class RunRecord:
    """One run of a sweep: its parameters, status, message and wall time."""

    index: int
    parameters: dict
    status: int
    message: str
    wall_time: float


@dataclass(frozen=True)
class SweepResult:
    """What :func:`sweep` wrote: the HDF5 ``path``, the ``runs`` and the ``summary``
    (``{'multipliers': {name: {max, argmax_parameters, min, argmin_parameters, max_abs}},
    'status_counts': {status: count}}``)."""

    path: Path
    runs: tuple[RunRecord, ...]
    summary: dict = field(default_factory=dict)

    @property
    def failed(self) -> tuple[RunRecord, ...]:
        return tuple(r for r in self.runs if r.status < 0)

    def summary_text(self) -> str:
        """The summary as a short table."""
        lines = [f"{len(self.runs)} runs -> {self.path}",
                 "status counts: " + ", ".join(f"{k}: {v}" for k, v in self.summary["status_counts"].items())]
        for name, s in self.summary["multipliers"].items():
            if s["max"] is None:
                lines.append(f"lambda_{name}: no finite values")
                continue
            lines.append(f"lambda_{name}: max {s['max']:.6g} at {s['argmax_parameters']}, "
                         f"min {s['min']:.6g} at {s['argmin_parameters']}")
        for r in self.failed:
            lines.append(f"run {r.index} {r.parameters} failed ({r.status}): {r.message.splitlines()[0][:200]}")
        return "\n".join(lines)


# ------------------------------------------------------------------ worker side
_MODELS: dict = {}


def _model_on_worker(token: str, payload, backend: str):
    """The Dynamics of a sweep, built once per worker process (derivation, compilation)."""
    model = _MODELS.get(token)
    if model is None:
        from appell.numerics.dynamics import Dynamics
        from appell.model import System

        model = payload
        if isinstance(model, System):
            from appell.core.derive import derive

            model = derive(model)
        if not isinstance(model, Dynamics):
            from appell.numerics.numeric import compile_model

            model = compile_model(model, backend)
        _MODELS.clear()
        _MODELS[token] = model
    return model


def _run_one(token, payload, backend, index, params, t_end, t_eval, options) -> dict:
    start = time.perf_counter()
    try:
        from appell.simulation.simulate import simulate

        model = _model_on_worker(token, payload, backend)
        sol = simulate(model, t_end, t_eval=t_eval, params=params, progress=False, **options)
        return {"index": index, "status": int(sol.status), "message": str(sol.message), "t": np.asarray(sol.t),
                "states": {k: np.asarray(v) for k, v in sol.states.items()},
                "multipliers": {k: np.asarray(v) for k, v in sol.multipliers.items()},
                "controls": {k: np.asarray(v) for k, v in sol.controls.items()},
                "wall_time": time.perf_counter() - start}
    except Exception as exc:  # noqa: BLE001 (a failed run is recorded, not fatal)
        return {"index": index, "status": RAISED, "message": f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}",
                "wall_time": time.perf_counter() - start}


# ------------------------------------------------------------------ client side
def _names(payload):
    """State, multiplier and control names and parameter names of the sweep's model."""
    from appell.numerics.dynamics import Dynamics
    from appell.model import System

    if isinstance(payload, Dynamics):
        return (tuple(payload.state_names), tuple(payload.constraint_names), tuple(payload.control_names),
                tuple(payload.parameter_names))
    system = payload if isinstance(payload, System) else payload.system
    kin_names = tuple(s.name for s in system.coordinates) + tuple(s.name for s in system.speeds)
    return None if system.controls else kin_names, tuple(c.name for c in system.constraints), None, \
        tuple(p.symbol.name for p in system.parameters)


def _assemble(results, runs_params, t_eval):
    R, T = len(results), len(t_eval)
    groups = {"states": {}, "multipliers": {}, "controls": {}}
    for r in results:
        for g in groups:
            for k in r.get(g, {}):
                groups[g].setdefault(k, np.full((R, T), np.nan))
    for r in results:
        if "t" not in r:
            continue
        # a run that ended early has fewer output times: match them to t_eval
        idx = np.searchsorted(t_eval, r["t"])
        ok = (idx < T) & np.isclose(t_eval[np.minimum(idx, T - 1)], r["t"], rtol=0, atol=1e-12 * max(1.0, abs(t_eval[-1])))
        for g in groups:
            for k, v in r.get(g, {}).items():
                groups[g][k][r["index"], idx[ok]] = np.asarray(v)[ok]
    return groups


def _summary(groups, runs) -> dict:
    out = {"multipliers": {}, "status_counts": {}}
    for r in runs:
        out["status_counts"][r.status] = out["status_counts"].get(r.status, 0) + 1
    for name, arr in groups["multipliers"].items():
        finite = np.isfinite(arr)
        if not finite.any():
            out["multipliers"][name] = {"max": None, "min": None, "max_abs": None}
            continue
        hi = np.where(finite, arr, -np.inf)
        lo = np.where(finite, arr, np.inf)
        imax = np.unravel_index(np.argmax(hi), arr.shape)
        imin = np.unravel_index(np.argmin(lo), arr.shape)
        out["multipliers"][name] = {
            "max": float(arr[imax]), "argmax_parameters": runs[imax[0]].parameters, "argmax_run": int(imax[0]),
            "min": float(arr[imin]), "argmin_parameters": runs[imin[0]].parameters, "argmin_run": int(imin[0]),
            "max_abs": float(max(abs(arr[imax]), abs(arr[imin]))),
        }
    return out


def _write_hdf5(path: Path, t_eval, runs, groups, summary, attrs):
    import h5py

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, suffix=".tmp") as tmp:
        with h5py.File(tmp, "w") as f:
            f["t"] = np.asarray(t_eval)
            names = list(runs[0].parameters) if runs else []
            for n in names:
                f[f"parameters/{n}"] = np.array([r.parameters[n] for r in runs])
            for g, items in groups.items():
                grp = f.require_group(g)
                for k, v in items.items():
                    grp.create_dataset(k, data=v, compression="gzip" if v.size > 4096 else None)
            f["status"] = np.array([r.status for r in runs], dtype=np.int8)
            f["message"] = np.array([r.message.encode() for r in runs], dtype=h5py.string_dtype())
            f["wall_time"] = np.array([r.wall_time for r in runs])
            for k, v in attrs.items():
                f.attrs[k] = v
            f.attrs["summary"] = json.dumps(summary, default=str)


def sweep(model, specs, t_end: float, *, output="sweep.h5", t_eval=None, samples: int = 501,
          scheduler: str | None = None, n_workers: int | None = None, processes: bool = True,
          backend: str = "auto", progress: bool = True, **simulate_options) -> SweepResult:
    """Simulate ``model`` at every point of a parameter grid, in parallel on Dask.

    Parameters
    ----------
    model : a :class:`~appell.model.System`, a :class:`~appell.core.equations.Derivation`
        (derived/compiled once per worker with ``backend``) or a picklable
        :class:`~appell.numerics.dynamics.Dynamics`.
    specs : ``['NAME=START:STOP:NUM', ...]`` (see :func:`parse_spec`) or
        ``{name: values}``; names are model parameters.
    t_end : final time of every run; ``t_eval`` output times (default ``samples``
        equally spaced in [0, t_end]).
    output : the HDF5 file to write (module docstring); a summary JSON is written beside it
        (``<output>.summary.json``).
    scheduler : address of a Dask scheduler; default a local cluster with ``n_workers``
        workers (``processes=False``: threads in this process).
    backend : numeric backend on the workers: 'numpy', 'c' or 'auto'.
    progress : show a progress bar (tqdm) while runs complete.
    simulate_options : passed to :func:`appell.simulation.simulate.simulate` (``rtol``, ``method``, ...).

    Returns
    -------
    SweepResult
    """
    from appell.errors import import_optional

    distributed = import_optional("dask.distributed", extra="sweep", feature="a parameter sweep")
    Client, LocalCluster, as_completed = distributed.Client, distributed.LocalCluster, distributed.as_completed

    grid = parameter_grid(specs)
    if not grid:
        raise ModelError("the sweep grid is empty")
    _, _, _, pnames = _names(model)
    unknown = sorted(set(grid[0]) - set(pnames))
    if unknown:
        raise ModelError(f"sweep over unknown parameter(s) {', '.join(unknown)}",
                         hint="parameters of the model: " + ", ".join(pnames))
    t_eval = np.linspace(0.0, float(t_end), samples) if t_eval is None else np.asarray(t_eval, float)
    token = uuid.uuid4().hex
    own_cluster = None
    if scheduler is None:
        own_cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=processes,
                                   dashboard_address=None)
        client = Client(own_cluster)
    else:
        client = Client(scheduler)
    results = []
    try:
        payload = client.scatter(model, broadcast=True)
        futures = [client.submit(_run_one, token, payload, backend, i, params, float(t_end), t_eval,
                                 simulate_options, key=f"appell-run-{i}-{token}", pure=False)
                   for i, params in enumerate(grid)]
        done = as_completed(futures)
        if progress:
            from tqdm.auto import tqdm

            done = tqdm(done, total=len(futures), desc="sweep", unit="run")
        for fut in done:
            try:
                results.append(fut.result())
            except Exception as exc:  # noqa: BLE001 (a lost worker: record the run as failed)
                i = futures.index(fut)
                results.append({"index": i, "status": RAISED, "message": f"{type(exc).__name__}: {exc}",
                                "wall_time": float("nan")})
    finally:
        client.close()
        if own_cluster is not None:
            own_cluster.close()
    results.sort(key=lambda r: r["index"])
    runs = tuple(RunRecord(r["index"], grid[r["index"]], r["status"], r["message"], r["wall_time"]) for r in results)
    groups = _assemble(results, grid, t_eval)
    summary = _summary(groups, runs)
    path = Path(output)
    name = getattr(model, "name", None) or getattr(getattr(model, "system", None), "name", "model")
    _write_hdf5(path, t_eval, runs, groups, summary,
                {"model": str(name), "specs": json.dumps(list(specs) if not isinstance(specs, Mapping) else
                                                          {k: list(map(float, v)) for k, v in specs.items()}),
                 "t_end": float(t_end), "backend": backend})
    summary_path = path.with_name(path.name + ".summary.json")
    with atomic_path(summary_path, suffix=".tmp") as tmp:
        tmp.write_text(json.dumps({"runs": [r.__dict__ | {"message": r.message.splitlines()[0] if r.message else ""}
                                            for r in runs], **summary}, indent=1, default=str))
    return SweepResult(path, runs, summary)
