"""Problems of the IFToMM library of computational benchmark problems for multibody dynamics.

Source: M. González, D. Dopico, U. Lugrís, J. Cuadrado, "A benchmarking system for MBS
simulation software: problem standardization and performance measurement", Multibody
System Dynamics 16 (2006) 179-190, and the library's problem pages (group A, "basic
problems").

**A02, the N four-bar mechanism.** A row of ``N + 1`` rockers hinged to the ground at
``x = 0, 1, ..., N`` (gravity 9.81 m/s^2 along -y), their tips joined by ``N`` couplers: ``2N
+ 1`` slender rods of 1 m and 1 kg (inertia ``m l^2/12`` about the middle). The rockers
start upright and the first rocker's tip moves along +x at 1 m/s; the library integrates
20 s. All rockers stay parallel and every coupler translates (the parallelogram branch),
so the motion has one degree of freedom, the rockers' angle ``phi``::

    ((N + 1)/3 + N) phi'' = -((N + 1)/2 + N) g cos(phi),  phi(0) = pi/2, phi'(0) = -1,

(kinetic energy of ``N + 1`` rods about their pivots and ``N`` translating rods, potential
of their centres). Whenever the rockers lie flat (``phi = k pi``), every rod is on the
x axis: the constraint Jacobian loses rank ``N`` (the degrees of freedom jump from 1 to
``N + 1``) and the motion must pass on the same branch (appell.simulation.passage).

**A04, Bricard's mechanism**: five rods of 1 m and 1 kg (square section 0.1 m side) and the
ground joined in a loop by six hinges, each rod perpendicular to both hinge axes at its ends
and consecutive axes perpendicular (the orthogonal 6R Bricard linkage). Grübler's count
gives no degree of freedom, yet it moves with one: one of the loop's constraints is redundant
wherever the loop is closed, though not at other configurations. Here the loop starts on the
edges of the unit cube, ``(0,0,0) (1,0,0) (1,1,0) (1,1,1) (0,1,1) (0,0,1)`` (the last rod is the
ground), and is released at rest under gravity along -y. The library's own start and reference
data were not available offline: the tests check this motion against independent routes
(energy, the augmented system of method.md §3 integrated by SciPy, ideal hinges that carry no
moment about their axes), not against the library's numbers.

**A05, the stiff flyball governor**: a vertical shaft of 1 m on a hinge about z at the ground
(gravity 9.81 m/s^2 along -z), a slider (a cube of 0.1 m) sliding on it and turning with it,
and two rods of 1 m hinged at A and B, 0.1 m apart at the shaft's top, each with a point mass
of 5 kg at its far end. The coupler rods of Watt's governor are spring-dampers (k = 8e5 N/m,
c = 4e4 N s/m, rest length 0.5 m) from the slider's sides to the rods' midpoints. Shaft, rods
and slider are prismatic bodies of density 3000 kg/m^3 (shaft and rods 1 x 0.01 x 0.01 m). At
the start the rods are 30 degrees below the horizontal, the slider's centre at s = 0.5 m (the
springs at rest length), and everything turns at 2 pi rad/s; the library integrates 10 s and
reports s. The data are those of the library's A05 page as its ports list them (the
MBSbenchmarksInOpenSim documentation; Exudyn's TestModels/stiffFlyballGovernor.py, whose
printed initial angular velocities are 2 pi rad/s). The shaft turns freely, so the angular
momentum about z is conserved; the damping takes energy out, and stiffness and damping give
the eigenvalues that make the problem stiff.

Written here with :class:`~appell.mechanism.Mechanism`: rocker ``i`` on hinge ``R<i>``
(absolute angle), coupler ``j`` on hinge ``C<j>`` at the tip of rocker ``j`` (angle relative to
it), and the loop closed at the tip of rocker ``j + 1`` by ``connect`` ``L<j>`` in x and y:
``lambda_L<j>_x``, ``lambda_L<j>_y`` are the force of rocker ``j + 1`` on coupler ``j``. The model
files ``iftomm_a02_n<N>.toml`` are written by :func:`n_four_bar_text`.
"""

from __future__ import annotations

import math

import sympy as sp

from appell.mechanism import Mechanism
from appell.model import System

