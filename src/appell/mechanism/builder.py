"""The mechanism builder: bodies, joints, closures, loads -> an :class:`appell.System`.

:class:`Mechanism` collects the parts (:mod:`appell.mechanism.parts`) with checks that name
the culprit; :mod:`appell.mechanism.assembly` builds the System from them (the kinematics by
recursion along the tree of joints, the joint reactions by the subtrees' Newton-Euler balance).
"""

from __future__ import annotations

import keyword
import warnings

import sympy as sp

from appell.errors import AppellNote, ModelError
from appell.mechanism import assembly
from appell.mechanism.couplings import gear_mesh, rack_mesh
from appell.mechanism.joints import joint_motion
from appell.mechanism.parts import (
    GROUND,
    Body,
    Frame,
    Joint,
    LoopParts,
    _Action,
    _alignment_rows,
    _Closure,
    _cross,
    _loop_points,
    _matrix,
    _orientation,
    _point_rows,
    _real,
    _text,
    _z_onto,
)
from appell.mechanism.rotations import identically_zero, unit_axis
from appell.model import (
    AppliedForce,
    AppliedTorque,
    Parameter,
    System,
    acceleration_constraint,
    holonomic,
    nonholonomic,
)
from appell.rigid_tree import RigidTree
from appell.symbols import derivative_symbol
from appell.view import SHAPES

#: largest expression (``count_ops``) a rolling contact passes through ``trigsimp``: the
#: rolling disc's are at most 43 operations (a few tenths of a second each); the benchmark
#: bicycle's front wheel's reach 1,829 (42 s), which are left as formed
SHORT_OPS = 60


def _rates_short(e):
    """``e``, linear in rates that no function holds (a body's angular velocity in world axes,
    ``R w_body``), with each rate's coefficient through ``trigsimp`` when that is shorter: the
    rolling disc's 43 operations a component become 7. Exact: the coefficients are products of
    sines and cosines, which ``trigsimp`` rewrites by identities (``sin^2 + cos^2 = 1``).
    Only for ``e`` of at most :data:`SHORT_OPS` operations."""
    if sp.count_ops(e) > SHORT_OPS:
        return e
    expanded = sp.expand(e)
    inside = set().union(set(), *(g.free_symbols for g in expanded.atoms(sp.Function)))
    rates = sorted(expanded.free_symbols - inside, key=str)
    parts = sp.collect(expanded, rates, evaluate=False) if rates else {}
    if not parts or any(k != 1 and k not in rates for k in parts):
        return e
    short = sp.Add(*(k * sp.trigsimp(v) for k, v in parts.items()))
    return short if sp.count_ops(short) < sp.count_ops(e) else e


