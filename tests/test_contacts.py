"""Unilateral constraints that behave like contacts (issue 11, section 4): release with
declared units, re-contact of a released constraint, Newton's impact law with the
impulses by the split, re-engagement and rest after a Zeno sequence of bounces.

Every reference is computed here from a closed form (named at each test) or by an
independent route (the augmented impulse system), never from appell's own output.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner
from scipy.integrate import quad

import appell
from appell import Event, ModelError, numeric_model, simulate
from appell.examples import event_examples, example_path
from appell.io.cli import cli
from appell.io.modelfile import load_model, loads_model
from appell.model import Constraint, Parameter, System, holonomic

G = 9.81


def first_return_to_circle(p0, v0, L, g=G):
    """Time after which the free-flight parabola p(tau) = p0 + v0 tau - g tau^2/2 e_y that
    starts on the circle |p| = L meets it again: the smallest positive root of the quartic
    |p(tau)|^2 - L^2, which has the root tau = 0 (numpy.roots of the remaining cubic; a
    start tangent to the circle, p0.v0 = 0, makes tau = 0 a double root, left out too)."""
    p0, v0 = np.asarray(p0, float), np.asarray(v0, float)
    a = np.array([0.0, -g])
    # |p0 + v0 t + a t^2/2|^2 - L^2 = t (c3 t^3 + c2 t^2 + c1 t + c0)
    c3 = a @ a / 4
    c2 = v0 @ a
    c1 = v0 @ v0 + p0 @ a
    c0 = 2 * p0 @ v0
    roots = np.roots([c3, c2, c1, c0])
    real = roots[np.abs(roots.imag) < 1e-9].real
    return float(min(r for r in real if r > 1e-6))


def radial_tangential(state, L=1.0):
    """Radial (outward) and tangential speed of a bob at (x, y) on the circle of radius L."""
    p = np.array([state["x"], state["y"]])
    v = np.array([state["x_dot"], state["y_dot"]])
    r_hat = p / np.linalg.norm(p)
    t_hat = np.array([-r_hat[1], r_hat[0]])
    return float(v @ r_hat), float(v @ t_hat)


# ------------------------------------------------- the pendulum file with a declared unit
def test_pendulum_file_with_a_rod_unit_goes_slack_and_snaps_taut_instead_of_flying_off():
    """examples/pendulum.toml (lambda_rod declared in N) started at the bottom with
    v0 = 5 m/s, too slow to loop: the string is released where its tension
    m v^2/L + m g cos(phi) vanishes, cos(phi_r) = -(v0^2 - 2 g L)/(3 g L) (energy and the
    radial equation, phi from the bottom; e.g. Kleppner & Kolenkow, circular motion), at the
    time t_r = int_0^phi_r L dphi / v(phi) with v^2 = v0^2 - 2 g L (1 - cos phi). It then
    flies on the free-fall parabola until it is at distance L again (the root of the
    quartic, computed here), where the string snaps taut plastically (e = 0, the file's
    default): the impulse is m v_radial, the tangential speed is kept. The bob never goes
    beyond L (before the fix: "units given for unknown name(s) rod", and without
    re-engagement it flew to 2.64 L)."""
    system = load_model(example_path("pendulum"), overrides={"x": 0.0, "y": -1.0, "x'": 5.0, "y'": 0.0})
    sol = simulate(
        appell.derive(system), 1.5, unilateral={"rod": +1}, t_eval=np.linspace(0.0, 1.5, 301), rtol=1e-11, atol=1e-12
    )
    assert sol.status == 0, sol.message
    assert sol.metadata.units["lambda_rod"] == "N"
    v0, L = 5.0, 1.0
    cos_r = -(v0**2 - 2 * G * L) / (3 * G * L)
    phi_r = math.acos(cos_r)
    t_r, _ = quad(
        lambda phi: L / math.sqrt(v0**2 - 2 * G * L * (1 - math.cos(phi))), 0.0, phi_r, epsabs=1e-14, epsrel=1e-13
    )
    release, snap = sol.events[0], sol.events[1]
    assert release.kind == "release" and release.name == "rod"
    # the release located on the run at rtol 1e-11 (off by ~5e-13, measured); quad's t_r to 1e-13
    assert abs(release.t - t_r) < 1e-7
    assert release.state["x"] == pytest.approx(L * math.sin(phi_r), abs=1e-7)
    assert release.state["y"] == pytest.approx(-L * cos_r, abs=1e-7)

    v_r = math.sqrt(v0**2 - 2 * G * L * (1 - cos_r))
    p0 = np.array([L * math.sin(phi_r), -L * cos_r])
    u0 = v_r * np.array([cos_r, math.sin(phi_r)])
    tau = first_return_to_circle(p0, u0, L)
    p_hit = p0 + u0 * tau + np.array([0.0, -G / 2]) * tau**2
    u_hit = u0 + np.array([0.0, -G]) * tau
    assert snap.kind == "impact" and snap.name == "rod"
    # the flight is a parabola, which DOP853 integrates exactly: the release's error (~5e-13) and
    # numpy.roots' rounding carry over into the snap's time, state, impulse, speeds (~1e-13 measured)
    assert abs(snap.t - (t_r + tau)) < 1e-6
    assert [snap.state["x"], snap.state["y"]] == pytest.approx(p_hit, abs=1e-6)
    radial = float(u_hit @ p_hit) / L
    tangential = float(u_hit @ np.array([-p_hit[1], p_hit[0]])) / L
    assert snap.impulses["rod"] == pytest.approx(1.0 * radial, rel=1e-6)
    after = radial_tangential(snap.state_after)
    assert after[0] == pytest.approx(0.0, abs=1e-9)  # e = 0 zeroes J v: rounding only (~2e-16)
    assert after[1] == pytest.approx(tangential, rel=1e-6)
    assert "engages again" in snap.detail
    r = np.hypot(sol["x"], sol["y"])
    assert np.max(r) < L * (1 + 1e-8)  # |p| drifts from L by the run's error (rtol 1e-11: 2.5e-12 measured)


# ------------------------------------------------------ leaving a sphere onto a floor
def test_particle_leaving_a_sphere_lands_on_the_floor_where_the_parabola_meets_it():
    """particle_on_sphere (theta0 = 0.4) on a sphere of radius R resting on a floor y = -R
    (restitution e = 0.5). It leaves the sphere at cos(theta) = (2/3) cos(theta0) with the
    speed v^2 = (2/3) g R cos(theta0) along the tangent (the textbook problem, see
    event_examples.particle_on_sphere), then flies on the parabola
    y_r + v_y tau - g tau^2/2 = -R: lands at tau = (v_y + sqrt(v_y^2 + 2 g (y_r + R)))/g,
    x = x_r + v_x tau, and the floor's impulse is (1 + e) m |v_n| (Newton), with the
    vertical speed reversed by the factor e and the horizontal one kept."""
    e, theta0, R = 0.5, 0.4, 1.0
    base = event_examples.particle_on_sphere(theta0)
    system = base.replace(
        constraints=base.constraints + (holonomic("floor", sp.Symbol("y") + sp.Symbol("R"), restitution=e),)
    )
    sol = simulate(appell.derive(system), 1.5, unilateral={"surface": +1, "floor": +1}, rtol=1e-12, atol=1e-13)
    assert sol.status == 0, sol.message
    assert sol.log[0].startswith("t = 0: the gap of contact(s) floor is open")
    (release,) = [ev for ev in sol.events if ev.kind == "release"]
    impacts = sol.impacts
    assert impacts[0].name == "floor" and all(ev.name == "floor" for ev in impacts)  # the sphere is never hit
    cos_r = 2.0 / 3.0 * math.cos(theta0)
    sin_r = math.sqrt(1 - cos_r**2)
    speed = math.sqrt(2.0 / 3.0 * G * R * math.cos(theta0))
    x_r, y_r, vx, vy = R * sin_r, R * cos_r, speed * cos_r, -speed * sin_r
    # the release located on the run at rtol 1e-12 (~1e-13 off, measured)
    assert [release.state[k] for k in ("x", "y", "x_dot", "y_dot")] == pytest.approx([x_r, y_r, vx, vy], abs=1e-8)
    tau = (vy + math.sqrt(vy**2 + 2 * G * (y_r + R))) / G
    landing = impacts[0]
    # the flight is a parabola, integrated exactly: only the release's error (~1e-13) carries over,
    # into the landing state and Newton's law applied to it
    assert abs(landing.t - (release.t + tau)) < 1e-9
    assert landing.state["x"] == pytest.approx(x_r + vx * tau, abs=1e-9)
    assert landing.state["y"] == pytest.approx(-R, abs=1e-9)
    v_n = vy - G * tau
    assert landing.impulses["floor"] == pytest.approx((1 + e) * 1.0 * abs(v_n), rel=1e-9)
    assert landing.state_after["y_dot"] == pytest.approx(-e * v_n, rel=1e-9)
    # x' is kept exactly by the flight and the impact: the release's error alone, from the run at
    # rtol 1e-12 (6e-14 measured)
    assert landing.state_after["x_dot"] == pytest.approx(vx, rel=1e-12)
    assert landing.state_after["y"] == landing.state["y"]  # an impact changes the speeds only
    assert np.all(sol["y"] >= -R - 1e-9)  # the impacts keep the gap >= 0 to the events' rounding


# ------------------------------------------------------- a string that snaps taut
@pytest.mark.parametrize("e", [0.0, 0.3, 1.0])
def test_slack_string_snaps_taut_and_loses_the_energy_newtons_law_says(e):
    """slack_pendulum: started at the top with v0 = 2 m/s < sqrt(g L), the tension
    m v0^2/L - m g < 0 releases the string at once; the bob flies on x = v0 t,
    y = L - g t^2/2 and the string is taut again at t* = 2 sqrt(g L - v0^2)/g. Newton's law
    there: the radial speed v_r reverses with the factor e, the tangential one is kept, the
    impulse is m (1 + e) v_r and the energy lost is m (1 - e^2) v_r^2 / 2 (computed here
    from the closed-form state at t*). With e = 0 the string stays taut and its tension
    just after is the pendulum's m v^2/L - m g y/L."""
    v0, L, m = 2.0, 1.0, 1.0
    d = appell.derive(event_examples.slack_pendulum(v0, e))
    sol = simulate(d, 0.6, unilateral={"rod": +1}, rtol=1e-11, atol=1e-12, t_eval=np.linspace(0.0, 0.6, 61))
    assert sol.status == 0, sol.message
    assert sol.events[0].kind == "release" and sol.events[0].t == 0.0
    # the split's formula at the given start: rounding only
    assert sol.events[0].multipliers["rod"] == pytest.approx(m * v0**2 / L - m * G, rel=1e-12)
    t_star = 2 * math.sqrt(G * L - v0**2) / G
    snap = sol.impacts[0]
    # the flight from the exact start is a parabola, integrated exactly: the event's root (brentq,
    # xtol 1e-13) and the state at it (~1e-13 measured)
    assert abs(snap.t - t_star) < 1e-9
    x, y, vx, vy = v0 * t_star, L - G * t_star**2 / 2, v0, -G * t_star
    assert [snap.state[k] for k in ("x", "y", "x_dot", "y_dot")] == pytest.approx([x, y, vx, vy], abs=1e-8)
    v_r = (x * vx + y * vy) / L
    v_t = (-y * vx + x * vy) / L
    radial, tangential = radial_tangential(snap.state_after, L)
    # Newton's law at the snap state, off the closed form's by its ~1e-13 (above)
    assert radial == pytest.approx(-e * v_r, abs=1e-9)
    assert tangential == pytest.approx(v_t, rel=1e-9)
    assert snap.impulses["rod"] == pytest.approx(m * (1 + e) * v_r, rel=1e-9)

    def energy(s):
        return m / 2 * (s["x_dot"] ** 2 + s["y_dot"] ** 2) + m * G * s["y"]

    # energies of ~10 J differenced: rounding, a few eps x 10 (e = 1 loses 0: approx's abs 1e-12)
    assert energy(snap.state) - energy(snap.state_after) == pytest.approx(m * (1 - e**2) * v_r**2 / 2, rel=1e-9)
    if e == 0.0:
        assert "engages again" in snap.detail
        later = (sol.t > snap.t) & (sol.t < snap.t + 0.05)
        assert np.any(later)
        v2 = sol["x_dot"][later] ** 2 + sol["y_dot"][later] ** 2
        # both from the same states: they differ by the states' drift off |p| = L (rtol 1e-11 run;
        # ~3e-11 relative measured)
        np.testing.assert_allclose(sol["lambda_rod"][later], m * v2 / L - m * G * sol["y"][later] / L, rtol=1e-7)
    else:
        assert "bounces" in snap.detail