#: the numbers of four-bars of the bundled A02 files
A02_SIZES = (1, 4, 10, 40)
G = 9.81


def _a02_name(n: int) -> str:
    return f"iftomm_a02_n{n}"


def _a02_description(n: int) -> str:
    return f"IFToMM benchmark A02: the N four-bar mechanism with N = {n} (Gonzalez et al. 2006)"


def _a02_initial(n: int) -> dict[str, float]:
    start = {f"R{i}": math.pi / 2 for i in range(n + 1)}
    start.update({f"R{i}_dot": -1.0 for i in range(n + 1)})
    start.update({f"C{j}": -math.pi / 2 for j in range(n)})
    start.update({f"C{j}_dot": 1.0 for j in range(n)})
    return start


def n_four_bar(n: int) -> System:
    """IFToMM A02 with ``n`` four-bars (module docstring)."""
    mech = Mechanism(_a02_name(n), gravity=(0, -G, 0), description=_a02_description(n))
    rockers = [mech.body(f"rocker{i}", 1.0, inertia=(0, 0, 1 / 12), com=(0.5, 0, 0)) for i in range(n + 1)]
    couplers = [mech.body(f"coupler{j}", 1.0, inertia=(0, 0, 1 / 12), com=(0.5, 0, 0)) for j in range(n)]
    for i, rocker in enumerate(rockers):
        mech.revolute(f"R{i}", "ground", rocker, origin=(float(i), 0, 0))
    for j, coupler in enumerate(couplers):
        mech.revolute(f"C{j}", rockers[j], coupler, origin=(1.0, 0, 0))
        mech.connect(f"L{j}", (coupler, (1.0, 0, 0)), (rockers[j + 1], (1.0, 0, 0)), directions="xy")
    units = {name: "rad" for i in range(n + 1) for name in (f"R{i}",)}
    units.update({f"C{j}": "rad" for j in range(n)})
    units.update({f"L{j}_{a}": "N" for j in range(n) for a in "xy"})
    return mech.system(initial=_a02_initial(n), units=units)


def n_four_bar_text(n: int) -> str:
    """The model file of :func:`n_four_bar` (``iftomm_a02_n<n>.toml``), each kind of body,
    joint, closure and value written once for all ``i`` (docs/model-format.md, Repeated
    entries): the files differ in ``N`` only."""
    out = [
        f"# {_a02_description(n)}: the model file of",
        f"# appell.examples.iftomm_examples.n_four_bar({n}), written by n_four_bar_text({n}).",
        "# Rockers rocker0..rocker{N} hinged to the ground at x = 0..N (joints R<i>, absolute angles),",
        "# couplers coupler0..coupler{N-1} hinged at the rockers' tips (joints C<j>, relative angles),",
        "# loops closed by 'connect' L<j>: lambda_L<j>_x, _y the force of rocker j+1 on coupler j.",
        "# All rods 1 m, 1 kg, uniform; gravity 9.81 along -y; the first rocker's tip starts at 1 m/s",
        "# along +x. tests/test_iftomm.py checks the motion against the one-degree-of-freedom",
        "# parallelogram branch and the pin forces against a free-body solution.",
        "",
        "[model]",
        f'name = "{_a02_name(n)}"',
        f'description = "{_a02_description(n)}"',
        "",
        "[counts]",
        f"N = {n}                      # the number of four-bars",
        "",
        "[mechanism]",
        f"gravity = [0, -{G}, 0]",
        "",
    ]
    for kind, last in (("rocker", "N"), ("coupler", "N-1")):
        out += [
            "[[bodies]]",
            f'for = "i in 0..{last}"',
            f'name = "{kind}{{i}}"',
            "mass = 1.0",
            f"inertia = [0, 0, {1 / 12!r}]",
            "com = [0.5, 0, 0]",
            "",
        ]
    out += [
        "[[joints]]",
        'for = "i in 0..N"',
        'name = "R{i}"',
        'type = "revolute"',
        'parent = "ground"',
        'child = "rocker{i}"',
        'origin = ["{i}", 0, 0]',
        "axis = [0, 0, 1]",
        "",
    ]
    out += [
        "[[joints]]",
        'for = "j in 0..N-1"',
        'name = "C{j}"',
        'type = "revolute"',
        'parent = "rocker{j}"',
        'child = "coupler{j}"',
        "origin = [1.0, 0, 0]",
        "axis = [0, 0, 1]",
        "",
    ]
    out += [
        "[[closures]]",
        'for = "j in 0..N-1"',
        'name = "L{j}"',
        'type = "connect"',
        'body_a = "coupler{j}"',
        "point_a = [1.0, 0, 0]",
        'body_b = "rocker{j+1}"',
        "point_b = [1.0, 0, 0]",
        'directions = "xy"',
        "",
    ]
    start = _a02_initial(1)
    out += [
        "[initial]",
        f'"R{{i in 0..N}}" = {start["R0"]!r}',
        f'"R{{i in 0..N}}\'" = {start["R0_dot"]!r}',
        f'"C{{j in 0..N-1}}" = {start["C0"]!r}',
        f'"C{{j in 0..N-1}}\'" = {start["C0_dot"]!r}',
    ]
    out += [
        "",
        "[simulation]",
        "t_end = 20.0",
        "rtol = 1e-12",
        "atol = 1e-14",
        "output_step = 0.01",
        "",
        "[units]",
        '"R{i in 0..N}" = "rad"',
        '"C{j in 0..N-1}" = "rad"',
        '"L{j in 0..N-1}_x" = "N"',
        '"L{j in 0..N-1}_y" = "N"',
    ]
    return "\n".join(out) + "\n"


