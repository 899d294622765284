"""Coulomb friction, stick-slip, rolling resistance and viscous friction (issue 12 §4).

Every value is checked against a closed form of elementary mechanics (the source is named
in each test), or against an independent route: the augmented multiplier system with the
same friction law solved by Newton's method (:func:`appell.numerics.friction.augmented_friction_solve`).
"""

import math

import numpy as np
import pytest
import sympy as sp

from appell import System, derive, holonomic, simulate
from appell.errors import ModelError, PainleveError
from appell.model import Friction
from appell.numerics.friction import FrictionLaws, augmented_friction_solve

G = 9.81
x, y, z, th = sp.symbols("x y z theta")
xd, yd, zd, thd = sp.symbols("x_dot y_dot z_dot theta_dot")
m, g, al, muk, mus, R, l = sp.symbols("m g alpha mu_k mu_s R l")


def block(alpha, v0, mu_k=0.3, mu_s=0.5, mass=2.0):
    """A block on an incline of angle alpha: x down the slope, y the gap to the surface."""
    return System(
        coordinates=(x, y),
        parameters={m: mass, g: G, al: alpha, muk: mu_k, mus: mu_s},
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        potential_energy=m * g * (-x * sp.sin(al) + y * sp.cos(al)),
        constraints=(holonomic("floor", y),),
        frictions=(Friction("slide", slip=(xd,), normal="floor", mu_k=muk, mu_s=mus),),
        initial={"x": 0.0, "y": 0.0, "x_dot": v0, "y_dot": 0.0},
        name="block",
    )


def test_block_sliding_down_an_incline_closed_form():
    """Elementary mechanics: a block sliding down a rough incline accelerates at
    a = g (sin alpha - mu_k cos alpha) under the normal force N = m g cos alpha and the
    friction -mu_k N."""
    alpha, mu = 0.5, 0.3
    sol = simulate(derive(block(alpha, 1.0, mu)), 1.0, t_eval=np.linspace(0, 1, 6))
    assert sol.status == 0
    # the split's formulas, constant along the slide: rounding only; x' is linear in t, which
    # DOP853 integrates exactly (~1e-15 measured)
    np.testing.assert_allclose(sol["x_ddot"], G * (math.sin(alpha) - mu * math.cos(alpha)), rtol=1e-12)
    np.testing.assert_allclose(sol["lambda_floor"], 2.0 * G * math.cos(alpha), rtol=1e-12)
    np.testing.assert_allclose(sol["friction_slide_t"], -mu * 2.0 * G * math.cos(alpha), rtol=1e-12)
    np.testing.assert_allclose(sol["x_dot"], 1.0 + G * (math.sin(alpha) - mu * math.cos(alpha)) * sol.t, rtol=1e-10)
    assert set(sol["friction_slide_slipping"]) == {1.0}
    assert "friction_slide_t" in sol.to_dataframe().columns


def test_block_at_rest_sticks_below_the_static_angle_and_slips_above():
    """Elementary mechanics: a block at rest on an incline stays at rest while
    tan alpha <= mu_s, held by the friction m g sin alpha up the slope; above it slides
    from t = 0 with a = g (sin alpha - mu_k cos alpha)."""
    stuck = simulate(derive(block(0.4, 0.0)), 1.0, t_eval=np.linspace(0, 1, 6))  # tan 0.4 = 0.42 < 0.5
    assert [(e.kind, e.t) for e in stuck.events] == [("stick", 0.0)]
    # held from the start: the split's force and x'' = 0, exact but for rounding (0 measured)
    np.testing.assert_allclose(stuck["friction_slide_t"], -2.0 * G * math.sin(0.4), rtol=1e-12)
    np.testing.assert_allclose(stuck["x"], 0.0, atol=1e-12)
    assert set(stuck["friction_slide_slipping"]) == {0.0}
    slips = simulate(derive(block(0.5, 0.0)), 1.0, t_eval=np.linspace(0, 1, 6))  # tan 0.5 = 0.546 > 0.5
    assert [(e.kind, e.t) for e in slips.events] == [("slip", 0.0)]
    # the split's formula, constant along the slide: rounding only
    np.testing.assert_allclose(slips["x_ddot"], G * (math.sin(0.5) - 0.3 * math.cos(0.5)), rtol=1e-12)