# ------------------------------------------------------------ the bouncing ball
def test_bouncing_ball_rebound_speeds_apex_heights_and_rest():
    """bouncing_ball.toml (h0 = 1 m, e = 0.8). Newton's law at each impact: the n-th
    rebound speed is e^n v0, v0 = sqrt(2 g h0), so the n-th apex is at h_n = e^(2n) h0
    (not e^n: the height goes with the square of the speed); impacts at t1 = sqrt(2 h0/g)
    and t_(n+1) = t_n + 2 e^n v0/g, each with the impulse m (1 + e) e^(n-1) v0. The flights
    sum to a finite time: the ball comes to rest at t_inf = t1 + 2 e v0/(g (1 - e)) (a
    geometric series) and then lies on the floor, lambda_floor = m g."""
    system = load_model(example_path("bouncing_ball"))
    (floor,) = system.constraints
    assert floor.restitution == 0.8
    e, h0, m, vx = 0.8, 1.0, 1.0, 0.5
    v0, t1 = math.sqrt(2 * G * h0), math.sqrt(2 * h0 / G)
    t_inf = t1 + 2 * e * v0 / (G * (1 - e))
    sol = simulate(appell.derive(system), events=[Event("apex", sp.Symbol("y_dot"), direction=-1)])
    assert sol.status == 0, sol.message
    impacts = sol.impacts
    times = [t1]
    for n in range(1, 12):
        times.append(times[-1] + 2 * e**n * v0 / G)
    # the flights are parabolas, integrated exactly: only the events' rounding, summed over the
    # impacts (~2e-13 in t, ~6e-13 relative in the speeds, measured)
    for n, ev in enumerate(impacts[:12]):
        assert abs(ev.t - times[n]) < 1e-8, n
        assert ev.state["y_dot"] == pytest.approx(-(e**n) * v0, rel=1e-8)
        assert ev.state_after["y_dot"] == pytest.approx(e ** (n + 1) * v0, rel=1e-8)
        assert ev.impulses["floor"] == pytest.approx(m * (1 + e) * e**n * v0, rel=1e-8)
        assert ev.state_after["x_dot"] == vx
    apexes = [ev for ev in sol.events if ev.name == "apex" and ev.t < t_inf - 1e-3]
    assert len(apexes) >= 10
    for n, ev in enumerate(apexes[:10], start=1):
        assert ev.state["y"] == pytest.approx(e ** (2 * n) * h0, rel=1e-7), n  # as above (~2e-13)
    # rest: the last impact is plastic (rebound below rest_speed) and the floor engages again:
    # the first n with e^(n+1) v0 <= rest_speed (1e-6, the default), at the sum of the series up to
    # it, t_inf - 2 e^(n+1) v0 / (g (1 - e)) (9.3e-7 s before t_inf); its error as above (~2e-13)
    last = impacts[-1]
    n_rest = math.ceil(math.log(1e-6 / v0) / math.log(e)) - 1
    assert len(impacts) == n_rest + 1
    t_rest = t_inf - 2 * e ** (n_rest + 1) * v0 / (G * (1 - e))
    assert "engages again" in last.detail and abs(last.t - t_rest) < 1e-8
    assert all("bounces" in ev.detail for ev in impacts[:-1])
    resting = sol.t > t_inf + 1e-3
    assert np.all(np.abs(sol["y"][resting]) < 1e-12)  # where the plastic impact left it (~3e-20), y' = 0
    np.testing.assert_allclose(sol["lambda_floor"][resting], m * G, rtol=1e-12)  # the split at y' = 0: rounding
    # x' = vx is kept by every impact and x is linear in t, integrated exactly: rounding only (~1e-15)
    np.testing.assert_allclose(sol["x"][resting], vx * sol.t[resting], rtol=1e-9)
    assert np.all(sol["lambda_floor"][sol.t < t_inf - 1e-3] == 0.0)  # released in flight


