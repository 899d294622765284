"""Inverse dynamics: the drive forces, reactions and joint wrenches along a given motion.

Given the motion ``q(t)`` (with its speeds ``w`` and accelerations ``a``, or derived from
``q`` by a cubic spline), the equations of motion with multipliers (method.md §2)::

    M a + (h - Q) = B tau + J^T lambda,        J a + c = 0   (the motion is given)

are solved at each time for the drive forces ``tau`` along the driven speeds (``B`` selects
them) and the multipliers ``lambda``: ``[B  J^T] [tau; lambda] = M a + h - Q``. For a tree
without constraints every speed is driven and ``tau = M a + h - Q`` (what RNEA computes);
a closed loop names its drives (as many as the loop leaves degrees of freedom), and the
system must then determine them and every multiplier (``[B J^T]`` square and regular, else
an error says which are not determined). The outputs (a mechanism's joint forces and
moments) follow from ``q, w, a, lambda`` as in a simulation. The given motion should
satisfy the constraints; its largest velocity-level residual is reported.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from appell.errors import ComputationError, ModelError
from appell.numerics.boundary import numeric_model
from appell.symbols import derivative_name

__all__ = ["Contact", "InverseDynamics", "inverse_dynamics", "closed_chain_inverse", "contact_model"]


@dataclass(frozen=True)
class Contact:
    """A foot or tool held on the ground along the motion, as a loop closure to the world.

    ``body``: a body of the joint tree (or, through ``points``, an MJCF site or merged body:
    :func:`contact_model`); ``point``: the contact point in the body's frame; ``kind``:
    ``'point'`` (a point contact: the point held at its place, rows ``<name>_x, _y, _z``,
    the ground's force on the body along the world axes) or ``'weld'`` (a flat foot, a
    clamped tool: the body's orientation held as well, rows ``<name>_rx, _ry, _rz`` as in
    :meth:`Mechanism.weld <appell.mechanism.Mechanism.weld>`, each the ground's moment on the
    body about the held frame's axis ``A e_i``); ``name``: the rows' prefix (default
    ``<body>_contact``); ``at`` the point's world place and ``rotation`` (a weld) the body's
    world orientation ``A`` while held (default: where the point and body are at the first time,
    the given coordinates at their first values and the others at their start values)."""

    body: str
    point: tuple = (0.0, 0.0, 0.0)
    kind: str = "point"
    name: str | None = None
    at: tuple | None = None
    rotation: tuple | None = None

    @classmethod
    def of(cls, item) -> Contact:
        """A :class:`Contact` from itself, ``"body"``, ``"body:point"``, ``"body:weld"``, a
        tuple ``(body, point[, kind])`` or a mapping of the fields."""
        if isinstance(item, Contact):
            return item
        if isinstance(item, str):
            body, _, kind = item.partition(":")
            return cls(body, kind=kind or "point")
        if isinstance(item, Mapping):
            return cls(**dict(item))
        if isinstance(item, (tuple, list)) and 1 <= len(item) <= 3:
            return cls(*item)
        raise ModelError(
            f"contact {item!r}: give a body name ('foot', 'foot:weld'), (body, point[, kind]) or appell.Contact(...)"
        )

    @property
    def rows(self) -> tuple[str, ...]:
        """The suffixes of its rows."""
        return ("_x", "_y", "_z") + (("_rx", "_ry", "_rz") if self.kind == "weld" else ())


@dataclass(frozen=True)
class InverseDynamics:
    """The answer along the motion: ``t``, the ``motion`` (coordinates, speeds and
    accelerations by name), ``drives`` (``{speed: force along it}``), ``multipliers``
    (``{constraint: lambda}``), ``outputs`` (joint forces and moments, the model's outputs)
    and ``residual`` (the largest velocity-level constraint residual of the given motion);
    ``undetermined`` (closed chains, :func:`closed_chain_inverse`): each combination of drives
    and multipliers that does no work, ``{name: weight}``, the answer being their minimum-norm
    choice; ``undetermined_wrenches`` the joints whose wrench those combinations change."""

    t: np.ndarray
    motion: Mapping[str, np.ndarray]
    drives: Mapping[str, np.ndarray]
    multipliers: Mapping[str, np.ndarray]
    outputs: Mapping[str, np.ndarray] = field(default_factory=dict)
    residual: float = 0.0
    undetermined: tuple = ()  # closed chains: combinations of drives and multipliers the motion leaves open
    undetermined_wrenches: tuple = ()  # closed chains: joints whose wrench those combinations change

    def columns(self) -> list[tuple[str, np.ndarray]]:
        """``(name, values)`` in the order of a result file: t, the motion, ``drive_<speed>``,
        ``lambda_<constraint>``, the outputs."""
        return (
            [("t", self.t)]
            + list(self.motion.items())
            + [(f"drive_{k}", v) for k, v in self.drives.items()]
            + [(f"lambda_{k}", v) for k, v in self.multipliers.items()]
            + list(self.outputs.items())
        )

    def to_csv(self, path, names=None):
        """Write :meth:`columns` as CSV, atomically; ``names`` (``{identifier: name in the
        model's file}``, :attr:`appell.System.names`) heads the columns as the file spells them."""
        import csv

        from appell.files import atomic_path
        from appell.names import shown_names

        cols = self.columns()
        with atomic_path(path) as tmp:
            with open(tmp, "w", newline="") as fh:
                writer = csv.writer(fh)
                writer.writerow(shown_names([n for n, _ in cols], names))
                for k in range(self.t.size):
                    writer.writerow([repr(float(v[k])) for _, v in cols])
        return path


def _loop_parts(source):
    """The :class:`~appell.mechanism.builder.LoopParts` of a mechanism, a mechanism's system or
    its derivation (contacts are added to these before the closed-chain model is built)."""
    from appell.numerics.loops import LoopModel

    if isinstance(source, LoopModel):
        raise ModelError(
            "contacts are added to a mechanism or its system, not to a LoopModel built already",
            hint="pass the Mechanism or System to inverse_dynamics(..., contacts=[...])",
        )
    try:
        return _parts_of(source)
    except ModelError as exc:
        raise ModelError(
            f"contacts are loop rows of the closed-chain route, which does not take this model: {exc.message}",
            hint="hold the foot by a closure of the model (a weld or connect to the "
            "ground) and give the motion of every coordinate",
        ) from None


def _parts_of(source):
    from appell.numerics.loops import _system_parts

    if hasattr(source, "loop_parts"):
        return source.loop_parts()
    system = getattr(source, "system", source)
    if getattr(system, "tree", None) is None:
        raise ModelError(
            f"system {getattr(system, 'name', '?')!r} has no joint tree: contacts are loop rows of a mechanism's tree",
            hint="build it with appell.Mechanism (or read a URDF or MJCF file)",
        )
    return _system_parts(system)


def contact_model(source, contacts, points: Mapping | None = None, backend: str = "auto"):
    """The :class:`~appell.numerics.loops.LoopModel` of ``source`` (a mechanism, its system or
    derivation) with each :class:`Contact` added as loop rows to the ground; its attribute
    ``contacts`` holds per contact ``(contact, node, point, at, A)``: its tree node, its point
    in that body's frame and the indices in :attr:`LoopModel.parameter_names` of its world
    place ``at`` (``<name>_at_x, _y, _z``) and, for a weld, its held orientation ``A``
    (``<name>_A11`` .. ``_A33``, row by row), set at the first time (:func:`closed_chain_inverse`).

    A point row is ``e_d . (p - at) = 0`` (:class:`~appell.rigid_tree.LoopRow` ``'point'``,
    ``p`` the body's point, ``e_d`` a world axis; its multiplier the ground's force on the body
    along ``e_d``); a weld adds ``(R e_j) . (A e_k) = 0`` for ``(j, k)`` = (y, z), (z, x), (x, y)
    (``'align'``, ``R`` the body's orientation; the multiplier the ground's moment on the body,
    ``lambda (R e_j) x (A e_k) = lambda A e_i`` where held). ``points``: ``{name: (body,
    (x, y, z))}`` for contact names that are not tree bodies (an MJCF file's sites and merged
    bodies)."""
    import dataclasses

    import sympy as sp

    from appell.model import Parameter
    from appell.numerics.loops import LoopModel
    from appell.rigid_tree import LoopRow

    parts = _loop_parts(source)
    tree = parts.tree
    nodes = {node.body: k for k, node in enumerate(tree.nodes)}
    taken = (
        {q.name for q in parts.coordinates}
        | {p.symbol.name for p in parts.parameters}
        | {name for name, _ in parts.constraints}
    )
    rows: list = []
    params: list = []
    held: list = []
    zero = sp.ImmutableMatrix([0, 0, 0])
    for item in contacts:
        c = Contact.of(item)
        if c.kind not in ("point", "weld"):
            raise ModelError(
                f"contact {c.body!r}: kind {c.kind!r} is not 'point' (a point contact) or 'weld' "
                "(a flat foot, the orientation held)"
            )
        what = f"contact {c.name or c.body!r}"
        try:
            r = np.asarray(c.point, float).reshape(3)
        except (TypeError, ValueError):
            raise ModelError(f"{what}: point {c.point!r} is not (x, y, z) in the body frame") from None
        body = c.body
        if body not in nodes and points and body in points:
            body, offset = points[body]
            r = r + np.asarray(offset, float).reshape(3)
        if body not in nodes:
            raise ModelError(
                f"{what}: no body {c.body!r} on the joint tree",
                hint="bodies: " + ", ".join(nodes) + (("; sites: " + ", ".join(points)) if points else ""),
            )
        name = c.name or re.sub(r"\W+", "_", c.body, flags=re.ASCII).strip("_") + "_contact"
        mine = [name + sfx for sfx in c.rows] + [f"{name}_at_{x}" for x in "xyz"]
        mine += [f"{name}_A{i}{j}" for i in "123" for j in "123"] if c.kind == "weld" else []
        clash = sorted(taken & set(mine))
        if clash or not name.isidentifier():
            raise ModelError(
                f"{what}: the name {name!r} "
                + (f"gives {', '.join(clash)}, taken already" if clash else "is not an identifier"),
                hint="give the contact another name (Contact(..., name=...))",
            )
        taken |= set(mine)
        base = len(parts.parameters) + len(params)
        at = [sp.Symbol(f"{name}_at_{x}") for x in "xyz"]
        A = sp.Matrix(3, 3, [sp.Symbol(f"{name}_A{i}{j}") for i in "123" for j in "123"]) if c.kind == "weld" else None
        params += [Parameter(s_, 0.0) for s_ in at] + ([Parameter(s_, 0.0) for s_ in A] if A is not None else [])
        k, point = nodes[body], sp.ImmutableMatrix([float(x) for x in r])
        rows += [
            LoopRow(
                f"{name}_{d}",
                name,
                "point",
                k,
                point,
                sp.ImmutableMatrix(sp.eye(3)[:, i]),
                -1,
                sp.ImmutableMatrix(at),
                zero,
            )
            for i, d in enumerate("xyz")
        ]
        if A is not None:
            rows += [
                LoopRow(
                    f"{name}_r{d}",
                    name,
                    "align",
                    k,
                    point,
                    sp.ImmutableMatrix(sp.eye(3)[:, j]),
                    -1,
                    zero,
                    sp.ImmutableMatrix(A[:, m]),
                )
                for d, (j, m) in zip("xyz", ((1, 2), (2, 0), (0, 1)))
            ]
        held.append(
            (
                dataclasses.replace(c, name=name),
                k,
                r,
                list(range(base, base + 3)),
                list(range(base + 3, base + 12)) if A is not None else None,
            )
        )
    tree = dataclasses.replace(tree, loops=tuple(tree.loops) + tuple(rows))
    parts = dataclasses.replace(
        parts,
        tree=tree,
        constraints=tuple(parts.constraints) + tuple((r_.name, None) for r_ in rows),
        parameters=tuple(parts.parameters) + tuple(params),
    )
    model = LoopModel(parts, backend)
    model.contacts = tuple(held)
    return model


def _plant(model, held, q, passive, pv, tol, max_iterations):
    """``(q, pv)``: the coordinates ``q`` with the passive ones moved (least steps, Newton's
    method) to close the model's own rows (the loops, a quaternion's norm: not the contacts),
    and the parameters ``pv`` with each contact's place and orientation set where its body is
    there (its own ``at``, ``rotation`` where given)."""
    pv, q = np.array(pv, float), np.array(q, float)
    n = len(model.speed_names)
    mine = {c.name + sfx for c, *_ in held for sfx in c.rows}
    own = [i for i, nm in enumerate(model.constraint_names) if nm not in mine]
    for _ in range(max_iterations if own and passive else 0):
        Phi, J = model.positions(q, pv)
        if np.abs(Phi[own]).max() <= tol:
            break
        dq = np.linalg.lstsq(J[np.ix_(own, passive)], -Phi[own], rcond=None)[0]
        q[passive] += dq * min(1.0, 0.5 / max(np.abs(dq).max(), 1e-300))
    arrays = model._evaluate_terms(0.0, q, np.zeros(n), pv, np.zeros(len(model.control_names)))[0]
    Rw, pw = model._kinematics(arrays, np.zeros(n))[:2]
    for c, k, r, at, A in held:
        pv[at] = pw[k] + Rw[k] @ r if c.at is None else np.asarray(c.at, float).reshape(3)
        if A is not None:
            R = Rw[k] if c.rotation is None else np.asarray(c.rotation, float).reshape(3, 3)
            pv[A] = R.reshape(-1)
    return q, pv


def _contact_wrenches(held, lam, names, pv) -> dict:
    """``F_<contact>_x .. _z`` (the ground's force on the body, world axes) and, for a weld,
    ``M_<contact>_x .. _z`` (its moment about the contact point, ``A (lambda_rx, _ry, _rz)``)."""
    out = {}
    for c, _, _, _, A in held:
        F = np.column_stack([lam[:, names.index(f"{c.name}_{d}")] for d in "xyz"])
        out.update({f"F_{c.name}_{d}": F[:, i] for i, d in enumerate("xyz")})
        if A is not None:
            R = np.asarray(pv[A], float).reshape(3, 3)
            M = np.column_stack([lam[:, names.index(f"{c.name}_r{d}")] for d in "xyz"]) @ R.T
            out.update({f"M_{c.name}_{d}": M[:, i] for i, d in enumerate("xyz")})
    return out


def _spline(t, q, order):
    from scipy.interpolate import CubicSpline

    return CubicSpline(t, q, axis=0)(t, order)


def inverse_dynamics(
    derivation, t, q, w=None, a=None, drives: Sequence[str] | None = None, p=None, **options
) -> InverseDynamics:
    """Drive forces, multipliers and outputs of ``derivation`` along the motion ``q``
    (rows: times ``t``, columns: coordinates in the model's order) with speeds ``w`` and
    accelerations ``a`` (same shapes; derived from ``q`` by a cubic spline when not given);
    ``drives`` the names of the driven speeds (default: every speed of a system without
    constraints). Module docstring: the equations.

    A closed chain (an :class:`appell.Mechanism`, a mechanism's :class:`appell.System` whose
    tree records loop closures, or the :class:`~appell.numerics.loops.LoopModel` of one)
    takes its motion for the actuated or
    other independent coordinates alone, ``q = {name: values}``, and completes the passive
    ones from the loop closures (:func:`closed_chain_inverse`, whose ``options`` it passes).
    ``contacts`` (feet or tools held on the ground, :class:`Contact`) take that route for any
    mechanism: its motion given likewise, the contact forces solved with the loop forces."""
    tree = getattr(derivation, "tree", None)
    loops = getattr(tree, "loops", None)
    if hasattr(derivation, "loop_parts") or hasattr(derivation, "loop_rows") or loops or options.get("contacts"):
        return closed_chain_inverse(derivation, t, q, w, a, drives, p, **options)
    model = numeric_model(derivation)
    names, speeds = model.coordinate_names, model.speed_names
    t = np.asarray(t, float).reshape(-1)
    q = np.asarray(q, float).reshape(t.size, -1)
    if q.shape[1] != len(names):
        raise ModelError(f"the motion gives {q.shape[1]} coordinates, the model has {len(names)}: {', '.join(names)}")
    if t.size < 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ModelError("the motion's times must be finite and increasing")
    if (w is None or a is None) and t.size < 4:
        raise ModelError(
            "deriving speeds and accelerations from the coordinates needs at least 4 times",
            hint="give the speeds and accelerations, or more rows",
        )
    if list(speeds) != [derivative_name(nm, 1) for nm in names] and (w is None or a is None):
        raise ModelError(
            "the model's speeds are not its coordinates' derivatives: give its speeds and accelerations",
            hint="columns " + ", ".join(speeds),
        )
    w = _spline(t, q, 1) if w is None else np.asarray(w, float).reshape(t.size, -1)
    a = _spline(t, w, 1) if a is None else np.asarray(a, float).reshape(t.size, -1)
    cons = model.constraint_names
    if drives is None:
        if cons:
            raise ModelError(
                f"the model has constraints ({', '.join(cons)}): name the driven speeds",
                hint="give drives=[...] (appell inverse --drive NAME), as many as the degrees of "
                "freedom the constraints leave",
            )
        drives = list(speeds)
    drives = [str(d) for d in drives]
    unknown = [d for d in drives if d not in speeds]
    if unknown:
        raise ModelError(f"unknown drive(s) {', '.join(unknown)}", hint="speeds: " + ", ".join(speeds))
    n, s = len(speeds), len(cons)
    if len(drives) + s != n:
        raise ModelError(
            f"{len(drives)} drive(s) and {s} constraint(s) for {n} speeds: the motion determines "
            f"{n} forces, so {n - s} drive(s) are needed",
            hint="name as many drives as the constraints leave degrees of freedom",
        )
    B = np.zeros((n, len(drives)))
    for k, d in enumerate(drives):
        B[speeds.index(d), k] = 1.0
    tau, lam = np.zeros((t.size, len(drives))), np.zeros((t.size, s))
    residual = 0.0
    pv = model.params(p)
    for k in range(t.size):
        M, hQ, J, c = model.evaluate_blocks(t[k], q[k], w[k], pv)
        A = np.hstack([B, J.T]) if s else B
        if np.linalg.matrix_rank(A) < n:
            raise ComputationError(
                f"at t = {t[k]:.10g} the drives {', '.join(drives)} and the constraints do not "
                "determine the forces (the drives move along the constraints' reactions)",
                hint="drive other speeds",
            )
        x = np.linalg.solve(A, M @ a[k] + hQ)
        tau[k], lam[k] = x[: len(drives)], x[len(drives) :]
        if s:
            residual = max(
                residual, float(np.nanmax(np.abs(model.constraint_residuals(t[k], q[k], w[k], pv)[1]), initial=0.0))
            )
    from appell.simulation.recording import acceleration_name, recorded_outputs

    motion = {
        **{nm: q[:, i] for i, nm in enumerate(names)},
        **{nm: w[:, i] for i, nm in enumerate(speeds)},
        **{acceleration_name(nm): a[:, i] for i, nm in enumerate(speeds)},
    }
    columns = {
        "t": t,
        **motion,
        **{f"lambda_{c}": lam[:, k] for k, c in enumerate(cons)},
        **dict(zip(model.parameter_names, (float(v) for v in pv))),
    }
    outputs = recorded_outputs(derivation.system, columns)  # every row at once
    return InverseDynamics(
        t,
        motion,
        {d: tau[:, k] for k, d in enumerate(drives)},
        {c: lam[:, k] for k, c in enumerate(cons)},
        dict(outputs),
        residual,
    )


def _given_columns(values, names, what, size):
    """``{index: values}`` of a mapping keyed by coordinate names (or their speeds' names)."""
    out = {}
    for key, column in dict(values).items():
        key = str(key)
        k = names[0].index(key) if key in names[0] else names[1].index(key) if key in names[1] else None
        if k is None:
            raise ModelError(f"{what}: unknown coordinate {key!r}", hint="coordinates: " + ", ".join(names[0]))
        column = np.asarray(column, float).reshape(-1)
        if column.size != size or not np.all(np.isfinite(column)):
            raise ModelError(f"{what}: {key!r} must have {size} finite values, one per time")
        out[k] = column
    return out


def _combinations(A, names, tol):
    """The null space of ``A`` as ``{name: weight}``, in reduced echelon form (each combination
    has its own leading name, weight 1, absent from the others)."""
    from appell.numerics.loops import echelon_null_space

    return echelon_null_space(A, names, tol)


def _independent(J, ind, passive, names, own=()):
    """A :class:`ModelError` where the given coordinates are related by the loops, or leave
    passive ones free (ranks of ``J`` and its passive columns, relative tolerance 1e-9; a row
    of ``own`` (a joint's own constraint, not a loop's) on the given coordinates alone, a
    floating base's unit quaternion given whole, is theirs to hold and left out)."""
    if own and passive:
        J = np.delete(J, [k for k in own if not np.any(J[k, passive])], axis=0)
    rank, rank_p = (
        np.linalg.matrix_rank(M_, tol=1e-9 * max(np.abs(J).max(initial=0.0), 1e-300)) for M_ in (J, J[:, passive])
    )
    if rank_p < rank:
        raise ModelError(
            f"the given coordinates {', '.join(names[i] for i in ind)} are not independent: the "
            "loop closures relate them",
            hint="give fewer, or other, coordinates",
        )
    if len(passive) > rank_p:
        raise ModelError(
            f"the loop closures leave {len(passive) - rank_p} passive coordinate(s) free: give "
            f"{len(passive) - rank_p} more",
            hint="passive: " + ", ".join(names[i] for i in passive),
        )


def _refuse_nearly_dependent(model, q, u, t0, p) -> None:
    """A :class:`ModelError` where the loop rows at the start are nearly dependent (the forward
    split's rule, :data:`appell.numerics.loops.RANK_TOLERANCE`: a linkage whose geometry
    misses a movable one by a little, as ToddlerBot's neck): held rigid it could barely move or
    not be closed, so the passive coordinates, and the forces along that combination, would
    come from the file's last digits."""
    from appell.numerics.loops import nearly_dependent, nearly_phrase

    M, _, J, _, _ = model.blocks(q, np.zeros(len(q)), u, t0, p)
    nearly = nearly_dependent(M, J, model.constraint_names)
    if nearly:
        raise ModelError(
            f"{nearly_phrase(nearly, model.names, ' at the start')}: the linkage as written misses a movable one "
            "by a little, so that held rigid it could barely move or not be closed, and inverse dynamics would "
            "take its passive coordinates and loop forces from the file's last digits",
            hint="make the linkage's geometry exact (the forward route, appell.loop_model(...).evaluate, holds "
            "such rows as dependent and says so)",
        )


def _passive_solve(Jp, rhs):
    """The least-squares solution of ``Jp x = rhs`` for a ``Jp`` of full column rank (the passive
    coordinates' columns, :func:`_independent`): by the normal equations ``Jp^T Jp x = Jp^T rhs``
    (a small dense solve, a tenth of ``lstsq``'s cost; the systems solved here are consistent:
    the loops' rows at a closed assembly), ``lstsq`` where ``Jp^T Jp`` is singular."""
    try:
        return np.linalg.solve(Jp.T @ Jp, Jp.T @ rhs)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(Jp, rhs, rcond=None)[0]


def _newton(model, q, passive, pv, tol, max_iterations):
    """Newton's method on the passive coordinates for ``Phi(q) = 0`` (least squares: dependent
    rows allowed); ``(q, Phi, J)`` at the last step, converged where ``|Phi| <= tol``."""
    q = q.copy()
    for step in range(max_iterations + 1):
        Phi, J = model.positions(q, pv)
        if np.abs(Phi).max(initial=0.0) <= tol or not passive or step == max_iterations:
            break
        dq = _passive_solve(J[:, passive], -Phi)
        q[passive] += dq * min(1.0, 0.5 / max(np.abs(dq).max(), 1e-300))  # at most half a radian a step
    return q, Phi, J


def _assemble(model, q, ind, passive, target, pv, tol, max_iterations, depth=0):
    """The passive coordinates closing the loops with the given ones at ``target``, from ``q``:
    Newton's method, and where it fails, the given coordinates moved there in halves."""
    trial = q.copy()
    trial[ind] = target
    out = _newton(model, trial, passive, pv, tol, max_iterations)
    if np.abs(out[1]).max(initial=0.0) <= tol or depth >= 8:
        return out
    mid, Phi, _ = _assemble(model, q, ind, passive, (q[ind] + target) / 2, pv, tol, max_iterations, depth + 1)
    if np.abs(Phi).max(initial=0.0) > tol:
        return out
    return _assemble(model, mid, ind, passive, target, pv, tol, max_iterations, depth + 1)


def _given_motion(t, q, w, a, names, speeds):
    """The motion given to :func:`closed_chain_inverse`, checked: ``(t, given, ind, qi, wi,
    ai)``, the times, the given coordinates ``{index: values}``, their sorted indices and their
    values, speeds and accelerations (a cubic spline of ``q`` where ``w`` or ``a`` is not given)."""
    t = np.asarray(t, float).reshape(-1)
    if t.size < 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ModelError("the motion's times must be finite and increasing")
    if not isinstance(q, Mapping):
        q = np.asarray(q, float).reshape(t.size, -1)
        if q.shape[1] != len(names):
            raise ModelError(
                f"the motion gives {q.shape[1]} coordinates, the model has {len(names)}",
                hint="give the independent ones by name: q={name: values}",
            )
        q = {nm: q[:, k] for k, nm in enumerate(names)}
    given = _given_columns(q, (names, speeds), "the motion", t.size)
    if not given:
        raise ModelError("the motion gives no coordinate", hint="q={name: values} for the independent coordinates")
    if (w is None or a is None) and t.size < 4:
        raise ModelError(
            "deriving speeds and accelerations from the coordinates needs at least 4 times",
            hint="give the speeds and accelerations, or more rows",
        )
    ind = sorted(given)
    qi = np.column_stack([given[k] for k in ind])
    wi = (
        _spline(t, qi, 1)
        if w is None
        else np.column_stack([_given_columns(w, (names, speeds), "the speeds", t.size)[k] for k in ind])
    )
    ai = (
        _spline(t, wi, 1)
        if a is None
        else np.column_stack([_given_columns(a, (names, speeds), "the accelerations", t.size)[k] for k in ind])
    )
    return t, given, ind, qi, wi, ai


def _drive_columns(model, drives, default_speeds, pv):
    """``(drives, B)``: the drives' names (the model's actuators by default, else
    ``default_speeds``) and ``B``, the generalized forces of a unit drive each (a speed's name
    drives it directly, an actuator's column is ``Q(u = e_j) - Q(u = 0)``)."""
    speeds = model.speed_names
    n = len(model.coordinate_names)
    u0 = np.zeros(len(model.control_names))
    if drives is None:
        drives = list(model.control_names) or list(default_speeds)
    drives = [str(d) for d in drives]
    B = np.zeros((n, len(drives)))
    _, _, _, _, Q0, *_ = model._evaluate_terms(0.0, np.zeros(n), np.zeros(n), pv, u0)
    for j, d in enumerate(drives):
        if d in speeds:
            B[speeds.index(d), j] = 1.0
        elif d in model.control_names:
            u = u0.copy()
            u[model.control_names.index(d)] = 1.0
            B[:, j] = model._evaluate_terms(0.0, np.zeros(n), np.zeros(n), pv, u)[4] - Q0
        else:
            raise ModelError(
                f"unknown drive {d!r}",
                hint="actuators: " + (", ".join(model.control_names) or "none") + "; speeds: " + ", ".join(speeds),
            )
    return drives, B


def _balanced(off, rhs, time, drives, speeds) -> None:
    """Refuse (:class:`ComputationError`, under-actuated) where the least-squares answer of
    ``[B J^T] [tau; lambda] = M a + h - Q`` leaves the residual ``off`` out of balance, naming
    the worst speeds."""
    if np.abs(off).max() > 1e-8 * max(1.0, np.abs(rhs).max()):
        worst = [speeds[i] for i in np.argsort(-np.abs(off))[:3] if abs(off[i]) > 1e-8 * max(1.0, np.abs(rhs).max())]
        raise ComputationError(
            f"at t = {time:.10g} the drives {', '.join(drives)} cannot produce the motion: "
            f"the forces along {', '.join(worst)} stay out of balance (under-actuated)",
            hint="drive more speeds, or prescribe a motion the passive chain can follow",
        )


def closed_chain_inverse(
    model,
    t,
    q,
    w=None,
    a=None,
    drives: Sequence[str] | None = None,
    p=None,
    guess: Mapping[str, float] | None = None,
    tol: float = 1e-11,
    max_iterations: int = 50,
    contacts: Sequence | None = None,
    points: Mapping | None = None,
) -> InverseDynamics:
    """Inverse dynamics of a closed chain along a motion given for its independent coordinates.

    ``model``: an :class:`appell.Mechanism` or its :class:`~appell.numerics.loops.LoopModel`;
    ``q = {coordinate: values}`` at the times ``t`` for the actuated (or any independent)
    coordinates, ``w``, ``a`` likewise for their speeds and accelerations (a cubic spline of
    ``q`` where not given). At each time the passive coordinates ``q_p`` solve the loops'
    position rows ``Phi(q) = 0`` by Newton's method (from the previous time's, at first
    ``guess`` or the model's defaults), then ``J_p w_p = -J_i w_i`` and
    ``J_p a_p = -(J_i a_i + c)``: the motion is consistent at position, speed and
    acceleration. The drive forces ``tau`` and multipliers ``lambda`` solve
    ``[B  J^T] [tau; lambda] = M a + h - Q``: ``B`` maps each drive to the generalized forces
    (``drives``: the model's actuators by default, else the given coordinates' speeds; a
    speed's name drives it directly). Where ``[B J^T]`` has more columns than it determines
    (over-actuated, a planar loop's idle rows), the minimum-norm answer is given and each
    combination left open is named in ``undetermined``; where the drives cannot balance the
    motion (under-actuated) a :class:`ComputationError` names the speeds out of balance.
    Every joint's wrench (``F_<joint>_x .. M_<joint>_z``, world axes, the parent's force and
    moment on the subtree at the joint's point) comes from RNEA's inward pass with the loop
    forces applied at their anchors; those an undetermined combination changes are named in
    ``undetermined_wrenches``.

    ``contacts``: feet or tools held on the ground (:class:`Contact`, or ``'body'``,
    ``'body:weld'``; ``points`` as :func:`contact_model`), each added as loop rows to the world
    at its place at the first time; their multipliers are the ground's forces (and a weld's
    moments), also given in the outputs as ``F_<contact>_x .. M_<contact>_z``. Where the motion
    leaves them open (double support), the minimum-norm answer is given and the combinations
    named in ``undetermined``, as for redundant loops."""
    from appell.numerics.loops import LoopModel, loop_model

    if contacts:
        model = contact_model(model, contacts, points)
    else:
        model = model if isinstance(model, LoopModel) else loop_model(model)
    held = getattr(model, "contacts", ())  # a contact_model's contacts
    names, speeds = model.coordinate_names, model.speed_names
    t, given, ind, qi, wi, ai = _given_motion(t, q, w, a, names, speeds)
    passive = [k for k in range(len(names)) if k not in given]
    pv = model.parameter_values if p is None else np.asarray(p, float)
    cons = model.constraint_names
    n, s = len(names), len(cons)
    u0 = np.zeros(len(model.control_names))
    drives, B = _drive_columns(model, drives, [speeds[k] for k in ind], pv)
    start = {**model.start, **{str(k): float(v) for k, v in (guess or {}).items()}}
    qk = np.array([start.get(nm, 0.0) for nm in names], float)
    if held:  # the contacts held where they are at the first time
        pv = np.concatenate([pv, model.parameter_values[pv.size :]])  # a given p without the contacts' places
        qk[ind] = qi[0]
        qk, pv = _plant(model, held, qk, passive, pv, tol, max_iterations)
    _refuse_nearly_dependent(model, qk, u0, t[0], pv)
    Q_all, W_all, A_all = np.zeros((t.size, n)), np.zeros((t.size, n)), np.zeros((t.size, n))
    tau, lam = np.zeros((t.size, len(drives))), np.zeros((t.size, s))
    wrench_all = np.zeros((t.size, len(model.joints), 6))
    undetermined: tuple = ()
    open_joints: set = set()
    residual = 0.0
    for k in range(t.size):
        if k >= 1 and passive:  # the passive coordinates predicted from the last time's speeds and accelerations
            dt = t[k] - t[k - 1]
            qk[passive] += W_all[k - 1, passive] * dt + A_all[k - 1, passive] * dt**2 / 2
        qk, Phi, J = _assemble(model, qk, ind, passive, qi[k], pv, tol, max_iterations)
        if np.abs(Phi).max(initial=0.0) > tol:
            if k == 0:
                _independent(J, ind, passive, names, model.other_rows)
            worst = cons[int(np.argmax(np.abs(Phi)))]
            raise ComputationError(
                f"at t = {t[k]:.10g} the loops do not close: {worst!r} keeps a residual "
                f"{np.abs(Phi).max():.3g} after Newton's method",
                hint="the given coordinates leave no assembly, or start the passive ones nearer (guess={name: value})",
            )
        if k == 0 and s:
            _independent(J, ind, passive, names, model.other_rows)
        wk = np.zeros(n)
        wk[ind] = wi[k]
        if passive:
            wk[passive] = _passive_solve(J[:, passive], -J[:, ind] @ wi[k])
        M, hQ, Jk, c, pieces = model.blocks(qk, wk, u0, t[k], pv)
        ak = np.zeros(n)
        ak[ind] = ai[k]
        if passive:
            ak[passive] = _passive_solve(Jk[:, passive], -(Jk[:, ind] @ ai[k] + c))
        residual = max(residual, float(np.abs(Jk @ wk).max(initial=0.0)))
        A = np.hstack([B, Jk.T])
        rhs = M @ ak + hQ
        x = np.linalg.lstsq(A, rhs, rcond=1e-10)[0]
        _balanced(A @ x - rhs, rhs, t[k], drives, speeds)
        if k == 0:
            undetermined = _combinations(A, list(drives) + list(cons), 1e-10)
        tau[k], lam[k] = x[: len(drives)], x[len(drives) :]
        wrench_all[k] = model.wrench_array(wk, ak, lam[k], pieces)
        if undetermined and k in (0, t.size - 1):  # the joints on the open rows' loops: checked at both ends
            in_lam = tuple({c: v for c, v in comb.items() if c in cons} for comb in undetermined)
            open_joints |= set(model.open_wrenches(wk, ak, lam[k], pieces, in_lam, wrench_all[k]))
        Q_all[k], W_all[k], A_all[k] = qk, wk, ak
    wrench = {
        f"{f}_{joint}_{x}": wrench_all[:, b, i]
        for b, joint in enumerate(model.joints)
        for i, (f, x) in enumerate((f, x) for f in "FM" for x in "xyz")
    }
    from appell.simulation.recording import acceleration_name

    motion = {
        **{nm: Q_all[:, i] for i, nm in enumerate(names)},
        **{nm: W_all[:, i] for i, nm in enumerate(speeds)},
        **{acceleration_name(nm): A_all[:, i] for i, nm in enumerate(speeds)},
    }
    wrench.update(_contact_wrenches(held, lam, list(cons), pv))
    return InverseDynamics(
        t,
        motion,
        {d: tau[:, j] for j, d in enumerate(drives)},
        {c: lam[:, j] for j, c in enumerate(cons)},
        wrench,
        residual,
        undetermined,
        tuple(j for j in model.joints if j in open_joints),
    )
