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
"""

from __future__ import annotations

import contextlib
import itertools
import json
import logging
import math
import os
import re
import time
import traceback
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from appell.core.equations import is_controlled
from appell.arguments import count, number, times
from appell.errors import ModelError, ResourceError
from appell.files import atomic_path, output_target, write_hdf5
from appell.simulation.resources import check_memory
from appell.model import System
from appell.numerics.boundary import numeric_model
from appell.numerics.dynamics import system_of

#: run status for a run that raised (simulate's own codes are 0, 1 and -1)
RAISED = -2
#: the most runs and output times per run a sweep accepts
MAX_RUNS, MAX_SAMPLES = 1_000_000, 10_000_000
#: Dask scheduler addresses: ``protocol://host:port`` or ``host:port``
_ADDRESS = re.compile(r"^(?:(?:tcp|tls|ws|wss|ucx)://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(\d{1,5})$")


def _distributed():
    """``dask.distributed``, or :class:`~appell.errors.MissingDependencyError` with the install
    command (``pip install 'appell[sweep]'``)."""
    from appell.errors import import_optional

    return import_optional("dask.distributed", extra="sweep", feature="a parameter sweep")


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
            if num < 1 or num > MAX_RUNS or not (math.isfinite(start) and math.isfinite(stop)):
                raise ValueError
            return name, np.linspace(start, stop, num)
        out = np.array([float(v) for v in values.split(",")])
        if not np.all(np.isfinite(out)):
            raise ValueError
        return name, out
    except ValueError:
        raise ModelError(f"bad sweep spec {spec!r}: values must be finite numbers and NUM a positive integer",
                         hint="e.g. m=0.5:2:4 or L=1,1.5,2") from None


def parameter_grid(specs: Sequence[str] | Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """The Cartesian product of the specs, one ``{name: value}`` per run (last name fastest)."""
    if isinstance(specs, (str, bytes)):
        specs = [specs]
    if not isinstance(specs, Mapping) and not hasattr(specs, "__iter__"):
        raise ModelError(f"sweep specs must be a list of 'NAME=...' strings or a mapping {{name: values}}, "
                         f"got {type(specs).__name__}")
    if isinstance(specs, Mapping):
        from appell.arguments import vector

        axes = {str(k): vector(v, f"sweep values of {k}") for k, v in specs.items()}
    else:
        axes = dict(parse_spec(s) if isinstance(s, str) else _not_a_spec(s) for s in specs)
    if math.prod(len(v) for v in axes.values()) > MAX_RUNS:
        raise ModelError(f"the sweep grid has more than {MAX_RUNS} runs", hint="use fewer values per parameter")
    names = list(axes)
    return [dict(zip(names, map(float, combo))) for combo in itertools.product(*(axes[n] for n in names))]


def _not_a_spec(spec):
    raise ModelError(f"bad sweep spec {spec!r}: a spec is a string NAME=START:STOP:NUM, NAME=V1,V2,... or NAME=V")


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
    'status_counts': {status: count}, 'successful_runs': count, 'failed_runs': [{run,
    parameters, status, message}]}``; the extremes are over the successful runs only)."""

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
        ok = len(self.runs) - len(self.failed)
        if self.summary["multipliers"]:
            lines.append(f"extreme reactions over the {ok} successful run(s):")
        for name, s in self.summary["multipliers"].items():
            if s["max"] is None:
                lines.append(f"lambda_{name}: no finite values")
                continue
            lines.append(f"lambda_{name}: max {s['max']:.6g} at {s['argmax_parameters']}, "
                         f"min {s['min']:.6g} at {s['argmin_parameters']}")
        if self.failed:
            lines.append(f"{len(self.failed)} failed run(s):")
        for r in self.failed:
            lines.append(f"run {r.index} {r.parameters} failed ({r.status}): {r.message.splitlines()[0][:200]}")
        return "\n".join(lines)


# ------------------------------------------------------------------ worker side
#: numeric models built on this worker process, by shipment key (the newest last)
_MODELS: dict = {}
#: how many models a worker keeps (a cluster kept across sweeps of several models)
_KEPT_MODELS = 8


@dataclass(frozen=True)
class _Shipment:
    """What a worker needs to build the sweep's numeric model, once per process.

    For a System, a Derivation or a NumericModel: the ``derivation`` (plain symbolic data,
    a few kB pickled, its reduced equations and reactions already formed) and the resolved
    ``backend`` ('c', 'auto' or 'numpy'). The C library itself is not shipped: the client
    compiled it into the shared cache (:func:`appell.numerics.codegen.build_library`),
    where :func:`~appell.numerics.codegen.compile_c` finds it by the key of its source; a
    worker on another machine compiles it once there (under the cache's lock). A derivation
    with servo constraints has ``backend`` 'own': each worker makes its NumPy model. Any other
    picklable Dynamics is shipped as it is (``dynamics``). ``key`` names the model by its
    content, so a cluster kept across sweeps builds each model once.
    """

    key: str
    derivation: object = None
    backend: str = "numpy"
    dynamics: object = None

    def build(self):
        """The Dynamics: ``dynamics``, or the derivation compiled with ``backend``."""
        if self.dynamics is not None:
            return self.dynamics
        # 'own': a controlled derivation's own NumPy model (servo constraints)
        return numeric_model(self.derivation, None if self.backend == "own" else self.backend)