def a02_reference(n: int):
    """``(I, K)`` of the branch's equation ``I phi'' = -K cos(phi)`` (module docstring)."""
    return (n + 1) / 3 + n, ((n + 1) / 2 + n) * G


#: the cube-edge loop of Bricard's mechanism: hinge points, rod directions, hinge axes (world)
BRICARD_POINTS = ((0, 0, 0), (1, 0, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1), (0, 0, 1))
BRICARD_AXES = ((0, 1, 0), (0, 0, 1), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 0))


def bricard() -> System:
    """Bricard's mechanism (module docstring): rods ``rod1..rod5`` on hinges ``H1..H5`` (each
    frame parallel to the world's at the start, so every hinge axis and point is written in
    world axes), the loop closed at the sixth hinge by ``connect`` ``H6`` (the rod's end on the
    ground point, x, y, z) and ``H6_axis`` (a second point of the hinge axis, y and z): five
    constraints, one of them redundant on the loop's motion. Each hinge's force and moment
    are given in its rod's axes, where the hinge axis is fixed: ``M_H1_y``, ``M_H2_z``,
    ``M_H3_x``, ``M_H4_y``, ``M_H5_z`` are the moments about the hinge axes."""
    mech = Mechanism("bricard", gravity=(0, -G, 0), description=_bricard_description())
    side = 0.1
    transverse, axial = (1.0 + side**2) / 12, 2 * side**2 / 12
    directions = [tuple(b - a for a, b in zip(BRICARD_POINTS[k], BRICARD_POINTS[k + 1])) for k in range(5)]
    rods = [
        mech.body(
            f"rod{k + 1}",
            1.0,
            inertia=tuple(axial if d else transverse for d in direction),
            com=tuple(0.5 * d for d in direction),
        )
        for k, direction in enumerate(directions)
    ]
    parent, origin = "ground", (0, 0, 0)
    for k in range(5):
        mech.revolute(f"H{k + 1}", parent, rods[k], axis=BRICARD_AXES[k], origin=origin)
        parent, origin = rods[k], directions[k]
    end = directions[4]
    mech.connect("H6", (rods[4], end), ("ground", BRICARD_POINTS[5]), directions="xyz")
    along = tuple(e + a for e, a in zip(end, BRICARD_AXES[5]))
    mech.connect(
        "H6_axis",
        (rods[4], along),
        ("ground", tuple(p + a for p, a in zip(BRICARD_POINTS[5], BRICARD_AXES[5]))),
        directions="yz",
    )
    units = {f"H{k}": "rad" for k in range(1, 6)}
    units.update({name: "N" for name in ("H6_x", "H6_y", "H6_z", "H6_axis_y", "H6_axis_z")})
    # each hinge's force and moment in the axes of its rod, where the hinge axis stays put
    return mech.system(
        initial={f"H{k}": 0.0 for k in range(1, 6)}, units=units, frame={f"H{k}": f"rod{k}" for k in range(1, 6)}
    )