def test_block_pushed_up_the_incline_stops_and_sticks_at_the_closed_form_time():
    """Elementary mechanics: pushed up the slope at v0 (tan alpha < mu_s), the block
    decelerates at g (sin alpha + mu_k cos alpha), stops at t = v0 / that, and sticks."""
    alpha, v0 = 0.3, 2.0
    sol = simulate(derive(block(alpha, -v0)), 2.0, t_eval=np.linspace(0, 2, 9))
    (ev,) = sol.events
    assert ev.kind == "stick" and ev.name == "slide"
    # x' is linear in t, integrated exactly: the stop is the event's root (~4e-12 measured), and the
    # stick holds x' = 0 and the force to rounding after it
    assert ev.t == pytest.approx(v0 / (G * (math.sin(alpha) + 0.3 * math.cos(alpha))), abs=1e-9)
    late = sol.t > ev.t
    np.testing.assert_allclose(sol["x_dot"][late], 0.0, atol=1e-9)
    np.testing.assert_allclose(sol["friction_slide_t"][late], -2.0 * G * math.sin(alpha), rtol=1e-9)


def test_block_reverses_when_the_slope_is_too_steep_to_stick():
    """Elementary mechanics: pushed up a slope with tan alpha > mu_s, the block stops at
    t1 = v0 / (g (sin alpha + mu_k cos alpha)) and slides back down at
    g (sin alpha - mu_k cos alpha)."""
    alpha, v0 = 0.6, 1.0
    sol = simulate(derive(block(alpha, -v0)), 1.0, t_eval=np.linspace(0, 1, 11))
    (ev,) = sol.events
    t1 = v0 / (G * (math.sin(alpha) + 0.3 * math.cos(alpha)))
    # x' is linear in t, integrated exactly: t1 is the event's root (~5e-13 measured), and x' after
    # it is off by a dt1 relative to a (t - t1) >= 0.05 a (~6e-12)
    assert ev.kind == "slip" and ev.t == pytest.approx(t1, abs=1e-9)
    late = sol.t > t1
    np.testing.assert_allclose(
        sol["x_dot"][late], G * (math.sin(alpha) - 0.3 * math.cos(alpha)) * (sol.t[late] - t1), rtol=1e-8
    )


def ball(alpha, mu_s=0.2, mu_k=0.15, v0=0.0, rolling_resistance=None):
    """A uniform ball (I = 2/5 m R^2) on an incline: x down the slope, y the gap, theta its
    rotation; the contact point slips at x' - R theta'."""
    frictions = [Friction("contact", slip=(xd - R * thd,), normal="floor", mu_k=muk, mu_s=mus)]
    params = {m: 1.5, g: G, al: alpha, muk: mu_k, mus: mu_s, R: 0.1}
    if rolling_resistance is not None:
        mur = sp.Symbol("mu_r")
        params[mur] = rolling_resistance
        frictions.append(Friction("rolling", slip=(thd,), normal="floor", mu_k=mur))
    return System(
        coordinates=(x, y, th),
        parameters=params,
        kinetic_energy=m / 2 * (xd**2 + yd**2) + sp.Rational(1, 5) * m * R**2 * thd**2,
        potential_energy=m * g * (-x * sp.sin(al) + y * sp.cos(al)),
        constraints=(holonomic("floor", y),),
        frictions=tuple(frictions),
        initial={"x": 0.0, "y": 0.0, "theta": 0.0, "x_dot": v0, "y_dot": 0.0, "theta_dot": v0 / 0.1},
        name="ball",
    )


