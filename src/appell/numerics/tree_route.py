"""A robot's first numbers without deriving its system and without a compiler: the numeric
recursive route of a joint tree, in two forms with one interface.

* :class:`NumericTreeRoute`, :func:`tree_route`'s choice for a URDF or MJCF file: the file
  read in floating point into its joint tree (:func:`appell.mechanism.urdf_tree.urdf_tree`: the
  bodies, joints, coordinates and names of :func:`~appell.mechanism.urdf.urdf_mechanism`;
  :func:`appell.mechanism.mjcf_tree.mjcf_tree`: MuJoCo's compiled model with the names of
  :func:`~appell.mechanism.mjcf.read_mjcf` and MuJoCo's armature, springs, dampers and
  actuators), without SymPy; the accelerations by the articulated-body algorithm (:func:`aba`).
  A fraction of a second from a fresh interpreter for a 38-speed humanoid
  (``benchmarks/instant.py``). It is also a model the simulator integrates
  (:class:`~appell.numerics.dynamics.Dynamics`).
* :class:`TreeRoute`, for a :class:`~appell.mechanism.Mechanism`, or a URDF holding what the
  floating-point reader does not take (a mimic of a multi-coordinate joint, ...); never for an
  MJCF file (the mechanism's tree has none of MuJoCo's forces):
  the mechanism's joint tree (:meth:`Mechanism.rigid_tree
  <appell.mechanism.Mechanism.rigid_tree>`: each joint's rotation, translation, motion
  subspace ``S``, bias ``c`` and body inertia, small expressions in the joint's own
  coordinates and speeds) compiled once (:func:`appell.symbols.lambdify`, the ``math``
  module); ``M`` by the composite-rigid-body algorithm, ``h`` (with gravity: the base
  accelerating at ``-g``) by the recursive Newton-Euler algorithm, then a dense solve.

Both give, at a state, the accelerations of ``M a = tau - h`` (``tau`` the joint forces given,
zero by default; with holonomic constraints, a URDF's mimic joints, the multipliers of the
augmented system ``M a + h = tau + J^T lambda``, ``J a + c = 0``) and every joint's reaction,
the force and moment of the parent on the child at the joint's origin in world axes (the
outputs ``F_<joint>_x .. M_<joint>_z`` that :meth:`Mechanism.system
<appell.mechanism.Mechanism.system>` states symbolically), by the inward pass of the
Newton-Euler recursion at those accelerations (:func:`appell.numerics.rigid_tree.wrenches`).

Neither the symbolic frames and reaction balances of the mechanism's system nor the
derivation are formed, which is what costs seconds to minutes on a robot; the numbers agree
with the NumPy and C backends' on the derived tree to rounding. Closed chains (a mechanism's
closures) and joints moved by time are refused: they need the derivation (:func:`appell.derive`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from appell.errors import ModelError
from appell.numerics.rigid_tree import (
    TreeArrays,
    _spatial_inertia,
    _transform,
    crba,
    point_matrices,
    rnea,
    tree_layout,
    tree_matrices,
    wrenches,
)

__all__ = ["NumericTreeRoute", "TreeRoute", "aba", "aba_at_rest", "tree_route"]


class TreeRoute:
    """The numeric recursive route of an open joint tree (the module's docstring).

    ``coordinate_names``, ``speed_names``: the joints' coordinates and speeds, in the order
    of the system :meth:`Mechanism.system <appell.mechanism.Mechanism.system>` states;
    ``output_names``: every joint's reaction components."""

    def __init__(self, mechanism, name: str = "", constraints=()):
        import sympy as sp

        from appell.symbols import derivative_symbol, lambdify, t

        self.name = name or getattr(mechanism, "name", "")
        if getattr(mechanism, "_closures", ()):
            raise ModelError(
                f"{self.name}: the numeric tree route takes open trees; this mechanism has closed loops",
                hint="derive it (appell.derive) for the constrained route",
            )
        coords = [q for j in mechanism.joints for q in j.coordinates]
        tree = mechanism.rigid_tree(coords)
        if tree is None:
            raise ModelError(
                f"{self.name}: a joint moves with time or with another joint's coordinates; the "
                "numeric tree route takes joints moved by their own coordinates only",
                hint="derive it (appell.derive)",
            )
        self.coordinates = tuple(coords)
        self.speeds = tuple(derivative_symbol(q) for q in coords)
        self.n = len(coords)
        params = list(mechanism.parameters)
        self.parameter_names = tuple(p.symbol.name for p in params)
        self.default_parameters = np.array([float(p.value) for p in params], float)
        args = [t, sp.Matrix(self.coordinates), sp.Matrix(self.speeds), sp.Matrix([p.symbol for p in params])]
        self.constraint_names = tuple(c.name for c in constraints)
        matrices = (
            tree_matrices(tree, self.n, gravity=True) + point_matrices(tree) + self._constraint_terms(constraints)
        )
        sizes = [len(m) for m in matrices]
        # without shared subexpressions: the per-joint terms are small, and finding them took
        # longer (0.65 s against 0.27 s the Panda's) than it saves on the first numbers
        function = lambdify(args, [e for m in matrices for e in m], modules="math", cse=False)
        self._function, self._cuts = function, np.cumsum(sizes)[:-1]
        self.parent, self.node_of = tree_layout(tree, self.n)
        self.joint_names = tuple(node.joint for node in tree.nodes)
        self.output_names = tuple(f"{s}_{j}_{axis}" for j in self.joint_names for s in "FM" for axis in "xyz")

    def _constraint_terms(self, constraints) -> list:
        """``J`` (row-major) and ``c`` of the holonomic constraints ``F(q) = 0`` in
        second-order form ``J a + c = 0``: ``J = dF/dq``, ``c = d(J w)/dq w``."""
        import sympy as sp

        if not constraints:
            return [sp.zeros(0, 1), sp.zeros(0, 1)]
        allowed = set(self.coordinates) | {p for p in sp.symbols(self.parameter_names)}
        F = sp.Matrix([c.expr for c in constraints])
        if any(getattr(c, "order", 0) != 0 for c in constraints) or not F.free_symbols <= allowed:
            raise ModelError(
                f"{self.name}: the numeric tree route takes holonomic constraints in the joints' coordinates only",
                hint="derive it (appell.derive)",
            )
        J = F.jacobian(list(self.coordinates))
        c = (J * sp.Matrix(self.speeds)).jacobian(list(self.coordinates)) * sp.Matrix(self.speeds)
        return [sp.Matrix(list(J)), c]

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        return tuple(q.name for q in self.coordinates)

    @property
    def speed_names(self) -> tuple[str, ...]:
        return tuple(w.name for w in self.speeds)

    def _terms(self, time, q, w, p):
        p = self.default_parameters if p is None else np.asarray(p, float)
        q, w = np.asarray(q, float).reshape(-1), np.asarray(w, float).reshape(-1)
        if q.shape != (self.n,) or w.shape != (self.n,):
            raise ModelError(
                f"{self.name}: q and w need {self.n} values each (got {q.size}, {w.size})",
                hint="in the order of coordinate_names and speed_names",
            )
        flat = np.array(self._function(float(time), q.tolist(), w.tolist(), p.tolist()), float)
        rot, trans, S, bias, inert, base, gravity, points, J, c = np.split(flat, self._cuts)
        self._constraint = (J.reshape(-1, self.n), c)
        return TreeArrays(rot, trans, S, bias, inert), base, gravity, points, q, w

    def blocks(self, time, q, w, p=None) -> tuple[np.ndarray, np.ndarray]:
        """``(M, h)``: the mass matrix (CRBA) and the forces ``h`` of ``M a + h = tau`` (RNEA at
        ``a = 0``, gravity included)."""
        arrays, base, _, _, q, w = self._terms(time, q, w, p)
        return crba(arrays, self.parent, self.node_of), rnea(
            arrays, self.parent, self.node_of, w, np.zeros(self.n), base
        )

    def accelerations(self, time, q, w, tau=None, p=None) -> np.ndarray:
        """``a`` of ``M a = tau - h`` (``tau``: the joint forces, zero by default)."""
        return self.forward(time, q, w, tau, p)[0]

    def forward(self, time, q, w, tau=None, p=None) -> tuple[np.ndarray, dict[str, float]]:
        """The accelerations and every joint's reaction ``{output name: value}`` at one state;
        with constraints (a URDF's mimic joints) also their multipliers ``lambda_<name>`` of
        ``M a + h = tau + J^T lambda``, ``J a + c = 0`` (method.md §2's augmented system)."""
        arrays, base, gravity, points, q, w = self._terms(time, q, w, p)
        M = crba(arrays, self.parent, self.node_of)
        h = rnea(arrays, self.parent, self.node_of, w, np.zeros(self.n), base)
        rhs = -h if tau is None else np.asarray(tau, float).reshape(self.n) - h
        J, c = self._constraint
        a, lam = _augmented_solve(
            M,
            J,
            rhs,
            c,
            f"{self.name}: the mass matrix (or the constraints) are singular at this state",
            "a body without mass or inertia on a joint, or dependent constraints",
        )
        W, _ = wrenches(arrays, self.parent, self.node_of, w[None], a[None], gravity[None], points[None])
        out = dict(zip(self.output_names, W[0].reshape(-1).tolist()))
        out.update((f"lambda_{name}", float(v)) for name, v in zip(self.constraint_names, lam))
        return a, out


def _augmented_solve(M, J, rhs, c, message: str, hint: str) -> tuple[np.ndarray, np.ndarray]:
    """``(a, lambda)`` of ``M a - J^T lambda = rhs``, ``J a = -c`` (method.md §2's augmented
    system; ``M a = rhs`` without rows); a singular system is a :class:`ModelError`."""
    s, n = len(c), len(rhs)
    K = np.block([[M, -J.T], [J, np.zeros((s, s))]]) if s else M
    try:
        x = np.linalg.solve(K, np.concatenate([rhs, -c]))
    except np.linalg.LinAlgError:
        raise ModelError(message, hint=hint) from None
    return x[:n], x[n:]


def _quaternion_rotation(q) -> np.ndarray:
    """``R(q)`` of a quaternion (scalar first), quadratic in q (:func:`appell.mechanism.rotations.quaternion_rotation`)."""
    q0, q1, q2, q3 = q
    return np.array(
        [
            [q0**2 + q1**2 - q2**2 - q3**2, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), q0**2 - q1**2 + q2**2 - q3**2, 2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0**2 - q1**2 - q2**2 + q3**2],
        ]
    )


