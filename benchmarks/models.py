"""The growing benchmark family: an n-link planar pendulum whose tip is held on a
vertical line, built three ways (appell, SymPy LagrangesMethod, SymPy KanesMethod).

Links i = 1..n have length l_i and a point mass m_i at their outer end; theta_i is the
absolute angle of link i from the downward vertical. The loop closure is
``tip: sum_i l_i sin(theta_i) - d = 0``; its multiplier is the horizontal force that the
line exerts on the tip (newtons).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

import appell
from appell.examples.catalog import nlink_pendulum


def nlink_parameters(n: int) -> dict[str, float]:
    """Parameter values of :func:`appell.examples.catalog.nlink_pendulum` (masses
    1 + 0.1 i kg, lengths 1 - 0.02 i m, g, d = 0.3 m)."""
    return {p.symbol.name: p.value for p in nlink_pendulum(n).parameters}


def nlink_state(n: int, seed: int = 1, params: dict[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A state (theta, theta_dot) on the constraint: the last angle closes the loop (the
    other angles are halved until it can)."""
    rng = np.random.default_rng(seed)
    p = nlink_parameters(n) if params is None else params
    lengths = np.array([p[f"l{i}"] for i in range(1, n + 1)])
    th = rng.uniform(-0.3, 0.3, n)
    while abs(p["d"] - lengths[:-1] @ np.sin(th[:-1])) > 0.9 * lengths[-1]:
        th[:-1] *= 0.5
    th[-1] = np.arcsin((p["d"] - lengths[:-1] @ np.sin(th[:-1])) / lengths[-1])
    w = rng.uniform(-0.5, 0.5, n)
    w[-1] = -(lengths[:-1] * np.cos(th[:-1])) @ w[:-1] / (lengths[-1] * np.cos(th[-1]))
    return th, w


def file_parameters(n: int) -> dict[str, float]:
    """Parameter values of the model-file case: those of :func:`nlink_parameters` while
    every link is longer than 0.1 m (n < 45); beyond, the catalog's lengths 1 - 0.02 i
    reach zero at n = 50 (a massless, inertia-free last link: a singular mass matrix), so
    the lengths become l_i = 1 - i / (2 n), between 0.5 and 1 m."""
    p = nlink_parameters(n)
    if min(p[f"l{i}"] for i in range(1, n + 1)) > 0.1:
        return p
    return p | {f"l{i}": 1.0 - i / (2.0 * n) for i in range(1, n + 1)}


def nlink_appell(n: int, s: int = 1) -> appell.System:
    """The family as an :class:`appell.System`: the bundled builder
    :func:`appell.examples.catalog.nlink_pendulum` (``s = 2`` also holds the tip at ``y = e``)."""
    return nlink_pendulum(n, s)


def _mechanics(n: int):
    from sympy.physics.mechanics import Particle, Point, ReferenceFrame, dynamicsymbols

    q = dynamicsymbols(f"theta1:{n + 1}")
    m = sp.symbols(f"m1:{n + 1}")
    l = sp.symbols(f"l1:{n + 1}")
    g, d = sp.symbols("g d")
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    P, particles, points = O, [], []
    for i in range(n):
        P = P.locatenew(f"P{i + 1}", l[i] * (sp.sin(q[i]) * N.x - sp.cos(q[i]) * N.y))
        P.set_vel(N, P.pos_from(O).dt(N))
        pa = Particle(f"bob{i + 1}", P, m[i])
        pa.potential_energy = m[i] * g * P.pos_from(O).dot(N.y)
        particles.append(pa)
        points.append(P)
    x_tip = points[-1].pos_from(O).dot(N.x)
    return q, m, l, g, d, N, particles, points, x_tip


def nlink_lagrange(n: int):
    """``LagrangesMethod`` with the loop closure as a holonomic constraint.

    Returns (LM, M, F, params, q, qd): ``M [q''; lambda] = F`` is the dynamic part
    (rows and columns after the kinematic identity) of ``mass_matrix_full``.
    """
    from sympy.physics.mechanics import LagrangesMethod, Lagrangian

    q, m, l, g, d, N, particles, _, x_tip = _mechanics(n)
    LM = LagrangesMethod(Lagrangian(N, *particles), q, hol_coneqs=[x_tip - d], frame=N)
    LM.form_lagranges_equations()
    Mf, Ff = LM.mass_matrix_full, LM.forcing_full
    qd = [qi.diff(sp.Symbol("t")) for qi in q]
    return LM, Mf[n:, n:], Ff[n:, :], [*m, *l, g, d], q, qd


