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

Written here with :class:`~appell.mechanism.Mechanism`: rocker ``i`` on hinge ``R<i>``
(absolute angle), coupler ``j`` on hinge ``C<j>`` at the tip of rocker ``j`` (angle relative to
it), and the loop closed at the tip of rocker ``j + 1`` by ``connect`` ``L<j>`` in x and y:
``lambda_L<j>_x``, ``lambda_L<j>_y`` are the force of rocker ``j + 1`` on coupler ``j``. The model
files ``iftomm_a02_n<N>.toml`` are written by :func:`n_four_bar_text`.
"""

from __future__ import annotations

import math

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
    """The model file of :func:`n_four_bar` (``iftomm_a02_n<n>.toml``)."""
    out = [f"# {_a02_description(n)}: the model file of",
           f"# appell.examples.iftomm_examples.n_four_bar({n}), written by n_four_bar_text({n}).",
           "# Rockers rocker0..rocker{N} hinged to the ground at x = 0..N (joints R<i>, absolute angles),",
           "# couplers coupler0..coupler{N-1} hinged at the rockers' tips (joints C<j>, relative angles),",
           "# loops closed by 'connect' L<j>: lambda_L<j>_x, _y the force of rocker j+1 on coupler j.",
           "# All rods 1 m, 1 kg, uniform; gravity 9.81 along -y; the first rocker's tip starts at 1 m/s",
           "# along +x. tests/test_iftomm.py checks the motion against the one-degree-of-freedom",
           "# parallelogram branch and the pin forces against a free-body solution.",
           "", "[model]", f'name = "{_a02_name(n)}"', f'description = "{_a02_description(n)}"', "",
           "[mechanism]", f"gravity = [0, -{G}, 0]", ""]
    for kind, count in (("rocker", n + 1), ("coupler", n)):
        for i in range(count):
            out += ["[[bodies]]", f'name = "{kind}{i}"', "mass = 1.0", f"inertia = [0, 0, {1 / 12!r}]",
                    "com = [0.5, 0, 0]", ""]
    for i in range(n + 1):
        out += ["[[joints]]", f'name = "R{i}"', 'type = "revolute"', 'parent = "ground"', f'child = "rocker{i}"',
                f"origin = [{float(i)!r}, 0, 0]", "axis = [0, 0, 1]", ""]
    for j in range(n):
        out += ["[[joints]]", f'name = "C{j}"', 'type = "revolute"', f'parent = "rocker{j}"', f'child = "coupler{j}"',
                "origin = [1.0, 0, 0]", "axis = [0, 0, 1]", ""]
    for j in range(n):
        out += ["[[closures]]", f'name = "L{j}"', 'type = "connect"', f'body_a = "coupler{j}"', "point_a = [1.0, 0, 0]",
                f'body_b = "rocker{j + 1}"', "point_b = [1.0, 0, 0]", 'directions = "xy"', ""]
    out.append("[initial]")
    for name, value in _a02_initial(n).items():
        key = f'"{name[:-4]}\'"' if name.endswith("_dot") else name
        out.append(f"{key} = {value!r}")
    out += ["", "[simulation]", "t_end = 20.0", "rtol = 1e-12", "atol = 1e-14", "output_step = 0.01", "",
            "[units]"]
    out += [f'R{i} = "rad"' for i in range(n + 1)] + [f'C{j} = "rad"' for j in range(n)]
    out += [f'L{j}_{a} = "N"' for j in range(n) for a in "xy"]
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
    rods = [mech.body(f"rod{k + 1}", 1.0, inertia=tuple(axial if d else transverse for d in direction),
                      com=tuple(0.5 * d for d in direction)) for k, direction in enumerate(directions)]
    parent, origin = "ground", (0, 0, 0)
    for k in range(5):
        mech.revolute(f"H{k + 1}", parent, rods[k], axis=BRICARD_AXES[k], origin=origin)
        parent, origin = rods[k], directions[k]
    end = directions[4]
    mech.connect("H6", (rods[4], end), ("ground", BRICARD_POINTS[5]), directions="xyz")
    along = tuple(e + a for e, a in zip(end, BRICARD_AXES[5]))
    mech.connect("H6_axis", (rods[4], along), ("ground", tuple(p + a for p, a in zip(BRICARD_POINTS[5], BRICARD_AXES[5]))),
                 directions="yz")
    units = {f"H{k}": "rad" for k in range(1, 6)}
    units.update({name: "N" for name in ("H6_x", "H6_y", "H6_z", "H6_axis_y", "H6_axis_z")})
    # each hinge's force and moment in the axes of its rod, where the hinge axis stays put
    return mech.system(initial={f"H{k}": 0.0 for k in range(1, 6)}, units=units,
                       frame={f"H{k}": f"rod{k}" for k in range(1, 6)})


def _bricard_description() -> str:
    return ("Bricard's mechanism (IFToMM A04 geometry): an overconstrained loop of five rods and six hinges "
            "with one degree of freedom")


IFTOMM_EXAMPLES = {**{_a02_name(n): (lambda n=n: n_four_bar(n)) for n in A02_SIZES}, "bricard": bricard}