def test_a_larger_rest_speed_ends_the_bounces_earlier():
    """With rest_speed above the n-th rebound speed e^n v0 but below e^(n-1) v0, the n-th
    impact is the plastic one (Newton's law gives the rebound speeds, bouncing_ball)."""
    e, v0 = 0.8, math.sqrt(2 * G)
    d = appell.derive(event_examples.bouncing_ball(1.0, e))
    sol = simulate(d, 5.0, unilateral={"floor": +1}, rest_speed=0.5 * (e**3 + e**4) * v0, rtol=1e-10, atol=1e-12)
    assert len(sol.impacts) == 4 and "engages again" in sol.impacts[3].detail
    # e = 0 at the resting impact: zero up to rounding
    assert sol.impacts[3].state_after["y_dot"] == 0.0 or abs(sol.impacts[3].state_after["y_dot"]) < 1e-12


# ------------------------------------- an impact with another constraint kept engaged
def _spherical_pendulum_over_a_floor(e):
    x, y, z = sp.symbols("x y z")
    xd, yd, zd = sp.symbols("x_dot y_dot z_dot")
    m, L, g, h = sp.symbols("m L g h")
    theta0, u, w = 1.2, 1.0, 0.8
    p0 = np.array([math.sin(theta0), 0.0, -math.cos(theta0)])
    theta_hat = np.array([math.cos(theta0), 0.0, math.sin(theta0)])
    v0 = -u * theta_hat + w * np.array([0.0, 1.0, 0.0])
    return System(
        name="pendulum_over_floor",
        coordinates=(x, y, z),
        parameters=(Parameter(m, 1.0), Parameter(L, 1.0), Parameter(g, G), Parameter(h, 0.8)),
        kinetic_energy=m / 2 * (xd**2 + yd**2 + zd**2),
        potential_energy=m * g * z,
        constraints=(holonomic("rod", (L**2 - x**2 - y**2 - z**2) / (2 * L)), holonomic("floor", z + h, restitution=e)),
        initial=dict(zip(("x", "y", "z", "x_dot", "y_dot", "z_dot"), [*p0, *v0])),
    )