def nlink_kane(n: int):
    """``KanesMethod`` with the constraint-force trick: an unknown horizontal force
    ``lam`` at the tip, and the loop closure differentiated twice appended.

    Returns (KM, A, b, params, q, u) with ``A [u'; lam] = b``.
    """
    from sympy.physics.mechanics import KanesMethod, dynamicsymbols

    q, m, l, g, d, N, particles, points, x_tip = _mechanics(n)
    u = dynamicsymbols(f"u1:{n + 1}")
    t = dynamicsymbols._t
    lam = sp.Symbol("lam")
    kd = [q[i].diff(t) - u[i] for i in range(n)]
    loads = [(points[i], -m[i] * g * N.y) for i in range(n)] + [(points[-1], lam * N.x)]
    KM = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    KM.kanes_equations(particles, loads)
    M, F = KM.mass_matrix, KM.forcing
    Fl = F.diff(lam)
    F0 = F.subs(lam, 0)
    # loop closure at the acceleration level: J u' + c = 0
    ud = [ui.diff(t) for ui in u]
    xdd = (
        x_tip.diff(t, 2)
        .subs({qi.diff(t, 2): udi for qi, udi in zip(q, ud)})
        .subs({qi.diff(t): ui for qi, ui in zip(q, u)})
    )
    J = sp.Matrix([[xdd.diff(udi) for udi in ud]])
    c = xdd.subs({udi: 0 for udi in ud})
    A = M.row_join(-Fl).col_join(J.row_join(sp.zeros(1, 1)))
    b = F0.col_join(sp.Matrix([-c]))
    return KM, A, b, [*m, *l, g, d], q, u


def nlink_kane_function(n: int):
    """SymPy's best practice for the family: ``KanesMethod`` with the tip force (see
    :func:`nlink_kane`) and ``lambdify(cse=True, modules="math")`` of the entries of the
    augmented system ``[M -J^T; J 0] [u'; lam] = [f; -c]``, solved by ``numpy.linalg.solve``.

    Returns ``evaluate(theta, theta_dot, params) -> (u', lam)`` with ``params`` in the order
    of :func:`nlink_parameters`.
    """
    KM, A, b, params, q, u = nlink_kane(n)
    entries = sp.lambdify([*q, *u, *params], list(A) + list(b), cse=True, modules="math")
    k = n + 1

    def evaluate(theta, theta_dot, p):
        out = np.array(entries(*theta, *theta_dot, *p))
        x = np.linalg.solve(out[: k * k].reshape(k, k), out[k * k :])
        return x[:n], x[n]

    return evaluate


def nlink_pinocchio(n: int):
    """The family as a Pinocchio model: n revolute joints about z (the plane is x-y, y up),
    joint i+1 at the end of link i, a point mass m_i at the end of link i (exact point-mass
    inertia: no rotational inertia about its centre), gravity (0, -g, 0), and a frame ``tip``
    at the end of link n.

    Pinocchio's coordinates are relative angles: ``q_i = theta_i - theta_{i-1}`` (see
    :func:`pinocchio_state`). Returns (model, tip frame id).
    """
    import pinocchio as pin

    p = nlink_parameters(n)
    masses = [p[f"m{i}"] for i in range(1, n + 1)]
    lengths = [p[f"l{i}"] for i in range(1, n + 1)]
    model, parent = pin.Model(), 0
    for i in range(n):
        place = pin.SE3(np.eye(3), np.array([0.0, -lengths[i - 1], 0.0]) if i else np.zeros(3))
        parent = model.addJoint(parent, pin.JointModelRZ(), place, f"joint{i + 1}")
        bob = pin.Inertia(masses[i], np.array([0.0, -lengths[i], 0.0]), np.zeros((3, 3)))
        model.appendBodyToJoint(parent, bob, pin.SE3.Identity())
    tip = model.addFrame(
        pin.Frame("tip", parent, 0, pin.SE3(np.eye(3), np.array([0.0, -lengths[-1], 0.0])), pin.FrameType.OP_FRAME)
    )
    model.gravity = pin.Motion(np.array([0.0, -p["g"], 0.0]), np.zeros(3))
    return model, tip


def pinocchio_state(theta, theta_dot) -> tuple[np.ndarray, np.ndarray]:
    """Absolute angles and rates -> Pinocchio's relative joint angles and rates."""
    return np.diff(theta, prepend=0.0), np.diff(theta_dot, prepend=0.0)