def _keep(key: str, model):
    """Keep ``model`` in this process by ``key``, as the newest; the oldest beyond
    :data:`_KEPT_MODELS` are dropped."""
    _MODELS.pop(key, None)
    _MODELS[key] = model
    while len(_MODELS) > _KEPT_MODELS:
        _MODELS.pop(next(iter(_MODELS)))
    return model


def _model_on_worker(shipment: _Shipment):
    """The Dynamics of a sweep, built once per worker process and kept by its key."""
    model = _MODELS.get(shipment.key)
    return _keep(shipment.key, shipment.build() if model is None else model)


def _run_one(shipment, index, params, t_end, t_eval, options) -> dict:
    """One run on a worker: its arrays, status and message (an exception is a failed run)."""
    start = time.perf_counter()
    try:
        from appell.simulation.simulate import simulate

        model = _model_on_worker(shipment)
        sol = simulate(model, t_end, t_eval=t_eval, params=params, progress=False, **options)
        groups: dict = {}
        for c in sol.grouped()[1:]:  # every column of the result, as the run's own HDF5 file has it
            groups.setdefault(c.group, {})[c.key] = np.asarray(c.values)
        return {"index": index, "status": int(sol.status), "message": str(sol.message), "t": np.asarray(sol.t),
                "groups": groups, "wall_time": time.perf_counter() - start}
    except Exception as exc:  # noqa: BLE001 (a failed run is recorded, not fatal)
        return {"index": index, "status": RAISED, "message": f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}",
                "wall_time": time.perf_counter() - start}


def _run_chunk(shipment, chunk, t_end, t_eval, options) -> list[dict]:
    """The runs of one task, ``chunk = [(index, parameters), ...]``, one after the other."""
    return [_run_one(shipment, i, params, t_end, t_eval, options) for i, params in chunk]


def _prepare_worker() -> int:
    """Import the simulation layer on a worker (a kept cluster pays it once, not in a sweep)."""
    import appell.numerics.codegen  # noqa: F401
    import appell.simulation.simulate  # noqa: F401

    return os.getpid()


def chunks(todo: Sequence, slots: int, per_slot: int = 4) -> list[list]:
    """Split the runs ``todo`` into tasks by guided self-scheduling: each task takes
    ``ceil(remaining / (per_slot * slots))`` runs, so the first tasks are large (little
    per-task overhead) and the last ones single runs (the workers finish together).
    ``slots`` is the number of worker threads; every run is in exactly one task, in order."""
    out, start, slots = [], 0, max(1, int(slots))
    while start < len(todo):
        size = max(1, math.ceil((len(todo) - start) / (per_slot * slots)))
        out.append(list(todo[start:start + size]))
        start += size
    return out


# ------------------------------------------------------------------ client side
def _names(payload):
    """State, multiplier and control names and parameter names of the sweep's model."""
    from appell.numerics.dynamics import Dynamics

    if isinstance(payload, Dynamics):
        return (tuple(payload.state_names), tuple(payload.constraint_names), tuple(payload.control_names),
                tuple(payload.parameter_names))
    system = payload if isinstance(payload, System) else payload.system
    kin_names = tuple(s.name for s in system.coordinates) + tuple(s.name for s in system.speeds)
    return None if system.controls else kin_names, tuple(c.name for c in system.constraints), None, \
        tuple(p.symbol.name for p in system.parameters)


#: the groups of a partial file written before every column was kept (resumed as they are)
_EARLIER_GROUPS = ("states", "multipliers", "controls")


def _groups_of(result: dict) -> dict:
    """``{group: {name: array}}`` of one run's result (also one from an earlier partial file)."""
    if "groups" in result:
        return result["groups"]
    return {g: result[g] for g in _EARLIER_GROUPS if g in result}