@pytest.mark.parametrize("e", [0.0, 0.6])
def test_impact_with_the_rod_kept_engaged_matches_the_augmented_impulse_system(e):
    """A spherical pendulum (bilateral rod) swinging onto a floor z = -h: the rod stays
    engaged through the impact. Independent route: the augmented impulse system
    [M -J^T; J 0] [dv; Lambda] = [0; r] with J the rows dF/dq of rod and floor and
    r = (0, -(1 + e) v_z) (numpy.linalg.solve here). Closed form: the impulse lies in the
    plane of the rod and the vertical, so the velocity component normal to that plane is
    kept, the one in it (along the circle) reverses with the factor e."""
    d = appell.derive(_spherical_pendulum_over_a_floor(e))
    sol = simulate(d, 0.5, unilateral={"floor": +1}, rtol=1e-11, atol=1e-12)
    assert sol.status == 0, sol.message
    hit = sol.impacts[0]
    assert set(hit.impulses) == {"floor", "rod"}
    p = np.array([hit.state[k] for k in ("x", "y", "z")])
    v = np.array([hit.state[k] for k in ("x_dot", "y_dot", "z_dot")])
    v_after = np.array([hit.state_after[k] for k in ("x_dot", "y_dot", "z_dot")])
    J = np.array([-p / 1.0, [0.0, 0.0, 1.0]])
    K = np.block([[np.eye(3), -J.T], [J, np.zeros((2, 2))]])
    ref = np.linalg.solve(K, np.concatenate([np.zeros(3), [0.0, -(1 + e) * v[2]]]))
    # two routes at the same state: rounding times cond(K) = 11, |dv| ~ 4 (~1e-15 measured)
    np.testing.assert_allclose(v_after - v, ref[:3], rtol=0, atol=1e-12)
    assert [hit.impulses["rod"], hit.impulses["floor"]] == pytest.approx(ref[3:], rel=1e-10)
    r_hat = p / np.linalg.norm(p)
    n_hat = np.cross(r_hat, [0.0, 0.0, 1.0])
    n_hat /= np.linalg.norm(n_hat)
    t_hat = np.cross(n_hat, r_hat)
    assert v_after @ n_hat == pytest.approx(v @ n_hat, rel=1e-10)  # rounding only (~2e-16)
    # the closed form assumes v.r_hat = 0: the hit state keeps the run's drift off it (~3e-12 at
    # rtol 1e-11, atol 1e-12, measured), which the impulse leaves unchanged
    assert v_after @ t_hat == pytest.approx(-e * (v @ t_hat), rel=1e-10, abs=1e-10)
    assert v_after @ r_hat == pytest.approx(0.0, abs=1e-10)
    assert np.all(sol["z"] >= -0.8 - 1e-9)  # the impact keeps the gap >= 0 to the event's rounding


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize("bad", [1.5, -0.1, True, "0.5", float("nan")])
def test_restitution_outside_zero_to_one_is_refused(bad):
    with pytest.raises(ModelError, match="restitution coefficient"):
        holonomic("floor", sp.Symbol("y"), restitution=bad)


