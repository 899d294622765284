"""What a SymPy mechanics model means, checked before it becomes an appell System.

SymPy's ``KanesMethod`` and ``System.form_eoms`` use the velocities and angular velocities
as the user set them (``Point.vel``, ``ReferenceFrame.ang_vel_in``); positions and
orientations only where no velocity was set. appell differentiates positions. The two agree
when the set velocity is the time derivative of the position; where they do not (a disc's
centre located from its contact point ``C`` and set by ``v2pt_theory`` from ``C`` at rest:
``C`` is no material point fixed in the ground), the SymPy model means its velocities. This
module holds the stages that keep that meaning:

* :func:`solve_linear` — ``A x = b`` by Gauss–Jordan elimination with the simplest pivots
  (numbers first), each entry cancelled as it is formed: the kinematic differential
  equations ``q' = K u + k`` without the ``0/0`` of an unlucky pivot (the upright disc's
  ``q1' = u3/cos(q2)``, not ``(...)/sin(q2)``);
* :class:`ConsistentStates` — random states ``(t, q, u)`` on the constraint manifold:
  ``f(t, q) = 0`` by minimum-norm Newton steps, ``u`` projected onto the velocity
  constraints ``C(t, q) u + c(t, q) = 0`` (both the holonomic constraints' derivatives and the
  nonholonomic ones), the parameters at their values;
* :func:`disagreement` — the largest relative difference of two vectors of expressions at
  those states (None where they agree to 1e-9).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from appell.errors import ModelError

__all__ = ["solve_linear", "ConsistentStates", "disagreement"]


def _light(e):
    """One entry cancelled (sin and cos as polynomial generators), trig-simplified while small."""
    e = sp.cancel(sp.sympify(e))
    if e.has(sp.sin, sp.cos, sp.tan) and sp.count_ops(e) < 60:
        s = sp.trigsimp(e)
        if sp.count_ops(s) <= sp.count_ops(e):
            e = s
    return e


def solve_linear(A: sp.Matrix, b: sp.Matrix) -> list:
    """``x`` with ``A x = b`` (``A`` square): Gauss–Jordan with full pivoting, the pivot a
    nonzero number where one is left, else the entry of fewest operations; each entry
    cancelled as it is formed (:func:`_light`). Raises ``ZeroDivisionError`` when ``A`` is
    singular."""
    n = A.rows
    A, b = sp.Matrix(A).applyfunc(sp.sympify), sp.Matrix(b)
    rows, cols, order = list(range(n)), list(range(n)), []
    for _ in range(n):
        best = None
        for i in rows:
            for j in cols:
                e = A[i, j]
                if e == 0:
                    continue
                key = (0 if e.is_number else 1, sp.count_ops(e), i, j)
                if best is None or key < best:
                    best = key
        if best is None:
            raise ZeroDivisionError("singular")
        _, _, i, j = best
        rows.remove(i)
        cols.remove(j)
        order.append((i, j))
        pivot = A[i, j]
        for k in range(n):
            if k != i and A[k, j] != 0:
                f = A[k, j] / pivot
                for c in range(n):
                    if A[i, c] != 0:
                        A[k, c] = _light(A[k, c] - f * A[i, c])
                if b[i] != 0:
                    b[k] = _light(b[k] - f * b[i])
    x = [sp.S.Zero] * n
    for i, j in order:
        x[j] = _light(b[i] / A[i, j])
    return x


class ConsistentStates:
    """Random states on the constraint manifold (module docstring).

    ``coordinates``, ``speeds``: plain symbols; ``rates``: ``q'`` in them; ``holonomic``,
    ``nonholonomic``: the constraint expressions; ``values``: ``{symbol: float}`` of the
    parameters (others get random values in [0.5, 1.5]). ``consistent`` is False where no
    state satisfying the holonomic constraints was found (the states are then unconstrained).
    """

    def __init__(self, coordinates, speeds, rates, holonomic, nonholonomic, values, *, count=3, seed=1):
        from appell.symbols import t

        self.coordinates, self.speeds = tuple(coordinates), tuple(speeds)
        self.args = (t,) + self.coordinates + self.speeds
        rng = np.random.default_rng(seed)
        self.values = dict(values)
        self.rng = rng
        q, u = list(self.coordinates), list(self.speeds)
        f = sp.Matrix(list(holonomic))
        rates = sp.Matrix(list(rates))
        if f.rows:
            Jf = f.jacobian(q)
            velocity = Jf * rates + f.diff(t)
        else:
            Jf, velocity = sp.zeros(0, len(q)), sp.zeros(0, 1)
        velocity = velocity.col_join(sp.Matrix(list(nonholonomic))) if nonholonomic else velocity
        C = velocity.jacobian(u) if velocity.rows else sp.zeros(0, len(u))
        c = velocity.xreplace({s: 0 for s in u})
        self.consistent = True
        self.states = []
        fn = self._lambdify([f, Jf, C, c])
        for _ in range(count):
            self.states.append(self._state(fn, rng, f.rows))

    def _fill(self, expr):
        free = sp.Matrix(expr).free_symbols if isinstance(expr, sp.MatrixBase) else sp.sympify(expr).free_symbols
        for s in sorted(free, key=str):
            if s not in self.args and s not in self.values:
                self.values[s] = float(self.rng.uniform(0.5, 1.5))

    def _lambdify(self, exprs):
        for e in exprs:
            self._fill(e)
        params = sorted(self.values, key=str)
        fn = sp.lambdify(self.args + tuple(params), exprs, modules="numpy")
        pvals = [float(self.values[p]) for p in params]
        return lambda tq: [np.array(a, dtype=float) for a in fn(*tq, *pvals)]

    def _state(self, fn, rng, holonomic: int):
        nq, nu = len(self.coordinates), len(self.speeds)
        for _attempt in range(8):
            time = float(rng.uniform(0, 1))
            q = rng.uniform(-1, 1, nq)
            ok = True
            if holonomic:
                ok = False
                for _ in range(60):
                    f, Jf, _, _ = fn((time, *q, *np.zeros(nu)))
                    f = f.reshape(-1)
                    if not np.all(np.isfinite(f)):
                        break
                    if np.linalg.norm(f) < 1e-13 * (1 + np.linalg.norm(q)):
                        ok = True
                        break
                    q = q - np.linalg.lstsq(Jf.reshape(len(f), nq), f, rcond=None)[0]
            if not ok:
                continue
            u = rng.uniform(-1, 1, nu)
            _, _, C, c = fn((time, *q, *u))
            c = c.reshape(-1)
            if len(c):
                C = C.reshape(len(c), nu)
                u = u - np.linalg.lstsq(C, C @ u + c, rcond=None)[0]
            if np.all(np.isfinite(q)) and np.all(np.isfinite(u)):
                return time, q, u
        self.consistent = False
        return float(rng.uniform(0, 1)), rng.uniform(-1, 1, nq), rng.uniform(-1, 1, nu)

    def values_of(self, exprs) -> list:
        """The vectors ``exprs`` (a list of column matrices) at each state."""
        fn = self._lambdify(list(exprs))
        return [fn((time, *q, *u)) for time, q, u in self.states]


def disagreement(states: ConsistentStates, first: sp.Matrix, second: sp.Matrix, tol: float = 1e-9):
    """The largest ``|first - second| / (1 + |first|)`` over the states where it exceeds
    ``tol`` (None where the two agree at every state)."""
    worst = None
    for a, b in states.values_of([sp.Matrix(first), sp.Matrix(second)]):
        a, b = a.reshape(-1), b.reshape(-1)
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            continue
        err = float(np.max(np.abs(a - b), initial=0.0)) / (1.0 + float(np.max(np.abs(a), initial=0.0)))
        if err > tol and (worst is None or err > worst):
            worst = err
    return worst


def refuse_disagreement(kind: str, name: str, set_value, derived, how: str, err: float, hint: str):
    """The ModelError of a set velocity that is not the derivative of the position."""
    raise ModelError(
        f"{kind} {name}: the velocity set in SymPy, {_short(set_value)}, is not the time derivative "
        f"of its {how}, {_short(derived)} (they differ by {err:.2g} relative, at random states "
        "that satisfy the constraints)",
        hint=hint,
    )


def _short(vec, limit: int = 200) -> str:
    text = str(list(sp.Matrix(vec))).replace("'", "")
    return text if len(text) <= limit else text[:limit] + " ...]"