def _assemble(results, runs_params, t_eval):
    """``{group: {name: (R, T) array}}`` over the runs, every column any run has
    (:meth:`~appell.simulation.solution.Solution.grouped`), NaN where a run has none."""
    from appell.simulation.solution import GROUPS

    R, T = len(results), len(t_eval)
    groups: dict = {"states": {}, "multipliers": {}, "controls": {}}
    for r in results:
        for g, items in _groups_of(r).items():
            for k in items:
                groups.setdefault(g, {}).setdefault(k, np.full((R, T), np.nan))
    for r in results:
        if "t" not in r:
            continue
        # a run that ended early has fewer output times: match them to t_eval
        idx = np.searchsorted(t_eval, r["t"])
        ok = (idx < T) & np.isclose(t_eval[np.minimum(idx, T - 1)], r["t"], rtol=0, atol=1e-12 * max(1.0, abs(t_eval[-1])))
        for g, items in _groups_of(r).items():
            for k, v in items.items():
                groups[g][k][r["index"], idx[ok]] = np.asarray(v)[ok]
    order = {g: i for i, g in enumerate(GROUPS)}
    return dict(sorted(groups.items(), key=lambda item: order.get(item[0], len(order))))


def _summary(groups, runs) -> dict:
    """Status counts, the failed runs, and the extreme multipliers over the successful runs."""
    out = {"multipliers": {}, "status_counts": {}, "successful_runs": sum(r.status >= 0 for r in runs),
           "failed_runs": [{"run": r.index, "parameters": r.parameters, "status": r.status,
                            "message": r.message.splitlines()[0] if r.message else ""}
                           for r in runs if r.status < 0]}
    for r in runs:
        out["status_counts"][r.status] = out["status_counts"].get(r.status, 0) + 1
    ok = np.array([r.status >= 0 for r in runs], dtype=bool).reshape(-1, 1)
    for name, arr in groups["multipliers"].items():
        finite = np.isfinite(arr) & ok  # a failed run's values are not evidence
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

    def fill(f):
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

    write_hdf5(path, fill, suffix=".tmp")


class _PartialFile:
    """``<output>.partial``: the finished runs, appended one JSON line each as they arrive.

    A failed append (a full disk) is remembered, the line cut back, and later runs are no
    longer appended; the sweep itself goes on (its runs stay in memory).
    """

    def __init__(self, path: Path, header: dict, kept: int | None = None):
        """A new file with ``header``; with ``kept`` (resuming) the file is appended to."""
        self.path, self.kept, self.error = path, kept or 0, None
        try:
            self.fh = open(path, "a" if kept is not None else "w", encoding="utf-8")
            if kept is None:
                self._append(header)
        except OSError as exc:
            self._fail(exc)

    def _append(self, obj):
        start = self.fh.tell()
        try:
            self.fh.write(json.dumps(obj, default=_json_default) + "\n")
            self.fh.flush()
        except OSError:
            self.fh.seek(start)
            self.fh.truncate()
            raise

    def _fail(self, exc: OSError):
        self.error = exc
        fh = getattr(self, "fh", None)
        if fh is not None:
            with contextlib.suppress(OSError):
                fh.close()
        self.fh = None

    def add(self, result: dict):
        if self.fh is None:
            return
        try:
            self._append(result)
            self.kept += 1
        except OSError as exc:
            self._fail(exc)

    def close(self):
        if self.fh is not None:
            with contextlib.suppress(OSError):
                self.fh.close()
            self.fh = None

    def remove(self):
        self.close()
        with contextlib.suppress(OSError):
            os.unlink(self.path)

    def describe(self) -> str:
        """Where the finished runs are kept (a partial file without runs is removed)."""
        if self.kept and self.path.exists():
            cut = f" (it could not take more: {self.error.strerror or self.error})" if self.error else ""
            return (f"the {self.kept} finished run(s) are kept in {self.path}{cut}; free space (or choose "
                    "another --out) and run the sweep again with --resume (resume=True) to compute only the others")
        self.remove()
        return "no finished run could be kept on disk; free space (or choose another --out) and run it again"


def read_partial(path) -> tuple[dict, list[dict]]:
    """The header and the runs of a partial file (``<output>.partial``, see the module
    docstring); a last line cut short is ignored. Arrays come back as NumPy arrays."""
    header, runs = None, []
    with open(path, "rb") as fh:
        for raw in fh:
            try:
                obj = json.loads(raw.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError):
                break  # cut short (the runs before it are complete), or not text at all
            if header is None:
                header = obj
                continue
            if not isinstance(obj, dict):
                break
            for group in _EARLIER_GROUPS:
                if group in obj:
                    obj[group] = {k: np.asarray(v, float) for k, v in obj[group].items()}
            if isinstance(obj.get("groups"), dict):
                obj["groups"] = {g: {k: np.asarray(v, float) for k, v in items.items()}
                                 for g, items in obj["groups"].items()}
            if "t" in obj:
                obj["t"] = np.asarray(obj["t"], float)
            runs.append(obj)
    if not isinstance(header, dict) or header.get("appell_sweep_partial") != 1:
        raise ModelError(f"{path} is not the partial file of an appell sweep")
    return header, runs


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def check_scheduler_address(scheduler: str) -> str:
    """``scheduler`` if it looks like a Dask scheduler address (``tcp://host:port``, also
    ``tls://``, ``ws://``, ``ucx://`` or a bare ``host:port``), else a ModelError."""
    if not isinstance(scheduler, str) or not (m := _ADDRESS.match(scheduler.strip())) or \
            not 0 < int(m.group(1)) < 65536:
        raise ModelError(f"bad Dask scheduler address {scheduler!r}",
                         hint="give the address 'dask scheduler' prints, e.g. tcp://192.168.1.10:8786")
    return scheduler.strip()


