"""The closures, contacts, couplings and drives of :class:`~appell.mechanism.Mechanism`
(its base :class:`MechanismConstraints`): each method adds named constraints (holonomic,
nonholonomic or in acceleration form) between points, frames or joints of the mechanism's
bodies, checked with messages that name the culprit. The bodies, joints and loads are
:mod:`appell.mechanism.builder`'s.
"""

from __future__ import annotations

import warnings

import sympy as sp

from appell.errors import AppellNote, ModelError
from appell.mechanism import assembly
from appell.mechanism.couplings import gear_mesh, rack_mesh
from appell.mechanism.parts import (
    Body,
    Joint,
    _Action,
    _alignment_rows,
    _Closure,
    _cross,
    _loop_points,
    _matrix,
    _point_rows,
    _real,
    _z_onto,
)
from appell.mechanism.rotations import unit_axis
from appell.model import (
    acceleration_constraint,
    holonomic,
    nonholonomic,
)
from appell.symbols import derivative_symbol

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


class MechanismConstraints:
    """The constraint methods of :class:`~appell.mechanism.Mechanism` (which keeps the bodies,
    joints, names and constraints they use: ``_body``, ``_joint``, ``_claim``, ...)."""

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