def _quaternion_g(q) -> np.ndarray:
    """``G(q)``: the body angular velocity is ``2 G(q) q'`` (:func:`appell.mechanism.rotations.quaternion_rates`)."""
    q0, q1, q2, q3 = q
    return np.array([[-q1, q0, q3, -q2], [-q2, -q3, q0, q1], [-q3, q2, -q1, q0]])


def _cross_matrix(x) -> np.ndarray:
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def _crm(v) -> np.ndarray:
    """``v x`` on motion vectors ``[omega; v]``: ``[[wx, 0], [vx, wx]]``."""
    out = np.zeros((6, 6))
    out[:3, :3] = out[3:, 3:] = _cross_matrix(v[:3])
    out[3:, :3] = _cross_matrix(v[3:])
    return out


def aba(X, inertia, parent, speed, S, w, tau, base, keep: dict | None = None, armature=None) -> np.ndarray:
    """The accelerations ``a`` of ``M a + h = tau`` by the articulated-body algorithm
    (Featherstone 2008, table 7.1), body axes, spatial vectors ``[omega; v]``: ``X`` (nb, 6, 6)
    each node's transform from its parent, ``inertia`` (nb, 6, 6) the bodies' spatial inertias
    about their origins, ``parent`` (-1: the ground), ``speed`` each node's speed (-1: a fixed
    joint), ``S`` (n, 6) each speed's motion axis, ``base`` the ground's spatial acceleration
    (``-g``: gravity). Outward ``v_i = X_i v_p + S_i w_i``, ``c_i = v_i x S_i w_i``,
    ``p_i = v_i x* I_i v_i``; inward ``U = I^A S``, ``D = S^T U``, ``u = tau - S^T p^A``,
    ``I^A_p += X^T (I^A - U U^T / D) X``, ``p^A_p += X^T (p^A + I^a c + U u / D)``; outward
    ``a_i = X_i a_p + c_i``, ``qdd = (u - U^T a_i) / D``, ``a_i += S qdd``. ``keep`` (a dict)
    receives ``U`` and ``D``, which depend on the configuration only (:func:`aba_at_rest`).
    ``armature`` (per speed, MuJoCo's ``M_kk += a_k``: a rotor's inertia reflected on the joint)
    adds to ``D`` (Featherstone 2008, §7.3's ``D = S^T U + I_m``)."""
    nb = len(parent)
    v, c, pA = np.zeros((nb, 6)), np.zeros((nb, 6)), np.zeros((nb, 6))
    IA = np.array(inertia, float)
    for i in range(nb):
        if parent[i] >= 0:
            v[i] = X[i] @ v[parent[i]]
        k = speed[i]
        if k >= 0:
            vJ = S[k] * w[k]
            v[i] += vJ
            c[i] = _crm(v[i]) @ vJ
        pA[i] = -_crm(v[i]).T @ (inertia[i] @ v[i])
    U, D, u = np.zeros((nb, 6)), np.ones(nb), np.zeros(nb)
    for i in reversed(range(nb)):
        k = speed[i]
        Ia = IA[i]
        if k >= 0:
            U[i] = IA[i] @ S[k]
            D[i] = S[k] @ U[i] + (armature[k] if armature is not None else 0.0)
            if not D[i] > 0.0:
                raise ModelError(
                    "a joint carries no inertia (a zero pivot of the articulated-body algorithm)",
                    hint="give the bodies it moves a mass and inertia",
                )
            u[i] = tau[k] - S[k] @ pA[i]
            Ia = IA[i] - np.outer(U[i], U[i]) / D[i]
        pa = pA[i] + Ia @ c[i] + U[i] * (u[i] / D[i])
        if parent[i] >= 0:
            IA[parent[i]] += X[i].T @ Ia @ X[i]
            pA[parent[i]] += X[i].T @ pa
    if keep is not None:
        keep.update(U=U, D=D)
    return _outward(X, parent, speed, S, U, D, u, c, base)