def nlink_pinocchio_function(n: int):
    """Pinocchio's constrained forward dynamics of the family: ``computeAllTerms`` (M, the
    nonlinear effects, the joint Jacobians and the velocity-product accelerations), the
    tip's x row of the frame Jacobian J and its drift gamma = (J' v) (classical acceleration
    at zero joint acceleration), then ``forwardDynamics`` solving
    ``[M J^T; J 0] [ddq; -lam] = [tau - b; -gamma]``.

    Returns ``evaluate(q, v) -> (ddq, lam)`` in Pinocchio's relative coordinates; ``lam`` is
    the x force on the tip.
    """
    import pinocchio as pin

    model, tip = nlink_pinocchio(n)
    data = model.createData()
    tau = np.zeros(n)
    frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

    def evaluate(q, v):
        pin.computeAllTerms(model, data, q, v)
        J = pin.getFrameJacobian(model, data, tip, frame)[:1]
        gamma = pin.getFrameClassicalAcceleration(model, data, tip, frame).linear[:1]
        ddq = pin.forwardDynamics(model, data, tau, J, gamma, 0.0)
        return ddq, data.lambda_c[0]

    return evaluate


def nlink_model_file(n: int) -> str:
    """The family as an appell model file (TOML): the same system as
    :func:`nlink_appell` (parameter values :func:`file_parameters`), with its particles as
    ``[[bodies]]`` and its start on the line."""
    p = file_parameters(n)
    th, w = nlink_state(n, params=p)
    lines = [
        f'[model]\nname = "pendulum{n}"',
        "coordinates = [" + ", ".join(f'"theta{i}"' for i in range(1, n + 1)) + "]",
        "\n[parameters]",
    ]
    lines += [f"{k} = {v!r}" for k, v in p.items()]
    x = y = ""
    for i in range(1, n + 1):
        x += f" + l{i}*sin(theta{i})"
        y += f" - l{i}*cos(theta{i})"
        lines += ["\n[[bodies]]", f'name = "bob{i}"', f'mass = "m{i}"', f'position = ["{x[3:]}", "{y}", 0]']
        lines += [
            "\n[[forces]]",
            f'name = "weight{i}"',
            f'vector = [0, "-m{i}*g", 0]',
            f'position = ["{x[3:]}", "{y}", 0]',
        ]
    lines += ["\n[constraints.tip]", 'kind = "holonomic"', f'expr = "{x[3:]} - d"', "\n[initial]"]
    lines += [f"theta{i + 1} = {float(th[i])!r}" for i in range(n)]
    lines += [f'"theta{i + 1}\'" = {float(w[i])!r}' for i in range(n)]
    return "\n".join(lines) + "\n"


def rolling_disc_sympy_linear():
    """The peer of :func:`appell.linearise`: SymPy's ``KanesMethod.linearize`` (the
    ``Linearizer``, A and B solved) of a thin disc (m r^2/4 about a diameter, m r^2/2 about
    its axis) rolling on a level plane, about upright rolling at spin rate ``Omega``.

    Coordinates yaw ``q1``, lean ``q2``, spin ``q3``; speeds ``u1, u2, u3`` the angular
    velocity in the lean frame (SymPy's rolling-disc example, the contact point at rest).
    Returns ``(timings, A)``: the seconds to form Kane's equations, to linearise them and
    to compile ``A(Omega, r, m, g)`` with ``lambdify(cse=True, modules='math')``, and that
    compiled function (a 6x6 list of lists, state ``(q1, q2, q3, u1, u2, u3)``).
    """
    import time

    from sympy.physics.mechanics import KanesMethod, Point, ReferenceFrame, RigidBody, dot, dynamicsymbols, inertia

    t0 = time.perf_counter()
    q1, q2, q3 = dynamicsymbols("q1 q2 q3")
    u1, u2, u3 = dynamicsymbols("u1 u2 u3")
    r, m, g, spin = sp.symbols("r m g Omega")
    N = ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    from_rates = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    contact = Point("C")
    contact.set_vel(N, 0)
    centre = contact.locatenew("D", r * L.z)
    centre.v2pt_theory(contact, N, R)
    disc = RigidBody("disc", centre, R, m, (inertia(L, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4), centre))
    kane = KanesMethod(
        N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3], kd_eqs=[dot(R.ang_vel_in(N) - from_rates, e) for e in L]
    )
    kane.kanes_equations([disc], [(centre, -m * g * Y.z)])
    t1 = time.perf_counter()
    A, _, _ = kane.linearize(op_point={q2: 0, u1: 0, u2: spin, u3: 0}, A_and_B=True)
    t2 = time.perf_counter()
    fn = sp.lambdify([spin, r, m, g], A.tolist(), cse=True, modules="math")
    t3 = time.perf_counter()
    return {"equations": t1 - t0, "linearise": t2 - t1, "compile": t3 - t2}, fn