def test_restitution_needs_a_holonomic_constraint():
    with pytest.raises(ModelError, match="needs a holonomic constraint"):
        Constraint("slip", sp.Symbol("x_dot"), 1, restitution=0.5)


CONTACT_TOML = """\
[model]
coordinates = ["x", "y"]

[parameters]
m = 1.0

[mechanics]
kinetic_energy = "m/2*(x'^2 + y'^2)"
potential_energy = "9.81*m*y"

[constraints.floor]
kind = "{kind}"
expr = "{expr}"
restitution = {e}
"""


def test_model_file_restitution_is_read_and_bad_values_are_located():
    system = loads_model(CONTACT_TOML.format(kind="holonomic", expr="y", e="0.25"), source="c.toml")
    assert system.constraints[0].restitution == 0.25
    with pytest.raises(ModelError) as high:
        loads_model(CONTACT_TOML.format(kind="holonomic", expr="y", e="2"), source="c.toml")
    assert high.value.where == "c.toml:14" and "from 0 to 1" in high.value.message
    with pytest.raises(ModelError) as kind:
        loads_model(CONTACT_TOML.format(kind="first-order", expr="y'", e="0.5"), source="c.toml")
    assert kind.value.where == "c.toml:14" and "holonomic" in kind.value.message
    servo = CONTACT_TOML.format(kind="holonomic", expr="y", e="0.5").replace(
        "[constraints.floor]", '[controls]\nF = "force"\n[servo_constraints.floor]'
    )
    with pytest.raises(ModelError, match="unknown key 'restitution'"):
        loads_model(servo, source="c.toml")


