"""Events watched during a simulation: zero crossings of scalar functions of the motion.

Each watched quantity is a function ``g(t, y, evaluation)`` whose zero crossing is
located by Brent's method on the integrator's dense output (to ``1e-13`` in time):

* unilateral constraint ``c`` with sign ``s`` (``unilateral={'c': +1}``):
  ``g = s lambda_c``; when it falls through zero the constraint is released;
* contact: a released unilateral holonomic constraint ``c`` (or one whose gap is open at
  the start): ``g = s F_c + offset``, the gap on the admissible side ``s F_c >= 0``; when
  it falls through zero the gap has closed and an impact follows
  (:mod:`appell.simulation.impact`). Right after a release the gap lies within the
  constraint's residual, so the watch starts with ``offset = max(2 |s F_c|, 1e-12)``
  (only a closing beyond that residual counts) and is armed (``offset = 0``) once the gap
  has opened by ``offset`` at a step's end. Right after a bounce the gap is taken as
  exactly zero and opening (at the rebound speed); the simulator also looks for a return
  within the first step;
* friction limit (``friction={'t': ('n', mu)}``): ``g = mu lambda_n - |lambda_t|``; each
  crossing is recorded ('exceeded' when ``|lambda_t|`` rises above ``mu lambda_n``);
* user events (:class:`Event`): a callable ``g(t, y, multipliers)`` with
  ``multipliers`` a ``{constraint name: lambda}`` mapping, or a SymPy expression in
  ``t``, the state names, the parameter names, ``lambda_<constraint>`` and
  ``control_<control>``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from appell.errors import ModelError

if TYPE_CHECKING:
    import sympy as sp
# SymPy (an event given as an expression) and SciPy's root finder are imported where used: a
# run of the numeric tree route imports neither

__all__ = ["Event", "Watch", "watches_for", "contact_watch", "gap_constraints", "locate", "ENDING"]


@dataclass(frozen=True)
class Event:
    """A user event: fires where ``function`` crosses zero.

    ``function`` is a callable ``(t, y, multipliers) -> float`` (``y`` the state vector,
    ``multipliers`` ``{constraint: lambda}``) or a SymPy expression (see the module
    docstring). ``terminal`` stops the integration there; ``direction`` +1 fires only
    on rising, -1 only on falling crossings, 0 on both.
    """

    name: str
    function: Callable | sp.Expr
    terminal: bool = False
    direction: int = 0


@dataclass(frozen=True)
class Watch:
    """A compiled watched quantity: ``g(t, y, evaluation, p) -> float``; ``kind`` one of
    'release', 'contact', 'friction', 'user'; ``action`` 'record', 'stop', 'release' or
    'impact'; ``offset`` the band a contact's gap must close beyond (module docstring)."""

    kind: str
    name: str
    g: Callable
    direction: int
    action: str
    constraints: tuple[str, ...] = ()
    offset: float = 0.0

    def crossed(self, g0: float, g1: float) -> bool:
        """Whether a crossing of the watched direction lies between the values g0, g1."""
        if not (np.isfinite(g0) and np.isfinite(g1)) or g0 == 0.0:
            return False
        rising, falling = g0 < 0.0 <= g1, g0 > 0.0 >= g1
        return (rising and self.direction >= 0) or (falling and self.direction <= 0)


def _multiplier(model, name):
    i = list(model.constraint_names).index(name)
    return lambda ev: float(ev.multipliers[i])


def _sympy_event(event: Event, model):
    import sympy as sp

    expr = sp.sympify(event.function)
    states = list(model.state_names)
    params = list(model.parameter_names)
    cons = list(model.constraint_names)
    ctrls = list(model.control_names)
    symbols = {"t": sp.Symbol("t")}
    for n in states + params + [f"lambda_{c}" for c in cons] + [f"control_{c}" for c in ctrls]:
        symbols[n] = sp.Symbol(n)
    unknown = sorted(s.name for s in expr.free_symbols if s.name not in symbols)
    if unknown:
        raise ModelError(
            f"event {event.name!r} uses unknown symbol(s) {', '.join(unknown)}",
            hint="events may use t, the state names, parameters, lambda_<constraint> and control_<control>",
        )
    order = list(symbols)
    fn = sp.lambdify([symbols[n] for n in order], expr, modules="numpy")
    ns, npar, nc = len(states), len(params), len(cons)

    def g(t, y, ev, p):
        args = [t, *y[:ns], *p[:npar], *ev.multipliers[:nc], *ev.controls]
        return float(fn(*args))

    return g, ()


def contact_watch(root, name: str, sign: float, offset: float = 0.0) -> Watch:
    """The gap ``s F_c + offset`` of the holonomic constraint ``name`` of ``root`` (a model
    holding every constraint; the state vectors of all the models of one run agree)."""
    i = list(root.constraint_names).index(name)
    s = float(np.sign(sign))

    def g(t, y, ev, p):
        return s * float(root.state_residuals(t, y, p)[0][i]) + offset

    return Watch("contact", name, g, -1, "impact", (name,), float(offset))


def gap_constraints(root, unilateral, t, y, p) -> tuple[str, ...]:
    """The unilateral constraints of ``root`` that have a gap (holonomic ones)."""
    F, _ = root.state_residuals(t, y, p)
    names = list(root.constraint_names)
    return tuple(c for c in dict(unilateral or {}) if c in names and not np.isnan(F[names.index(c)]))