def _outward(X, parent, speed, S, U, D, u, c, base) -> np.ndarray:
    """The articulated-body algorithm's last pass (:func:`aba`): ``a_i = X_i a_p + c_i``,
    ``qdd = (u - U^T a_i) / D``, ``a_i += S qdd``."""
    nb = len(parent)
    acc, qdd = np.zeros((nb, 6)), np.zeros(len(S))
    for i in range(nb):
        acc[i] = X[i] @ (acc[parent[i]] if parent[i] >= 0 else base) + c[i]
        k = speed[i]
        if k >= 0:
            qdd[k] = (u[i] - U[i] @ acc[i]) / D[i]
            acc[i] += S[k] * qdd[k]
    return qdd


def mass_and_bias(X, inertia, parent, speeds_of, S, w, base) -> tuple[np.ndarray, np.ndarray]:
    """``M`` by the composite-rigid-body algorithm and ``h`` of ``M a + h = tau`` by the
    recursive Newton-Euler algorithm at ``a = 0`` (Featherstone 2008, tables 6.2 and 5.1), on the
    transforms ``X`` of :func:`aba`, a node moved by several speeds (``speeds_of[i]``, rows of
    ``S``: a quaternion's four) as well as by one or none, its joint's ``dS/dt w = 0`` (the
    axes of a hinge or slider are the body's; a quaternion's ``2 G(q') q' = 0``): outward
    ``v_i = X_i v_p + S_i^T w_i``, ``a_i = X_i a_p + v_i x S_i^T w_i`` (``a_p`` of the ground:
    ``base``), ``f_i = I_i a_i + v_i x* I_i v_i``; inward ``h_i = S_i f_i``, ``f_p += X_i^T f_i``;
    ``I^c_p += X_i^T I^c_i X_i``, ``M_ij = S_i X_(i..j)^T I^c_i S_j^T``."""
    nb, n = len(parent), len(S)
    v, acc, f = np.zeros((nb, 6)), np.zeros((nb, 6)), np.zeros((nb, 6))
    for i in range(nb):
        p, k = parent[i], speeds_of[i]
        vJ = S[k].T @ w[k]
        v[i] = X[i] @ v[p] + vJ if p >= 0 else vJ
        acc[i] = X[i] @ (acc[p] if p >= 0 else base) + _crm(v[i]) @ vJ
        f[i] = inertia[i] @ acc[i] - _crm(v[i]).T @ (inertia[i] @ v[i])
    h, M, Ic = np.zeros(n), np.zeros((n, n)), np.array(inertia, float)
    for i in reversed(range(nb)):
        h[speeds_of[i]] = S[speeds_of[i]] @ f[i]
        if parent[i] >= 0:
            f[parent[i]] += X[i].T @ f[i]
            Ic[parent[i]] += X[i].T @ Ic[i] @ X[i]
    # a node's speeds are consecutive: slices, not index arrays, into M
    cut = [slice(k[0], k[-1] + 1) if len(k) else None for k in speeds_of]
    for i in range(nb):
        if cut[i] is None:
            continue
        F = Ic[i] @ S[cut[i]].T
        M[cut[i], cut[i]] = S[cut[i]] @ F
        j = i
        while parent[j] >= 0:
            F, j = X[j].T @ F, parent[j]
            if cut[j] is not None:
                M[cut[i], cut[j]] = F.T @ S[cut[j]].T
                M[cut[j], cut[i]] = M[cut[i], cut[j]].T
    return M, h


