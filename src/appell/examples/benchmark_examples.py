"""Published multibody benchmarks.

Andrews' squeezing mechanism: seven rigid bodies in the plane, seven angles, six
holonomic loop-closure constraints, driven by a constant torque and a spring. It is the
index-3 DAE test problem of Hairer & Wanner (Solving ODEs II, §VII.7, after Manning
1981 and Schiehlen 1990) and of the IVP test set of Mazzia & Magherini (problem
"andrews"), which publish consistent initial values and, at t = 0, the accelerations
and multipliers the tests compare with.
"""

from __future__ import annotations

import sympy as sp

from appell.model import Parameter, System, holonomic

#: the parameters of the test set (SI units)
ANDREWS_PARAMETERS = {
    "m1": 0.04325,
    "m2": 0.00365,
    "m3": 0.02373,
    "m4": 0.00706,
    "m5": 0.07050,
    "m6": 0.00706,
    "m7": 0.05498,
    "xa": -0.06934,
    "ya": -0.00227,
    "xb": -0.03635,
    "yb": 0.03273,
    "xc": 0.014,
    "yc": 0.072,
    "c0": 4530.0,
    "I1": 2.194e-6,
    "I2": 4.410e-7,
    "I3": 5.255e-6,
    "I4": 5.667e-7,
    "I5": 1.169e-5,
    "I6": 5.667e-7,
    "I7": 1.912e-5,
    "d": 28e-3,
    "da": 11.5e-3,
    "e": 2e-2,
    "ea": 1.421e-2,
    "rr": 7e-3,
    "ra": 9.2e-4,
    "l0": 7.785e-2,
    "ss": 35e-3,
    "sa": 1.874e-2,
    "sb": 1.043e-2,
    "sc": 1.8e-2,
    "sd": 2e-2,
    "ta": 2.308e-2,
    "tb": 9.16e-3,
    "u": 4e-2,
    "ua": 1.228e-2,
    "ub": 4.49e-3,
    "zf": 2e-2,
    "zt": 4e-2,
    "fa": 1.421e-2,
    "mom": 33e-3,
}

#: consistent initial angles of the test set (at rest)
ANDREWS_INITIAL = {
    "beta": -0.0617138900142764496358948458001,
    "Theta": 0.0,
    "gamma": 0.455279819163070380255912382449,
    "Phi": 0.222668390165885884674473185609,
    "delta": 0.487364979543842550225598953530,
    "Omega": -0.222668390165885884674473185609,
    "epsilon": 1.23054744454982119249735015568,
}


def andrews_squeezer() -> System:
    """Andrews' squeezing mechanism (module docstring).

    ``T = 1/2 q'^T M(q) q'`` with the mass matrix of the test set, ``Q`` the driving
    torque ``mom`` on beta and the spring (stiffness c0, rest length l0) acting on gamma;
    the constraints g1..g6 close the three loops. The test set writes
    ``M q'' = f - G^T lambda``; with appell's sign convention (method.md §2) the same
    multipliers come out with the opposite sign. Published at t = 0:
    ``beta'' = 14222.4439199541, Theta'' = -10666.8329399656`` (the other five zero),
    ``lambda_g1 = -98.5668703962, lambda_g2 = 6.12268834425`` (the others zero).
    """
    names = ("beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon")
    q = sp.symbols(names)
    qd = sp.symbols([f"{n}_dot" for n in names])
    be, Th, ga, Ph, de, Om, ep = q
    P = {k: sp.Symbol(k) for k in ANDREWS_PARAMETERS}
    m1, m2, m3, m4, m5, m6, m7 = (P[f"m{i}"] for i in range(1, 8))
    I1, I2, I3, I4, I5, I6, I7 = (P[f"I{i}"] for i in range(1, 8))
    xa, ya, xb, yb, xc, yc = P["xa"], P["ya"], P["xb"], P["yb"], P["xc"], P["yc"]
    d, da, e, ea, rr, ra, ss = P["d"], P["da"], P["e"], P["ea"], P["rr"], P["ra"], P["ss"]
    sa, sb, sc, sd, ta, tb = P["sa"], P["sb"], P["sc"], P["sd"], P["ta"], P["tb"]
    u, ua, ub, zf, zt, fa = P["u"], P["ua"], P["ub"], P["zf"], P["zt"], P["fa"]
    c0, l0, mom = P["c0"], P["l0"], P["mom"]
    M = sp.zeros(7, 7)
    M[0, 0] = m1 * ra**2 + m2 * (rr**2 - 2 * da * rr * sp.cos(Th) + da**2) + I1 + I2
    M[1, 0] = M[0, 1] = m2 * (da**2 - da * rr * sp.cos(Th)) + I2
    M[1, 1] = m2 * da**2 + I2
    M[2, 2] = m3 * (sa**2 + sb**2) + I3
    M[3, 3] = m4 * (e - ea) ** 2 + I4
    M[4, 3] = M[3, 4] = m4 * ((e - ea) ** 2 + zt * (e - ea) * sp.sin(Ph)) + I4
    M[4, 4] = m4 * (zt**2 + 2 * zt * (e - ea) * sp.sin(Ph) + (e - ea) ** 2) + m5 * (ta**2 + tb**2) + I4 + I5
    M[5, 5] = m6 * (zf - fa) ** 2 + I6
    M[6, 5] = M[5, 6] = m6 * ((zf - fa) ** 2 - u * (zf - fa) * sp.sin(Om)) + I6
    M[6, 6] = m6 * ((zf - fa) ** 2 - 2 * u * (zf - fa) * sp.sin(Om) + u**2) + m7 * (ua**2 + ub**2) + I6 + I7
    v = sp.Matrix(qd)
    # the spring between the point (xd, yd) of body 3 and the fixed point C
    xd = sd * sp.cos(ga) + sc * sp.sin(ga) + xb
    yd = sd * sp.sin(ga) - sc * sp.cos(ga) + yb
    L = sp.sqrt((xd - xc) ** 2 + (yd - yc) ** 2)
    F = -c0 * (L - l0) / L
    spring = F * (xd - xc) * (sc * sp.cos(ga) - sd * sp.sin(ga)) + F * (yd - yc) * (sd * sp.cos(ga) + sc * sp.sin(ga))
    x0 = rr * sp.cos(be) - d * sp.cos(be + Th)
    y0 = rr * sp.sin(be) - d * sp.sin(be + Th)
    return System(
        name="andrews_squeezer",
        description="Andrews' squeezing mechanism (Hairer & Wanner; Mazzia & Magherini IVP test set)",
        coordinates=q,
        parameters=tuple(Parameter(P[k], val) for k, val in ANDREWS_PARAMETERS.items()),
        kinetic_energy=sp.expand((v.T * M * v)[0] / 2),
        generalized_forces=(mom, 0, spring, 0, 0, 0, 0),
        constraints=(
            holonomic("g1", x0 - ss * sp.sin(ga) - xb),
            holonomic("g2", y0 + ss * sp.cos(ga) - yb),
            holonomic("g3", x0 - e * sp.sin(Ph + de) - zt * sp.cos(de) - xa),
            holonomic("g4", y0 + e * sp.cos(Ph + de) - zt * sp.sin(de) - ya),
            holonomic("g5", x0 - zf * sp.cos(Om + ep) - u * sp.sin(ep) - xa),
            holonomic("g6", y0 - zf * sp.sin(Om + ep) + u * sp.cos(ep) - ya),
        ),
        initial={**ANDREWS_INITIAL, **{f"{n}_dot": 0.0 for n in names}},
    )


BENCHMARK_EXAMPLES = {"andrews_squeezer": andrews_squeezer}