def test_ball_rolls_without_slipping_up_to_tan_alpha_seven_halves_mu_s():
    """Elementary mechanics (a uniform sphere on an incline): rolling, the centre
    accelerates at 5/7 g sin alpha held by the friction 2/7 m g sin alpha up the slope,
    which stays in the cone for tan alpha <= 7/2 mu_s; beyond, it slides with
    a = g (sin alpha - mu_k cos alpha) and theta'' = 5 mu_k g cos alpha / (2 R)."""
    mu_s = 0.2
    limit = math.atan(3.5 * mu_s)
    rolls = simulate(derive(ball(limit - 0.01, mu_s)), 1.0, t_eval=np.linspace(0, 1, 6))
    a = limit - 0.01
    assert [e.kind for e in rolls.events] == ["stick"]
    # here and below: the split's formulas, constant along the motion: rounding only (~5e-16)
    np.testing.assert_allclose(rolls["x_ddot"], 5 / 7 * G * math.sin(a), rtol=1e-10)
    np.testing.assert_allclose(rolls["friction_contact_t"], -2 / 7 * 1.5 * G * math.sin(a), rtol=1e-10)
    a = limit + 0.01
    slips = simulate(derive(ball(a, mu_s)), 1.0, t_eval=np.linspace(0, 1, 6))
    assert [e.kind for e in slips.events] == ["slip"]
    np.testing.assert_allclose(slips["x_ddot"], G * (math.sin(a) - 0.15 * math.cos(a)), rtol=1e-10)
    np.testing.assert_allclose(slips["theta_ddot"], 5 * 0.15 * G * math.cos(a) / (2 * 0.1), rtol=1e-10)


def test_rolling_resistance_stops_a_rolling_ball_at_the_closed_form_time():
    """Elementary mechanics: a ball rolling on level ground against the rolling-resistance
    torque mu_r N (N = m g) decelerates at x'' = -5 mu_r g / (7 R) (rolling: x' = R theta',
    I theta'' = -R F - mu_r m g, m x'' = F), stops at t = 7 R v0 / (5 mu_r g) and stays."""
    mu_r, v0 = 0.002, 0.5
    sol = simulate(derive(ball(0.0, v0=v0, rolling_resistance=mu_r)), 4.0, t_eval=np.linspace(0, 4, 41))
    t_stop = 7 * 0.1 * v0 / (5 * mu_r * G)
    stops = [e for e in sol.events if e.t > 0]
    assert [(e.kind, e.name) for e in stops] == [("stick", "rolling")]
    # x' is linear in t, integrated exactly, and crosses 0 at the slope 0.014 m/s^2: its rounding
    # moves the stop by up to ~2e-11 (measured); the forces and x'' are the split's, rounding only
    assert stops[0].t == pytest.approx(t_stop, abs=1e-8)
    moving = sol.t < t_stop
    np.testing.assert_allclose(sol["x_ddot"][moving], -5 * mu_r * G / (7 * 0.1), rtol=1e-9)
    np.testing.assert_allclose(sol["x_dot"][~moving], 0.0, atol=1e-9)
    np.testing.assert_allclose(sol["friction_rolling_t"][moving], -mu_r * 1.5 * G, rtol=1e-9)


def test_viscous_friction_decays_the_speed_exponentially():
    """Elementary mechanics: a mass on a smooth floor with viscous friction -c x' moves
    with x' = v0 exp(-c t / m)."""
    c = sp.Symbol("c")
    system = System(
        coordinates=(x,),
        parameters={m: 2.0, c: 0.7},
        kinetic_energy=m / 2 * xd**2,
        frictions=(Friction("damper", slip=(xd,), viscous=c),),
        initial={"x": 0.0, "x_dot": 3.0},
    )
    sol = simulate(derive(system), 2.0, t_eval=np.linspace(0, 2, 11), rtol=1e-11)
    # the run at rtol 1e-11 over 2 s: ~8e-12 relative (measured; 2.3e-10 at the default rtol 1e-9)
    np.testing.assert_allclose(sol["x_dot"], 3.0 * np.exp(-0.7 * sol.t / 2.0), rtol=1e-9)
    np.testing.assert_allclose(sol["friction_damper_t"], -0.7 * sol["x_dot"], rtol=1e-12)  # same state: rounding