def aba_at_rest(X, parent, speed, S, U, D, tau) -> np.ndarray:
    """:func:`aba` at zero speeds without gravity, ``M^-1 tau``, on the articulated inertias of
    a call of :func:`aba` at the same configuration (its ``keep``: ``U``, ``D``): the inward pass
    of the bias forces alone (``p^A_p += X^T (p^A + U u / D)``, ``u = tau - S^T p^A``) and the
    outward pass."""
    nb = len(parent)
    pA, u = np.zeros((nb, 6)), np.zeros(nb)
    for i in reversed(range(nb)):
        k = speed[i]
        pa = pA[i]
        if k >= 0:
            u[i] = tau[k] - S[k] @ pA[i]
            pa = pa + U[i] * (u[i] / D[i])
        if parent[i] >= 0:
            pA[parent[i]] += X[i].T @ pa
    return _outward(X, parent, speed, S, U, D, u, np.zeros((nb, 6)), np.zeros(6))


class _JointForces:
    """A MuJoCo model's forces on the speeds of its tree (:class:`~appell.mechanism.mjcf_tree.MjcfTree`),
    in appell's speeds (a quaternion's rates ``q'``, the body-axes angular velocity ``omega = 2 G(q) q'``,
    so that a force ``f`` on ``omega`` is ``2 G^T f`` on ``q'``):

    * ``M += diag(armature)`` on the hinges, slides and a free joint's sliders, ``4 G^T diag(a) G``
      on a quaternion (the kinetic energy ``omega^T diag(a) omega / 2``, MuJoCo's ``M_ii += a``;
      isotropic on a joint, so without gyroscopic terms);
    * ``f = -d w - k (q - q_spring) + sum gear (gain u + b0 + b1 gear (q + qpos0) + b2 gear w)``
      on a hinge or slide (damping, spring about ``qpos_spring``, the actuators at ``ctrl`` ``u``),
      ``-d w`` on a free joint's sliders (its world velocity is ``R0 w``), ``-4 G^T diag(d) G q'``
      on a quaternion."""

    def __init__(self, tree, ctrl=None):
        n = len(tree.coordinates)
        self.armature = np.asarray(tree.armature, float)
        self.rotational = tree.rotational
        self.actuator_names = tuple(a.name for a in tree.actuators)
        given = dict(ctrl or {})
        known = {name for a in tree.actuators for name in (a.name, a.mjcf)}
        unknown = sorted(str(k) for k in given if str(k) not in known)
        if unknown:
            raise ModelError(
                f"{tree.name}: ctrl for unknown actuator(s) {', '.join(unknown)}",
                hint="actuators: " + (", ".join(a.mjcf for a in tree.actuators) or "none"),
            )
        u = np.array([float(given.get(a.mjcf, given.get(a.name, 0.0))) for a in tree.actuators])
        # f = f0 + Kq q + Kw w (diagonal): the springs, dampers and actuators, linear on hinges and slides
        self.f0 = np.asarray(tree.stiffness, float) * np.asarray(tree.spring, float)
        self.kq, self.kw = -np.asarray(tree.stiffness, float), -np.asarray(tree.damping, float)
        for a, value in zip(tree.actuators, u):
            b0, b1, b2 = a.bias
            self.f0[a.k] += a.gear * (a.gain * value + b0 + b1 * a.gear * a.qpos0)
            self.kq[a.k] += a.gear * b1 * a.gear
            self.kw[a.k] += a.gear * b2 * a.gear
        self.f0.setflags(write=False)
        assert self.f0.shape == (n,)

    def mass(self, M, q) -> np.ndarray:
        """``M`` with the armature."""
        M = M + np.diag(self.armature)
        for k, a, _ in self.rotational:
            if np.any(a):
                G = _quaternion_g(q[k : k + 4])
                M[k : k + 4, k : k + 4] += 4.0 * G.T @ (a[:, None] * G)
        return M

    def unit_terms(self, starts, q, w) -> np.ndarray:
        """What a quaternion's armature adds to its unit row's multiplier in the derived route,
        which takes the rotor energy ``T = omega^T A omega / 2`` through Lagrange's equations in
        ``q``: their row of ``q`` gains ``q^T (d/dt dT/dq' - dT/dq) = -2 omega^T A omega`` (the
        armature's ``M`` has no row of ``q``), so its multiplier ``2 omega^T A omega / (q.q)`` less
        than the rigid recursions' (``starts``: each quaternion's first coordinate)."""
        armature = {k: a for k, a, _ in self.rotational}
        out = np.zeros(len(starts))
        for row, k in enumerate(starts):
            if k in armature:
                omega = 2.0 * _quaternion_g(q[k : k + 4]) @ w[k : k + 4]
                out[row] = 2.0 * omega @ (armature[k] * omega) / (q[k : k + 4] @ q[k : k + 4])
        return out

    def forces(self, q, w) -> np.ndarray:
        """The passive and actuator forces ``f(q, w)`` on the speeds."""
        f = self.f0 + self.kq * q + self.kw * w
        for k, _, d in self.rotational:
            if np.any(d):
                G = _quaternion_g(q[k : k + 4])
                f[k : k + 4] -= 4.0 * G.T @ (d * (G @ w[k : k + 4]))
        return f