def watches_for(
    model, unilateral=None, on_release="continue", friction=None, events=(), root=None, offsets=None
) -> list[Watch]:
    """The :class:`Watch` list for a model; release and friction entries naming
    constraints the model lacks (released) are left out. ``root`` the model with every
    constraint: its holonomic unilateral constraints that ``model`` lacks are watched for
    contact, with ``offsets`` ``{constraint: offset}`` (default 0)."""
    names = set(model.constraint_names)
    out = []
    for c, sign in dict(unilateral or {}).items():
        if c not in names:
            continue
        sign = float(np.sign(sign))
        lam = _multiplier(model, c)
        out.append(
            Watch(
                "release",
                c,
                lambda t, y, ev, p, lam=lam, s=sign: s * lam(ev),
                -1,
                "stop" if on_release == "stop" else "release",
                (c,),
            )
        )
    if root is not None:
        offsets = dict(offsets or {})
        kinds = getattr(root, "has_position", None)
        for c, sign in dict(unilateral or {}).items():
            i = list(root.constraint_names).index(c)
            if c not in names and (kinds is None or kinds[i]):
                out.append(contact_watch(root, c, sign, offsets.get(c, 0.0)))
    for ct, (cn, mu) in dict(friction or {}).items():
        if ct not in names or cn not in names:
            continue
        lt, ln = _multiplier(model, ct), _multiplier(model, cn)
        out.append(
            Watch(
                "friction",
                ct,
                lambda t, y, ev, p, lt=lt, ln=ln, mu=float(mu): mu * ln(ev) - abs(lt(ev)),
                0,
                "record",
                (ct, cn),
            )
        )
    for e in events:
        if not isinstance(e, Event):
            e = Event(getattr(e, "__name__", str(e)), e)
        sympy = sys.modules.get("sympy")  # a SymPy expression means SymPy is imported
        if isinstance(e.function, str) or sympy is not None and isinstance(e.function, sympy.Basic):
            g, _ = _sympy_event(e, model)
        else:
            cons = tuple(model.constraint_names)
            fn = e.function

            def g(t, y, ev, p, fn=fn, cons=cons):
                return float(fn(t, y, dict(zip(cons, (float(v) for v in ev.multipliers)))))

        out.append(Watch("user", e.name, g, int(np.sign(e.direction)), "stop" if e.terminal else "record"))
    return out


def check_event_names(model, unilateral=None, friction=None):
    """Raise ModelError for unilateral/friction entries naming no constraint of the model."""
    names = list(model.constraint_names)
    bad = [c for c in dict(unilateral or {}) if c not in names]
    for ct, spec in dict(friction or {}).items():
        try:
            cn, _ = spec
        except (TypeError, ValueError) as exc:
            raise ModelError(f"friction entry for {ct!r} must be (normal constraint, mu)") from exc
        bad += [c for c in (ct, cn) if c not in names]
    if bad:
        raise ModelError(
            f"unknown constraint(s) {', '.join(sorted(set(bad)))} in unilateral/friction",
            hint="constraints: " + ", ".join(names),
        )


#: the actions of a watch that end a step where it fires (the run changes there)
ENDING = ("stop", "release", "impact", "mode")


def locate(watches, g, g_new, t: float, t_new: float, dense, evaluate, p) -> list[tuple[float, int, Watch]]:
    """Every crossing of a watched quantity within the step from ``t`` to ``t_new``, in time
    order, as ``(time, index, watch)``: the one place where events are located.

    ``g``, ``g_new`` are the watches' values at the step's ends, ``dense`` its dense output,
    ``evaluate(s, y)`` the model's evaluation at an inner time (a contact's gap needs none).
    A crossing is located by Brent's method to 1e-13 in time; where the interpolant loses the
    sign change, at the step's end. A contact that bounced at ``t`` (its gap zero and opening
    there) and is closed again at ``t_new`` is searched for an opening inside the step first,
    then located from there; where none is found it closes at ``t`` itself."""
    hits = []
    for i, w in enumerate(watches):

        def gi(s, w=w):
            ys = dense(s)
            return w.g(s, ys, None if w.kind == "contact" else evaluate(s, ys), p)

        lo = t if w.crossed(g[i], g_new[i]) else None
        if lo is None and w.kind == "contact" and g[i] == 0.0 and g_new[i] < 0.0:
            lo = _opening(gi, t, t_new)  # a bounce at t: the gap opens and closes again within this step
            if lo is None:
                hits.append((t, i, w))
                continue
        if lo is not None:
            from scipy.optimize import brentq

            try:
                ts = brentq(gi, lo, t_new, xtol=1e-13, rtol=4 * np.finfo(float).eps, maxiter=200)
            except ValueError:  # the interpolant lost the sign change: take the step's end
                ts = t_new
            hits.append((ts, i, w))
    hits.sort(key=lambda h: h[0])
    return hits


def _opening(g, a: float, b: float):
    """A time in (a, b] where ``g > 0``, searched at ``a + (b - a) / 2^k`` (k = 1..60):
    after a bounce at ``a`` the gap grows at the rebound speed, so it is positive just
    after ``a``; None when no such time is found."""
    for k in range(1, 61):
        s = a + (b - a) * 0.5**k
        if s <= a:
            break
        if g(s) > 0.0:
            return s
    return None