def _connect(scheduler: str, timeout: float):
    Client = _distributed().Client

    try:
        return Client(scheduler, timeout=timeout, set_as_default=False)
    except Exception as exc:  # noqa: BLE001 (refused, timed out, or not a Dask scheduler at all)
        raise ResourceError(f"cannot connect to the Dask scheduler at {scheduler}: {type(exc).__name__}: {exc}",
                            hint="start one with 'dask scheduler' and give the address it prints, or leave out "
                                 "the scheduler to run on a local cluster") from None


def _cancelled(exc: BaseException) -> bool:
    """Whether ``exc`` says a future was cancelled (asyncio's or concurrent.futures' error)."""
    import asyncio
    import concurrent.futures

    return isinstance(exc, (asyncio.CancelledError, concurrent.futures.CancelledError))


def _failed(index: int, message: str) -> dict:
    return {"index": index, "status": RAISED, "message": message, "wall_time": float("nan")}


def _worker_count(client) -> tuple[int, int]:
    """The scheduler's workers and their threads."""
    try:
        workers = client.scheduler_info(n_workers=-1).get("workers", {})
    except TypeError:  # older distributed: no n_workers argument
        workers = client.scheduler_info().get("workers", {})
    return len(workers), sum(int(w.get("nthreads", 1)) for w in workers.values())


def _gather(client, futures, tasks, on_result, worker_timeout: float, bar=None):
    """Collect the tasks' runs as they finish (``on_result(dict)`` per run). ``tasks[k]``
    lists the run indices of ``futures[k]``. A task whose worker was lost is computed again
    by Dask; one lost for good (KilledWorker) or cancelled gives failed runs. A finished
    task's result is released at once, so that losing its worker later computes nothing
    again (each task is taken once, when it finishes); a task whose worker dies while its
    result is fetched is fetched again once Dask has computed it again (it never blocks the
    sweep: the checks below still run). When the cluster has had no
    worker for ``worker_timeout`` seconds (or the scheduler is lost), the pending tasks are
    cancelled and their runs recorded as failed."""
    as_completed = _distributed().as_completed

    pending = dict(zip(futures, tasks))
    finished = as_completed(futures, loop=client.loop)  # the sweep's client is not the default one

    def record(r):
        on_result(r)
        if bar is not None:
            bar.update(1)

    no_worker_since, last_check, regather = None, 0.0, []
    while pending:
        done = finished.next_batch(block=False) if finished.has_ready() else []
        done += [f for f in regather if f.done()]
        regather = [f for f in regather if f not in done]
        for fut in done:
            try:
                results = fut.result(timeout=10.0)
            except TimeoutError:
                # its worker died while its result was fetched: Dask computes it again
                regather.append(fut)
                continue
            except BaseException as exc:  # noqa: BLE001 (a lost worker, a cancelled run: record it)
                if not isinstance(exc, Exception) and not _cancelled(exc):
                    raise
                lost = "lost with the Dask workers (killed, or their machine gone): " \
                    if _cancelled(exc) or type(exc).__name__ == "KilledWorker" else ""
                results = [_failed(i, f"{lost}{type(exc).__name__}: {exc}") for i in pending[fut]]
            pending.pop(fut)
            fut.release()
            for r in results:
                record(r)
        if done or not pending:
            continue
        time.sleep(0.05)
        now = time.monotonic()
        if now - last_check < 0.5:
            continue
        last_check = now
        reason = None
        try:
            workers, _ = _worker_count(client)
        except Exception as exc:  # noqa: BLE001 (the scheduler is gone)
            workers, reason = 0, f"lost the Dask scheduler ({type(exc).__name__}: {exc})"
        if workers:
            no_worker_since = None
            continue
        no_worker_since = no_worker_since or now
        if reason is None and now - no_worker_since < worker_timeout:
            continue
        reason = reason or f"no Dask worker for {worker_timeout:g} s (all workers lost?)"
        try:
            client.cancel(list(pending))
        except Exception:  # noqa: BLE001 (the scheduler may be gone too)
            pass
        for i in sorted(i for indices in pending.values() for i in indices):
            record(_failed(i, f"not run: {reason}"))
        pending.clear()


#: what a kept run depends on, as the partial file's header names it (checked by --resume)
RESUME_KEYS = (("model", "the model's name"), ("content", "the model's content (equations, parameter values, "
               "initial values, programs, outputs)"), ("specs", "the parameter grid"), ("t", "the output times"),
               ("options", "the solver options"), ("backend", "the numeric backend"), ("appell", "appell's version"))


