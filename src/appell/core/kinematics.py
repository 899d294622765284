"""Stage 1 — kinematics: the total time derivative along the motion (method.md §1).

For an expression ``e(t, q, w, a, ...)`` the derivative along the motion is

.. math::
    \\dot e = \\partial_t e + \\frac{\\partial e}{\\partial q}(K w + k)
            + \\sum_j \\frac{\\partial e}{\\partial w^{(m)}_j} w^{(m+1)}_j
            + \\sum_g \\frac{\\partial e}{\\partial g^{(m)}} g^{(m+1)},

where ``g`` runs over programs (given functions of time) and kinematic controls, whose
derivatives are new symbols ``g_dot, g_ddot, ...``.

Every variable is real. SymPy's symbols are not known to be, so a derivative of ``|u|``,
``sign(u)``, ``min``/``max`` would come out through ``re(u)``, ``im(u)`` and unevaluated
``Derivative`` objects: :func:`derivative` differentiates such expressions in real
variables (``|u|' = sign(u) u'``, ``max(u, v)' = H(u - v) u' + H(v - u) v'``), and takes the
derivative of a jump (``DiracDelta``) as zero: these functions are piecewise smooth, and
the equations hold on either side of a kink, where they are evaluated.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import sympy as sp

from appell.core.simplification import refuse_derivative, refuse_result, tree_size
from appell.errors import ModelError
from appell.model import System
from appell.symbols import GraphDerivative, contains, derivative_symbol, split_derivative_name, t


@dataclass(frozen=True)
class Kinematics:
    """Time derivative operator of a system.

    Attributes
    ----------
    coordinates, speeds, accelerations : tuples of symbols q, w, a.
    coordinate_rates : ``dq/dt`` as expressions in (t, q, w) (the kinematic relations).
    K, k : the affine split ``dq/dt = K w + k``.
    chains : base symbols (programs, kinematic controls) whose derivatives are symbols.
    """

    coordinates: tuple[sp.Symbol, ...]
    speeds: tuple[sp.Symbol, ...]
    accelerations: tuple[sp.Symbol, ...]
    coordinate_rates: sp.ImmutableMatrix
    K: sp.ImmutableMatrix
    k: sp.ImmutableMatrix
    chains: tuple[sp.Symbol, ...]

    def successor(self, symbol: sp.Symbol) -> sp.Symbol | None:
        """The time derivative of a symbol on a derivative chain (speeds, programs,
        kinematic controls and their derivatives), or None for anything else."""
        base, order = split_derivative_name(symbol.name)
        lowest = self._chain_roots.get(base)
        return derivative_symbol(symbol) if lowest is not None and order >= lowest else None

    @functools.cached_property
    def _chain_roots(self) -> dict[str, int]:
        """Per base name of a chain's root (the speeds, programs, kinematic controls): the
        lowest derivative order among them (:meth:`successor`)."""
        roots: dict[str, int] = {}
        for root in self.speeds + self.chains:
            rbase, rorder = split_derivative_name(root.name)
            roots[rbase] = min(rorder, roots.get(rbase, rorder))
        return roots

    def diff(self, expr):
        """Total time derivative of ``expr`` (scalar or matrix) along the motion."""
        if isinstance(expr, sp.MatrixBase):
            return sp.ImmutableMatrix(expr.shape[0], expr.shape[1], [self.diff(e) for e in expr])
        expr = sp.sympify(expr)
        free = expr.free_symbols
        rates = [(t, sp.S.One)] if t in free else []
        rates += [(q, rate) for q, rate in zip(self.coordinates, self.coordinate_rates) if q in free]
        for s in sorted(free - set(self.coordinates) - {t}, key=str):
            nxt = self.successor(s)
            if nxt is not None:
                rates.append((s, nxt))
        # a required step: refused before it runs when the derivative would swell (bound policy)
        refuse_derivative(expr, [s for s, _ in rates], [tree_size(r) for _, r in rates])
        terms, smooth = terms_by_symbol(expr), not contains([expr], NONSMOOTH)
        # one sum of every term (adding term by term flattens and sorts the growing sum again)
        out = sp.Add(*[partial(terms, s, smooth) * rate for s, rate in rates])
        refuse_result(out)  # where the estimate fell short (|u| of a complex-valued u)
        return out


#: the derivatives of smooth expressions, over their graphs (:class:`appell.symbols.GraphDerivative`:
#: SymPy's rules, each shared subexpression differentiated once)
GRAPH_DERIVATIVE = GraphDerivative()

#: functions whose derivative needs the variables to be real (:func:`derivative`)
NONSMOOTH = (sp.Abs, sp.sign, sp.Min, sp.Max, sp.Heaviside, sp.arg, sp.re, sp.im, sp.conjugate)


def derivative(expr, symbol):
    """``d expr / d symbol`` with every variable real (module docstring): SymPy's ``diff``,
    through real stand-ins where ``expr`` holds a function of :data:`NONSMOOTH`, and
    ``DiracDelta`` taken as zero."""
    expr = sp.sympify(expr)
    if not contains([expr], NONSMOOTH):
        return GRAPH_DERIVATIVE(expr, symbol)
    real = {
        s: sp.Dummy(s.name, real=True)
        for s in expr.free_symbols | {symbol}
        if isinstance(s, sp.Symbol) and not s.is_real
    }
    out = expr.xreplace(real).diff(real.get(symbol, symbol)).xreplace({v: k for k, v in real.items()})
    return out.replace(lambda e: isinstance(e, sp.DiracDelta), lambda e: sp.S.Zero) if out.has(sp.DiracDelta) else out


def jacobian(vector, symbols) -> sp.Matrix:
    """``d vector / d symbols`` (``Matrix.jacobian`` by :func:`derivative`)."""
    vector, symbols = sp.Matrix(vector), list(symbols)
    return sp.Matrix(len(vector), len(symbols), lambda i, j: derivative(vector[i], symbols[j]))


def terms_by_symbol(expr) -> dict:
    """The terms of the sum ``expr`` that contain each of its symbols (for :func:`partial`)."""
    out: dict = {}
    for term in sp.Add.make_args(expr):
        for sym in term.free_symbols:
            out.setdefault(sym, []).append(term)
    return out


def partial(terms: dict, symbol, smooth: bool = False):
    """``d expr / d symbol`` from :func:`terms_by_symbol`: only the terms containing the
    symbol are differentiated (the same sum as ``sympy.diff(expr, symbol)``, whose other terms
    give zeros; on a long sum of terms in few symbols each, n times less work). ``smooth``:
    the caller knows that ``expr`` holds no function of :data:`NONSMOOTH` (plain ``diff``)."""
    if smooth:
        return sp.Add(*[GRAPH_DERIVATIVE(term, symbol) for term in terms.get(symbol, ())])
    return sp.Add(*[derivative(term, symbol) for term in terms.get(symbol, ())])


def kinematics_of(system: System) -> Kinematics:
    """Build the :class:`Kinematics` of a system; checks that ``dq/dt`` is affine in w."""
    q = system.coordinates
    w = system.speeds
    rates = dict(system.kinematics)
    missing = [c for c in q if c not in rates]
    if missing:
        raise ModelError(
            f"no kinematic relation for coordinate(s) {', '.join(map(str, missing))}",
            hint="give dq/dt in terms of t, q and the speeds for every coordinate",
        )
    extra = [c for c in rates if c not in q]
    if extra:
        raise ModelError(f"kinematic relation given for unknown coordinate(s) {', '.join(map(str, extra))}")
    rate_vec = sp.Matrix([rates[c] for c in q]) if q else sp.zeros(0, 1)
    wv = sp.Matrix(w)
    K = jacobian(rate_vec, wv) if q else sp.zeros(0, len(w))
    if any(e.has(*w) for e in K):
        bad = [str(c) for c, row in zip(q, K.tolist()) if any(e.has(*w) for e in row)]
        raise ModelError(
            f"kinematic relation of {', '.join(bad)} is not affine in the speeds",
            hint="write dq/dt = K(t,q) w + k(t,q)",
        )
    kk = rate_vec.subs({s: 0 for s in w}) if q else sp.zeros(0, 1)
    chains = tuple(p.symbol for p in system.programs) + tuple(
        c.symbol for c in system.controls if c.kind == "kinematic"
    )
    return Kinematics(
        coordinates=q,
        speeds=w,
        accelerations=system.accelerations,
        coordinate_rates=sp.ImmutableMatrix(rate_vec),
        K=sp.ImmutableMatrix(K),
        k=sp.ImmutableMatrix(kk),
        chains=chains,
    )