class NumericTreeRoute:
    """The numeric route of a URDF's joint tree read in floating point
    (:func:`appell.mechanism.urdf_tree.urdf_tree`), without SymPy: the accelerations by the
    articulated-body algorithm (:func:`aba`; with mimic rows ``J a = 0``, ``lambda`` from
    ``(J M^-1 J^T) lambda = -J a_0``, the columns of ``M^-1 J^T`` by :func:`aba_at_rest` on the
    same articulated inertias), every joint's reaction by the inward pass (:func:`appell.numerics.rigid_tree.wrenches`).
    The same attributes and calls as :class:`TreeRoute`; the one parameter is ``g``. It is also
    a model the simulator integrates (:class:`~appell.numerics.dynamics.Dynamics`):
    ``appell.simulate(tree_route("panda.urdf"), options=...)`` runs without deriving (the
    joint forces are not recorded along the motion: :meth:`forward` gives them at a state).

    A MuJoCo model's tree (:func:`appell.mechanism.mjcf_tree.mjcf_tree`) brings its gravity
    vector (no parameter) and its forces on the speeds (:class:`_JointForces`: armature,
    damping, springs, actuators at ``ctrl``, ``{actuator: value}``, MJCF or appell names, 0
    where not given)."""

    def __init__(self, tree, name: str = "", ctrl=None):
        self.name = name or tree.name
        nodes = tree.nodes
        self.coordinate_names = tree.coordinates
        self.speed_names = tuple(f"{q}_dot" for q in self.coordinate_names)
        self.n = n = len(self.coordinate_names)
        self.parameter_names, self.default_parameters = ("g",), np.array([9.81])
        self._gravity = getattr(tree, "gravity", None)
        self._forces = _JointForces(tree, ctrl) if getattr(tree, "armature", None) is not None else None
        #: a MuJoCo model's armature as the symbolic reader's rotors (``armature='rotors'``):
        #: ``(rotor coordinate, its constraint, coordinate index, armature)`` (:mod:`appell.io.cli_tree`)
        self.rotors = tuple(getattr(tree, "rotors", ()))
        if self._gravity is not None:  # a MuJoCo model's: a vector, no parameter
            self.parameter_names, self.default_parameters = (), np.zeros(0)
        self.parent = np.array([node.parent for node in nodes], dtype=np.int64)
        self.speed = np.full(len(nodes), -1, dtype=np.int64)  # each node's (first) speed
        self.S = np.zeros((n, 6))
        self.node_of = np.zeros(n, dtype=np.int64)
        self._quaternions = []  # (node, its first speed): S = [2 G(q); 0] at each state
        for b, node in enumerate(nodes):
            if node.coordinate is not None:
                k = self.speed[b] = self.coordinate_names.index(node.coordinates[0])
                self.node_of[k : k + len(node.coordinates)] = b
                if node.kind == "quaternion":
                    self._quaternions.append((b, int(k)))
                else:  # [axis; 0] or [0; axis]: the joint's axes are the body's
                    start = 0 if node.kind == "revolute" else 3
                    self.S[k, start : start + 3] = node.axis
        self._speeds_of = [np.flatnonzero(self.node_of == b) for b in range(len(nodes))]
        self._nodes = nodes
        #: the state the derived route starts from by default: at rest, zero but each quaternion's q0 = 1
        self.initial_state = np.zeros(2 * n)
        self.initial_state[[k for _, k in self._quaternions]] = 1.0
        self._inert = np.array(
            [
                [
                    node.mass,
                    *node.com,
                    node.inertia[0, 0],
                    node.inertia[1, 1],
                    node.inertia[2, 2],
                    node.inertia[0, 1],
                    node.inertia[0, 2],
                    node.inertia[1, 2],
                ]
                for node in nodes
            ]
        )
        self._spatial = np.array([_spatial_inertia(node.mass, node.com, node.inertia) for node in nodes])
        self.joint_names = tuple(node.reaction for node in nodes if node.reaction is not None)
        self._reporting = [b for b, node in enumerate(nodes) if node.reaction is not None]
        self.output_names = tuple(f"{s}_{j}_{axis}" for j in self.joint_names for s in "FM" for axis in "xyz")
        self.constraint_names = tuple(f"{j}_unit" for j in tree.quaternions) + tuple(name for name, *_ in tree.mimics)
        self._J = np.zeros((len(tree.mimics), n))
        self._offsets = np.array([offset for *_, offset in tree.mimics], float)
        for row, (_, a, b, multiplier, _) in enumerate(tree.mimics):
            self._J[row, a] += 1.0
            self._J[row, b] -= multiplier

    def _arrays(self, q, w, p):
        p = self.default_parameters if p is None else np.asarray(p, float).reshape(-1)
        q, w = np.asarray(q, float).reshape(-1), np.asarray(w, float).reshape(-1)
        if q.shape != (self.n,) or w.shape != (self.n,):
            raise ModelError(
                f"{self.name}: q and w need {self.n} values each (got {q.size}, {w.size})",
                hint="in the order of coordinate_names and speed_names",
            )
        nb = len(self._nodes)
        R, r = np.empty((nb, 3, 3)), np.empty((nb, 3))
        S = self.S.copy() if self._quaternions else self.S
        for b, node in enumerate(self._nodes):
            k = self.speed[b]
            R[b], r[b] = node.rotation, node.origin
            if node.kind == "revolute":  # Rodrigues: R0 (E + sin K + (1 - cos) K^2)
                K = _cross_matrix(node.axis)
                R[b] = node.rotation @ (np.eye(3) + np.sin(q[k]) * K + (1.0 - np.cos(q[k])) * K @ K)
            elif node.kind == "prismatic":
                r[b] = node.origin + node.rotation @ node.axis * q[k]
            elif node.kind == "quaternion":  # R(q) quadratic in q, omega = 2 G(q) q' (appell.mechanism.rotations)
                R[b] = node.rotation @ _quaternion_rotation(q[k : k + 4])
                S[k : k + 4, :3] = 2.0 * _quaternion_g(q[k : k + 4]).T
        arrays = TreeArrays(R.ravel(), r.ravel(), S.ravel(), np.zeros(6 * nb), self._inert.ravel())
        gravity = self._gravity if self._gravity is not None else np.array([0.0, 0.0, -p[0]])
        return arrays, q, w, gravity

    def _aba(self, arrays, w, tau, base, keep=None):
        X = [_transform(arrays.R[0, b], arrays.r[0, b]) for b in range(len(self._nodes))]
        armature = self._forces.armature if self._forces is not None else None
        return X, aba(X, self._spatial, self.parent, self.speed, self.S, w, tau, base, keep, armature)

    def _mass_and_bias(self, arrays, q, w, gravity) -> tuple[np.ndarray, np.ndarray]:
        """``M`` (CRBA, with a MuJoCo model's armature) and ``h`` of ``M a + h = tau`` (RNEA at
        ``a = 0``, gravity in it, less a MuJoCo model's passive and actuator forces)."""
        base = np.concatenate([np.zeros(3), -gravity])
        X = [_transform(arrays.R[0, b], arrays.r[0, b]) for b in range(len(self._nodes))]
        M, h = mass_and_bias(X, self._spatial, self.parent, self._speeds_of, arrays.S[0], w, base)
        if self._forces is not None:
            M, h = self._forces.mass(M, q), h - self._forces.forces(q, w)
        return M, h

    def blocks(self, time, q, w, p=None) -> tuple[np.ndarray, np.ndarray]:
        """``(M, h)`` (CRBA and RNEA, :mod:`appell.numerics.rigid_tree`), gravity in ``h``."""
        arrays, q, w, gravity = self._arrays(q, w, p)
        return self._mass_and_bias(arrays, q, w, gravity)

    def accelerations(self, time, q, w, tau=None, p=None) -> np.ndarray:
        """``a`` of ``M a = tau - h`` (with the mimic rows, :meth:`forward`)."""
        return self.forward(time, q, w, tau, p)[0]

    def _rows(self, q, w) -> tuple[np.ndarray, np.ndarray]:
        """``J``, ``c`` of the rows in second-order form ``J a + c = 0``: each quaternion's unit
        norm (``J = q^T``, ``c = q'.q'``), then the mimic rows (``c = 0``)."""
        units = np.zeros((len(self._quaternions), self.n))
        c = np.zeros(len(self.constraint_names))
        for row, (_, k) in enumerate(self._quaternions):
            units[row, k : k + 4] = q[k : k + 4]
            c[row] = w[k : k + 4] @ w[k : k + 4]
        return np.vstack([units, self._J]), c

    def _dense(self, arrays, q, w, tau, gravity):
        """``a`` and the multipliers of the augmented system ``[[M, -J^T], [J, 0]]`` (a floating
        joint's quaternion: ``M`` is singular along ``q``, so no articulated-body solve); each
        unit row's multiplier as the derived route's (:meth:`_unit_multipliers`)."""
        M, h = self._mass_and_bias(arrays, q, w, gravity)
        J, c = self._rows(q, w)
        a, lam = _augmented_solve(
            M,
            J,
            tau - h,
            c,
            f"{self.name}: the mass matrix and the constraints are singular at this state",
            "a quaternion of norm zero, a body without mass, or dependent mimic rows",
        )
        lam[: len(self._quaternions)] = self._unit_multipliers(arrays, q, gravity)
        if self._forces is not None:
            lam[: len(self._quaternions)] -= self._forces.unit_terms([k for _, k in self._quaternions], q, w)
        return a, lam

    def _unit_multipliers(self, arrays, q, gravity) -> np.ndarray:
        """Each unit row's multiplier as the derived route gives it. Both routes have the same
        ``M`` (the partial angular velocities ``2 G(q)`` vanish along ``q``, so does its row of
        ``q``) and the same accelerations; the derived route takes gravity's generalized force
        from the potential ``V = -sum m g.c`` through the quadratic ``R(q)``, whose direction
        ``q`` scales the joint's subtree about its origin ``o`` (``d/de R((1 + e) q) = 2 R``):
        its row of ``q`` reads ``(q.q) lambda = -sum_b 2 m_b g.(c_b - o)`` over the mass
        centres ``c_b`` of the subtree (world axes), which the rigid recursions (zero there) do
        not hold."""
        nb = len(self._nodes)
        Rw, pw = np.empty((nb, 3, 3)), np.empty((nb, 3))
        for i in range(nb):
            j = self.parent[i]
            R, r = arrays.R[0, i], arrays.r[0, i]
            Rw[i], pw[i] = (Rw[j] @ R, pw[j] + Rw[j] @ r) if j >= 0 else (R, r)
        out = np.zeros(len(self._quaternions))
        for row, (b0, k) in enumerate(self._quaternions):
            inside = {b0}
            for i in range(b0 + 1, nb):  # the nodes come after their parents
                if self.parent[i] in inside:
                    inside.add(i)
            moment = sum(self._nodes[i].mass * (pw[i] + Rw[i] @ self._nodes[i].com - pw[b0]) for i in inside)
            out[row] = -2.0 * gravity @ moment / (q[k : k + 4] @ q[k : k + 4])
        return out

    def _solve(self, q, w, tau, p):
        arrays, q, w, gravity = self._arrays(q, w, p)
        tau = np.zeros(self.n) if tau is None else np.asarray(tau, float).reshape(self.n)
        if self._quaternions:
            a, lam = self._dense(arrays, q, w, tau, gravity)
            return arrays, w, gravity, a, lam
        keep: dict = {}
        if self._forces is not None:
            tau = tau + self._forces.forces(q, w)
        X, a = self._aba(arrays, w, tau, np.concatenate([np.zeros(3), -gravity]), keep)
        lam = np.zeros(len(self._J))
        if len(self._J):
            MJ = np.array(
                [aba_at_rest(X, self.parent, self.speed, self.S, keep["U"], keep["D"], row) for row in self._J]
            ).T
            try:
                lam = np.linalg.solve(self._J @ MJ, -self._J @ a)
            except np.linalg.LinAlgError:
                raise ModelError(f"{self.name}: the mimic rows are dependent", hint="remove a <mimic>") from None
            a = a + MJ @ lam
        return arrays, w, gravity, a, lam

    def forward(self, time, q, w, tau=None, p=None) -> tuple[np.ndarray, dict[str, float]]:
        """The accelerations and every joint's reaction ``{output name: value}`` at one state,
        and the mimic rows' multipliers ``lambda_<name>`` of ``M a + h = tau + J^T lambda``."""
        arrays, w, gravity, a, lam = self._solve(q, w, tau, p)
        W, _ = wrenches(
            arrays, self.parent, self.node_of, w[None], a[None], gravity[None], np.zeros((1, 3 * len(self._nodes)))
        )
        out = dict(zip(self.output_names, W[0, self._reporting].reshape(-1).tolist()))
        out.update((f"lambda_{name}", float(v)) for name, v in zip(self.constraint_names, lam))
        return a, out

    def forward_rows(self, t, ys, p=None) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
        """:meth:`forward` at the states ``ys`` (T, 2n) of a motion, without joint forces: the
        accelerations (T, n), every joint's reaction ``{output name: (T,)}`` and the multipliers
        (T, constraints); the inward pass of all the rows in one call."""
        ys = np.asarray(ys, float).reshape(-1, 2 * self.n)
        rows = [self._solve(y[: self.n], y[self.n :], None, p) for y in ys]
        if not rows:
            empty = np.zeros((0, self.n))
            return empty, {k: np.zeros(0) for k in self.output_names}, np.zeros((0, len(self.constraint_names)))
        arrays = TreeArrays(
            *(np.stack([getattr(r[0], f)[0].ravel() for r in rows]) for f in ("R", "r", "S", "c")),
            np.stack([self._inert.ravel()] * len(rows)),
        )
        a = np.stack([r[3] for r in rows])
        gravity = np.stack([r[2] for r in rows])
        W, _ = wrenches(
            arrays, self.parent, self.node_of, ys[:, self.n :], a, gravity, np.zeros((len(rows), 3 * len(self._nodes)))
        )
        W = W[:, self._reporting].reshape(len(rows), -1)
        return a, dict(zip(self.output_names, W.T)), np.array([r[4] for r in rows], float).reshape(len(rows), -1)

    @property
    def units(self) -> dict[str, str]:
        """The units of the coordinates and speeds (rad, m: as :func:`~appell.mechanism.urdf.urdf_units`),
        of the joints' forces and moments (N, N*m) and of ``g``."""
        out = {"g": "m/s^2"} if self.parameter_names else {}
        for node in self._nodes:
            if node.coordinate is not None and node.coordinate == node.reaction:  # a one-coordinate URDF joint
                angle = node.kind == "revolute"
                out.update(
                    {node.coordinate: "rad" if angle else "m", f"{node.coordinate}_dot": "rad/s" if angle else "m/s"}
                )
        out.update((name, "N" if name.startswith("F_") else "N*m") for name in self.output_names)
        return out

    # ------------------------------------------------ the simulator's contract (appell.numerics.dynamics)
    control_names: tuple[str, ...] = ()

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.coordinate_names + self.speed_names

    def params(self, p=None) -> np.ndarray:
        """``[g]``: the default, or ``p`` (one value, or ``{"g": value}``); ``[]`` for a MuJoCo
        model (its gravity is the file's)."""
        if p is None:
            return self.default_parameters
        if isinstance(p, dict):
            unknown = set(map(str, p)) - set(self.parameter_names)
            if unknown:
                hint = f"parameters: {', '.join(self.parameter_names)}" if self.parameter_names else "it has none"
                raise ModelError(f"unknown parameter {sorted(unknown)[0]!r}", hint=hint)
            return np.array([float(p.get(k, v)) for k, v in zip(self.parameter_names, self.default_parameters)])
        return np.asarray(p, float).reshape(len(self.parameter_names))

    def evaluate(self, t, y, p=None):
        """``dy/dt = (w, a)`` and the mimic rows' multipliers at ``(t, y)`` (no joint forces)."""
        from appell.numerics.dynamics import Evaluation

        y = np.asarray(y, float)
        _, w, _, a, lam = self._solve(y[: self.n], y[self.n :], None, p)
        return Evaluation(np.concatenate([w, a]), lam, np.zeros(0))

    def state_residuals(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """Each quaternion's ``(q.q - 1)/2`` and ``q.q'``, then the mimic rows ``a - m b - offset``
        and their rates ``J w``."""
        y = np.asarray(y, float)
        q, w = y[: self.n], y[self.n :]
        units = [q[k : k + 4] for _, k in self._quaternions]
        rates = [w[k : k + 4] for _, k in self._quaternions]
        F = [(u @ u - 1.0) / 2.0 for u in units] + list(self._J @ q - self._offsets)
        phi = [u @ r for u, r in zip(units, rates)] + list(self._J @ w)
        return np.array(F, float), np.array(phi, float)

    def normalized(self, y) -> np.ndarray:
        """``y`` with each quaternion of unit norm and its rate normal to it (the nearest state
        on the unit rows; the simulator's projection, :func:`appell.simulation.projection.project`,
        reaches the same)."""
        y = np.array(y, float)
        for _, k in self._quaternions:
            q = y[k : k + 4] / np.linalg.norm(y[k : k + 4])
            rate = y[self.n + k : self.n + k + 4]
            y[k : k + 4], y[self.n + k : self.n + k + 4] = q, rate - (rate @ q) * q
        return y

    def residual_jacobians(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """``(dF/dq, dphi/dw)``: both ``q^T`` on a unit row, ``J`` on the (linear) mimic rows."""
        J, _ = self._rows(np.asarray(y, float)[: self.n], np.zeros(self.n))
        return J, J


def tree_route(source, *, floating_base: bool = False, ctrl=None, frictionloss: str = "refuse"):
    """The numeric route of a robot file (URDF or MJCF, by its suffix) or of a
    :class:`~appell.mechanism.Mechanism` (a :class:`TreeRoute`). A URDF is read in floating
    point (:class:`NumericTreeRoute`) where :func:`~appell.mechanism.urdf_tree.urdf_tree` takes
    it; an MJCF file always (:func:`~appell.mechanism.mjcf_tree.mjcf_tree`: its armature,
    springs, dampers and actuators at ``ctrl``, ``frictionloss='ignore'`` leaving MuJoCo's dry
    friction out), or a :class:`ModelError` naming what it does not read (never the
    mechanism's tree, which has none of MuJoCo's forces)."""
    if not isinstance(source, (str, Path)):
        return TreeRoute(source)
    path = Path(source)
    if path.suffix.lower() in (".xml", ".mjcf"):
        return mjcf_route(path, ctrl, frictionloss)
    if path.suffix.lower() == ".urdf":  # read in floating point, no SymPy (NumericTreeRoute)
        from appell.mechanism.urdf import read_urdf
        from appell.mechanism.urdf_tree import NotNumeric, urdf_tree

        try:
            return NumericTreeRoute(urdf_tree(read_urdf(path), floating_base), path.stem)
        except NotNumeric:
            pass  # the symbolic route reads it (or says why not)
    from appell.mechanism.formats import importer_for

    importer = importer_for(path)
    if importer is None or importer.mechanism is None:
        raise ModelError(
            f"{path}: the numeric tree route reads a robot file (URDF or MJCF)",
            hint="for a model file, derive it: appell.derive(appell.load_model(path))",
        )
    mechanism, constraints = importer.mechanism(path, floating_base)
    return TreeRoute(mechanism, path.stem, constraints)


def mjcf_route(path, ctrl=None, frictionloss: str = "refuse") -> NumericTreeRoute:
    """The :class:`NumericTreeRoute` of a MuJoCo model file (:func:`tree_route`); what the
    floating-point tree does not read is a :class:`ModelError` naming it."""
    from appell.mechanism.mjcf_compiled import load_mjcf
    from appell.mechanism.mjcf_tree import INSTEAD, mjcf_tree
    from appell.mechanism.urdf_tree import NotNumeric

    path = Path(path)
    try:
        tree = mjcf_tree(load_mjcf(path), str(path), frictionloss)
    except NotNumeric as exc:
        raise ModelError(f"{path}: the numeric tree route does not take {exc}", hint=INSTEAD) from None
    return NumericTreeRoute(tree, path.stem, ctrl)
