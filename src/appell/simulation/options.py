"""The settings of a run: one frozen :class:`SimulationOptions`, read and checked in one place.

Where a setting comes from, lowest first:

1. the defaults of :class:`SimulationOptions` (the final time :data:`DEFAULT_T_END`);
2. the model's run settings (a model file's ``[simulation]`` table, ``System(settings=...)``):
   :meth:`SimulationOptions.from_model`;
3. what the caller gives: ``simulate``'s keyword arguments or ``appell simulate``'s flags,
   both through :meth:`SimulationOptions.given` (``None`` from a flag means "not given").

The API and the command line build their options by the same two calls, so they run a model
alike. When the final (or initial) time differs from the model's, output times the model gives
on an equal spacing are regenerated with that spacing over the new span; other output times
are cut to it.

:meth:`SimulationOptions.checked` checks every value against the model before the
integrator sees it (:mod:`appell.arguments`): times finite (``t_end = inf`` never ends),
output times finite, non-decreasing and inside ``[t0, t_end]``, tolerances positive,
Baumgarte gains two non-negative numbers, unilateral signs +1 or -1, friction coefficients
non-negative, flags True or False. A wrong value is a :class:`~appell.errors.ModelError`
naming the setting. The events of a run are checked by :func:`check_events`.
"""

from __future__ import annotations

import dataclasses
import difflib
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from appell.arguments import mapping, number, times, vector
from appell.errors import ModelError
from appell.simulation.events import Event

__all__ = ["DEFAULT_T_END", "MAX_STEPS", "SettingError", "SimulationOptions", "check_events"]

#: final time when neither the caller nor the model's settings give one
DEFAULT_T_END = 10.0

#: the most integration steps a ``max_step`` may force (``(t_end - t0) / max_step``)
MAX_STEPS = 1e9

#: output times when none are given
DEFAULT_SAMPLES = 501

#: the most output times a model's ``[simulation]`` table may ask for
MAX_OUTPUT_TIMES = 10_000_000

STABILIZATIONS = ("projection", "baumgarte", None)
RELEASES = ("continue", "stop")


def _toml(text: str, check: str | None = None):
    """A setting a model file's ``[simulation]`` table may give, with what it holds and how
    :meth:`SimulationOptions.from_table` checks it (:data:`TABLE_CHECKS`; None: by the type of
    the field's default)."""
    return {"toml": text} if check is None else {"toml": text, "check": check}


#: the checks of a ``[simulation]`` value: the name in a field's ``check`` metadata
TABLE_CHECKS = ("number", "positive", "count", "string", "boolean", "times", "gains", "signs", "friction", "choice")


class SettingError(ModelError):
    """A wrong value in a model's ``[simulation]`` table; ``path``: where inside the table
    (the key, then the item), for the model-file reader to give its file and line."""

    def __init__(self, path: tuple, message: str, hint: str | None = None):
        super().__init__(message, hint=hint)
        self.path = tuple(path)


def _default_check(f: dataclasses.Field) -> str:
    """The check of a field without ``check`` metadata, by the type of its default."""
    default = f.default
    if isinstance(default, bool):
        return "boolean"
    if isinstance(default, (int, float)):
        return "number"
    return "string" if isinstance(default, str) else "any"