def turntable(omega_rate=1.0, mu_s=0.2, r=0.981):
    """A block on a turntable turning at omega = omega_rate * t (the program phi =
    omega_rate t^2 / 2); x, y in the horizontal plane, z the gap; the block slips relative
    to the table at (x' + omega y, y' - omega x)."""
    ph, w_rate = sp.symbols("phi w_rate")
    om = sp.Symbol("phi_dot")
    return System(
        coordinates=(x, y, z),
        parameters={m: 0.5, g: G, mus: mu_s, muk: 0.1, w_rate: omega_rate},
        programs={ph: w_rate * sp.Symbol("t") ** 2 / 2},
        kinetic_energy=m / 2 * (xd**2 + yd**2 + zd**2),
        potential_energy=m * g * z,
        constraints=(holonomic("floor", z),),
        frictions=(Friction("pad", slip=(xd + om * y, yd - om * x), normal="floor", mu_k=muk, mu_s=mus),),
        initial={"x": r, "y": 0.0, "z": 0.0, "x_dot": 0.0, "y_dot": 0.0, "z_dot": 0.0},
        name="turntable_block",
    )


def test_turntable_block_slips_where_the_isotropic_cone_is_left():
    """Elementary mechanics: a block turning with a table at omega = omega' t needs the
    friction m r sqrt(omega^4 + omega'^2) (centripetal and tangential); it slips where this
    reaches mu_s m g: omega^4 = (mu_s g / r)^2 - omega'^2. With omega' = 1 rad/s^2 and
    mu_s g / r = 2 s^-2 that is t = 3^(1/4) = 1.316 s; a per-axis limit on the radial
    component alone (omega^2 r = mu_s g) would give sqrt(2) = 1.414 s."""
    sol = simulate(derive(turntable()), 2.0, t_eval=np.linspace(0, 2, 21), rtol=1e-11)
    slip = [e for e in sol.events if e.kind == "slip"]
    assert [e.name for e in slip] == ["pad"]
    # the force is m r sqrt(omega^4 + omega'^2) with r off by the run's error (rtol 1e-11: ~1e-11
    # relative, measured; 6e-10 at the default rtol 1e-9), which moves the slip by ~1e-13
    assert slip[0].t == pytest.approx(3**0.25, abs=1e-8)
    assert abs(slip[0].t - math.sqrt(2)) > 0.09
    stuck = sol.t < slip[0].t
    force = np.hypot(sol["friction_pad_t1"], sol["friction_pad_t2"])
    # r off by the run's error, as above (~1e-11 relative)
    np.testing.assert_allclose(force[stuck], 0.5 * 0.981 * np.sqrt(sol.t[stuck] ** 4 + 1.0), rtol=1e-9)
    assert set(sol["friction_pad_slipping"][stuck]) == {0.0} and set(sol["friction_pad_slipping"][~stuck]) == {1.0}
    # kinetic friction mu_k m g once sliding: the law applied to the split's N, rounding only
    np.testing.assert_allclose(force[~stuck], 0.1 * 0.5 * G, rtol=1e-9)


def rod(mu):
    """A uniform rod of half-length l (I = m l^2 / 3) whose lower end A slides on a rough
    floor: centre (x, y), theta its angle to the floor; A = (x - l cos theta, y - l sin theta),
    gap y - l sin theta, slip x' + l sin(theta) theta'."""
    return System(
        coordinates=(x, y, th),
        parameters={m: 1.2, g: G, l: 0.5, muk: mu},
        kinetic_energy=m / 2 * (xd**2 + yd**2) + m * l**2 / 6 * thd**2,
        potential_energy=m * g * y,
        constraints=(holonomic("floor", y - l * sp.sin(th)),),
        frictions=(Friction("end", slip=(xd + l * sp.sin(th) * thd,), normal="floor", mu_k=muk),),
        name="painleve_rod",
    )


