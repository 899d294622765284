"""The mechanism builder: bodies, joints, closures, loads -> an :class:`appell.System`.

:class:`Mechanism` collects the parts (:mod:`appell.mechanism.parts`) with checks that name
the culprit; :mod:`appell.mechanism.assembly` builds the System from them (the kinematics by
recursion along the tree of joints, the joint reactions by the subtrees' Newton-Euler balance).
"""

from __future__ import annotations

import keyword

import sympy as sp

from appell.errors import ModelError
from appell.mechanism import assembly
from appell.mechanism.builder_constraints import MechanismConstraints
from appell.mechanism.joints import joint_motion
from appell.mechanism.parts import (
    GROUND,
    Body,
    Frame,
    Joint,
    LoopParts,
    _Action,
    _Closure,
    _cross,
    _matrix,
    _orientation,
    _real,
    _text,
)
from appell.mechanism.rotations import identically_zero, unit_axis
from appell.model import (
    AppliedForce,
    AppliedTorque,
    Parameter,
    System,
)
from appell.rigid_tree import RigidTree
from appell.view import SHAPES


class Mechanism(MechanismConstraints):
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
