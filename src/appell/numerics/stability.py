"""Eigenvalues of the linear model against a parameter: modes tracked across the sweep and
the critical values where a real part crosses zero.

At each value ``v_k`` of the varied name (a parameter, or a coordinate or speed of the
point: the forward speed of a vehicle), the point is the given one, or the steady motion
found from the previous one (:func:`~appell.numerics.linearise.steady_motion`, ``free``),
and :func:`~appell.numerics.linearise.linearise` gives ``A(v_k)``. Modes are tracked by the
assignment that minimises ``sum |s_i(v_k) - s_j(v_{k+1})|`` (:func:`scipy.optimize.
linear_sum_assignment`, the eigenvalues predicted linearly from the two previous values).
Between two values where a tracked mode's real part changes sign, the crossing is located
by Brent's method on the real part of the eigenvalue nearest the tracked one
(:func:`scipy.optimize.brentq`, to ``xtol``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from appell.errors import ModelError
from appell.numerics.linearise import linearise, steady_motion

__all__ = ["Crossing", "StabilitySweep", "stability_sweep"]


@dataclass(frozen=True)
class Crossing:
    """A tracked mode whose real part crosses zero at ``value`` of the varied name:
    ``kind`` 'oscillatory' (the mode's imaginary part is nonzero there) or 'real';
    ``direction`` +1 when it becomes unstable as the value grows, -1 when it becomes stable."""

    mode: int
    value: float
    imag: float
    direction: int
    scale: float = 1.0

    @property
    def kind(self) -> str:
        """'oscillatory' where the mode's frequency there is more than 1e-4 of the spectrum's
        largest magnitude ``scale`` (a pair that meets on the real axis at zero, as the rolling
        disc's lean mode at its critical speed, is 'real')."""
        return "oscillatory" if abs(self.imag) > 1e-4 * max(self.scale, 1.0) else "real"


@dataclass(frozen=True)
class StabilitySweep:
    """``eigenvalues[k, j]``: mode ``j`` at ``values[k]`` of ``name``; ``names[j]``: the
    states that dominate mode ``j`` at the first value; ``crossings`` located by root finding."""

    name: str
    values: np.ndarray
    eigenvalues: np.ndarray
    names: tuple[str, ...]
    states: tuple[str, ...]
    crossings: tuple[Crossing, ...]

    def stable(self, tol: float = 1e-9) -> np.ndarray:
        """Per value, whether every real part is below ``tol`` (marginal modes count as stable)."""
        return np.all(self.eigenvalues.real < tol, axis=1)

    def to_xarray(self):
        """An :class:`xarray.Dataset` with ``real`` and ``imag`` over (``name``, ``mode``)."""
        import xarray as xr

        return xr.Dataset(
            {
                "real": ((self.name, "mode"), self.eigenvalues.real),
                "imag": ((self.name, "mode"), self.eigenvalues.imag),
            },
            coords={
                self.name: self.values,
                "mode": np.arange(self.eigenvalues.shape[1]),
                "dominant_states": ("mode", list(self.names)),
            },
            attrs={
                "states": ", ".join(self.states),
                "crossings": "; ".join(
                    f"mode {c.mode} at {self.name} = {c.value:.12g} ({c.kind})" for c in self.crossings
                ),
            },
        )

    def table(self) -> str:
        """The crossings and the stable ranges as text."""
        lines = [
            f"eigenvalues against {self.name} ({self.values[0]:g} .. {self.values[-1]:g}, "
            f"{self.values.size} values; states {', '.join(self.states)})"
        ]
        for c in self.crossings:
            turn = "unstable" if c.direction > 0 else "stable"
            lines.append(
                f"  mode {c.mode} ({self.names[c.mode]}) becomes {turn} at {self.name} = {c.value:.12g} "
                f"({c.kind}{f', frequency {abs(c.imag):.6g} rad/s' if c.kind == 'oscillatory' else ''})"
            )
        stable = self.stable()
        if stable.any():
            lines.append(f"  stable at {int(stable.sum())} of {stable.size} values")
        else:
            lines.append("  unstable at every value")
        return "\n".join(lines)

    def plot(self, path=None):
        """Real and imaginary parts against the varied name (matplotlib figure, saved to
        ``path`` when given)."""
        from pathlib import Path

        from matplotlib.figure import Figure

        fig = Figure(figsize=(7, 6), constrained_layout=True)
        ax1, ax2 = fig.subplots(2, 1, sharex=True)
        for j in range(self.eigenvalues.shape[1]):
            ax1.plot(self.values, self.eigenvalues[:, j].real, label=f"{j}: {self.names[j]}")
            ax2.plot(self.values, np.abs(self.eigenvalues[:, j].imag))
        # rounding-sized real parts (a marginal mode) are drawn flat, not magnified
        span = max(float(np.abs(self.eigenvalues.real).max()), 1e-3 * max(1.0, float(np.abs(self.eigenvalues).max())))
        ax1.set_ylim(-1.1 * span, 1.1 * span)
        ax1.axhline(0.0, color="k", lw=0.6)
        for c in self.crossings:
            ax1.axvline(c.value, color="grey", ls=":", lw=0.8)
        ax1.set_ylabel("real part [1/s]")
        ax2.set_ylabel("|imaginary part| [rad/s]")
        ax2.set_xlabel(self.name)
        ax1.legend(fontsize="small")
        if path is not None:
            from appell.files import atomic_path

            path = Path(path)
            with atomic_path(path) as tmp:
                fig.savefig(tmp, format=path.suffix.lstrip(".") or "png")
        return fig


def _track(previous: np.ndarray, before: np.ndarray | None, current: np.ndarray) -> np.ndarray:
    """``current`` reordered to follow ``previous`` (predicted linearly from ``before``)."""
    from scipy.optimize import linear_sum_assignment

    guess = previous if before is None else 2 * previous - before
    cost = np.abs(guess[:, None] - current[None, :])
    _, cols = linear_sum_assignment(cost)
    return current[cols]


def stability_sweep(
    derivation,
    name: str,
    values: Sequence[float],
    *,
    at: Mapping[str, float] | None = None,
    free: Sequence[str] = (),
    ignore=None,
    params: Mapping | None = None,
    coordinates=None,
    speeds=None,
    xtol: float = 1e-12,
    progress: bool | None = None,
) -> StabilitySweep:
    """Eigenvalues of :func:`~appell.numerics.linearise.linearise` at each of ``values`` of
    ``name`` (module docstring). ``at``: the point (over the system's initial values; those
    the system writes in the parameter ``name``, such as ``rear_x' = v``, follow it);
    ``free``: names solved for a steady motion at each value (none: the point is used as it
    is); ``ignore``, ``coordinates``, ``speeds``: as for :func:`linearise`."""
    grid = np.asarray(values, float)
    if grid.ndim != 1 or grid.size < 2 or not np.all(np.diff(grid) > 0):
        raise ModelError("the values of a stability sweep must be at least two, increasing")
    point = dict(at or {})
    system = derivation.system
    # a parameter the initial values are written in (a bicycle's speed v): those values follow it
    expressions = dict(system.initial_expressions)
    positions = {q.name for q in system.coordinates}
    follows = {}  # name -> (its symbols, its value compiled), positions first
    if name in {p.symbol.name for p in system.parameters}:
        moving = [k for k, e in expressions.items() if sp.Symbol(name) in e.free_symbols and k not in point]
        for k in sorted(moving, key=lambda k: k not in positions):
            symbols = sorted(expressions[k].free_symbols, key=str)
            follows[k] = (symbols, sp.lambdify(symbols, expressions[k], modules="math"))
    fixed = {p.symbol: float((params or {}).get(p.symbol.name, p.value)) for p in system.parameters}

    def model_at(v, start):
        here = {**start, name: float(v)}
        if follows:  # positions first: a speed's value may use the initial coordinates
            known = {**fixed, **{sp.Symbol(n): x for n, x in here.items() if n not in follows}}
            for k, (symbols, fn) in follows.items():
                here[k] = float(fn(*(known[x] for x in symbols)))
                known[sp.Symbol(k)] = here[k]
        if free:
            here = steady_motion(derivation, here, free=free, ignore=ignore, params=params)
        return linearise(derivation, here, params=params, ignore=ignore, coordinates=coordinates, speeds=speeds), here

    from tqdm import tqdm

    show = progress if progress is not None else False
    eig, before, start, first = [], None, point, None
    for v in tqdm(grid, desc=f"eigenvalues against {name}", disable=not show, leave=False):
        lm, start = model_at(v, start)
        ev = np.linalg.eigvals(lm.A)
        if first is None:
            first = lm
            order = np.lexsort((ev.imag, ev.real))
            ev = ev[order]
        else:
            ev = _track(eig[-1], before, ev)
            before = eig[-1]
        eig.append(ev)
    eigenvalues = np.array(eig)
    assert first is not None  # the grid holds two values or more
    names = tuple(n for _, n in sorted(first.modes(), key=lambda m: (m[0].real, m[0].imag)))
    crossings = _crossings(model_at, point, grid, eigenvalues, xtol)
    return StabilitySweep(name, grid, eigenvalues, names, first.states, crossings)


#: real parts within this of zero count as zero (marginal modes: conserved quantities,
#: undamped oscillations of a Hamiltonian or reversible system)
MARGINAL = 1e-9


def _spectrum(A):
    """Eigenvalues of ``A`` and their eigenvectors, each of unit length."""
    ev, vec = np.linalg.eig(A)
    return ev, vec / np.maximum(np.linalg.norm(vec, axis=0), np.finfo(float).tiny)


def _crossings(model_at, point, values, eigenvalues, xtol) -> tuple[Crossing, ...]:
    """Where a tracked mode turns unstable (real part above :data:`MARGINAL`) or stable: by
    Brent's method on its real part where that changes sign, by bisection on ``real >
    MARGINAL`` where it reaches zero and stays there (a Hamiltonian or reversible pair that
    becomes oscillatory, as the sleeping top or the rolling disc: the real part vanishes
    like a square root)."""
    from scipy.optimize import brentq

    found = []
    re = eigenvalues.real
    cls = np.where(re > MARGINAL, 1, np.where(re < -MARGINAL, -1, 0))
    for j in range(eigenvalues.shape[1]):
        for k in range(values.size - 1):
            c0, c1 = cls[k, j], cls[k + 1, j]
            if c0 == c1 or 1 not in (c0, c1):
                continue
            e0, e1 = eigenvalues[k], eigenvalues[k + 1]
            v0, v1 = values[k], values[k + 1]
            ev0, vec0 = _spectrum(model_at(v0, point)[0].A)
            u = vec0[:, np.argmin(np.abs(ev0 - e0[j]))]
            spread = max(abs(e1[j] - e0[j]), MARGINAL)

            def spectrum(v, e0=e0, e1=e1, v0=v0, v1=v1, j=j, u=u, spread=spread):
                """``(the tracked mode's eigenvalue, every eigenvalue)`` at ``v``: the one
                nearest the mode's eigenvalue interpolated from the bracket, with its
                eigenvector's departure from the mode's at the bracket's start as a tie
                breaker (weight: the mode's change over the bracket), so that a mode
                crossing zero is not taken for another that stays there (a conserved
                speed's zero eigenvalue: at equal distance, nearest-eigenvalue alone may
                pick it and end the root search on its exact zero)."""
                ev, vec = _spectrum(model_at(v, point)[0].A)
                guess = e0[j] + (e1[j] - e0[j]) * (v - v0) / (v1 - v0)
                cost = np.abs(ev - guess) + spread * (1.0 - np.abs(u.conj() @ vec))
                return ev[np.argmin(cost)], ev

            def nearest(v):
                return spectrum(v)[0]

            if c0 * c1 == -1:
                v = brentq(lambda x: float(nearest(x).real), v0, v1, xtol=xtol, rtol=4 * np.finfo(float).eps)
            else:
                lo, hi = v0, v1
                while hi - lo > xtol * (1 + abs(lo)):
                    mid = 0.5 * (lo + hi)
                    if (nearest(mid).real > MARGINAL) == (c0 == 1):
                        lo = mid
                    else:
                        hi = mid
                v = 0.5 * (lo + hi)
            mode, ev = spectrum(v)  # one linear model at the crossing for its frequency and scale
            found.append(
                Crossing(j, float(v), float(mode.imag), 1 if c1 == 1 else -1, float(np.abs(ev).max(initial=0.0)))
            )
    # a complex pair crosses together: keep the member with the positive imaginary part
    pairs = [
        c
        for c in found
        if not (
            c.imag < 0
            and any(
                o is not c and o.imag > 0 and abs(o.value - c.value) <= 1e3 * xtol * (1 + abs(c.value)) for o in found
            )
        )
    ]
    return tuple(sorted(pairs, key=lambda c: c.value))
