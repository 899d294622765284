"""A model's run settings as the defaults of :func:`~appell.simulation.simulate.simulate`.

A :class:`~appell.model.System` carries run settings: a model file's ``[simulation]``
table, or ``System(settings=...)``. The Python API and the command line read them the
same way, through :func:`model_options`:

* an argument the caller gives wins (``simulate(d, 2.0, rtol=1e-6)``, ``appell simulate
  --t-end 2``);
* an argument left out takes the model's setting;
* a setting the model does not make takes :func:`simulate`'s own default; the final time,
  when neither the caller nor the model gives one, is :data:`DEFAULT_T_END`.

When the final (or initial) time differs from the model's, output times the model gives
on an equal spacing are regenerated with that spacing over the new span; other output
times are cut to it.
"""

from __future__ import annotations

import functools
import inspect

import numpy as np

from appell.arguments import number

__all__ = ["DEFAULT_T_END", "settings_options", "model_options", "with_model_defaults"]

#: final time when neither the caller nor the model's settings give one
DEFAULT_T_END = 10.0


def settings_options(system) -> dict:
    """``system.settings`` as keyword arguments of ``simulate``, as stored.

    The settings are stored hashable (pairs); ``unilateral`` and ``friction`` become
    dictionaries again, ``t_eval`` stays an array-like tuple.
    """
    options = dict(system.settings)
    options.pop("stability", None)  # the [stability] table: appell stability's, not the simulation's
    for key in ("unilateral", "friction"):
        if key in options:
            options[key] = dict(options[key])
    return options


def model_options(system, t_end: float | None = None, t0: float | None = None, *,
                  samples: int | None = None, output_step: float | None = None) -> dict:
    """Keyword arguments of ``simulate`` from the model's settings (module docstring), with
    ``t_end`` and ``t0`` (when not None) overriding the model's final and initial time, and
    ``samples`` (that many equally spaced times) or ``output_step`` (t0, t0 + step, ... and
    t_end) replacing the model's output times.

    The result always holds ``t0`` and ``t_end``, and ``t_eval`` when output times are
    given (``t_eval`` or ``output_step`` of the model, or the arguments). When ``t_end`` or
    ``t0`` changes the span, equally spaced output times of the model are regenerated with
    their step over the new span, and other output times are cut to it.
    """
    opts = settings_options(system)
    table_t0 = float(opts.pop("t0", 0.0))
    table_t_end = opts.pop("t_end", None)
    start = table_t0 if t0 is None else number(t0, "t0")
    final = number(t_end if t_end is not None else table_t_end if table_t_end is not None else DEFAULT_T_END,
                   "t_end", hint="give a finite final time")
    step = opts.pop("output_step", None)
    times = opts.pop("t_eval", None)
    if samples is not None or output_step is not None:  # given output times replace the model's
        step = None if output_step is None else number(output_step, "output_step", positive=True)
        times = np.linspace(start, final, int(samples)) if samples is not None and final > start else None
    if times is not None and step is None and (final != table_t_end or start != table_t0):
        grid = np.asarray(times, float)
        spacing = np.diff(grid)
        if grid.size > 2 and grid[0] == table_t0 and np.allclose(spacing, spacing[0], rtol=1e-9, atol=0.0):
            step, times = float(spacing[0]), None
        else:
            times = grid[(grid >= start) & (grid <= final)]
    if step is not None and final > start:
        count = int(np.floor((final - start) / float(step) + 1e-9))
        grid = np.minimum(start + float(step) * np.arange(count + 1), final)
        if np.isclose(grid[-1], final, rtol=1e-12, atol=1e-12 * float(step)):
            grid[-1] = final
        times = grid if grid[-1] == final else np.append(grid, final)
    if times is not None and len(times):
        opts["t_eval"] = np.asarray(times, float)
    opts["t0"], opts["t_end"] = start, final
    return opts


def with_model_defaults(simulate):
    """Make the model's settings the defaults of ``simulate`` (module docstring).

    ``simulate``'s first parameter is the model (a Derivation or a Dynamics, whose system
    gives the settings); ``t_end=None`` means "the model's final time". Settings that are
    not parameters of ``simulate`` are ignored.
    """
    signature = inspect.signature(simulate)
    accepted = set(signature.parameters)

    @functools.wraps(simulate)
    def wrapper(*args, **kwargs):
        from appell.simulation.initial import dynamics_of

        bound = signature.bind(*args, **kwargs)
        given = dict(bound.arguments)
        first = next(iter(signature.parameters))
        _, system = dynamics_of(given[first])
        t_end, t0 = given.get("t_end"), given.get("t0")
        if system is not None:
            defaults = model_options(system, t_end, t0)
        else:
            start = 0.0 if t0 is None else t0
            defaults = {"t0": start, "t_end": DEFAULT_T_END if t_end is None else t_end}
        for key, value in defaults.items():
            if key in ("t0", "t_end") or (key in accepted and key not in given):
                given[key] = value
        return simulate(**given)

    return wrapper