def model_fingerprint(model) -> str | None:
    """SHA-256 of everything a run of ``model`` depends on: for a System, a Derivation or a
    NumericModel the canonical text (:class:`_ExpressionGraph`, the same in every process) of the
    blocks ``M``, ``h``, ``Q``, ``J``, ``c``, the constraints in second-order form, the
    coordinate rates, the residuals, the programs and the outputs, with the names and values
    of the parameters and the initial values; for another Dynamics its pickle. None when it
    cannot be formed (a Dynamics that does not pickle)."""
    import hashlib
    import pickle

    import sympy as sp

    from appell.numerics.dynamics import Dynamics
    from appell.numerics.numeric import NumericModel

    derivation = model.derivation if isinstance(model, NumericModel) else model
    if isinstance(derivation, System):
        from appell.core.derive import derive

        derivation = derive(derivation)
    if not hasattr(derivation, "inertia"):
        if isinstance(model, Dynamics):
            try:
                return hashlib.sha256(pickle.dumps(model)).hexdigest()
            except Exception:  # noqa: BLE001 (a Dynamics holding closures)
                return None
        return None
    system, inertia, cons = derivation.system, derivation.inertia, derivation.constraints
    graph = _ExpressionGraph()
    if inertia.tree is not None:  # the recursive route: the joints' terms, never the expanded M and h
        from appell.numerics.rigid_tree import point_matrices, tree_matrices

        n = len(derivation.kinematics.speeds)
        blocks = tree_matrices(inertia.tree, n, inertia.gravity) + point_matrices(inertia.tree)
        blocks.append(sp.Matrix([[node.parent] for node in inertia.tree.nodes]))
    else:
        blocks = [inertia.mass_matrix, inertia.inertial_forces]
    text = [graph.text(sp.Matrix(m)) for m in (*blocks, inertia.generalized_forces,
                                                 derivation.kinematics.coordinate_rates)]
    if cons.count:
        text += [graph.text(sp.Matrix(cons.jacobian)), graph.text(sp.Matrix(cons.bias)),
                 graph.text(sp.Matrix(cons.second_order))]
        text += [graph.text(e) for e in tuple(cons.position_residual) + tuple(cons.velocity_residual)]
    text.append(repr(tuple(cons.names)))
    text.append(repr([(p.symbol.name, float(p.value)) for p in system.parameters]))
    text.append(repr(sorted((str(k), repr(v)) for k, v in system.initial_definitions.items())))
    text += [f"{g.symbol.name}={graph.text(g.expr)}" for g in system.programs]
    text += [f"{o.name}={graph.text(o.expr)}" for o in system.outputs]
    text.append(graph.nodes())
    return hashlib.sha256("\n".join(text).encode()).hexdigest()


class _ExpressionGraph:
    """The canonical text of SymPy expressions as a graph: each distinct subexpression is one
    line ``kind(arg ids)`` (a symbol by its name, a number by ``srepr``), numbered in the
    order first met, and an expression is the id of its root. SymPy keeps the arguments of
    sums and products in a canonical order (``Basic.compare``), so the text is the same in
    every process, as ``srepr``'s is; a subexpression shared by many entries (the URDF arm's
    joint forces) is written once, where ``srepr`` writes the whole tree of each entry and
    sorts its terms for printing (23 s for the arm's 30 outputs, 0.3 s here)."""

    def __init__(self):
        self.ids: dict = {}
        self.lines: list[str] = []

    def _id(self, root) -> int:
        import sympy as sp

        stack = [(root, False)]
        while stack:
            node, ready = stack.pop()
            if node in self.ids:
                continue
            args = node.args if isinstance(node, sp.Basic) and not node.is_Atom else ()
            if args and not ready:
                stack.append((node, True))
                stack.extend((a, False) for a in reversed(args) if a not in self.ids)
                continue
            if isinstance(node, sp.Symbol):
                line = f"Symbol:{node.name}"
            elif not args:
                line = sp.srepr(node)
            else:
                line = f"{type(node).__name__}({','.join(str(self.ids[a]) for a in args)})"
            self.ids[node] = len(self.lines)
            self.lines.append(line)
        return self.ids[root]

    def text(self, expr) -> str:
        """The ids of ``expr`` (a matrix: of its entries, with its shape)."""
        import sympy as sp

        if isinstance(expr, sp.MatrixBase):
            return f"{expr.shape}[{','.join(str(self._id(e)) for e in expr)}]"
        return str(self._id(sp.sympify(expr)))

    def nodes(self) -> str:
        """Every subexpression met so far, one per line."""
        return "\n".join(self.lines)