@dataclass(frozen=True)
class SimulationOptions:
    """Every setting of a run (:func:`appell.simulation.simulate.simulate`'s keyword arguments).

    Build it with :meth:`from_model` and :meth:`given`; :meth:`checked` gives the checked
    copy a run uses (``t_eval`` an array, tolerances floats). The ``toml`` metadata of a field
    says what a model file's ``[simulation]`` table holds there (:meth:`table_keys`).
    """

    t0: float = field(default=0.0, metadata=_toml("number, the initial time (default 0)", "number"))
    t_end: float = field(default=DEFAULT_T_END, metadata=_toml("number, the final time", "number"))
    #: output times (None: :data:`DEFAULT_SAMPLES` equally spaced in [t0, t_end])
    t_eval: tuple | np.ndarray | None = field(
        default=None, metadata=_toml("array of non-decreasing output times", "times")
    )
    method: str | type = field(default="DOP853", metadata=_toml("string, the integrator", "string"))
    rtol: float = field(default=1e-9, metadata=_toml("positive number", "positive"))
    atol: float | tuple | np.ndarray = field(default=1e-12, metadata=_toml("positive number", "positive"))
    max_step: float = field(default=np.inf, metadata=_toml("positive number", "positive"))
    stabilization: str | None = field(
        default="projection", metadata=_toml("'projection', 'baumgarte' or 'none'", "choice")
    )
    baumgarte: tuple = field(
        default=(10.0, 10.0), metadata=_toml("array [alpha, beta] of non-negative numbers", "gains")
    )
    projection_tol: float = field(default=1e-10, metadata=_toml("positive number", "positive"))
    project_output: bool = field(
        default=False, metadata=_toml("boolean: also project output states taken from inside a step", "boolean")
    )
    unilateral: Mapping | None = field(
        default=None, metadata=_toml("table: constraint name = 1 or -1 (the sign its multiplier keeps)", "signs")
    )
    on_release: str = field(default="continue", metadata=_toml("'continue' or 'stop'", "choice"))
    friction: Mapping | None = field(
        default=None,
        metadata=_toml("table: tangential constraint = { normal = constraint name, mu = number }", "friction"),
    )
    rest_speed: float = field(
        default=1e-6,
        metadata=_toml(
            "positive number: a contact whose rebound speed would be at most this engages again", "positive"
        ),
    )
    complete: bool = field(default=False, metadata=_toml("boolean: complete the dependent initial values", "boolean"))
    #: with ``complete``, which given values may change: None (automatic), names, or () (none)
    adjust: object = None
    #: a tqdm progress bar; None: only when stderr is a terminal
    progress: bool | None = None
    #: a budget of right-hand-side evaluations (None: none)
    max_evaluations: int | None = None

    # ------------------------------------------------------------ building
    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def table_keys(cls) -> dict[str, str]:
        """``{key: what it holds}`` of a model file's ``[simulation]`` table: the settings with
        ``toml`` metadata, and ``output_step`` and ``samples`` (stored as ``t_eval``)."""
        keys = {f.name: f.metadata["toml"] for f in dataclasses.fields(cls) if "toml" in f.metadata}
        keys["output_step"] = (
            "positive number; equally spaced output times from t0 to t_end (expanded into t_eval by from_model)"
        )
        keys["samples"] = (
            "integer >= 2; that many equally spaced output times from t0 to t_end (expanded into t_eval by from_model)"
        )
        return keys

    @classmethod
    def from_table(
        cls, table, *, constraints: Sequence[str] | None = None, constant: Callable | None = None
    ) -> tuple[tuple[str, object], ...]:
        """A model's ``[simulation]`` table read and checked: its settings ``((key, value),
        ...)`` in the table's order, values hashable, for ``System(settings=...)`` and
        :meth:`from_model`. The keys are :meth:`table_keys` (a field added with ``toml``
        metadata is a key at once); each value is checked by its field's ``check`` metadata
        (:data:`TABLE_CHECKS`, else by the type of its default). ``output_step`` and ``samples``
        are kept as given and expand into output times in :meth:`from_model` (the one expansion).

        ``constant(path, value)``: how a number is read (a model file's reader also takes
        constant expressions such as ``"pi/2"``; default a plain finite number);
        ``constraints``: the model's constraint names, which ``unilateral`` and ``friction``
        name. A wrong value or an unknown key is a :class:`SettingError` whose ``path`` names it."""
        keys = cls.table_keys()
        if not isinstance(table, Mapping):
            raise SettingError((), f"must be a table, got {type(table).__name__}")
        for key in table:
            if key not in keys:
                close = difflib.get_close_matches(str(key), list(keys), n=1)
                guess = f"did you mean {close[0]!r}? " if close else ""
                raise SettingError((key,), f"unknown key {key!r}", hint=f"{guess}allowed keys here: {', '.join(keys)}")
        reader = _TableReader(constant or _plain_number, constraints)
        checks = {f.name: f.metadata.get("check") or _default_check(f) for f in dataclasses.fields(cls)}
        checks.update(output_step="positive", samples="count")
        out = {key: reader.value(key, checks[key], value, keys[key]) for key, value in table.items()}
        if out.get("stabilization") == "none":
            out["stabilization"] = None
        t0, t_end = out.get("t0", 0.0), out.get("t_end")
        if t_end is not None and t_end <= t0:
            raise SettingError(("t_end",), f"t_end must be after t0 ({t0})")
        if "samples" in out and (t_end is None or "t_eval" in out or "output_step" in out):
            raise SettingError(("samples",), "samples needs t_end and excludes t_eval and output_step")
        if "output_step" in out:
            if t_end is None or "t_eval" in out:
                raise SettingError(("output_step",), "output_step needs t_end and excludes t_eval")
            if (t_end - t0) / out["output_step"] > MAX_OUTPUT_TIMES:
                raise SettingError(
                    ("output_step",), f"{int((t_end - t0) / out['output_step']) + 1} output times are too many"
                )
        return tuple(out.items())

    @classmethod
    def keywords(cls, settings) -> dict:
        """``{name: value}`` of the settings ``((key, value), ...)`` (:meth:`from_table`) that
        are fields (``output_step`` and ``samples`` left out), ``unilateral`` and ``friction``
        as dictionaries again."""
        out = {k: v for k, v in dict(settings).items() if k in cls.names()}
        for key in ("unilateral", "friction"):
            if key in out:
                out[key] = dict(out[key])
        return out

    @classmethod
    def from_model(cls, system=None) -> SimulationOptions:
        """The model's run settings over the defaults (``system`` None: the defaults). The
        settings are stored hashable (pairs); ``unilateral`` and ``friction`` become
        dictionaries again. Settings that are not options of a run are left out."""
        if system is None:
            return cls()
        settings = dict(system.settings)
        options = cls(**cls.keywords(system.settings))
        if "output_step" in settings or "samples" in settings:
            options = options._span(
                options.t0, options.t_end, samples=settings.get("samples"), output_step=settings.get("output_step")
            )
        return options

    def given(self, samples: int | None = None, output_step: float | None = None, **given) -> SimulationOptions:
        """These options with what a caller gives (``None``: not given, for ``t0``, ``t_end``,
        ``samples`` and ``output_step``). A new span regenerates or cuts the output times
        (module docstring); ``samples`` (that many equally spaced times) or ``output_step``
        (t0, t0 + step, ... and t_end) replace them. An unknown name is a :class:`TypeError`,
        as for any function."""
        unknown = sorted(set(given) - set(self.names()))
        if unknown:
            raise TypeError(
                f"unknown simulation option(s) {', '.join(unknown)}; the options are " + ", ".join(self.names())
            )
        if samples is not None and output_step is not None:
            raise ModelError("give samples or output_step, not both")
        t0, t_end = given.pop("t0", None), given.pop("t_end", None)
        start = self.t0 if t0 is None else number(t0, "t0")
        final = self.t_end if t_end is None else number(t_end, "t_end", hint="give a finite final time")
        out = dataclasses.replace(self, **given)
        if "t_eval" in given:
            return dataclasses.replace(out, t0=start, t_end=final)
        return out._span(start, final, samples=samples, output_step=output_step)

    def _span(self, start: float, final: float, *, samples=None, output_step=None) -> SimulationOptions:
        """The output times over ``[start, final]`` (module docstring)."""
        step, grid = None, self.t_eval
        if samples is not None or output_step is not None:  # given output times replace these
            step = None if output_step is None else number(output_step, "output_step", positive=True)
            grid = np.linspace(start, final, int(samples)) if samples is not None and final > start else None
        elif grid is not None and (final != self.t_end or start != self.t0):
            grid = np.asarray(grid, float)
            spacing = np.diff(grid)
            if grid.size > 2 and grid[0] == self.t0 and np.allclose(spacing, spacing[0], rtol=1e-9, atol=0.0):
                step, grid = float(spacing[0]), None
            else:
                grid = grid[(grid >= start) & (grid <= final)]
        if step is not None and final > start:
            count = int(np.floor((final - start) / float(step) + 1e-9))
            grid = np.minimum(start + float(step) * np.arange(count + 1), final)
            if np.isclose(grid[-1], final, rtol=1e-12, atol=1e-12 * float(step)):
                grid[-1] = final
            grid = grid if grid[-1] == final else np.append(grid, final)
        if grid is not None and not len(grid):
            grid = None
        return dataclasses.replace(
            self, t0=float(start), t_end=float(final), t_eval=None if grid is None else np.asarray(grid, float)
        )

    def changes(self, but=()) -> dict:
        """``{name: value}`` of the settings that differ from the defaults (those in ``but``
        left out): the keyword arguments that give these options to ``simulate``."""
        default = SimulationOptions()
        return {
            name: getattr(self, name)
            for name in self.names()
            if name not in but and not _same(getattr(self, name), getattr(default, name))
        }

    # ------------------------------------------------------------ checking
    def output_times(self) -> np.ndarray:
        """The output times: ``t_eval``, else :data:`DEFAULT_SAMPLES` equally spaced ones (the
        start alone when the span is empty)."""
        if self.t_eval is None:
            return np.linspace(self.t0, self.t_end, DEFAULT_SAMPLES) if self.t_end > self.t0 else np.array([self.t0])
        return np.asarray(self.t_eval, float)

    def checked(self, model) -> SimulationOptions:
        """A checked copy for a run of ``model`` (a Dynamics); see the module docstring."""
        for name in ("complete", "project_output"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise ModelError(f"{name} must be True or False, got {value!r}")
        t0 = number(self.t0, "t0")
        t_end = number(self.t_end, "t_end", hint="give a finite final time")
        if t_end < t0:
            raise ModelError(f"t_end = {t_end:g} is before t0 = {t0:g}")
        t_eval = self.output_times() if self.t_eval is None else times(self.t_eval, "t_eval", t0, t_end)
        rtol = number(self.rtol, "rtol", positive=True, hint="a relative tolerance such as 1e-9")
        if np.ndim(self.atol) == 0:
            atol = number(self.atol, "atol", nonnegative=True, hint="an absolute tolerance such as 1e-12")
        else:
            atol = vector(self.atol, "atol", len(model.state_names), nonnegative=True, names=list(model.state_names))
        max_step = number(self.max_step, "max_step", positive=True, finite=False)
        if (t_end - t0) / max_step > MAX_STEPS:
            raise ModelError(
                f"max_step = {max_step:g} would take more than {MAX_STEPS:.0e} steps to reach t_end",
                hint="give a larger max_step or a shorter time span",
            )
        projection_tol = number(self.projection_tol, "projection_tol", positive=True)
        if self.stabilization not in STABILIZATIONS:
            raise ModelError(
                f"unknown stabilization {self.stabilization!r}", hint="use 'projection', 'baumgarte' or None"
            )
        gains = (0.0, 0.0)
        if self.stabilization == "baumgarte":
            if isinstance(self.baumgarte, (str, bytes)):
                raise ModelError(f"baumgarte must be two numbers (alpha, beta), got {self.baumgarte!r}")
            gains = tuple(float(v) for v in vector(self.baumgarte, "baumgarte (alpha, beta)", 2, nonnegative=True))
        if self.on_release not in RELEASES:
            raise ModelError(f"on_release must be 'continue' or 'stop', not {self.on_release!r}")
        for name, sign in mapping(self.unilateral or {}, "unilateral").items():
            if isinstance(sign, (bool, np.bool_)) or sign not in (1, -1):
                raise ModelError(f"unilateral[{name!r}] must be +1 or -1 (the sign lambda_{name} keeps), got {sign!r}")
        for name, spec in mapping(self.friction or {}, "friction").items():
            if isinstance(spec, (tuple, list)) and len(spec) == 2:
                number(spec[1], f"friction coefficient of {name!r}", nonnegative=True)
        rest_speed = number(self.rest_speed, "rest_speed", positive=True)
        return dataclasses.replace(
            self,
            t0=t0,
            t_end=t_end,
            t_eval=t_eval,
            rtol=rtol,
            atol=atol,
            max_step=max_step,
            projection_tol=projection_tol,
            baumgarte=gains,
            rest_speed=rest_speed,
        )


def _plain_number(path: tuple, value) -> float:
    """A finite number of a ``[simulation]`` table (:meth:`SimulationOptions.from_table`)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(float(value)):
        raise SettingError(path, f"must be a finite number, got {value!r}")
    return float(value)


class _TableReader:
    """The checks of a ``[simulation]`` table's values (:data:`TABLE_CHECKS`), raising
    :class:`SettingError` at the value's path."""

    def __init__(self, constant: Callable, constraints: Sequence[str] | None):
        self.constant, self.constraints = constant, constraints

    def value(self, key: str, check: str, value, what: str):
        path = (key,)
        if check in ("number", "positive"):
            number = self.constant(path, value)
            if check == "positive" and not number > 0:
                raise SettingError(path, f"must be positive, got {number}")
            return number
        if check == "count":
            if isinstance(value, bool) or not isinstance(value, int) or not 2 <= value <= MAX_OUTPUT_TIMES:
                raise SettingError(
                    path,
                    f"must be an integer from 2 to {MAX_OUTPUT_TIMES}, got {value!r}",
                    hint="samples = 501 gives 501 equally spaced output times from t0 to t_end",
                )
            return value
        if check in ("string", "choice"):
            if not isinstance(value, str):
                raise SettingError(path, f"must be a string, got {type(value).__name__}")
            allowed = {"stabilization": ("projection", "baumgarte", "none"), "on_release": RELEASES}.get(key)
            if check == "choice" and allowed and value not in allowed:
                raise SettingError(
                    path, f"{value!r} is not allowed", hint=f"{key} is one of {', '.join(map(repr, allowed))}"
                )
            return value
        if check == "boolean":
            if not isinstance(value, bool):
                raise SettingError(path, f"must be true or false, got {type(value).__name__}")
            return value
        if check in ("times", "gains"):
            if not isinstance(value, (list, tuple)) or (check == "gains" and len(value) != 2):
                raise SettingError(path, f"must be {what}")
            numbers = tuple(self.constant(path + (i,), v) for i, v in enumerate(value))
            if check == "times" and any(b < a for a, b in zip(numbers, numbers[1:])):
                raise SettingError(path, "output times must be non-decreasing")
            if check == "gains" and min(numbers) < 0:
                raise SettingError(path, "alpha and beta must be non-negative")
            return numbers
        if check == "signs":
            pairs = []
            for name, sign in self.table(path, value).items():
                self.constraint(path + (name,), name)
                if sign not in (1, -1) or isinstance(sign, bool):
                    raise SettingError(path + (name,), f"must be 1 or -1, got {sign!r}")
                pairs.append((name, int(sign)))
            return tuple(pairs)
        if check == "friction":
            return tuple(
                (name, self.friction(path + (name,), name, spec)) for name, spec in self.table(path, value).items()
            )
        return tuple(value) if isinstance(value, list) else value  # a field of another type: stored as given

    def table(self, path: tuple, value) -> Mapping:
        if not isinstance(value, Mapping):
            raise SettingError(path, f"must be a table, got {type(value).__name__}")
        return value

    def constraint(self, path: tuple, name):
        if self.constraints is not None and name not in self.constraints:
            raise SettingError(
                path,
                f"{name!r} is not a constraint of the model",
                hint=f"constraints: {', '.join(self.constraints) or '(none)'}",
            )
        return name

    def friction(self, path: tuple, name: str, spec) -> tuple:
        self.constraint(path, name)
        spec = self.table(path, spec)
        for key in spec:
            if key not in ("normal", "mu"):
                raise SettingError(path + (key,), f"unknown key {key!r}", hint="allowed keys here: normal, mu")
        for key in ("normal", "mu"):
            if key not in spec:
                raise SettingError(
                    path, f"missing key {key!r}", hint=f"add {key} = ... to [simulation.friction.{name}]"
                )
        if not isinstance(spec["normal"], str):
            raise SettingError(path + ("normal",), f"must be a string, got {type(spec['normal']).__name__}")
        normal = self.constraint(path + ("normal",), spec["normal"])
        mu = self.constant(path + ("mu",), spec["mu"])
        if mu < 0:
            raise SettingError(path + ("mu",), "the friction coefficient must be non-negative")
        return (normal, mu)


def _same(a, b) -> bool:
    """Whether two settings are equal (arrays and tuples entry by entry)."""
    if isinstance(a, (np.ndarray, tuple)) or isinstance(b, (np.ndarray, tuple)):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    return a == b


def check_events(events) -> tuple:
    """The events of a run as a tuple: :class:`~appell.simulation.events.Event` items or
    callables ``g(t, y, multipliers)``; anything else is a :class:`ModelError`."""
    try:
        items = tuple(events)
    except TypeError:
        raise ModelError(f"events must be a list of Event items or callables, got {type(events).__name__}") from None
    for e in items:
        if not (isinstance(e, Event) or callable(e)):
            raise ModelError(f"event {e!r} is neither an Event nor a callable g(t, y, multipliers)")
        if not isinstance(e, Event):
            continue
        sympy = sys.modules.get("sympy")  # a SymPy expression means SymPy is imported
        expression = isinstance(e.function, str) or sympy is not None and isinstance(e.function, sympy.Basic)
        if not (callable(e.function) or expression):
            raise ModelError(f"event {e.name!r}: function must be a callable or a SymPy expression")
    return items