def test_rest_speed_must_be_positive():
    d = appell.derive(event_examples.bouncing_ball())
    with pytest.raises(ModelError, match="rest_speed"):
        simulate(d, 1.0, unilateral={"floor": +1}, rest_speed=0.0)
    text = CONTACT_TOML.format(kind="holonomic", expr="y", e="0.5") + "\n[simulation]\nrest_speed = -1\n"
    with pytest.raises(ModelError, match="must be positive"):
        loads_model(text, source="c.toml")


def test_a_contact_that_overlaps_at_the_start_is_refused_by_name():
    """A gap below zero beyond the tolerance is not a contact that starts open: the
    initial values violate the constraint and the check names it."""
    d = appell.derive(event_examples.bouncing_ball())
    with pytest.raises(ModelError, match="floor"):
        simulate(d, 1.0, unilateral={"floor": +1}, initial={"x": 0.0, "y": -0.1, "x_dot": 0.0, "y_dot": 0.0})


# ------------------------------------------------------------------ command line
def test_cli_simulates_the_slack_pendulum_file(tmp_path):
    """appell simulate slack_pendulum: exit 0, the snap at t* = 2 sqrt(g L - v0^2)/g
    (event_examples.slack_pendulum) is in the summary, the bob stays within L."""
    out = tmp_path / "slack.csv"
    result = CliRunner().invoke(cli, ["simulate", "slack_pendulum", "--t-end", "1", "--out", str(out)])
    assert result.exit_code == 0, result.output
    t_star = 2 * math.sqrt(G - 4.0) / G
    impacts = [float(m) for m in re.findall(r"t = ([0-9.e+-]+): impact rod", result.output)]
    # the summary prints t to 10 digits (9e-12 off here); the event itself is exact to ~1e-14
    assert impacts and abs(impacts[0] - t_star) < 1e-8
    data = np.genfromtxt(out, delimiter=",", names=True)
    # |p| drifts from L by the file's run error (rtol 1e-10, atol 1e-12: 2.2e-10 measured)
    assert np.max(np.hypot(data["x"], data["y"])) < 1 + 1e-8


@pytest.mark.skipif(__import__("shutil").which("cc") is None, reason="no C compiler")
def test_compiled_backend_gives_the_same_snap_as_the_closed_form():
    """slack_pendulum run on the C backend (the released and re-engaged models are derived
    again with NumPy; the impact uses the compiled model's blocks): the snap at
    t* = 2 sqrt(g L - v0^2)/g with the impulse m (1 + e) v_r (event_examples.slack_pendulum)."""
    e, v0, L = 0.3, 2.0, 1.0
    compiled = numeric_model(appell.derive(event_examples.slack_pendulum(v0, e)), "c")
    sol = simulate(compiled, 0.6, unilateral={"rod": +1}, rtol=1e-11, atol=1e-12)
    t_star = 2 * math.sqrt(G * L - v0**2) / G
    snap = sol.impacts[0]
    # as on NumPy: the parabola integrated exactly, the event's root to ~1e-13
    assert abs(snap.t - t_star) < 1e-9
    x, y, vx, vy = v0 * t_star, L - G * t_star**2 / 2, v0, -G * t_star
    assert snap.impulses["rod"] == pytest.approx((1 + e) * (x * vx + y * vy) / L, rel=1e-9)
