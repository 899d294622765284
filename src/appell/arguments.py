"""Checks of the arguments of the public functions (``simulate``, ``sweep``, ``solve``,
``derive``, ``load_model``, ...).

A wrong value is a :class:`~appell.errors.ModelError` (exit code 2) that names the
argument, the value and what is allowed, raised before NumPy or SciPy see it: no
``ValueError: array must not contain infs or NaNs`` from inside SciPy, no NaN output
time silently dropped, no negative tolerance silently accepted, no endless integration
towards ``t_end = inf``.
"""

from __future__ import annotations

import math
import numbers
import sys
from collections.abc import Mapping

import numpy as np

from appell.errors import ModelError

__all__ = ["number", "count", "vector", "times", "mapping"]


def number(
    value, name: str, *, positive: bool = False, nonnegative: bool = False, finite: bool = True, hint: str | None = None
) -> float:
    """``value`` as a float: a real number (not a bool, not a string), finite unless
    ``finite=False`` (then +inf is allowed, never NaN), and > 0 or >= 0 when asked."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    sp = sys.modules.get("sympy")  # a SymPy value means SymPy is imported (the numeric tree route needs none)
    if sp is not None and isinstance(value, sp.Basic) and value.is_number and value.is_real is not False:
        try:
            value = float(value)  # a SymPy constant such as pi/3
        except TypeError:
            pass
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
        raise ModelError(f"{name} must be a number, got {value!r} ({type(value).__name__})", hint=hint)
    x = float(value)
    if math.isnan(x) or (finite and math.isinf(x)) or (not finite and x == -math.inf):
        raise ModelError(f"{name} must be a finite number, got {x}", hint=hint)
    if positive and not x > 0:
        raise ModelError(f"{name} must be positive, got {x:g}", hint=hint)
    if nonnegative and not x >= 0:
        raise ModelError(f"{name} must be non-negative, got {x:g}", hint=hint)
    return x


def count(value, name: str, *, minimum: int = 1, maximum: int | None = None) -> int:
    """``value`` as an int in ``[minimum, maximum]`` (an integer, not a bool or a float)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)):
        raise ModelError(f"{name} must be an integer, got {value!r} ({type(value).__name__})")
    k = int(value)
    if k < minimum or (maximum is not None and k > maximum):
        bound = f"at least {minimum}" if maximum is None else f"between {minimum} and {maximum}"
        raise ModelError(f"{name} must be {bound}, got {k}")
    return k


def vector(value, name: str, length: int | None = None, *, nonnegative: bool = False, names=None) -> np.ndarray:
    """``value`` as a 1-D float array of finite numbers (of ``length`` entries when given;
    ``names`` label the entries in the message)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be numbers, got {_short(value)}") from None
    if arr.ndim > 1 and arr.size == max(arr.shape):
        arr = arr.reshape(-1)
    if arr.ndim != 1:
        raise ModelError(f"{name} must be a flat list of numbers, got an array of shape {arr.shape}")
    if length is not None and arr.size != length:
        listed = f" ({', '.join(names)})" if names is not None else ""
        raise ModelError(f"{name} has {arr.size} entries, {length} expected{listed}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        label = names[bad[0]] if names is not None else f"entry {bad[0]}"
        raise ModelError(f"{name}: {label} is {arr[bad[0]]}, not a finite number")
    if nonnegative and np.any(arr < 0):
        raise ModelError(f"{name} must be non-negative, got {arr[arr < 0][0]:g}")
    return arr


def times(value, name: str, start: float, end: float) -> np.ndarray:
    """Output times: finite, non-decreasing, inside ``[start, end]``."""
    arr = vector(value, name)
    if np.any(np.diff(arr) < 0):
        i = int(np.flatnonzero(np.diff(arr) < 0)[0])
        raise ModelError(f"{name} must be non-decreasing: {arr[i]:g} is followed by {arr[i + 1]:g}")
    if arr.size and (arr[0] < start or arr[-1] > end):
        raise ModelError(f"{name} must lie in [t0, t_end] = [{start:g}, {end:g}], got [{arr[0]:g}, {arr[-1]:g}]")
    return arr


def mapping(value, name: str) -> Mapping:
    """``value`` if it is a mapping (``{name: value}``), else a ModelError."""
    if not isinstance(value, Mapping):
        raise ModelError(f"{name} must be a mapping {{name: value}}, got {type(value).__name__}")
    return value


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
