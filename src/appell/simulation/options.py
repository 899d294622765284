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
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from appell.arguments import mapping, number, times, vector
from appell.errors import ModelError
from appell.simulation.events import Event

__all__ = ["DEFAULT_T_END", "MAX_STEPS", "SimulationOptions", "check_events"]

#: final time when neither the caller nor the model's settings give one
DEFAULT_T_END = 10.0

#: the most integration steps a ``max_step`` may force (``(t_end - t0) / max_step``)
MAX_STEPS = 1e9

#: output times when none are given
DEFAULT_SAMPLES = 501

STABILIZATIONS = ("projection", "baumgarte", None)
RELEASES = ("continue", "stop")


def _toml(text: str):
    """A setting a model file's ``[simulation]`` table may give, with what it holds."""
    return {"toml": text}


@dataclass(frozen=True)
class SimulationOptions:
    """Every setting of a run (:func:`appell.simulation.simulate.simulate`'s keyword arguments).

    Build it with :meth:`from_model` and :meth:`given`; :meth:`checked` gives the checked
    copy a run uses (``t_eval`` an array, tolerances floats). The ``toml`` metadata of a field
    says what a model file's ``[simulation]`` table holds there (:meth:`table_keys`).
    """

    t0: float = field(default=0.0, metadata=_toml("number, the initial time (default 0)"))
    t_end: float = field(default=DEFAULT_T_END, metadata=_toml("number, the final time"))
    #: output times (None: :data:`DEFAULT_SAMPLES` equally spaced in [t0, t_end])
    t_eval: tuple | np.ndarray | None = field(default=None, metadata=_toml("array of non-decreasing output times"))
    method: str | type = field(default="DOP853", metadata=_toml("string, the integrator"))
    rtol: float = field(default=1e-9, metadata=_toml("positive number"))
    atol: float | tuple | np.ndarray = field(default=1e-12, metadata=_toml("positive number"))
    max_step: float = field(default=np.inf, metadata=_toml("positive number"))
    stabilization: str | None = field(default="projection", metadata=_toml("'projection', 'baumgarte' or 'none'"))
    baumgarte: tuple = field(default=(10.0, 10.0), metadata=_toml("array [alpha, beta] of non-negative numbers"))
    projection_tol: float = field(default=1e-10, metadata=_toml("positive number"))
    project_output: bool = field(
        default=False, metadata=_toml("boolean: also project output states taken from inside a step")
    )
    unilateral: Mapping | None = field(
        default=None, metadata=_toml("table: constraint name = 1 or -1 (the sign its multiplier keeps)")
    )
    on_release: str = field(default="continue", metadata=_toml("'continue' or 'stop'"))
    friction: Mapping | None = field(
        default=None, metadata=_toml("table: tangential constraint = { normal = constraint name, mu = number }")
    )
    rest_speed: float = field(
        default=1e-6,
        metadata=_toml("positive number: a contact whose rebound speed would be at most this engages again"),
    )
    complete: bool = field(default=False, metadata=_toml("boolean: complete the dependent initial values"))
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
        keys["output_step"] = "positive number; equally spaced output times from t0 to t_end (stored as t_eval)"
        keys["samples"] = "integer >= 2; that many equally spaced output times from t0 to t_end (stored as t_eval)"
        return keys

    @classmethod
    def from_model(cls, system=None) -> SimulationOptions:
        """The model's run settings over the defaults (``system`` None: the defaults). The
        settings are stored hashable (pairs); ``unilateral`` and ``friction`` become
        dictionaries again. Settings that are not options of a run are left out."""
        if system is None:
            return cls()
        settings = dict(system.settings)
        out = {k: v for k, v in settings.items() if k in cls.names()}
        for key in ("unilateral", "friction"):
            if key in out:
                out[key] = dict(out[key])
        options = cls(**out)
        if "output_step" in settings:
            options = options._span(options.t0, options.t_end, output_step=settings["output_step"])
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
        if isinstance(e, Event) and not (callable(e.function) or isinstance(e.function, (sp.Basic, str))):
            raise ModelError(f"event {e.name!r}: function must be a callable or a SymPy expression")
    return items