def _resumed(path: Path, header: dict, runs: int) -> list[dict]:
    """The successful runs kept in the partial file ``path`` by an earlier call of the same
    sweep (:func:`read_partial`); none when there is no such file. Every entry of
    :data:`RESUME_KEYS` must match: a run computed from another model file, another
    ``--set`` value, other solver options, another backend or appell version is refused by
    name (mixing it into the dataset would be a silent wrong result)."""
    if not path.exists():
        return []
    old_header, old = read_partial(path)
    if header.get("content") is None:
        raise ModelError(f"cannot resume from {path}: the model's content cannot be fingerprinted (it does not "
                         "pickle), so the kept runs cannot be shown to come from the same model",
                         hint="run without resume (the file is then replaced), or remove it")
    differ = []
    for key, what in RESUME_KEYS:
        mine, theirs = header.get(key), old_header.get(key)
        same = (np.array_equal(np.asarray(theirs if theirs is not None else [], float), np.asarray(mine, float))
                if key == "t" else mine == theirs)
        if not same:
            differ.append(what)
    if differ:
        raise ModelError(f"{path} holds the runs of another sweep: " + "; ".join(differ) + " differ from this one's",
                         hint="run without resume (the file is then replaced), or remove it")
    kept = {}
    for r in old:
        if isinstance(r.get("index"), int) and 0 <= r["index"] < runs and r.get("status", RAISED) >= 0:
            kept[r["index"]] = r
    return list(kept.values())


def _prepare(model, backend: str) -> _Shipment:
    """Compile the sweep's model once, here (:func:`sweep` has derived a System already): a Derivation
    compiled with ``backend`` (the C library goes to the shared cache), a NumericModel
    shipped by its derivation and its own backend (the NumPy functions are lambdified
    closures that do not pickle; a worker makes them again from the derivation). The model
    built here is also kept in this process (workers that are threads use it as it is)."""
    import hashlib
    import pickle

    from appell.numerics.codegen import CompiledNumericModel
    from appell.numerics.dynamics import Dynamics
    from appell.numerics.numeric import NumericModel

    if isinstance(model, NumericModel):
        numeric, derivation = model, model.derivation
    elif isinstance(model, Dynamics):
        shipment = _Shipment(uuid.uuid4().hex, dynamics=model)
        _model_on_worker(shipment)
        return shipment
    elif is_controlled(model):
        # servo constraints: the derivation's own NumPy model, made again on each worker
        numeric, derivation, backend = numeric_model(model), model, "own"
    else:
        numeric, derivation = numeric_model(model, backend), model
    compiled = isinstance(numeric, CompiledNumericModel)
    # 'auto' stays 'auto' on the workers (a machine without a compiler falls back there too)
    if backend != "own":
        backend = ("auto" if backend == "auto" else "c") if compiled else "numpy"
    try:
        key = hashlib.sha256(pickle.dumps((backend, derivation))).hexdigest()[:32]
    except Exception:  # noqa: BLE001 (Python callables in a System: threads still share the model built here)
        key = uuid.uuid4().hex
    _keep(key, numeric)
    return _Shipment(key, derivation, backend)


def _start_cluster(n_workers, processes, scheduler, connect_timeout, host=None, port=0):
    """``(client, cluster)``: a new local cluster of single-threaded workers whose scheduler
    listens on ``host:port`` (default 127.0.0.1, a free port; ``cluster`` to be closed after
    the client), or a client of the scheduler at ``scheduler``."""
    if scheduler is not None:
        return _connect(scheduler, connect_timeout), None
    distributed = _distributed()
    cluster = client = None
    try:
        with _interrupt_after():  # a cluster half started cannot be closed cleanly
            # Dask's warnings (a worker restarted, a task cancelled) stay off the terminal: the
            # sweep records every run's fate itself
            cluster = distributed.LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=processes,
                                               dashboard_address=None, host=host, scheduler_port=port,
                                               silence_logs=logging.ERROR)
            client = distributed.Client(cluster, set_as_default=False)
        return client, cluster
    except BaseException as exc:
        if isinstance(exc, KeyboardInterrupt) and client is not None:
            _silence(client)
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
        if isinstance(exc, OSError):  # the port is taken, the host is not this machine's
            raise ResourceError(f"cannot start a Dask scheduler on {host or '127.0.0.1'}:{port}: "
                                f"{exc.strerror or exc}", hint="choose another port (0: a free one) or host") from None
        raise


@contextlib.contextmanager
def _interrupt_after():
    """Hold a Ctrl-C (SIGINT) until the block has run, then raise it (KeyboardInterrupt); a
    second one meanwhile goes to the previous handler at once. Only in the main thread."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = []

    def hold(signum, frame):
        if held and callable(previous):
            previous(signum, frame)
        held.append(signum)

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if held:
        raise KeyboardInterrupt


def _silence(client) -> None:
    """Nothing more on the terminal from an interrupted sweep's cluster while it closes: Dask's
    loggers here, and the workers' stderr (:func:`_mute_worker`)."""
    _quiet_dask()
    try:
        client.run(_mute_worker, on_error="ignore")
    except Exception:  # noqa: BLE001 (a worker gone: its messages may stay)
        pass