def painleve_normal(theta, theta_dot, mu, s, mass=1.2, half=0.5):
    """N = m (g - l theta'^2 sin theta) / (1 + 3 cos^2 theta + 3 mu s sin theta cos theta)."""
    c, si = math.cos(theta), math.sin(theta)
    return mass * (G - half * theta_dot**2 * si) / (1 + 3 * c * c + 3 * mu * s * si * c)


@pytest.mark.parametrize("mu, s", [(0.5, 1), (0.5, -1), (1.2, 1), (1.2, -1)])
def test_painleve_rod_normal_force_closed_form(mu, s):
    """Painlevé's rod (e.g. Stewart, SIAM Review 42 (2000) §5; elementary rigid-body
    mechanics): N = m (g - l theta'^2 sin theta) / (1 + 3 cos^2 + 3 mu s sin cos), s the
    sign of the end's slip; checked at several states, and against the augmented system
    with the same friction law (Newton's method, no linear map in the normals)."""
    model = FrictionLaws(derive(rod(mu))).mode()
    for theta, theta_dot in [(0.4, 0.3), (0.9, -1.0), (1.2, 0.5)]:
        xdot = s * 1.0 - 0.5 * math.sin(theta) * theta_dot
        q = np.array([0.0, 0.5 * math.sin(theta), theta])
        w = np.array([xdot, 0.5 * math.cos(theta) * theta_dot, theta_dot])
        sol, fe = model.solve(0.0, q, w)
        # the split's 1 x 1 system in N at the given state: rounding only (~3e-16 measured)
        assert sol.multipliers[0] == pytest.approx(painleve_normal(theta, theta_dot, mu, s), rel=1e-12)
        assert fe.forces["end"][0] == pytest.approx(-mu * s * sol.multipliers[0], rel=1e-12)
        # Newton stops at steps below 1e-12 on the augmented system (condition < 14), then
        # rounding: ~1e-15 from the split (measured)
        a, lam = augmented_friction_solve(model, 0.0, q, w)
        np.testing.assert_allclose(a, sol.accelerations, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(lam, sol.multipliers, rtol=1e-9)


def test_painleve_rod_is_refused_where_the_denominator_vanishes():
    """Painlevé's paradox: for s = -1 the coefficient 1 + 3 cos^2 - 3 mu sin cos of N
    vanishes somewhere iff mu > 4/3 (its least ratio (tan + 4 cot)/3 = 4/3 at tan theta
    = 2). At tan theta = 2 with mu = 1.5 it is 1.6 - 1.8 < 0: refused, naming the contact;
    with s = +1, or mu = 1.2, the same state is accepted."""
    theta = math.atan(2.0)
    q = np.array([0.0, 0.5 * math.sin(theta), theta])
    w = np.array([-1.0, 0.0, 0.0])
    with pytest.raises(PainleveError, match="end"):
        FrictionLaws(derive(rod(1.5))).mode().solve(0.0, q, w)
    FrictionLaws(derive(rod(1.5))).mode().solve(0.0, q, -w)
    sol, _ = FrictionLaws(derive(rod(1.2))).mode().solve(0.0, q, w)
    # rounding amplified ~20x by the cancellation 1.6 - 1.44 = 0.16 in the denominator (2.5e-15 measured)
    assert sol.multipliers[0] == pytest.approx(painleve_normal(theta, 0.0, 1.2, -1), rel=1e-12)


def test_painleve_rod_simulation_stops_at_the_paradox_instead_of_integrating_through():
    """The rod sliding with s = -1 (its end at 5 m/s) and mu = 1.5 from theta = 0.6: N
    follows the closed form with s the sign of the end's slip at every output; the slip
    reverses (s = +1), and where it would reverse again to s = -1 at theta near 1.2, the
    coefficient 1 + 3 cos^2 - 4.5 sin cos is negative (-0.13 at theta = 1.19): no
    rigid-body normal force exists, and the run ends there with the Painlevé refusal
    naming the contact instead of integrating through."""
    theta0 = 0.6
    system = rod(1.5).replace(
        initial={
            "x": 0.0,
            "y": 0.5 * math.sin(theta0),
            "theta": theta0,
            "x_dot": -5.0 - 0.5 * math.sin(theta0),
            "y_dot": 0.5 * math.cos(theta0),
            "theta_dot": 1.0,
        }
    )
    sol = simulate(derive(system), 0.5, t_eval=np.linspace(0, 0.5, 101))
    assert sol.status == -1 and "Painlevé" in sol.message and "end" in sol.message
    theta, theta_dot = sol["theta"], sol["theta_dot"]
    slip = sol["x_dot"] + 0.5 * np.sin(theta) * theta_dot
    sliding = np.abs(slip) > 1e-6
    expected = [painleve_normal(a, b, 1.5, np.sign(v)) for a, b, v in zip(theta, theta_dot, slip)]
    # the closed form at the run's own states: rounding, amplified where the denominator falls
    # towards ~0.1 (7e-15 measured)
    np.testing.assert_allclose(sol["lambda_floor"][sliding], np.array(expected)[sliding], rtol=1e-8)
    assert [e.kind for e in sol.events] == ["slip"] and slip[0] < 0 < slip[-1]
    assert 1 + 3 * math.cos(theta[-1]) ** 2 - 4.5 * math.sin(theta[-1]) * math.cos(theta[-1]) < -0.1


def test_friction_bad_input_is_refused_with_the_culprit_named():
    """A normal naming no constraint, Coulomb friction without a normal, three slip
    components, a negative coefficient and an undeclared symbol are refused."""
    with pytest.raises(ModelError, match="'nowhere' is not a constraint"):
        block(0.3, 0.0).replace(frictions=(Friction("f", slip=(xd,), normal="nowhere", mu_k=0.3),))
    with pytest.raises(ModelError, match="needs the normal constraint"):
        Friction("f", slip=(xd,), mu_k=0.3)
    with pytest.raises(ModelError, match="1 component"):
        Friction("f", slip=(xd, yd, xd), normal="floor", mu_k=0.3)
    with pytest.raises(ModelError, match="non-negative"):
        Friction("f", slip=(xd,), normal="floor", mu_k=-0.3)
    with pytest.raises(ModelError, match="undeclared symbol.*nu"):
        derive(block(0.3, 0.0).replace(frictions=(Friction("f", slip=(xd,), normal="floor", mu_k=sp.Symbol("nu")),)))


def test_cross_check_friction_route_agrees_on_the_rod_and_fails_on_a_perturbed_normal(monkeypatch):
    """The cross-check's friction route (the augmented system with the same friction law,
    solved by Newton's method) agrees with the split's linear system in the normals on
    the Painlevé rod (mu = 0.5, where friction couples into N), and fails when the split's
    normal force is perturbed by 1e-6 relative."""
    import appell.numerics.friction as friction
    from appell import cross_check

    d = derive(
        rod(0.5).replace(
            initial={
                "x": 0.0,
                "y": 0.5 * math.sin(0.5),
                "theta": 0.5,
                "x_dot": 1.0,
                "y_dot": 0.5 * math.cos(0.5) * 0.3,
                "theta_dot": 0.3,
            }
        )
    )
    report = cross_check(d)
    (route,) = [c for c in report.comparisons if c.route == "friction"]
    # the routes agree to rounding (2e-16 relative, measured); the 1e-6 perturbation below shows
    # as ~1e-7, 100x over the same 1e-9
    assert route.states >= 4 and report.passed(1e-9)
    original = friction._painleve_checked

    def perturbed(*args):
        N, sigma = original(*args)
        return N * (1 + 1e-6), sigma

    monkeypatch.setattr(friction, "_painleve_checked", perturbed)
    assert not cross_check(d).passed(1e-9)


MODEL = """
[model]
name = "block_on_incline"
coordinates = ["x", "y"]

[parameters]
m = 2.0
g = 9.81
alpha = 0.5
mu_k = 0.3
mu_s = 0.5

[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"
potential_energy = "m*g*(-x*sin(alpha) + y*cos(alpha))"

[constraints.floor]
kind = "holonomic"
expr = "y"

[[friction]]
name = "slide"
slip = "x'"
normal = "floor"
mu_k = "mu_k"
mu_s = "mu_s"

[initial]
x = 0
y = 0
"x'" = 1
"y'" = 0
"""


def test_model_file_friction_table_gives_the_incline_closed_form(tmp_path):
    """A [[friction]] table reads into System.frictions; `appell simulate` writes the
    friction columns, with a = g (sin alpha - mu_k cos alpha) (elementary mechanics) and
    `appell check` passes with the friction route."""
    from click.testing import CliRunner

    from appell import loads_model
    from appell.io.cli import cli

    system = loads_model(MODEL)
    (item,) = system.frictions
    assert (item.name, item.normal, item.slip[0]) == ("slide", "floor", xd)
    path = tmp_path / "incline.toml"
    path.write_text(MODEL)
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(cli, ["simulate", str(path), "--t-end", "1", "--out", str(out)])
    assert result.exit_code == 0, result.output
    import pandas as pd

    table = pd.read_csv(out)
    # the split's formulas, constant along the slide, written with repr: rounding only
    np.testing.assert_allclose(table["x_ddot"], G * (math.sin(0.5) - 0.3 * math.cos(0.5)), rtol=1e-12)
    np.testing.assert_allclose(table["friction_slide_t"], -0.3 * 2 * G * math.cos(0.5), rtol=1e-12)
    result = CliRunner().invoke(cli, ["check", str(path)])
    assert result.exit_code == 0 and "[friction]" in result.output and "not formed" in result.output
    result = CliRunner().invoke(cli, ["derive", str(path)])
    assert result.exit_code == 0 and "the friction of slide adds Q_f" in result.output


@pytest.mark.parametrize(
    "change, message, line",
    [
        ('normal = "floor"', 'normal = "wall"', "'wall' is not a constraint"),
        ('slip = "x\'"', 'slip = ["x\'", "y\'", "x\'"]', "1 component"),
        ('mu_k = "mu_k"', 'mu_k = "nu"', "undeclared symbol"),
        ('mu_k = "mu_k"', "mu_x = 0.3", "unknown key 'mu_x'"),
    ],
)
def test_model_file_friction_errors_name_file_and_line(change, message, line):
    """Bad [[friction]] entries are refused with the model file's name and line."""
    from appell import loads_model

    text = MODEL.replace(change, message)
    with pytest.raises(ModelError) as info:
        loads_model(text, source="incline.toml")
    assert line in str(info.value) and "incline.toml:" in str(info.value)


def ladder(mu_floor, mu_wall):
    """A uniform ladder (half-length l, I = m l^2 / 3) with its foot A = (x + l cos theta,
    y - l sin theta) on a rough floor and its top B = (x - l cos theta, y + l sin theta)
    against a rough wall x = 0: two unit gaps and two sliding contacts."""
    return System(
        coordinates=(x, y, th),
        parameters={m: 10.0, g: G, l: 2.0, muk: mu_floor, mus: mu_wall},
        kinetic_energy=m / 2 * (xd**2 + yd**2) + m * l**2 / 6 * thd**2,
        potential_energy=m * g * y,
        constraints=(holonomic("floor", y - l * sp.sin(th)), holonomic("wall", x - l * sp.cos(th))),
        frictions=(
            Friction("foot", slip=(xd - l * sp.sin(th) * thd,), normal="floor", mu_k=muk),
            Friction("top", slip=(yd + l * sp.cos(th) * thd,), normal="wall", mu_k=mus),
        ),
        name="ladder",
    )


def test_ladder_two_sliding_contacts_agree_with_the_augmented_route():
    """Two coupled sliding contacts (the 2 x 2 system in the normals): the split agrees with
    the augmented system with the same friction law (Newton's method on all accelerations
    and multipliers at once) at states of the sliding ladder, and with mu = 0 both give
    the frictionless split; the friction forces are -mu |N| sign(slip) (Coulomb's law)."""
    for mu_floor, mu_wall in [(0.0, 0.0), (0.3, 0.2), (0.6, 0.5)]:
        model = FrictionLaws(derive(ladder(mu_floor, mu_wall))).mode()
        for theta, theta_dot in [(1.2, -0.4), (0.9, -1.1), (0.5, -2.0)]:
            q = np.array([2.0 * math.cos(theta), 2.0 * math.sin(theta), theta])
            w = np.array([-2.0 * math.sin(theta) * theta_dot, 2.0 * math.cos(theta) * theta_dot, theta_dot])
            sol, fe = model.solve(0.0, q, w)
            a, lam = augmented_friction_solve(model, 0.0, q, w)
            # Newton stops at steps below 1e-12 on the augmented system (condition 140), then
            # rounding: ~1e-14 from the split (measured); Coulomb's law on the same N: rounding
            np.testing.assert_allclose(sol.accelerations, a, rtol=1e-9, atol=1e-10)
            np.testing.assert_allclose(sol.multipliers, lam, rtol=1e-9)
            slips = fe.slips
            assert fe.forces["foot"][0] == pytest.approx(-mu_floor * abs(lam[0]) * np.sign(slips["foot"][0]), abs=1e-9)
            assert fe.forces["top"][0] == pytest.approx(-mu_wall * abs(lam[1]) * np.sign(slips["top"][0]), abs=1e-9)
            if mu_floor == 0.0:
                ideal = model.base.solve(0.0, q, w)
                # the same split with zero friction terms: at most rounding times the condition (~140)
                np.testing.assert_allclose(sol.multipliers, ideal.multipliers, rtol=1e-12)


def test_servo_constraints_and_routh_reduction_refuse_frictions():
    """The controlled derivation and Routh reduction do not carry friction: refused, not
    silently frictionless."""
    from appell import Control, derive_controlled, routh_reduction

    u = sp.Symbol("u")
    system = block(0.3, 1.0).replace(
        controls=(Control(u, "force"),),
        generalized_forces=(u, 0),
        servo_constraints=(holonomic("track", x - sp.Symbol("t")),),
    )
    with pytest.raises(ModelError, match="frictions with servo constraints"):
        derive_controlled(system)
    with pytest.raises(ModelError, match="Routh reduction of a system with frictions"):
        routh_reduction(block(0.3, 1.0).replace(potential_energy=m * g * y * sp.cos(al)), ["x"])


def test_a_start_in_the_painleve_region_is_refused_by_simulate_and_the_cli(tmp_path):
    """A rod starting to slide with s = -1 at tan theta = 2 with mu = 1.5 (coefficient
    1.6 - 1.8 < 0): simulate raises the Painlevé refusal naming the contact, and
    `appell simulate` exits with 2 (a refusal, not a crash)."""
    from click.testing import CliRunner

    from appell.io.cli import cli

    theta = math.atan(2.0)
    start = {"x": 0.0, "y": 0.5 * math.sin(theta), "theta": theta, "x_dot": -1.0, "y_dot": 0.0, "theta_dot": 0.0}
    with pytest.raises(PainleveError, match="contact\\(s\\) end"):
        simulate(derive(rod(1.5).replace(initial=start)), 0.1)
    path = tmp_path / "rod.toml"
    path.write_text(f"""
[model]
name = "rod"
coordinates = ["x", "y", "theta"]
[parameters]
m = 1.2
g = 9.81
l = 0.5
mu = 1.5
[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2) + m*l^2/6*theta'^2"
potential_energy = "m*g*y"
[constraints.floor]
kind = "holonomic"
expr = "y - l*sin(theta)"
[[friction]]
name = "end"
slip = "x' + l*sin(theta)*theta'"
normal = "floor"
mu_k = "mu"
[initial]
x = 0
y = {start["y"]!r}
theta = {theta!r}
"x'" = -1
"y'" = 0
"theta'" = 0
""")
    result = CliRunner().invoke(cli, ["simulate", str(path), "--t-end", "0.1"])
    assert result.exit_code == 2 and "Painlevé" in result.output
