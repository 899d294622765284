"""Stick–slip of Coulomb contacts during a simulation (modes of :mod:`appell.numerics.friction`).

A run with frictions moves through *modes*: which Coulomb contacts stick (the ideal
constraint ``v_k = 0``) and which slide. The transitions are events located by root
finding on the dense output, like the release and contact events of
:mod:`appell.simulation.events`:

* a sticking contact ``k`` watches its cone ``g = mu_s |N_k| - |F_k|`` (``F_k`` the
  multipliers of ``v_k = 0``, ``|.|`` the Euclidean norm: an isotropic cone); where
  ``g`` falls through zero it starts to slide, in the direction ``-F_k / |F_k|`` (its
  slip starts opposite the force that held it; exact for a 1-D contact and for a contact
  whose tangential effective mass is isotropic). Event ``'slip'``;
* a sliding contact watches ``g = v_k . d_k`` (``d_k`` its slip direction at the start
  of the mode). Where ``g`` falls through zero with ``|v_k| <= STOP_SPEED`` (the slip
  speed has returned to zero) the contact is tried as sticking: the state is projected onto
  ``v_k = 0`` and, if ``|F_k| <= mu_s |N_k|`` there, it sticks (event ``'stick'``);
  otherwise it slides on in the direction ``-F_k / |F_k|`` (event ``'slip'``, a
  reversal). Where ``|v_k|`` is larger (a 2-D slip that turned by 90 degrees) only
  ``d_k`` is renewed;
* a sliding contact also watches ``sigma_k N_k``: where its normal force passes through
  zero, the side it presses on (``sigma_k``, kept along a slide) is taken again.

At the start a contact with ``|v_k| <= STICK_SPEED`` is tried as sticking, together with
the others at rest; the one whose cone is violated most slides, until every sticking
contact is inside its cone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from appell.numerics.dynamics import FrictionModes
from appell.simulation.events import Watch

__all__ = ["STICK_SPEED", "Transition", "initial_mode", "stick_slip_watches", "transition"]

#: a slip speed at most this (in the slip velocity's unit; the tolerance of the initial
#: check of velocity residuals) counts as zero at the start and at a stick test
STICK_SPEED = 1e-9

#: a slip speed above this where ``v_k . d_k`` crosses zero is a 2-D slip that turned (its
#: direction is renewed); at most this, the slip speed has returned to zero
STOP_SPEED = 1e-7

#: relative slack of the cone test ``|F| <= mu_s |N| (1 + CONE_SLACK)`` at a stick test
CONE_SLACK = 1e-9


@dataclass(frozen=True)
class Transition:
    """A change of mode: the new ``sticking`` set and ``directions``, the state ``y`` to
    go on from (projected onto ``v_k = 0`` when the contact sticks), the event ``kind``
    (``'stick'``, ``'slip'`` or None for a renewed direction only) and ``detail``."""

    sticking: frozenset
    directions: dict
    y: np.ndarray
    kind: str | None
    detail: str


def _mu_s(model, t, y, p, name) -> float:
    q, w = model.split_state(y)
    k = [i.name for i in model.frictions].index(name)
    return float(model.laws.at(t, q, w, model.params(p))[2][k, 1])


def _slip_direction(force) -> np.ndarray | None:
    size = float(np.linalg.norm(force))
    return None if size == 0.0 else -np.asarray(force, float) / size


def initial_mode(laws, released, t, y, p, directions=None) -> tuple[frozenset, dict, tuple]:
    """The sticking set, the slip directions and the contacts at rest that start to slide,
    at the start (module docstring)."""
    directions = dict(directions or {})
    probe = laws.mode(released, (), {})
    slips = probe.slip_velocities(t, y, p)
    sticking, started = set(), []
    for item in probe.sliding():
        speed = float(np.linalg.norm(slips[item.name]))
        if speed <= STICK_SPEED:
            sticking.add(item.name)
        else:
            directions[item.name] = slips[item.name] / speed
    while sticking:
        model = laws.mode(released, sticking, directions)
        ev = model.evaluate(t, y, p)
        excess = {}
        for name in model.sticking:
            k = [i.name for i in model.frictions].index(name)
            F = float(np.linalg.norm(ev.forces[name]))
            limit = _mu_s(model, t, y, p, name) * float(ev.normals[k])
            if F > limit * (1.0 + CONE_SLACK):
                excess[name] = F - limit
        if not excess:
            break
        worst = max(excess, key=excess.get)
        sticking.discard(worst)
        started.append(worst)
        directions[worst] = _slip_direction(ev.forces[worst])
    return frozenset(sticking), directions, tuple(started)


def stick_slip_watches(model) -> list[Watch]:
    """The cone watch of every sticking contact and the slip watch of every sliding one."""
    out = []
    for k, item in enumerate(model.frictions if isinstance(model, FrictionModes) else ()):
        if item.name in model.sticking:

            def g(t, y, ev, p, k=k, name=item.name):
                return _mu_s(model, t, y, p, name) * float(ev.normals[k]) - float(np.linalg.norm(ev.forces[name]))

            out.append(Watch("slip", item.name, g, -1, "mode"))
        elif item in model.sliding() and item.name in model.directions:
            d = np.asarray(model.directions[item.name], float)

            def g(t, y, ev, p, d=d, name=item.name):
                return float(np.dot(model.slip_velocities(t, y, p)[name], d))

            out.append(Watch("stick", item.name, g, -1, "mode"))
            if item.name in model.signs:  # the normal force passes through zero: its sign is renewed
                out.append(
                    Watch(
                        "normal",
                        item.name,
                        lambda t, y, ev, p, name=item.name, sg=model.signs[item.name]: sg * ev.signed_normals[name],
                        -1,
                        "mode",
                    )
                )
    return out


def transition(laws, model, kind, name, t, y, p, project) -> Transition:
    """The change of mode at contact ``name`` where its watch crossed zero at ``(t, y)``
    (module docstring; ``kind`` the watch's, 'normal' where a normal force passed through
    zero: its sign is taken again); ``project(model, t, y, p)`` projects a state onto a model's
    constraints."""
    sticking, directions = set(model.sticking), dict(model.directions)
    if kind == "normal":
        return Transition(frozenset(sticking), directions, np.asarray(y, float), None, "")
    if name in sticking:
        ev = model.evaluate(t, y, p)
        sticking.discard(name)
        directions[name] = _slip_direction(ev.forces[name])
        k = [i.name for i in model.frictions].index(name)
        return Transition(
            frozenset(sticking),
            directions,
            np.asarray(y, float),
            "slip",
            f"|F_t| = {np.linalg.norm(ev.forces[name]):.6g} reaches mu_s |N| = "
            f"{_mu_s(model, t, y, p, name) * ev.normals[k]:.6g}: the contact starts to slide",
        )
    v = model.slip_velocities(t, y, p)[name]
    speed = float(np.linalg.norm(v))
    if speed > STOP_SPEED:
        directions[name] = v / speed
        return Transition(frozenset(sticking), directions, np.asarray(y, float), None, "")
    trial = laws.mode(model.released, sticking | {name}, directions)
    y_stuck = project(trial, t, y, p)
    ev = trial.evaluate(t, y_stuck, p)
    k = [i.name for i in model.frictions].index(name)
    F, limit = float(np.linalg.norm(ev.forces[name])), _mu_s(model, t, y, p, name) * float(ev.normals[k])
    if F <= limit * (1.0 + CONE_SLACK):
        return Transition(
            frozenset(sticking | {name}),
            directions,
            y_stuck,
            "stick",
            f"the slip speed returns to zero and |F_t| = {F:.6g} <= mu_s |N| = {limit:.6g}: the contact sticks",
        )
    directions[name] = _slip_direction(ev.forces[name])
    return Transition(
        frozenset(sticking),
        directions,
        y_stuck,
        "slip",
        f"the slip speed returns to zero but sticking needs |F_t| = {F:.6g} > mu_s |N| = "
        f"{limit:.6g}: the contact slides on in the direction opposite to that force",
    )