@contextlib.contextmanager
def _workers_without_interrupts(local: bool):
    """Worker processes of a local cluster started in the block ignore SIGINT, so that Ctrl-C in
    the terminal (sent to the whole process group) stops this process only, which then closes
    the cluster, instead of a traceback from every worker (``local``: a local cluster of
    processes; else nothing is done).

    A disposition ``SIG_IGN`` survives ``fork`` and ``exec`` (a handler or a blocked mask does
    not reach a spawned worker): the workers are forked from multiprocessing's fork server
    (Dask's ``multiprocessing-method = "forkserver"``), started here with SIGINT ignored for
    the instant of its own start, so that every process it forks ignores SIGINT too."""
    import multiprocessing
    import signal
    import threading

    if not local or "forkserver" not in multiprocessing.get_all_start_methods() \
            or threading.current_thread() is not threading.main_thread():
        yield
        return
    import dask
    from distributed.utils import get_mp_context
    from multiprocessing import forkserver

    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        get_mp_context()  # Dask's preload of the fork server (its imports, done once there)
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            forkserver.ensure_running()
        finally:
            signal.signal(signal.SIGINT, previous)
        yield


def _mute_worker() -> None:
    """In a worker process of an interrupted sweep (``client.run``): nothing more on the
    terminal's stderr while the cluster closes (Dask's warnings, a traceback of a connection
    closed under the worker's feet)."""
    import sys

    _quiet_dask()
    sys.stderr = open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115 (kept until the process ends)


def _quiet_dask() -> None:
    """Silence Dask's loggers while an interrupted sweep closes its cluster (its warnings, such
    as a worker killed after its grace period, are expected then)."""
    for name in list(logging.root.manager.loggerDict):
        if name.split(".")[0] in ("distributed", "tornado", "asyncio"):
            logging.getLogger(name).disabled = True


@contextlib.contextmanager
def sweep_cluster(n_workers: int | None = None, *, scheduler: str | None = None, processes: bool = True,
                  host: str | None = None, port: int = 0, connect_timeout: float = 30.0):
    """A Dask client kept for several sweeps: ``with sweep_cluster(2) as client:
    sweep(..., client=client)``.

    Starts a local cluster of ``n_workers`` single-threaded workers (default one per core;
    ``processes=False``: threads of this process) whose scheduler listens on ``host:port``
    (default 127.0.0.1 and a free port; more workers may join it with ``dask worker
    ADDRESS``), or connects to the running scheduler at ``scheduler`` (``dask scheduler``,
    ``appell cluster``). The scheduler's address is ``client.scheduler.address``.
    The workers import appell's simulation layer at once, and keep the numeric model of
    each sweep (by the content of its derivation), so that a later sweep of the same model
    starts its runs without a cluster start, an import or a compilation. The cluster (not a
    scheduler given by address) is closed when the block ends.
    """
    if n_workers is not None:
        n_workers = count(n_workers, "n_workers", maximum=4096)
    if scheduler is not None:
        scheduler = check_scheduler_address(scheduler)
    connect_timeout = number(connect_timeout, "connect_timeout", positive=True)
    port = count(port, "port", minimum=0, maximum=65535)
    with _workers_without_interrupts(processes and scheduler is None):
        client, cluster = _start_cluster(n_workers, processes, scheduler, connect_timeout, host, port)
        try:
            client.run(_prepare_worker)
            yield client
        finally:
            client.close()
            if cluster is not None:
                cluster.close()


def _compute(shipment, todo, t_end, t_eval, simulate_options, on_result, *, client, scheduler, n_workers,
             processes, progress, worker_timeout, connect_timeout):
    """Run the grid points ``todo`` (``[(index, parameters), ...]``) on Dask: on ``client``
    (kept by the caller), else on a new local cluster or the scheduler at ``scheduler``
    (closed afterwards). The runs go in tasks of several grid points (:func:`chunks`, from
    the number of worker threads); every finished run goes to ``on_result``."""
    own = client is None
    with _workers_without_interrupts(own and processes and scheduler is None):
        _compute_on(shipment, todo, t_end, t_eval, simulate_options, on_result, client=client, scheduler=scheduler,
                    n_workers=n_workers, processes=processes, progress=progress, worker_timeout=worker_timeout,
                    connect_timeout=connect_timeout)


