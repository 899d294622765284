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