def _bricard_description() -> str:
    return (
        "Bricard's mechanism (IFToMM A04 geometry): an overconstrained loop of five rods and six hinges "
        "with one degree of freedom"
    )


def flyball_governor() -> System:
    """IFToMM A05, the stiff flyball governor (module docstring): the shaft's angle ``phi``
    (continuous, about z), the slider's height ``s`` on it, the rods' angles ``beta1``,
    ``beta2`` below the horizontal (rod 2 hinged in a frame turned half a turn about z), the
    balls fixed at the rods' ends; spring-dampers ``spring1``, ``spring2``; the energies and
    the balls' positions ``ball1_x`` .. ``ball2_z`` as outputs."""
    mech = Mechanism(
        "iftomm_a05_governor",
        gravity=(0, 0, -sp.Symbol("g")),
        description="IFToMM benchmark A05: the stiff flyball governor (Gonzalez et al. 2006)",
    )
    p = {
        name: mech.parameter(name, value, unit, description)
        for name, value, unit, description in (
            ("L", 1.0, "m", "length of the shaft and of each rod"),
            ("w", 0.01, "m", "side of the shaft's and the rods' square section"),
            ("a", 0.1, "m", "side of the slider"),
            ("d", 0.1, "m", "distance between the hinges A and B"),
            ("rho", 3000.0, "kg/m^3", "density of shaft, rods and slider"),
            ("m_ball", 5.0, "kg", "point mass at each rod's end"),
            ("k", 8e5, "N/m", "spring stiffness"),
            ("c", 4e4, "N*s/m", "spring damping"),
            ("l0", 0.5, "m", "spring rest length"),
            ("g", G, "m/s^2", None),
        )
    }
    L, w, a, d, rho = (p[n] for n in ("L", "w", "a", "d", "rho"))
    bar = rho * L * w**2  # the mass of the shaft and of each rod
    transverse, axial = bar * (L**2 + w**2) / 12, bar * w**2 / 6
    shaft = mech.body("shaft", bar, inertia=(transverse, transverse, axial), com=(0, 0, L / 2))
    slider = mech.body("slider", rho * a**3, inertia=(rho * a**5 / 6,) * 3)
    rods = [mech.body(f"rod{i}", bar, inertia=(axial, transverse, transverse), com=(L / 2, 0, 0)) for i in (1, 2)]
    balls = [mech.particle(f"ball{i}", p["m_ball"]) for i in (1, 2)]
    mech.revolute("phi", "ground", shaft, axis=(0, 0, 1))
    mech.prismatic("s", shaft, slider, axis=(0, 0, 1))
    mech.revolute("beta1", shaft, rods[0], axis=(0, 1, 0), origin=(d / 2, 0, L))
    mech.revolute("beta2", shaft, rods[1], axis=(0, 1, 0), origin=(-d / 2, 0, L), rpy=(0, 0, sp.pi))
    for i, (rod, ball) in enumerate(zip(rods, balls), start=1):
        mech.fixed(f"ball{i}_on_rod{i}", rod, ball, origin=(L, 0, 0))
    for i, (rod, side) in enumerate(zip(rods, (a / 2, -a / 2)), start=1):
        mech.spring(f"spring{i}", (slider, (side, 0, 0)), (rod, (L / 2, 0, 0)), p["k"], p["l0"], p["c"])
    for i, rod in enumerate(rods, start=1):
        mech.watch_point(f"ball{i}", (rod, (L, 0, 0)))
    initial = {
        "phi": 0.0,
        "phi_dot": 2 * math.pi,
        "s": 0.5,
        "s_dot": 0.0,
        "beta1": math.pi / 6,
        "beta1_dot": 0.0,
        "beta2": math.pi / 6,
        "beta2_dot": 0.0,
    }
    units = {"phi": "rad", "s": "m", "beta1": "rad", "beta2": "rad"}
    return mech.system(initial=initial, units=units, energy=True)


IFTOMM_EXAMPLES = {
    **{_a02_name(n): (lambda n=n: n_four_bar(n)) for n in A02_SIZES},
    "bricard": bricard,
    "iftomm_a05_governor": flyball_governor,
}