def _compute_on(shipment, todo, t_end, t_eval, simulate_options, on_result, *, client, scheduler, n_workers,
                processes, progress, worker_timeout, connect_timeout):
    """:func:`_compute` (its docstring), inside its handling of Ctrl-C for the workers."""
    own = client is None
    cluster = None
    if own:
        client, cluster = _start_cluster(n_workers, processes, scheduler, connect_timeout)
    token = uuid.uuid4().hex
    bar = None
    try:
        _, threads = _worker_count(client)
        tasks = chunks(todo, threads or os.cpu_count() or 1)
        futures = [client.submit(_run_chunk, shipment, chunk, t_end, t_eval, simulate_options,
                                 key=f"appell-runs-{chunk[0][0]}-{chunk[-1][0]}-{token}", pure=False)
                   for chunk in tasks]
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=len(todo), desc="sweep", unit="run")
        _gather(client, futures, [[i for i, _ in chunk] for chunk in tasks], on_result, worker_timeout, bar)
    except KeyboardInterrupt:
        if own:  # the workers ignore Ctrl-C and run on until the cluster closes below
            _silence(client)
        raise
    finally:
        if bar is not None:
            bar.close()
        if own:
            client.close()
            if cluster is not None:
                cluster.close()


def sweep(model, specs, t_end: float, *, output="sweep.h5", t_eval=None, samples: int = 501,
          scheduler: str | None = None, n_workers: int | None = None, processes: bool = True, client=None,
          backend: str = "auto", progress: bool = True, worker_timeout: float = 60.0, connect_timeout: float = 30.0,
          resume: bool = False, **simulate_options) -> SweepResult:
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
    from appell.numerics.codegen import BACKENDS

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
        raise ModelError("give a sweep either a client or a scheduler address / a number of workers, not both",
                         hint="the client's cluster runs the sweep as it is")
    if client is not None and not all(hasattr(client, a) for a in ("submit", "scheduler_info")):
        raise ModelError(f"client must be a dask.distributed Client, got {type(client).__name__}",
                         hint="use 'with appell.sweep_cluster() as client: ...'")
    grid = parameter_grid(specs)
    if not grid:
        raise ModelError("the sweep grid is empty")
    _, _, _, pnames = _names(model)
    unknown = sorted(set(grid[0]) - set(pnames))
    if unknown:
        raise ModelError(f"sweep over unknown parameter(s) {', '.join(unknown)}",
                         hint="parameters of the model: " + ", ".join(pnames))
    t_eval = np.linspace(0.0, t_end, samples) if t_eval is None else times(t_eval, "t_eval", 0.0, t_end)
    states, multipliers, controls, _ = _names(model)
    # every column kept: states and their accelerations, per constraint its multiplier and two
    # residuals, the controls and the outputs
    system = model if isinstance(model, System) else getattr(model, "system", None) or system_of(model)
    outputs = len(system.outputs) if isinstance(system, System) else 0
    columns = 1 + 2 * len(states or ()) + 3 * len(multipliers or ()) + len(controls or ()) + outputs
    check_memory(len(grid) * len(t_eval), columns, f"the sweep's {len(grid):,} runs at {len(t_eval):,} output times",
                 row_by_row=False, hint="sweep fewer runs or record fewer output times (--samples, t_eval)")
    path = Path(output)
    output_target(path)  # a device, a FIFO, a directory: refused before the runs
    name = getattr(model, "name", None) or getattr(getattr(model, "system", None), "name", "model")
    spec_text = json.dumps(list(specs) if not isinstance(specs, Mapping) else
                           {k: list(map(float, np.asarray(v, float).reshape(-1))) for k, v in specs.items()})
    import appell

    if isinstance(model, System):  # derived once: for the fingerprint and for the runs
        from appell.core.derive import derive

        model = derive(model)
    options = json.dumps({k: simulate_options[k] for k in sorted(simulate_options)}, default=repr)
    header = {"appell_sweep_partial": 1, "model": str(name), "specs": spec_text, "t": t_eval,
              "content": model_fingerprint(model), "options": options, "backend": backend,
              "appell": appell.__version__}
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
            _compute(shipment, todo, float(t_end), t_eval, simulate_options, on_result, client=client,
                     scheduler=scheduler, n_workers=n_workers, processes=processes, progress=progress,
                     worker_timeout=worker_timeout, connect_timeout=connect_timeout)
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
    summary_path = path.with_name(path.name + ".summary.json")
    try:
        _write_hdf5(path, t_eval, runs, groups, summary,
                    {"model": str(name), "specs": spec_text, "t_end": float(t_end), "backend": backend})
        with atomic_path(summary_path, suffix=".tmp") as tmp:
            tmp.write_text(json.dumps({"runs": [r.__dict__ | {"message": r.message.splitlines()[0] if r.message else ""}
                                                for r in runs], **summary}, indent=1, default=str))
    except OSError as exc:
        error = ResourceError(f"cannot write the sweep's results to {exc.filename or path}: "
                              f"{exc.strerror or exc}",
                              hint=partial.describe())
        error.result = result
        raise error from exc
    partial.remove()
    return result
