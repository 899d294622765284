"""The runs of a sweep (:mod:`appell.simulation.sweep`): the parameter grid from its specs,
the records of the runs and their result, what a worker receives and runs (a shipment of the
derivation built into its numeric model once per process, chunks of grid points), and the
assembly of the finished runs into the dataset's groups, its summary and its HDF5 file."""

from __future__ import annotations

import itertools
import json
import math
import os
import time
import traceback
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from appell._cache import Cache
from appell.core.equations import is_controlled
from appell.errors import ModelError
from appell.files import write_hdf5
from appell.model import System
from appell.numerics.boundary import numeric_model

#: run status for a run that raised (simulate's own codes are 0, 1 and -1)
RAISED = -2


#: the most runs and output times per run a sweep accepts
MAX_RUNS, MAX_SAMPLES = 1_000_000, 10_000_000


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
        raise ModelError(
            f"bad sweep spec {spec!r}: values must be finite numbers and NUM a positive integer",
            hint="e.g. m=0.5:2:4 or L=1,1.5,2",
        ) from None


def parameter_grid(specs: Sequence[str] | Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """The Cartesian product of the specs, one ``{name: value}`` per run (last name fastest)."""
    if isinstance(specs, (str, bytes)):
        specs = [specs]
    if not isinstance(specs, Mapping) and not hasattr(specs, "__iter__"):
        raise ModelError(
            f"sweep specs must be a list of 'NAME=...' strings or a mapping {{name: values}}, "
            f"got {type(specs).__name__}"
        )
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
        lines = [
            f"{len(self.runs)} runs -> {self.path}",
            "status counts: " + ", ".join(f"{k}: {v}" for k, v in self.summary["status_counts"].items()),
        ]
        ok = len(self.runs) - len(self.failed)
        if self.summary["multipliers"]:
            lines.append(f"extreme reactions over the {ok} successful run(s):")
        for name, s in self.summary["multipliers"].items():
            if s["max"] is None:
                lines.append(f"lambda_{name}: no finite values")
                continue
            lines.append(
                f"lambda_{name}: max {s['max']:.6g} at {s['argmax_parameters']}, "
                f"min {s['min']:.6g} at {s['argmin_parameters']}"
            )
        if self.failed:
            lines.append(f"{len(self.failed)} failed run(s):")
        for r in self.failed:
            lines.append(f"run {r.index} {r.parameters} failed ({r.status}): {r.message.splitlines()[0][:200]}")
        return "\n".join(lines)


# ------------------------------------------------------------------ worker side
#: how many models a worker keeps (a cluster kept across sweeps of several models)
_KEPT_MODELS = 8
#: numeric models built on this worker process, by shipment key (least recently used dropped first)
_MODELS: Cache = Cache(_KEPT_MODELS)


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


def _model_on_worker(shipment: _Shipment):
    """The Dynamics of a sweep, built once per worker process and kept by its key."""
    return _MODELS.get_or_make(shipment.key, shipment.build)


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
        return {
            "index": index,
            "status": int(sol.status),
            "message": str(sol.message),
            "t": np.asarray(sol.t),
            "groups": groups,
            "wall_time": time.perf_counter() - start,
        }
    except Exception as exc:  # noqa: BLE001 (a failed run is recorded, not fatal)
        return {
            "index": index,
            "status": RAISED,
            "message": f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}",
            "wall_time": time.perf_counter() - start,
        }


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
        out.append(list(todo[start : start + size]))
        start += size
    return out


# ------------------------------------------------------------------ client side
def _names(payload):
    """State, multiplier and control names and parameter names of the sweep's model."""
    from appell.numerics.dynamics import Dynamics

    if isinstance(payload, Dynamics):
        return (
            tuple(payload.state_names),
            tuple(payload.constraint_names),
            tuple(payload.control_names),
            tuple(payload.parameter_names),
        )
    system = payload if isinstance(payload, System) else payload.system
    kin_names = tuple(s.name for s in system.coordinates) + tuple(s.name for s in system.speeds)
    return (
        None if system.controls else kin_names,
        tuple(c.name for c in system.constraints),
        None,
        tuple(p.symbol.name for p in system.parameters),
    )


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
        ok = (idx < T) & np.isclose(
            t_eval[np.minimum(idx, T - 1)], r["t"], rtol=0, atol=1e-12 * max(1.0, abs(t_eval[-1]))
        )
        for g, items in _groups_of(r).items():
            for k, v in items.items():
                groups[g][k][r["index"], idx[ok]] = np.asarray(v)[ok]
    order = {g: i for i, g in enumerate(GROUPS)}
    return dict(sorted(groups.items(), key=lambda item: order.get(item[0], len(order))))


def _summary(groups, runs) -> dict:
    """Status counts, the failed runs, and the extreme multipliers over the successful runs."""
    out = {
        "multipliers": {},
        "status_counts": {},
        "successful_runs": sum(r.status >= 0 for r in runs),
        "failed_runs": [
            {
                "run": r.index,
                "parameters": r.parameters,
                "status": r.status,
                "message": r.message.splitlines()[0] if r.message else "",
            }
            for r in runs
            if r.status < 0
        ],
    }
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
            "max": float(arr[imax]),
            "argmax_parameters": runs[imax[0]].parameters,
            "argmax_run": int(imax[0]),
            "min": float(arr[imin]),
            "argmin_parameters": runs[imin[0]].parameters,
            "argmin_run": int(imin[0]),
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
    _MODELS.put(key, numeric)
    return _Shipment(key, derivation, backend)