class Mechanism:
    """A multibody mechanism: bodies joined by joints into a tree rooted at :attr:`ground`
    (whose frame is the world frame), closures and contacts, loads; :meth:`system` gives
    the :class:`appell.System` (docs/mechanism.md).

    ``gravity`` is the gravity vector in world axes (entries may be parameter symbols) or None.
    """

    def __init__(self, name: str = "mechanism", gravity=(0, 0, -9.81), description: str = ""):
        if not isinstance(name, str) or not name:
            raise ModelError(f"mechanism name {name!r} must be a non-empty string")
        self.name, self.description = name, description
        self.gravity = None if gravity is None else _matrix(gravity, "gravity")
        self.ground = Body(GROUND, sp.S.Zero, sp.zeros(3, 3), sp.zeros(3, 1))
        self.bodies: list[Body] = []
        self.joints: list[Joint] = []
        self.parameters: list[Parameter] = []
        self._closures: list[_Closure] = []
        self._springs: list[tuple] = []  # (body_a, r_a, body_b, r_b, k, l0): their energy (system(energy=True))
        self._points: list[tuple] = []  # (name, body, r): world positions as outputs (watch_point)
        self._forces: list[tuple[str, object]] = []  # (name, builder(frames) -> (model loads, actions))
        self._drawn: set[str] = set()  # springs, bushings and force pairs: the view draws their force
        self._actuators: list[tuple[str, Joint, sp.Symbol, sp.Expr | None]] = []
        self._names: dict[str, str] = {GROUND: "body"}
        self._shapes: list[tuple] = []  # (body, kind, sizes, origin, rotation, colour, mesh): the view
        self._marks: list[tuple[Body, sp.Matrix]] = []  # body points of closures and loads (the view's bars)
        self._couplings: dict[str, Body] = {}  # tooth meshes: the body whose tooth force is an output
        self._tooth_axes: dict[str, Body | None] = {}  # coupling -> the axes of its tooth force (reaction_output)
        self._drives: list[tuple[str, bool]] = []  # (drive, rotational): its effort is an output
        self._reading: dict[str, tuple] = {}  # joint -> (on, marker body, marker point, axes): reaction_output
        #: the axes of the reactions without a reaction_output of their own (system(reactions_in=...) overrides)
        self.reactions_in: str | None = None

    # ------------------------------------------------------------ naming
    def _claim(self, name, kind: str) -> str:
        if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
            raise ModelError(f"{kind} name {name!r} must be an identifier (letters, digits, underscores)")
        if name in self._names:
            raise ModelError(
                f"{kind} name {name!r} is already used by a {self._names[name]}",
                hint="give every body, joint, closure and load its own name",
            )
        self._names[name] = kind
        return name

    def _body(self, body, what: str) -> Body:
        if isinstance(body, str):
            if body == GROUND:
                return self.ground
            found = next((b for b in self.bodies if b.name == body), None)
            if found is None:
                raise ModelError(
                    f"{what}: unknown body {body!r}",
                    hint="bodies: " + ", ".join([GROUND] + [b.name for b in self.bodies]),
                )
            return found
        if body is self.ground or any(body is b for b in self.bodies):
            return body
        raise ModelError(
            f"{what}: {body!r} is not a body of mechanism {self.name!r}",
            hint="create it with mech.body(...) or mech.particle(...) of this mechanism",
        )

    def _joint(self, joint, what: str) -> Joint:
        name = joint.name if isinstance(joint, Joint) else joint
        found = next((j for j in self.joints if j.name == name), None)
        if found is None:
            raise ModelError(
                f"{what}: unknown joint {name!r}", hint="joints: " + ", ".join(j.name for j in self.joints)
            )
        return found

    # ------------------------------------------------------------ parts
    def parameter(self, name: str, value, unit: str | None = None, description: str | None = None) -> sp.Symbol:
        """A parameter with a default value; returns its symbol for use in masses, lengths, ..."""
        self._claim(name, "parameter")
        p = Parameter(sp.Symbol(name), value, unit, description)
        self.parameters.append(p)
        return p.symbol

    def body(self, name: str, mass, inertia=(0, 0, 0), com=(0, 0, 0)) -> Body:
        """A rigid body: ``mass``, ``inertia`` about the mass centre in body axes (3 principal
        moments or 3x3), mass centre ``com`` in the body frame."""
        self._claim(name, "body")
        mass = _real(mass, f"mass of body {name!r}")
        if mass.is_number and not mass.is_positive:
            raise ModelError(f"body {name!r} has mass {mass}; a mass must be positive")
        I = sp.Matrix(inertia)
        if I.shape in ((3, 1), (1, 3)):
            I = sp.diag(*I)
        if I.shape != (3, 3):
            raise ModelError(f"inertia of body {name!r} must be 3 principal moments or a 3x3 matrix")
        if any(not identically_zero(I[i, j] - I[j, i]) for i in range(3) for j in range(i + 1, 3)):
            raise ModelError(f"inertia of body {name!r} is not symmetric")
        for e in I:
            _real(e, f"inertia of body {name!r}")
        b = Body(name, mass, I.applyfunc(sp.sympify), _matrix(com, f"mass centre of body {name!r}"))
        self.bodies.append(b)
        return b

    def massless(self, name: str) -> Body:
        """A body without mass or inertia: a frame carried between joints (a MuJoCo body with
        several joints, a mount that carries a joint). It moves and bears the reactions of its
        joints, but adds no body to the system (its kinetic energy is zero)."""
        self._claim(name, "body")
        b = Body(name, sp.S.Zero, sp.zeros(3, 3), sp.zeros(3, 1))
        self.bodies.append(b)
        return b

    def particle(self, name: str, mass) -> Body:
        """A point mass (a body without inertia) at its frame's origin."""
        b = self.body(name, mass)
        b = Body(b.name, b.mass, b.inertia, b.com, particle=True)
        self.bodies[-1] = b
        return b

    def shape(
        self, body, kind: str, size, origin=(0, 0, 0), rpy=(0, 0, 0), colour: str | None = None, mesh=None
    ) -> None:
        """Geometry of ``body`` for the picture of the motion (:class:`appell.view.Shape`: a
        ``'box'`` of edges ``size``, a ``'sphere'`` of radius ``size``, a ``'cylinder'`` or
        ``'capsule'`` of ``(radius, length)`` along its z axis), placed at ``origin`` turned by
        the roll-pitch-yaw angles ``rpy`` in the body frame; sizes may be parameters; a
        ``'mesh'`` takes ``mesh = (vertices, faces)`` and no sizes. It does not change the
        dynamics."""
        b = self._body(body, f"shape of {body!r}")
        if kind not in SHAPES:
            raise ModelError(f"shape of body {b.name!r}: {kind!r} is not a shape", hint="shapes: " + ", ".join(SHAPES))
        size = tuple(sp.sympify(v) for v in (size if isinstance(size, (tuple, list)) else (size,)))
        if len(size) != SHAPES[kind]:
            raise ModelError(f"shape of body {b.name!r}: a {kind} takes {SHAPES[kind]} size(s), got {len(size)}")
        rot = _orientation(rpy, f"shape of body {b.name!r}: rpy")
        self._shapes.append((b, kind, size, _matrix(origin, f"shape of body {b.name!r}: origin"), rot, colour, mesh))

    def _add_joint(
        self,
        kind,
        name,
        parent,
        child,
        axis=None,
        origin=(0, 0, 0),
        rpy=(0, 0, 0),
        child_origin=(0, 0, 0),
        coordinate=None,
        rotation="xyz",
    ) -> Joint:
        what = f"{kind} joint {name!r}"
        parent, child = self._body(parent, what), self._body(child, what)
        if child is self.ground:
            raise ModelError(f"{what}: the ground cannot be a joint's child", hint="swap parent and child")
        if child is parent:
            raise ModelError(f"{what}: parent and child are the same body {child.name!r}")
        old = next((j for j in self.joints if j.child is child), None)
        if old is not None:
            raise ModelError(
                f"{what}: body {child.name!r} already hangs on joint {old.name!r}; a second joint "
                "would close a loop of joints",
                hint="close loops with mech.connect(name, (body_a, point_a), (body_b, point_b))",
            )
        up = parent
        while up is not self.ground:
            j = next((j for j in self.joints if j.child is up), None)
            if j is None:
                break
            if j.parent is child:
                raise ModelError(
                    f"{what}: joining {parent.name!r} to {child.name!r} makes a cycle of joints",
                    hint="the joints form a tree; close loops with mech.connect",
                )
            up = j.parent
        if kind == "universal":
            k = tuple(unit_axis(a, f"{what}: axis {i}") for i, a in enumerate(axis, start=1))
            if not identically_zero(k[0].dot(k[1])):
                raise ModelError(
                    f"{what}: the axes {_text(k[0])} and {_text(k[1])} are not perpendicular "
                    f"(cos = {_text(k[0].dot(k[1]))})",
                    hint="a Hooke joint's cross has perpendicular arms, e.g. axes (1, 0, 0) and (0, 1, 0)",
                )
        elif kind == "screw":
            k = (unit_axis(axis[0], what), _real(axis[1], f"{what}: pitch"))
            if k[1].is_number and k[1] == 0:
                raise ModelError(
                    f"{what}: the pitch is 0",
                    hint="a screw of pitch 0 is a revolute joint; give the advance per turn, e.g. pitch=0.005",
                )
        else:
            k = unit_axis(axis, what) if axis is not None else None
        motion = joint_motion(name, kind, k, coordinate, rotation)
        self._claim(name, "joint")
        for q in motion.coordinates:
            if q.name in self._names and q.name != name:
                raise ModelError(f"{what}: coordinate {q.name!r} is already used by a {self._names[q.name]}")
        for q in motion.coordinates:
            if q.name != name:
                self._claim(q.name, "coordinate")
        j = Joint(
            name,
            kind,
            parent,
            child,
            _matrix(origin, f"origin of {what}"),
            _orientation(rpy, f"rpy of {what}"),
            _matrix(child_origin, f"child_origin of {what}"),
            motion,
        )
        self.joints.append(j)
        return j

    def revolute(
        self,
        name,
        parent,
        child,
        axis=(0, 0, 1),
        origin=(0, 0, 0),
        rpy=(0, 0, 0),
        child_origin=(0, 0, 0),
        coordinate=None,
    ) -> Joint:
        """A hinge about the unit ``axis`` (joint frame); coordinate ``coordinate`` (default the
        joint's name), speed ``<coordinate>_dot``."""
        return self._add_joint("revolute", name, parent, child, axis, origin, rpy, child_origin, coordinate)

    def prismatic(
        self,
        name,
        parent,
        child,
        axis=(1, 0, 0),
        origin=(0, 0, 0),
        rpy=(0, 0, 0),
        child_origin=(0, 0, 0),
        coordinate=None,
    ) -> Joint:
        """A slider along the unit ``axis`` (joint frame); coordinate default the joint's name."""
        return self._add_joint("prismatic", name, parent, child, axis, origin, rpy, child_origin, coordinate)

    def fixed(self, name, parent, child, origin=(0, 0, 0), rpy=(0, 0, 0), child_origin=(0, 0, 0)) -> Joint:
        """A weld: no relative motion (its reaction is still reported)."""
        return self._add_joint("fixed", name, parent, child, None, origin, rpy, child_origin)

    def cylindrical(
        self,
        name,
        parent,
        child,
        axis=(0, 0, 1),
        origin=(0, 0, 0),
        rpy=(0, 0, 0),
        child_origin=(0, 0, 0),
        coordinates=None,
    ) -> Joint:
        """Slide along and turn about the unit ``axis``: coordinates ``<name>_z``, ``<name>_rz``."""
        return self._add_joint("cylindrical", name, parent, child, axis, origin, rpy, child_origin, coordinates)

    def planar(
        self, name, parent, child, origin=(0, 0, 0), rpy=(0, 0, 0), child_origin=(0, 0, 0), coordinates=None
    ) -> Joint:
        """Motion in the joint frame's x-y plane: ``<name>_x``, ``<name>_y`` (translation, joint
        axes), then ``<name>_rz`` (rotation about z)."""
        return self._add_joint("planar", name, parent, child, None, origin, rpy, child_origin, coordinates)

    def screw(
        self,
        name,
        parent,
        child,
        pitch,
        axis=(0, 0, 1),
        origin=(0, 0, 0),
        rpy=(0, 0, 0),
        child_origin=(0, 0, 0),
        coordinate=None,
    ) -> Joint:
        """A screw (a lead screw and its nut): the child turns by the coordinate ``q`` about the
        unit ``axis`` and advances ``pitch q / (2 pi)`` along it (``pitch``: the advance per
        turn, negative for a left-hand thread). Ideal threads do no work: the reaction's
        force ``F`` and moment ``M`` along the axis satisfy ``M.k + pitch / (2 pi) F.k = Q``
        (``Q`` an actuator's torque on the coordinate)."""
        return self._add_joint("screw", name, parent, child, (axis, pitch), origin, rpy, child_origin, coordinate)

    def universal(
        self,
        name,
        parent,
        child,
        axes=((1, 0, 0), (0, 1, 0)),
        origin=(0, 0, 0),
        rpy=(0, 0, 0),
        child_origin=(0, 0, 0),
        coordinates=None,
    ) -> Joint:
        """A universal (Hooke, Cardan) joint: the child turns by ``<name>_r1`` about the unit
        ``axes[0]`` (joint frame, fixed in the parent) and by ``<name>_r2`` about ``axes[1]``
        (the cross's other arm, normal to the first, fixed in the child):
        ``R_m = R(k1, q1) R(k2, q2)`` (:mod:`appell.mechanism.joints`). Two coordinates; its
        reaction has four working rows (the force, and the moment normal to both arms)."""
        if not isinstance(axes, (tuple, list)) or len(axes) != 2:
            raise ModelError(
                f"universal joint {name!r}: axes must be two unit vectors, got {axes!r}",
                hint="e.g. axes=((1, 0, 0), (0, 1, 0))",
            )
        return self._add_joint("universal", name, parent, child, tuple(axes), origin, rpy, child_origin, coordinates)

    def spherical(
        self,
        name,
        parent,
        child,
        origin=(0, 0, 0),
        rpy=(0, 0, 0),
        child_origin=(0, 0, 0),
        rotation="xyz",
        coordinates=None,
    ) -> Joint:
        """A ball joint: an intrinsic Euler sequence (``'xyz'``, ``'zyx'``, ``'zxz'``, ...;
        coordinates ``<name>_rx``, ...) or ``'quaternion'`` (``<name>_q0..q3`` with the
        unit-norm holonomic constraint ``<name>_unit``)."""
        return self._add_joint("spherical", name, parent, child, None, origin, rpy, child_origin, coordinates, rotation)

    def free(
        self,
        name,
        parent,
        child,
        origin=(0, 0, 0),
        rpy=(0, 0, 0),
        child_origin=(0, 0, 0),
        rotation="quaternion",
        coordinates=None,
    ) -> Joint:
        """Six degrees of freedom: translation ``<name>_x, _y, _z`` (joint axes) then a
        rotation as in :meth:`spherical` (default a quaternion)."""
        return self._add_joint("free", name, parent, child, None, origin, rpy, child_origin, coordinates, rotation)

    # ------------------------------------------------------------ closures and contacts
    def _point(self, item, what: str) -> tuple[Body, sp.Matrix]:
        if not isinstance(item, (tuple, list)) or len(item) != 2:
            raise ModelError(f"{what}: a point is (body, (x, y, z) in the body frame), got {item!r}")
        return self._body(item[0], what), _matrix(item[1], f"{what}: point")

    def connect(self, name, a, b, directions="xyz", axes=None):
        """Loop closure: the point ``a = (body_a, r_a)`` coincides with ``b = (body_b, r_b)``
        along the world ``directions`` (a subset of ``'xyz'``; along body_a's axes where
        ``axes='a'``: a planar loop carried by a moving body keeps its normal there):
        holonomic constraints ``<name>_<d> = e_d . (r_A - r_B) = 0``; ``lambda_<name>_<d>`` is
        the force of ``body_b`` on ``body_a`` along ``e_d`` (and its opposite on ``body_b``;
        along body_a's axis ``e_d = R_a u_d`` it also turns body_a by ``lambda e_d x (r_A - r_B)``,
        zero where the points meet). The closed-chain route records the rows as
        :class:`~appell.rigid_tree.LoopRow` of kind ``'point'`` or, with ``axes='a'``, ``'point_a'``."""
        if axes not in (None, "a"):
            raise ModelError(f"closure {name!r}: axes must be None (the world's) or 'a' (body_a's), got {axes!r}")
        self._claim(name, "closure")
        what = f"closure {name!r}"
        (ba, ra), (bb, rb) = self._point(a, what), self._point(b, what)
        self._marks += [(ba, ra), (bb, rb)]
        dirs = str(directions)
        if not dirs or any(d not in "xyz" for d in dirs) or len(set(dirs)) != len(dirs):
            raise ModelError(f"{what}: directions {directions!r} must be distinct letters of 'xyz'")

        def build(frames):
            return _point_rows(
                name,
                ba,
                frames[ba].point(ra)[0],
                bb,
                frames[bb].point(rb)[0],
                dirs,
                axes=frames[ba].R if axes == "a" else None,
                gap=assembly.gap_in(self, ba, ra, bb, rb) if axes == "a" else None,
            )

        rows = _loop_points(name, ba, ra, bb, rb, dirs, "point_a" if axes == "a" else "point")
        self._closures.append(_Closure(name, build, rows=rows))

    def weld(self, name, a, b, rotation=None):
        """Loop closure that holds two bodies together: the point ``a = (body_a, r_a)``
        coincides with ``b = (body_b, r_b)`` (holonomic ``<name>_x``, ``_y``, ``_z`` as
        :meth:`connect`) and ``body_b`` keeps the orientation ``R_b = R_a R_ab`` (``rotation``:
        ``R_ab``, 3 x 3, body_b's axes in body_a's; default the identity). With
        ``A = R_a R_ab`` and ``B = R_b``, the three orientation rows are
        ``<name>_rx = (A e_y).(B e_z)``, ``<name>_ry = (A e_z).(B e_x)``,
        ``<name>_rz = (A e_x).(B e_y)``, zero where the orientations agree (independent
        there); ``lambda_<name>_r<i>`` acts as the moment ``lambda (A e_j) x (B e_k)`` on
        ``body_a`` and its opposite on ``body_b`` (the virtual work of a rotation ``dtheta``:
        ``d((A e_j).(B e_k)) = dtheta_a . (A e_j x B e_k)``)."""
        self._claim(name, "closure")
        what = f"weld {name!r}"
        (ba, ra), (bb, rb) = self._point(a, what), self._point(b, what)
        if ba is bb:
            raise ModelError(f"{what}: both points are on body {ba.name!r}", hint="weld two different bodies")
        self._marks += [(ba, ra), (bb, rb)]
        R_ab = sp.eye(3) if rotation is None else _matrix(rotation, f"{what}: rotation", shape=(3, 3))

        def build(frames):
            fa, fb = frames[ba], frames[bb]
            pa, pb = fa.point(ra)[0], fb.point(rb)[0]
            A, B = fa.R * R_ab, fb.R
            cons, acts = _point_rows(name, ba, pa, bb, pb)
            more, turn = _alignment_rows(
                [(f"{name}_r{d}", A[:, j], B[:, k]) for d, (j, k) in zip("xyz", ((1, 2), (2, 0), (0, 1)))],
                ba,
                pa,
                bb,
                pb,
            )
            return cons + more, acts + turn

        rows = _loop_points(name, ba, ra, bb, rb, "xyz") + tuple(
            (f"{name}_r{d}", "align", ba, ra, R_ab[:, j], bb, rb, sp.eye(3)[:, k])
            for d, (j, k) in zip("xyz", ((1, 2), (2, 0), (0, 1)))
        )
        self._closures.append(_Closure(name, build, rows=rows))

    def watch_point(self, name, point):
        """Outputs ``<name>_x``, ``_y``, ``_z``: the world position of the body point
        ``point = (body, r)`` (``r`` in the body frame), in every result."""
        what = f"point {name!r}"
        if not isinstance(name, str) or not name.isidentifier():
            raise ModelError(f"{what}: a point's name is a letter or _ followed by letters, digits or _")
        if any(p[0] == name for p in self._points):
            raise ModelError(f"{what} is given twice", hint="give each watched point its own name")
        body, r = self._point(point, what)
        self._points.append((name, body, r))

    def hinge(self, name, a, b, axis, axis_b=None):
        """Loop closure by a revolute joint: the point ``a = (body_a, r_a)`` coincides with
        ``b = (body_b, r_b)`` (``<name>_x``, ``_y``, ``_z`` as :meth:`connect`) and the hinge
        axis ``axis`` fixed in body_a stays along ``axis_b`` fixed in body_b (default the
        same components: the two frames parallel where the loop closes). With ``a`` the
        axis in the world, ``b1``, ``b2`` two unit vectors of body_b normal to ``axis_b``
        (``b1`` normal to the body axis least aligned with it, ``b2 = axis_b x b1``), the rows
        ``<name>_r1 = a . b1`` and ``<name>_r2 = a . b2``; ``lambda_<name>_r<k>`` acts as the
        moment ``lambda a x b_k`` on body_a (normal to the axis: an ideal hinge carries no
        moment about it) and its opposite on body_b. Rows that hold identically — the
        out-of-plane point row and both axis rows of a planar loop — are left out with a
        note, so that a planar loop is closed by the joint it has without redundant rows."""
        self._claim(name, "closure")
        what = f"hinge {name!r}"
        (ba, ra), (bb, rb) = self._point(a, what), self._point(b, what)
        if ba is bb:
            raise ModelError(f"{what}: both points are on body {ba.name!r}", hint="join two different bodies")
        self._marks += [(ba, ra), (bb, rb)]
        u = unit_axis(axis, f"{what}: axis")
        v = u if axis_b is None else unit_axis(axis_b, f"{what}: axis_b")
        numbers = [abs(float(x)) if not x.free_symbols else 0.0 for x in v]
        least = sp.Matrix([1 if k == numbers.index(min(numbers)) else 0 for k in range(3)])
        b1 = _cross(v, least)
        b1 = b1 / sp.sqrt(b1.dot(b1))
        b2 = _cross(v, b1)

        def build(frames):
            fa, fb = frames[ba], frames[bb]
            pa, pb = fa.point(ra)[0], fb.point(rb)[0]
            along, idle = fa.R * u, []
            cons, acts = _point_rows(name, ba, pa, bb, pb, idle=idle)
            more, turn = _alignment_rows(
                [(f"{name}_r1", along, fb.R * b1), (f"{name}_r2", along, fb.R * b2)], ba, pa, bb, pb, idle=idle
            )
            cons, acts = cons + more, acts + turn
            if idle:
                warnings.warn(
                    AppellNote(
                        f"{what}: {', '.join(idle)} hold at every configuration (a planar loop) and are left out"
                    ),
                    stacklevel=2,
                )
            return cons, acts

        rows = _loop_points(name, ba, ra, bb, rb, "xyz") + (
            (f"{name}_r1", "align", ba, ra, u, bb, rb, b1),
            (f"{name}_r2", "align", ba, ra, u, bb, rb, b2),
        )
        self._closures.append(_Closure(name, build, rows=rows))

    def point_on_surface(self, name, point, surface):
        """The body point ``point = (body, r)`` stays on the surface ``s(x, y, z) = 0`` (world
        coordinates; ``surface`` an expression in the symbols ``x``, ``y``, ``z`` or a callable):
        the holonomic constraint ``<name>``; its force on the body is ``lambda grad s``."""
        self._claim(name, "closure")
        what = f"contact {name!r}"
        body, r = self._point(point, what)
        self._marks.append((body, r))
        X = sp.symbols("x y z")
        expr = surface(*X) if callable(surface) else sp.sympify(surface)
        if not isinstance(expr, sp.Expr) or not expr.free_symbols & set(X):
            raise ModelError(f"{what}: the surface {surface!r} must be an expression in x, y, z")
        grad = sp.Matrix([sp.diff(expr, x) for x in X])

        def build(frames):
            p = frames[body].point(r)[0]
            at = dict(zip(X, p))
            c = holonomic(name, expr.xreplace(at))
            return [c], [_Action(body, p, grad.xreplace(at) * sp.Symbol(f"lambda_{name}"), sp.zeros(3, 1))]

        self._closures.append(_Closure(name, build))

    def _plane(self, normal, what):
        n = unit_axis(normal, f"{what}: normal")
        helper = sp.Matrix([1, 0, 0]) if abs(float(n[0])) < 0.9 else sp.Matrix([0, 1, 0])
        t1 = n.cross(helper)
        t1 = t1 / sp.sqrt(t1.dot(t1))
        return n, t1, n.cross(t1)

    def _rolling(self, name, body, contact, normal, height, what):
        """Constraints of a body touching the plane ``n.x = height``: ``contact(frame, n)``
        gives ``(d, z)``, the contact point P relative to the body origin (world axes) and
        the height of P above the origin's projection along n (so that the holonomic
        ``<name>_n`` is ``n.p + z - height``); no slip ``<name>_t1``, ``<name>_t2`` is
        ``t_k . v_P = 0`` (v_P the velocity of the body's material point at P); forces
        ``lambda n``, ``lambda t_k`` at P."""
        n, t1, t2 = self._plane(normal, what)
        height = sp.sympify(height)

        def build(frames):
            f = frames[body]
            d, z = contact(f, n)
            vP = f.v + _cross(f.w.applyfunc(_rates_short), d)
            P = f.p + d
            cons = [
                holonomic(f"{name}_n", n.dot(f.p) + z - height),
                nonholonomic(f"{name}_t1", t1.dot(vP)),
                nonholonomic(f"{name}_t2", t2.dot(vP)),
            ]
            acts = [
                _Action(body, P, v * sp.Symbol(f"lambda_{c.name}"), sp.zeros(3, 1)) for v, c in zip((n, t1, t2), cons)
            ]
            return cons, acts

        self._closures.append(_Closure(name, build))

    def locate(self, name: str, where: str) -> None:
        """Record ``where`` (file and line) as the origin of the closure or contact ``name``:
        its constraints carry it into error messages."""
        for k, closure in enumerate(self._closures):
            if closure.name == name:
                self._closures[k] = _Closure(closure.name, closure.build, where, closure.rows)
                return
        raise ModelError(f"mechanism {self.name!r}: no closure or contact {name!r}", where=where)

    def rolling_disc(self, name, body, radius, axis=(0, 1, 0), normal=(0, 0, 1), height=0):
        """A thin disc (centre at the body frame's origin, symmetry ``axis`` in body axes) rolls
        without slip on the plane ``normal . x = height``: with ``a`` the disc's axis in world
        axes, ``s = n.a`` and ``u = n - a s``, the contact point is ``P = C - r u / |u|``
        (the rim point nearest the plane; ``|u| = sqrt(1 - s^2)``) and its height
        ``n.C - r (1 - s^2) / |u|``;
        constraints ``<name>_n`` (the height of P), ``<name>_t1``, ``<name>_t2`` (no slip).
        Singular where the disc lies flat (s = +-1)."""
        self._claim(name, "contact")
        what = f"rolling disc {name!r}"
        b = self._body(body, what)
        k = unit_axis(axis, f"{what}: axis")
        r = sp.sympify(radius)
        self._shapes.append((b, "cylinder", (r, r / 10), sp.zeros(3, 1), _z_onto(k), None, None))
        for spoke in ((1.8 * r, r / 12, r / 8), (r / 12, 1.8 * r, r / 8)):  # two spokes: the spin shows
            self._shapes.append((b, "box", spoke, sp.zeros(3, 1), _z_onto(k), "#444444", None))

        def contact(f, n):
            a = f.R * k
            s = n.dot(a)
            u = n - a * s
            square = u.dot(u)  # = 1 - s^2 where |a| = 1 (the rotation's entries say so: a shorter root)
            norm = a.dot(a)
            if sp.count_ops(norm) <= SHORT_OPS and sp.trigsimp(norm) == 1:
                square = 1 - s**2
            root = sp.sqrt(square)  # a norm, real at any point
            return -r * u / root, -r * (1 - s**2) / root

        self._rolling(name, b, contact, normal, height, what)

    def rolling_sphere(self, name, body, radius, normal=(0, 0, 1), height=0):
        """A sphere (centre at the body frame's origin) rolls without slip on the plane
        ``normal . x = height``: contact P = C - r n; constraints as :meth:`rolling_disc`."""
        self._claim(name, "contact")
        what = f"rolling sphere {name!r}"
        b = self._body(body, what)
        r = sp.sympify(radius)
        self._shapes.append((b, "sphere", (r,), sp.zeros(3, 1), sp.eye(3), None, None))
        self._rolling(name, b, lambda f, n: (-r * n, -r), normal, height, what)

    def no_lateral_slip(self, name, point, direction):
        """A knife edge or wheel: the body point ``point = (body, r)`` has no velocity along
        the body-fixed unit ``direction`` (first-order constraint ``<name>``, force
        ``lambda R d`` at the point)."""
        self._claim(name, "contact")
        what = f"no-slip contact {name!r}"
        body, r = self._point(point, what)
        self._marks.append((body, r))
        d = unit_axis(direction, f"{what}: direction")

        def build(frames):
            f = frames[body]
            dw = f.R * d
            p, v, _ = f.point(r)
            c = nonholonomic(name, dw.dot(v))
            return [c], [_Action(body, p, dw * sp.Symbol(f"lambda_{name}"), sp.zeros(3, 1))]

        self._closures.append(_Closure(name, build))

    def _mesh(self, name, ja, jb, mesh_of, what):
        """A tooth mesh (:mod:`appell.mechanism.couplings`) as a closure: the row
        ``<name> = c_a q_a - c_b q_b``; the tooth force ``f_A`` on the child of ``ja`` at the
        pitch point and ``-f_A`` on the child of ``jb``, so that their bearings and guides
        carry it (the outputs ``F_<name>_x .. _z``: the force on the child of ``jb``)."""
        self._claim(name, "coupling")
        ja, jb = self._joint(ja, what), self._joint(jb, what)
        mesh = mesh_of(ja, jb)
        housing = ja.parent
        self._couplings[name] = jb.child

        def build(frames):
            h = frames[housing]
            P = h.p + h.R * mesh.pitch_point
            c = holonomic(name, mesh.row(ja.coordinates[0], jb.coordinates[0]))
            f = h.R * mesh.force_on_pinion(sp.Symbol(f"lambda_{name}"))
            return [c], [_Action(ja.child, P, f, sp.zeros(3, 1)), _Action(jb.child, P, -f, sp.zeros(3, 1))]

        self._closures.append(_Closure(name, build))

    def gear(self, name, joint_a, joint_b, ratio, internal=False, pressure_angle=0, helix_angle=0):
        """Two gears on the revolute joints ``joint_a`` and ``joint_b`` (parallel axes, mounted
        in the same body) mesh: ``ratio = r_b / r_a`` (teeth of b over teeth of a), the pitch
        radii from the joints' centre distance ``d``, ``r_a = d / (1 + ratio)`` (``internal``:
        b is a ring gear, ``r_a = d / (ratio - 1)``); they mesh in the plane of ``joint_a``'s
        origin. The holonomic row ``<name>`` and its tooth force at the pitch point along the
        line of action (``pressure_angle``, ``helix_angle`` in radians):
        :mod:`appell.mechanism.couplings`. ``lambda_<name>`` is the tangential tooth force on
        the gear of ``joint_a``; each joint's reaction is its bearing load."""
        what = f"gear {name!r}"
        self._mesh(
            name,
            joint_a,
            joint_b,
            lambda ja, jb: gear_mesh(what, ja, jb, ratio, bool(internal), pressure_angle, helix_angle),
            what,
        )

    def rack_pinion(self, name, pinion, rack, radius, pressure_angle=0, helix_angle=0):
        """A pinion on the revolute joint ``pinion`` (pitch radius ``radius``) drives a rack on
        the prismatic joint ``rack`` (normal to the pinion's axis, mounted in the same body):
        the holonomic row ``<name> = r theta - (t . u) s`` and its tooth force at the pitch
        point, on the side of the pinion facing the rack's line (through the rack joint's
        origin), along the line of action: :mod:`appell.mechanism.couplings`.
        ``lambda_<name>`` is the tangential tooth force on the pinion; the rack joint's
        reaction is the guide's load."""
        what = f"rack and pinion {name!r}"
        self._mesh(
            name, pinion, rack, lambda ja, jb: rack_mesh(what, ja, jb, radius, pressure_angle, helix_angle), what
        )

    def distance(self, name, a, b, length):
        """The points ``a = (body_a, r_a)`` and ``b = (body_b, r_b)`` keep the distance
        ``length`` (a number, a parameter or an expression in ``t``: a driven distance, a
        linear actuator): the holonomic ``<name> = |d| - L``, ``d = r_A - r_B``;
        ``lambda_<name>`` is the force of b on a along ``d / |d|`` (positive pushes them
        apart; a linear actuator's force), its opposite on b. ``L`` must not vanish (the
        direction is undefined there: join coinciding points with :meth:`connect`)."""
        self._claim(name, "closure")
        what = f"distance {name!r}"
        (ba, ra), (bb, rb) = self._point(a, what), self._point(b, what)
        if ba is bb:
            raise ModelError(f"{what}: both points are on body {ba.name!r}", hint="join two different bodies")
        L = _real(length, f"{what}: length")
        if L.is_number and not L > 0:
            raise ModelError(
                f"{what}: the length is {L}; a distance must be positive",
                hint="join coinciding points with connect(...)",
            )
        self._marks += [(ba, ra), (bb, rb)]

        def build(frames):
            pa, pb = frames[ba].point(ra)[0], frames[bb].point(rb)[0]
            d = pa - pb
            length_now = sp.sqrt(d.dot(d))
            f = d / length_now * sp.Symbol(f"lambda_{name}")
            return [holonomic(name, length_now - L)], [
                _Action(ba, pa, f, sp.zeros(3, 1)),
                _Action(bb, pb, -f, sp.zeros(3, 1)),
            ]

        self._closures.append(_Closure(name, build))

    def drive(self, name, joint, position=None, speed=None, acceleration=None, coordinate=None):
        """A joint drive: the joint coordinate ``q`` (``coordinate``; the joint's only one by
        default) follows a prescribed ``position`` (holonomic ``<name> = q - f(t)``), ``speed``
        (first order ``q' - v(t)``) or ``acceleration`` (second order ``q'' - a(t)``),
        expressions in ``t`` and the parameters (exactly one of them). Its multiplier
        ``lambda_<name>``, by its own formula (1.5), is the drive's force or torque along the
        coordinate (the output ``<name>_effort``); it acts in the joint like an actuator (the
        joint's reaction includes it)."""
        self._claim(name, "drive")
        what = f"drive {name!r}"
        given = [
            (k, v)
            for k, v in (("position", position), ("speed", speed), ("acceleration", acceleration))
            if v is not None
        ]
        if len(given) != 1:
            raise ModelError(
                f"{what}: give exactly one of position, speed, acceleration (got "
                f"{', '.join(k for k, _ in given) or 'none'})",
                hint="e.g. speed='v*t'",
            )
        kind, value = given[0]
        j = self._joint(joint, what)
        q = self._coordinate(j, coordinate, what)
        value = _real(value, f"{what}: {kind}")
        if kind == "position":
            c = holonomic(name, q - value)
        elif kind == "speed":
            c = nonholonomic(name, derivative_symbol(q) - value)
        else:
            c = acceleration_constraint(name, derivative_symbol(q, 2) - value)
        rotational = j.motion.translation.diff(q) == sp.zeros(3, 1)
        self._drives.append((name, rotational))
        self._closures.append(_Closure(name, lambda frames: ([c], [])))

    def _coordinate(self, j: Joint, coordinate, what: str) -> sp.Symbol:
        if coordinate is None:
            if len(j.coordinates) != 1:
                raise ModelError(
                    f"{what}: joint {j.name!r} has {len(j.coordinates)} coordinates",
                    hint="name one: coordinate=" + " or ".join(repr(q.name) for q in j.coordinates),
                )
            return j.coordinates[0]
        q = next((s for s in j.coordinates if s.name == str(coordinate)), None)
        if q is None:
            raise ModelError(
                f"{what}: joint {j.name!r} has no coordinate {coordinate!r}",
                hint="coordinates: " + ", ".join(s.name for s in j.coordinates),
            )
        return q

    # ------------------------------------------------------------ loads
    def force(self, name, point, vector, axes="world"):
        """A force ``vector`` (world axes, or the body's with ``axes="body"``; expressions in t,
        q, speeds, parameters) at the body point ``point = (body, r)``."""
        self._claim(name, "load")
        body, r = self._point(point, f"force {name!r}")
        if axes not in ("world", "body"):
            raise ModelError(f"force {name!r}: axes {axes!r} must be 'world' or 'body'")
        self._marks.append((body, r))
        given = _matrix(vector, f"force {name!r}")

        def build(frames):
            p, v, _ = frames[body].point(r)
            f = frames[body].R * given if axes == "body" else given
            return [AppliedForce(f, position=p, velocity=v, name=name)], [_Action(body, p, f, sp.zeros(3, 1))]

        self._forces.append((name, build))

    def torque(self, name, body, vector, axes="world"):
        """A torque ``vector`` (world axes, or the body's with ``axes="body"``) on ``body``."""
        self._claim(name, "load")
        b = self._body(body, f"torque {name!r}")
        if axes not in ("world", "body"):
            raise ModelError(f"torque {name!r}: axes {axes!r} must be 'world' or 'body'")
        given = _matrix(vector, f"torque {name!r}")

        def build(frames):
            f = frames[b]
            if axes == "body":
                return [AppliedTorque(given, f.omega, name=name)], [_Action(b, None, sp.zeros(3, 1), f.R * given)]
            return [AppliedTorque(f.R.T * given, f.omega, name=name)], [_Action(b, None, sp.zeros(3, 1), given)]

        self._forces.append((name, build))

    def spring(self, name, a, b, stiffness, rest_length=0, damping=0):
        """A spring-damper between the points ``a = (body_a, r_a)`` and ``b``: tension
        ``k (l - l0) + c dl/dt`` pulling them together (``l`` their distance). With the rest
        length ``l0 = 0`` (a centring spring, a bushing's translation) the force on ``a`` is
        ``-k d - c (v_a - v_b)``, ``d = r_A - r_B``: defined where the ends meet, where the
        direction of the spring is not."""
        self._claim(name, "load")
        what = f"spring {name!r}"
        (ba, ra), (bb, rb) = self._point(a, what), self._point(b, what)
        self._marks += [(ba, ra), (bb, rb)]
        k, l0, c = (sp.sympify(v) for v in (stiffness, rest_length, damping))
        self._springs.append((ba, ra, bb, rb, k, l0))
        self._drawn.add(name)

        def build(frames):
            pa, va, _ = frames[ba].point(ra)
            pb, vb, _ = frames[bb].point(rb)
            d = pa - pb
            if l0 == 0:
                f = -k * d - c * (va - vb)  # on a
            else:
                length = sp.sqrt(d.dot(d))
                tension = k * (length - l0) + c * d.dot(va - vb) / length
                f = -tension * d / length  # on a
            loads = [
                AppliedForce(f, position=pa, velocity=va, name=f"{name}_a"),
                AppliedForce(-f, position=pb, velocity=vb, name=f"{name}_b"),
            ]
            return loads, [_Action(ba, pa, f, sp.zeros(3, 1)), _Action(bb, pb, -f, sp.zeros(3, 1))]

        self._forces.append((name, build))

    def reaction_output(self, joint, on="child", about=None, axes="world"):
        """Where the reaction outputs ``F_<joint>_*``, ``M_<joint>_*`` are read: the force and
        moment ``on`` the joint's ``"child"`` (of the parent: the default) or its ``"parent"``
        (of the child: both negated); ``about`` a marker ``(body, r)``, a point fixed in a
        body (``r`` in its frame; default the joint origin ``O``): ``M_P = M_O + (O - P) x F``;
        along the ``axes`` of ``"world"`` (``"ground"``), a body (its name), ``"joint"`` (the
        joint frame fixed in the parent, ``R_parent R0``: a bearing's housing), ``"child"`` or
        ``"parent"``. The recursive route then leaves these outputs to their formulas.

        For a gear or rack coupling (``joint`` its name) only ``axes`` applies: ``"world"`` or a
        body's name, the axes of its tooth force ``F_<coupling>_*`` (on the second body, at the
        pitch point)."""
        if isinstance(joint, str) and joint in self._couplings:
            what = f"reaction output of coupling {joint!r}"
            if on != "child" or about is not None:
                raise ModelError(
                    f"{what}: a tooth force is read on its second body at the pitch point",
                    hint="give only axes ('world' or a body's name)",
                )
            try:
                body = None if axes in ("world", "ground", None) else self._body(axes, what)
            except ModelError as exc:
                raise ModelError(f"{exc.message}; a coupling's axes are 'world' or a body", hint=exc.hint) from None
            self._tooth_axes[joint] = None if body is self.ground else body
            return
        j = self._joint(joint, "reaction output")
        what = f"reaction output of joint {j.name!r}"
        if on not in ("child", "parent"):
            raise ModelError(
                f"{what}: on={on!r} must be 'child' or 'parent'",
                hint=f"the reaction on {j.child.name!r} (child) or on {j.parent.name!r} (parent)",
            )
        marker = None if about is None else self._point(about, f"{what}: about")
        self._axes_of(j, axes, what)
        self._reading[j.name] = (on, marker, axes)

    def _axes_of(self, j: Joint, axes, what: str):
        """The body whose axes ``axes`` names for joint ``j`` (None: the world), or ``"joint"``."""
        if axes in ("world", "ground", None):
            return None
        if axes == "joint":
            return "joint"
        if axes == "child":
            return j.child
        if axes == "parent":
            return None if j.parent is self.ground else j.parent
        try:
            body = self._body(axes, what)
        except ModelError as exc:
            raise ModelError(
                f"{exc.message}; axes are 'world', 'joint', 'child', 'parent' or a body", hint=exc.hint
            ) from None
        return None if body is self.ground else body

    def _pair_loads(self, name, ba, ra, bb, rb, frames, f_b, tau_b):
        """Model loads and actions of a force ``f_b`` at ``b``'s point and a torque ``tau_b`` on
        ``b`` (world axes) with their reaction on ``a``: ``-f_b`` at ``a``'s point and
        ``-tau_b - (r_B - r_A) x f_b`` (equal, opposite and of zero total moment)."""
        fa, fb = frames[ba], frames[bb]
        pa, va, _ = fa.point(ra)
        pb, vb, _ = fb.point(rb)
        tau_a = -tau_b - _cross(pb - pa, f_b)
        loads = [
            AppliedForce(f_b, position=pb, velocity=vb, name=f"{name}_b"),
            AppliedForce(-f_b, position=pa, velocity=va, name=f"{name}_a"),
        ]
        acts = [_Action(bb, pb, f_b, tau_b), _Action(ba, pa, -f_b, tau_a)]
        for body, frame, tau in ((bb, fb, tau_b), (ba, fa, tau_a)):
            if any(x != 0 for x in tau) and body is not self.ground:
                loads.append(AppliedTorque(frame.R.T * tau, frame.omega, name=f"{name}_{body.name}"))
        return loads, acts

    def force_pair(self, name, a, b, force=(0, 0, 0), torque=(0, 0, 0), axes="world"):
        """A general force element between two markers ``a = (body_a, r_a)`` and ``b``: the
        force ``force`` at b's point and the torque ``torque`` on body_b (expressions in t, the
        coordinates, speeds and parameters; components along the world axes, or along
        body_a's with ``axes="a"``), and on body_a their reaction: ``-force`` at a's point and
        ``-torque - (r_B - r_A) x force``."""
        self._claim(name, "load")
        what = f"force element {name!r}"
        (ba, ra), (bb, rb) = self._point(a, what), self._point(b, what)
        if ba is bb:
            raise ModelError(f"{what}: both markers are on body {ba.name!r}", hint="join two different bodies")
        if axes not in ("world", "a"):
            raise ModelError(f"{what}: axes {axes!r} must be 'world' or 'a'")
        self._marks += [(ba, ra), (bb, rb)]
        self._drawn.add(name)
        f, tau = _matrix(force, f"{what}: force"), _matrix(torque, f"{what}: torque")

        def build(frames):
            R = frames[ba].R if axes == "a" else sp.eye(3)
            return self._pair_loads(name, ba, ra, bb, rb, frames, R * f, R * tau)

        self._forces.append((name, build))

    def bushing(
        self,
        name,
        a,
        b,
        stiffness,
        damping=(0, 0, 0),
        rotational_stiffness=(0, 0, 0),
        rotational_damping=(0, 0, 0),
        rotation=None,
    ):
        """A bushing: a six-component linear spring-damper between the frame ``A`` at the
        marker ``a = (body_a, r_a)`` (axes ``R_A = R_a R_0``, ``rotation``: ``R_0``, 3x3 or
        roll-pitch-yaw, default the body's axes) and the frame ``B`` at the marker ``b`` on
        body_b (axes ``R_B = R_b R_0``: at rest where the bodies' axes agree). In A's axes,
        with ``d = R_A^T (r_B - r_A)``, its rate
        ``d' = R_A^T (v_B - v_A - w_a x (r_B - r_A))``, ``theta = vex(R - R^T) / 2`` of
        ``R = R_A^T R_B`` (the rotation angle's sine along its axis) and
        ``omega = R_A^T (w_b - w_a)``: the force on b ``f = -K d - C d'`` and the torque
        ``tau = -K_r theta - C_r omega`` (K, C, K_r, C_r: three diagonal entries or 3x3),
        on a their reaction (:meth:`force_pair`)."""
        self._claim(name, "load")
        what = f"bushing {name!r}"
        (ba, ra), (bb, rb) = self._point(a, what), self._point(b, what)
        if ba is bb:
            raise ModelError(f"{what}: both markers are on body {ba.name!r}", hint="join two different bodies")
        self._marks += [(ba, ra), (bb, rb)]
        self._drawn.add(name)

        def gains(value, key):
            m = sp.Matrix(value)
            return (
                sp.diag(*_matrix(value, f"{what}: {key}"))
                if m.shape in ((3, 1), (1, 3))
                else _matrix(value, f"{what}: {key}", shape=(3, 3))
            )

        K, C, Kr, Cr = (
            gains(v, k)
            for v, k in (
                (stiffness, "stiffness"),
                (damping, "damping"),
                (rotational_stiffness, "rotational_stiffness"),
                (rotational_damping, "rotational_damping"),
            )
        )
        R0 = sp.eye(3) if rotation is None else _orientation(rotation, f"{what}: rotation")

        def build(frames):
            fa, fb = frames[ba], frames[bb]
            RA = fa.R * R0
            pa, va, _ = fa.point(ra)
            pb, vb, _ = fb.point(rb)
            d = pb - pa
            R = RA.T * fb.R * R0
            theta = sp.Matrix([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2
            f = -K * (RA.T * d) - C * (RA.T * (vb - va - _cross(fa.w, d)))
            tau = -Kr * theta - Cr * (RA.T * (fb.w - fa.w))
            return self._pair_loads(name, ba, ra, bb, rb, frames, RA * f, RA * tau)

        self._forces.append((name, build))

    def actuator(self, name, joint, value=None, coordinate=None) -> sp.Symbol:
        """A generalized force (force or torque) along a joint coordinate (``coordinate``; the
        joint's only one by default): ``value`` an expression in t, q, speeds and parameters,
        or None for a force :class:`~appell.model.Control` named ``name`` (for servo
        constraints). Returns the control's symbol (or ``value``)."""
        self._claim(name, "actuator")
        j = self._joint(joint, f"actuator {name!r}")
        q = self._coordinate(j, coordinate, f"actuator {name!r}")
        sym = sp.Symbol(name)
        self._actuators.append((name, j, q, None if value is None else sp.sympify(value)))
        return sym if value is None else sp.sympify(value)

    # ------------------------------------------------------------ the system (mechanism/assembly.py)
    def frames(self) -> dict[Body, Frame]:
        """The :class:`Frame` of every body (:func:`appell.mechanism.assembly.body_frames`)."""
        return assembly.body_frames(self)

    def rigid_tree(self, coordinates, potential=sp.S.Zero, positions=None, wrenches=(), loops=()) -> RigidTree | None:
        """The :class:`~appell.rigid_tree.RigidTree` of the bodies for the recursive route, or None
        (:func:`appell.mechanism.assembly.rigid_tree` states the arguments and the blocks)."""
        return assembly.rigid_tree(self, coordinates, potential, positions, wrenches, loops)

    def loop_parts(self) -> LoopParts:
        """What the closed-chain route (:mod:`appell.numerics.loops`) takes
        (:func:`appell.mechanism.assembly.loop_parts`)."""
        return assembly.loop_parts(self)

    def subtree(self, joint: Joint) -> list[Body]:
        """The bodies carried by ``joint``: its child and all the child's descendants."""
        return assembly.subtree(self, joint)

    def reactions(self, frames, actions) -> dict[Joint, tuple[sp.Matrix, sp.Matrix]]:
        """``{joint: (F, M)}``: force and moment (world axes) of the parent on the child of each
        joint at the joint origin (:func:`appell.mechanism.assembly.joint_reactions`)."""
        return assembly.joint_reactions(self, frames, actions)

    def system(
        self,
        parameters=None,
        initial=None,
        reactions="all",
        frame=None,
        settings=(),
        units=None,
        constraints=(),
        controls=(),
        servo_constraints=(),
        outputs=(),
        force_unit="N",
        moment_unit="N*m",
        energy: bool = False,
        reactions_in=None,
        joint_forces=None,
        rotor_energy=None,
        programs=(),
    ) -> System:
        """The :class:`appell.System` of the mechanism.

        Parameters
        ----------
        parameters : ``{name: value}`` overriding the parameters' default values.
        initial : initial values ``{name: value}`` of coordinates and speeds; the others start
            at zero (a quaternion at the identity, q0 = 1) as starting guesses
            (``System.initial_guesses``): where they violate a closure or contact, the
            simulation computes them from the constraints, never changing a given value.
        reactions : ``'all'`` (every joint), a list of joint names, or None: six outputs
            ``F_<joint>_x .. F_<joint>_z``, ``M_<joint>_x .. M_<joint>_z`` each, the force and
            moment of the parent on the child at the joint origin.
        frame : ``{joint: body}``: give that joint's components along the body's axes (default
            world axes).
        reactions_in : the axes of every joint's reaction without a :meth:`reaction_output`
            or ``frame`` of its own: ``'world'``/``'ground'`` (the default), ``'joint'``,
            ``'child'``, ``'parent'`` or a body's name (``appell ... --reactions-in``).
        constraints, controls, servo_constraints, outputs, settings, units : added as given
            (constraints written in joint coordinates act as generalized forces at the
            joints, not through the reactions' cuts: docs/mechanism.md).
        energy : add the outputs ``energy_kinetic`` (the bodies' ``m v.v/2 + w.I w/2``),
            ``energy_potential`` (gravity and the springs' ``k (l - l0)^2/2``) and ``energy``,
            their sum, constant where no damper, actuator or time-dependent load acts. The
            points of :meth:`watch_point` are outputs too.
        joint_forces : ``{coordinate name: Q}``: generalized forces added along the speeds of
            those coordinates (a joint's damper, spring or actuator, MJCF's passive forces),
            acting between the joint's parent and child (inside its reaction).
        rotor_energy : a kinetic energy ``T(q, w)`` added to the bodies' (the reflected inertia
            of rotors, MJCF's ``armature``: ``sum a_k w_k^2 / 2``); the system then takes the
            expanded route.
        programs : :class:`~appell.model.Program` items (given functions of time, e.g. an
            actuator's control signal), added as given.
        """
        return assembly.system(
            self,
            parameters=parameters,
            initial=initial,
            reactions=reactions,
            frame=frame,
            settings=settings,
            units=units,
            constraints=constraints,
            controls=controls,
            servo_constraints=servo_constraints,
            outputs=outputs,
            force_unit=force_unit,
            moment_unit=moment_unit,
            energy=energy,
            reactions_in=reactions_in,
            joint_forces=joint_forces,
            rotor_energy=rotor_energy,
            programs=programs,
        )
