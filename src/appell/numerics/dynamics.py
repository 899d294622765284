"""The contract between a derived model and the simulator.

Anything that can be integrated — the plain constrained system
(:class:`appell.numerics.numeric.NumericModel`), a controlled system with servo constraints, a
Routh-reduced system — implements :class:`Dynamics`: a state vector ``y`` with named
entries, and at each ``(t, y)`` an :class:`Evaluation` with ``dy/dt``, every multiplier
and every control.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class Evaluation:
    """What the model gives at one ``(t, y)``.

    ``derivative`` dy/dt; ``multipliers`` one per constraint (recorded as
    ``lambda_<name>``); ``controls`` one per control (``control_<name>``);
    ``dependent`` the indices of the dependent accelerations used; ``switched`` whether
    that partition differs from the derivation's (the old one turned singular).
    """

    derivative: np.ndarray
    multipliers: np.ndarray
    controls: np.ndarray
    dependent: tuple[int, ...] = ()
    switched: bool = False


@runtime_checkable
class Dynamics(Protocol):
    """Numeric model the simulator integrates.

    Attributes
    ----------
    name : model name.
    state_names : names of the entries of ``y`` (coordinates, then speeds, then any
        extra states such as a kinematic control's position and rate).
    coordinate_names, speed_names : the position- and velocity-level parts of ``y``.
    constraint_names, control_names : labels of the multipliers and controls.
    parameter_names, default_parameters : the parameter vector ``p``.
    """

    name: str
    state_names: tuple[str, ...]
    coordinate_names: tuple[str, ...]
    speed_names: tuple[str, ...]
    constraint_names: tuple[str, ...]
    control_names: tuple[str, ...]
    parameter_names: tuple[str, ...]
    default_parameters: np.ndarray

    def params(self, p=None) -> np.ndarray:
        """Parameter vector from None (defaults), an array or ``{name: value}``."""

    def evaluate(self, t: float, y: np.ndarray, p: np.ndarray) -> Evaluation:
        """``dy/dt``, multipliers and controls at ``(t, y)``."""

    def state_residuals(self, t: float, y: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Position- and velocity-level residual of every constraint (NaN where the
        constraint has no such level)."""


def delegating(to: str, names):
    """Class decorator: each of ``names`` becomes a read-only property giving the attribute of
    the same name of ``self.<to>`` (a wrapped model). The members are then the wrapper's own,
    so ``isinstance`` with the protocols below sees them (a ``__getattr__`` proxy is invisible
    to the static lookup that later Pythons use for runtime protocols)."""

    def wrap(cls):
        for name in names:
            if name in vars(cls):
                continue

            def get(self, name=name):
                return getattr(getattr(self, to), name)

            get.__name__ = name
            get.__doc__ = f"``{to}.{name}``"
            setattr(cls, name, property(get))
        return cls

    return wrap


#: the members of :class:`Dynamics`
DYNAMICS_MEMBERS = (
    "name",
    "state_names",
    "coordinate_names",
    "speed_names",
    "constraint_names",
    "control_names",
    "parameter_names",
    "default_parameters",
    "params",
    "evaluate",
    "state_residuals",
)


def system_of(model):
    """The :class:`~appell.model.System` behind a model built from a derivation, else None."""
    derivation = model.derivation if isinstance(model, FromDerivation) else None
    return None if derivation is None else derivation.system


# ------------------------------------------------------------ capabilities beyond Dynamics
# What the simulator and the start's completion use when a model offers it; each is a
# protocol checked with ``isinstance`` (never an attribute probe). A model that wraps another
# (RedundantModel, FrictionModel) defines the members it offers itself.


@runtime_checkable
class FromDerivation(Protocol):
    """A model built from a derivation (:func:`appell.numerics.boundary.numeric_model`): its
    ``derivation`` gives the system (outputs, constraint orders, frictions)."""

    derivation: object


@runtime_checkable
class SplitBlocks(Protocol):
    """The blocks of the split at a state: ``M``, ``h - Q``, ``J``, ``c`` (method.md §3), for
    the impact law, the singular-position watch and the check of a start."""

    def evaluate_blocks(self, t: float, q, w, p=None) -> tuple:
        """``(M, h - Q, J, c)`` at ``(t, q, w)``."""


@runtime_checkable
class ResidualJacobians(Protocol):
    """Compiled Jacobians of the constraint residuals, ``dF/dq`` and ``dphi/dw`` (else the
    simulator differences :meth:`Dynamics.state_residuals`)."""

    def residual_jacobians(self, t: float, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """``(dF/dq, dphi/dw)`` at ``(t, y)``."""


@runtime_checkable
class ServoTracking(Protocol):
    """A controlled model (method.md §4): the servo constraints it realises, recorded and
    monitored along the motion; a start must satisfy them and their state relations."""

    servo_names: tuple[str, ...]
    #: ``(servo constraint, order of its time derivative)`` of each state relation
    relation_of: tuple

    @property
    def start_conditions(self) -> tuple[str, ...]:
        """Names of what a start must satisfy besides the real constraints."""

    def start_residuals(self, t: float, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """Position- and velocity-level residuals of :attr:`start_conditions`."""

    def start_blocks(self, t: float, y, p=None) -> tuple:
        """The blocks with the control blocks at a start (checked finite there)."""


@runtime_checkable
class FrictionModes(Protocol):
    """A system with Coulomb friction in one mode (:mod:`appell.numerics.friction`): the
    contacts, which of them stick, and the laws that give the model of another mode."""

    laws: object
    sticking: frozenset

    @property
    def frictions(self) -> tuple:
        """The friction contacts of the system."""
