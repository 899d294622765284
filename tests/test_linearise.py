"""Linear models, steady motions and stability sweeps (issue 23) against closed forms and
against central differences of the nonlinear split.

Sources of the closed forms:
* pendulum: small oscillations about the lowest point, s = +-i sqrt(g/L); about the
  highest, s = +-sqrt(g/L) (any mechanics text);
* conical pendulum: the steady rate Omega^2 = g / (L cos theta0) and the frequency of
  small oscillations about it, omega^2 = Omega^2 (1 + 3 cos^2 theta0) (Routh's reduced
  equation theta'' = p^2 cos/sin^3 - g/L sin linearised, derived in the test's docstring);
* sleeping top: s = +-i (I3 w +- sqrt(I3^2 w^2 - 4 I1 M g l)) / (2 I1), stable for
  w^2 > 4 I1 M g l / I3^2 (Goldstein, Classical Mechanics, 3rd ed., §5.7; Routh);
* rolling disc: upright rolling at spin rate w is stable for
  w^2 > m g r I_d / (I_p (I_p + m r^2)) = g / (3 r) for a thin uniform disc
  (Neimark and Fufaev, Dynamics of Nonholonomic Systems, ch. III; Routh, Advanced Rigid
  Dynamics, §244);
* spring-mass-damper chain: M, C, K and F read off its equations of motion.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

from appell import ModelError, Parameter, System, derive, numeric_model
from appell.examples import example_path
from appell.examples.mechanism_examples import double_pendulum_joints, rolling_disc
from appell.io.cli import cli, load_system
from appell.numerics.linearise import linearise, steady_motion
from appell.numerics.stability import stability_sweep

G, L = 9.81, 1.0


@pytest.fixture(scope="module")
def pendulum():
    """The bundled pendulum: Cartesian x, y with the rod (L^2 - x^2 - y^2)/(2L) = 0, m = L = 1."""
    return derive(load_system(str(example_path("pendulum"))))


def test_a_pendulum_oscillates_below_and_falls_away_above(pendulum):
    """The chart of the rod leaves one coordinate and one speed: s = +-i sqrt(g/L) at the
    lowest point, +-sqrt(g/L) at the highest (the eigenvalues of a 2 x 2 A to rounding)."""
    down = linearise(pendulum, {"x": 0.0, "y": -L, "x_dot": 0.0, "y_dot": 0.0})
    assert down.states == ("x", "x_dot")
    assert np.allclose(down.eigenvalues(), [-1j * math.sqrt(G / L), 1j * math.sqrt(G / L)], rtol=1e-13, atol=0)
    up = linearise(pendulum, {"x": 0.0, "y": L, "x_dot": 0.0, "y_dot": 0.0})
    assert np.allclose(up.eigenvalues(), [-math.sqrt(G / L), math.sqrt(G / L)], rtol=1e-13, atol=0)
    # the rod's reaction at rest at the lowest point is lambda = m g (F = (L^2 - x^2 - y^2)/(2L)
    # has dF/dy = 1 there): d lambda / dg = m = 1, and it is even in x (no first-order change)
    lm = linearise(pendulum, {"x": 0.0, "y": -L}, inputs=["g"], outputs=["lambda_rod"])
    assert lm.outputs == ("lambda_rod",) and lm.D[0, 0] == pytest.approx(1.0, rel=1e-14)
    assert np.allclose(lm.C, 0.0, atol=1e-14)


def test_a_point_that_moves_is_refused_by_name(pendulum):
    with pytest.raises(ModelError, match="neither an equilibrium nor a steady motion: x_dot'"):
        linearise(pendulum, {"x": 0.6, "y": -0.8, "x_dot": 0.0, "y_dot": 0.0})
    with pytest.raises(ModelError, match="'z' in ignore is not a coordinate"):
        linearise(pendulum, {"x": 0.0, "y": -L}, ignore=["z"])


def _central(f, y0, direction, h=1e-6):
    return (f(y0 + h * direction) - f(y0 - h * direction)) / (2 * h)


def test_the_conical_pendulum_steady_rate_and_its_small_oscillations():
    """Spherical pendulum (theta, phi), phi cyclic: at theta0 = 0.6 the steady rate is
    Omega^2 = g / (L cos theta0); about it theta'' linearises (Routh's reduced equation with
    p = Omega sin^2 theta0: d/dtheta [p^2 cos/sin^3 - g/L sin] = -p^2 (sin^2 + 3 cos^2)/sin^4
    - g/L cos) to omega^2 = Omega^2 (1 + 3 cos^2 theta0); the conserved p_phi adds s = 0."""
    d = derive(load_system(str(example_path("spherical_pendulum"))))
    th0 = 0.6
    point = steady_motion(d, {"theta": th0, "theta_dot": 0.0, "phi_dot": 3.0}, free=["phi_dot"], ignore=["phi"])
    omega_s = math.sqrt(G / (L * math.cos(th0)))
    assert point["phi_dot"] == pytest.approx(omega_s, rel=1e-12)
    lm = linearise(d, point, ignore="cyclic")
    assert lm.ignored == ("phi",) and lm.states == ("theta", "theta_dot", "phi_dot")
    w = omega_s * math.sqrt(1 + 3 * math.cos(th0) ** 2)
    assert np.allclose(lm.eigenvalues(), [-1j * w, 0.0, 1j * w], rtol=0, atol=1e-12 * w)


def test_linearised_reactions_and_outputs_match_central_differences_of_the_split():
    """A double pendulum of rods hanging at rest (mechanism with joint-force outputs) and a
    perturbation along each column of the chart T: C (the multipliers' and the outputs'
    sensitivities) against central differences of the nonlinear split (h = 1e-6: truncation
    h^2 |z'''| ~ 1e-11, rounding eps |z| / h ~ 2e-9 of forces of 20 N, so 1e-7 absolute)."""
    d = derive(double_pendulum_joints())
    model = numeric_model(d)
    point = {"shoulder": 0.0, "elbow": 0.0, "shoulder_dot": 0.0, "elbow_dot": 0.0}
    lm = linearise(d, point)
    assert lm.states == ("shoulder", "elbow", "shoulder_dot", "elbow_dot")
    names = model.coordinate_names + model.speed_names
    y0 = np.array([point[n] for n in names])
    from appell.numerics.outputs import compile_outputs

    outputs = compile_outputs(d.system)
    nq = len(model.coordinate_names)

    def z(y):
        sol = model.solve(0.0, y[:nq], y[nq:])
        cols = {"t": 0.0, **dict(zip(names, y)), **dict(zip(model.parameter_names, model.params(None)))}
        cols.update({a.name: v for a, v in zip(d.system.accelerations, sol.accelerations)})
        cols.update({f"lambda_{c}": v for c, v in zip(model.constraint_names, sol.multipliers)})
        out = outputs(cols)
        return np.concatenate([sol.multipliers, [out[n] for n in outputs.names]])

    for k in range(len(lm.states)):
        direction = np.zeros(len(names))
        direction[names.index(lm.states[k])] = 1.0
        assert np.allclose(lm.C[:, k], _central(z, y0, direction), rtol=0, atol=1e-7), lm.states[k]
    assert lm.outputs[-1].startswith(("F_", "M_")) and lm.C.shape[0] == len(lm.outputs)
    # hanging rods: each joint's vertical force moves with neither angle to first order
    assert np.allclose(lm.C[list(lm.outputs).index("F_shoulder_y"), :2], 0.0, atol=1e-12)


def spring_chain() -> System:
    """Two masses on springs in a chain, a damper on the second and a force F on it:
    m1 x1'' = -k1 x1 + k2 (x2 - x1), m2 x2'' = -k2 (x2 - x1) - c x2' + F."""
    x1, x2, m1, m2, k1, k2, c, F = sp.symbols("x1 x2 m1 m2 k1 k2 c F")
    x1d, x2d = sp.symbols("x1_dot x2_dot")
    return System(
        name="spring_chain",
        coordinates=(x1, x2),
        parameters=(
            Parameter(m1, 2.0),
            Parameter(m2, 3.0),
            Parameter(k1, 5.0),
            Parameter(k2, 7.0),
            Parameter(c, 0.4),
            Parameter(F, 0.0),
        ),
        kinetic_energy=m1 / 2 * x1d**2 + m2 / 2 * x2d**2,
        potential_energy=k1 / 2 * x1**2 + k2 / 2 * (x2 - x1) ** 2,
        generalized_forces=(0, -c * x2d + F),
    )


def test_the_second_order_form_and_an_input_of_a_spring_chain():
    """M, C, K, F of the chain exactly (their entries are the parameters), and the input
    column B of the force F against a central difference of the accelerations."""
    d = derive(spring_chain())
    lm = linearise(d, {"x1": 0.0, "x2": 0.0}, inputs=["F"])
    M, C, K, Fu = lm.second_order()
    assert np.allclose(M, np.diag([2.0, 3.0]), rtol=0, atol=1e-14)
    assert np.allclose(C, [[0, 0], [0, 0.4]], rtol=0, atol=1e-14)
    assert np.allclose(K, [[12.0, -7.0], [-7.0, 7.0]], rtol=0, atol=1e-13)
    assert np.allclose(Fu, [[0.0], [1.0]], rtol=0, atol=1e-14)
    fd = (
        numeric_model(d).solve(0.0, [0, 0], [0, 0], {"F": 1e-3}).accelerations
        - numeric_model(d).solve(0.0, [0, 0], [0, 0], {"F": -1e-3}).accelerations
    ) / 2e-3
    assert np.allclose(lm.B[2:, 0], fd, rtol=1e-12, atol=0)
    ss = lm.statespace()
    assert ss.A.shape == (4, 4) and ss.B.shape == (4, 1)
    with pytest.raises(ModelError, match="inputs must be parameters: x1"):
        linearise(d, {}, inputs=["x1"])


def test_a_model_with_a_non_analytic_function_is_differentiated_symbolically():
    """A force -d (|x1 + 1| - 1) on the first mass (|.| has no complex-analytic extension, so
    the complex step does not apply): near x1 = 0 it is -d x1, a stiffness d added to K11."""
    x1, d_ = sp.Symbol("x1"), sp.Symbol("d")
    chain = spring_chain()
    system = dataclasses.replace(
        chain,
        parameters=chain.parameters + (Parameter(d_, 2.0),),
        generalized_forces=(-d_ * (sp.Abs(x1 + 1) - 1), chain.generalized_forces[1]),
    )
    lm = linearise(derive(system), {"x1": 0.0, "x2": 0.0})
    _, _, K, _ = lm.second_order()
    assert np.allclose(K, [[14.0, -7.0], [-7.0, 7.0]], rtol=0, atol=1e-13)


def sleeping_top() -> System:
    """A symmetric top on a fixed point, its axis turned by alpha about x, then beta about y,
    then spinning by gamma about the body axis (no gimbal lock upright): with the body
    angular velocity (alpha' cos beta, beta', gamma' + alpha' sin beta) in the axes after
    the second turn, T = I1/2 (alpha'^2 cos^2 beta + beta'^2) + I3/2 (gamma' + alpha' sin
    beta)^2 and the centre of mass at height l cos alpha cos beta."""
    a, b, g_, I1, I3, M, gr, l = sp.symbols("alpha beta gamma I1 I3 M g l")
    ad, bd, gd = sp.symbols("alpha_dot beta_dot gamma_dot")
    return System(
        name="sleeping_top",
        coordinates=(a, b, g_),
        parameters=(Parameter(I1, 0.8), Parameter(I3, 0.4), Parameter(M, 1.0), Parameter(gr, 9.81), Parameter(l, 0.5)),
        kinetic_energy=I1 / 2 * (ad**2 * sp.cos(b) ** 2 + bd**2) + I3 / 2 * (gd + ad * sp.sin(b)) ** 2,
        potential_energy=M * gr * l * sp.cos(a) * sp.cos(b),
    )


def test_the_sleeping_top_spectrum_and_its_critical_spin():
    """Upright at spin w (gamma cyclic): s = +-i (I3 w +- sqrt(I3^2 w^2 - 4 I1 M g l))/(2 I1)
    above the critical spin, and the sweep finds w_c = 2 sqrt(I1 M g l)/I3 where the last
    unstable pair turns marginal (a square-root approach: located by bisection)."""
    d = derive(sleeping_top())
    I1, I3, Mgl = 0.8, 0.4, 9.81 * 0.5
    w = 12.0
    lm = linearise(d, {"gamma_dot": w}, ignore=["gamma"])
    root = math.sqrt(I3**2 * w**2 - 4 * I1 * Mgl)
    expected = sorted(
        [0.0] + [s * 1j * (I3 * w + r) / (2 * I1) for s in (1, -1) for r in (root, -root)],
        key=lambda z: (z.real, z.imag),
    )
    got = sorted(lm.eigenvalues(), key=lambda z: (round(z.real, 8), z.imag))
    assert np.allclose(got, expected, rtol=0, atol=1e-11 * w)
    sweep = stability_sweep(d, "gamma_dot", np.linspace(4.0, 16.0, 13), ignore=["gamma"])
    critical = 2 * math.sqrt(I1 * Mgl) / I3
    assert len(sweep.crossings) == 1
    assert sweep.crossings[0].direction == -1
    assert sweep.crossings[0].value == pytest.approx(critical, rel=1e-8)
    assert not sweep.stable()[0] and sweep.stable()[-1]


def test_the_rolling_disc_is_stable_above_its_critical_speed():
    """The bundled thin disc (m r^2/4 about a diameter, m r^2/2 about its axis) on a level
    plane, rolling upright at spin rate w: the steady motion is found at each w (x', y', z',
    z free; x, y, heading and spin cyclic), and the lean mode turns stable at
    w^2 = g / (3 r) (module docstring)."""
    d = derive(rolling_disc())
    r = 0.25
    free = ["float_x_dot", "float_y_dot", "float_z_dot", "float_z"]
    ignore = ["float_x", "float_y", "float_rz", "float_ry"]
    point = steady_motion(
        d, {"alpha": 0.0, "float_z": r, "float_ry_dot": 6.0, "float_x_dot": -1.0}, free=free, ignore=ignore
    )
    assert point["float_x_dot"] == pytest.approx(6.0 * r, rel=1e-12) and point["float_z"] == pytest.approx(r)
    sweep = stability_sweep(
        d,
        "float_ry_dot",
        np.linspace(1.0, 8.0, 15),
        at={"alpha": 0.0, "float_z": r, "float_x_dot": 0.25},
        free=free,
        ignore=ignore,
    )
    assert [c.direction for c in sweep.crossings] == [-1]
    assert sweep.crossings[0].value == pytest.approx(math.sqrt(9.81 / (3 * r)), rel=1e-8)
    assert sweep.crossings[0].kind == "real"


def test_appell_stability_writes_each_format(tmp_path):
    """The command line sweeps the conical pendulum's angle (the steady rate solved at each)
    and writes JSON, CSV, netCDF and a plot; the JSON's frequencies are the closed form's."""
    import xarray as xr

    files = [tmp_path / f"s.{k}" for k in ("json", "csv", "nc", "png")]
    args = [
        "stability",
        "spherical_pendulum",
        "--vary",
        "theta=0.2:1.2:6",
        "--free",
        "phi'",
        "--ignore",
        "phi",
        "--set",
        "theta'=0",
        "--set",
        "phi'=2",
    ] + sum((["-o", str(f)] for f in files), [])
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert "stable at 6 of 6 values" in result.output
    data = json.loads(files[0].read_text())
    theta = np.array(data["values"])
    w = np.sqrt(G / (L * np.cos(theta)) * (1 + 3 * np.cos(theta) ** 2))
    assert np.allclose(np.max(data["imag"], axis=1), w, rtol=1e-10)
    assert files[1].read_text().splitlines()[0].startswith("theta,real_0,imag_0")
    assert xr.open_dataset(files[2], engine="h5netcdf")["imag"].shape == (6, 3)
    assert files[3].read_bytes()[:4] == b"\x89PNG"
    bad = CliRunner().invoke(cli, ["stability", "spherical_pendulum", "--vary", "theta=1:0:3"])
    assert bad.exit_code != 0 and "increasing" in bad.output


def test_the_internal_dynamics_of_an_ordinary_derivation_is_refused_with_a_pointer(pendulum):
    """Issue 23: on a derivation without servo constraints the servo code said AttributeError."""
    from appell.control.internal_dynamics import internal_linearisation

    with pytest.raises(ModelError, match="servo constraints") as info:
        internal_linearisation(pendulum)
    assert "appell.linearise" in info.value.hint


def test_a_hinge_axis_given_by_a_parameter():
    """A point mass m on a massless rod of length L swinging about a hinge whose axis is
    tilted by beta from the vertical, axis (sin beta, 0, cos beta), gravity -z: only
    g sin(beta) acts in the plane of the swing, so small oscillations about the lowest point
    have s^2 = -g sin(beta) / L (the axis is a parameter; its unit length is an identity).
    A body's inertia rotated by a symbolic angle, R^T I R, is recognised as symmetric."""
    from appell.mechanism import Mechanism
    from appell.mechanism.rotations import axis_rotation

    b = sp.Symbol("beta")
    mech = Mechanism("tilted_pendulum", gravity=(0, 0, -9.81))
    mech.parameter("beta", 0.4)
    R = axis_rotation((0, 1, 0), b)
    bob = mech.body("bob", 1.0, inertia=R.T * sp.diag(0, 0, 0) * R, com=(0, 0, 0))
    rod = (sp.cos(b), 0, -sp.sin(b))  # perpendicular to the axis, pointing down-and-aside at rest
    mech.revolute("hinge", "ground", bob, axis=(sp.sin(b), 0, sp.cos(b)), child_origin=tuple(-x for x in rod))
    d = derive(mech.system(reactions=None))
    for beta in (0.4, 1.1):
        lm = linearise(d, {"hinge": 0.0, "beta": beta})
        assert np.allclose(
            lm.eigenvalues(),
            [-1j * math.sqrt(G * math.sin(beta)), 1j * math.sqrt(G * math.sin(beta))],
            rtol=1e-12,
            atol=0,
        )
    body = mech.body("plate", 2.0, inertia=R.T * sp.Matrix([[1, 0, 0.2], [0, 2, 0], [0.2, 0, 3]]) * R)
    assert body.inertia.shape == (3, 3)
    with pytest.raises(ModelError, match="not of unit length"):
        mech.revolute("bad", "ground", "plate", axis=(sp.sin(b), 0, 2 * sp.cos(b)))
