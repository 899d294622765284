"""The internal dynamics left by servo constraints: linearised at a state, and flagged when
unstable (issue 11 §6).

Closed forms (sources):

* cart-pole whose cart follows x_d(t) (catalog: ``servo_examples.cart_pole``): the pendulum
  left over obeys Lagrange's equation of theta with x'' = x_d'',
  ``theta'' = (g/l) sin(theta) - (x_d''/l) cos(theta)`` (theta from the upward vertical) or
  ``theta'' = -(g/l) sin(theta) - (x_d''/l) cos(theta)`` (hanging), so in (theta, theta') the
  Jacobian is ``[[0, 1], [+-(g/l) cos(theta) + (x_d''/l) sin(theta), 0]]``; at theta = 0 the
  eigenvalues are ``+-sqrt(g/l)`` upright and ``+-i sqrt(g/l)`` hanging (Spong,
  "Underactuated mechanical systems", 1998);
* two masses with a spring and a damper, the second tracking y_d (``spring_masses_damped``):
  the internal dynamics ``d (x1' - y_d') + k (x1 - y_d) = m2 y_d''`` is first order in x1
  with eigenvalue ``-k/d`` (the second mass's equation, builder docstring).
"""

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import solve_ivp

import appell
from appell import derive_controlled, numeric_model, simulate
from appell.control.internal_dynamics import internal_linearisation
from appell.examples.servo_examples import appell_ball, cart_pole, spring_masses
from appell.io.cli import cli

G, L = 9.81, 0.5  # the builder's g and l


def _xd_ddot(t):
    return -0.5 * np.sin(t)  # x_d = sin(t)/2


@pytest.fixture(scope="module")
def upright():
    return derive_controlled(cart_pole(upright=True))


@pytest.fixture(scope="module")
def hanging():
    return derive_controlled(cart_pole(upright=False))


def _on_manifold(t, theta, theta_dot):
    """State (x, theta, x', theta') with the cart on its prescribed motion."""
    return [0.5 * np.sin(t), theta, 0.5 * np.cos(t), theta_dot]


@pytest.mark.parametrize("t, theta, theta_dot", [(0.0, 0.0, 0.0), (1.0, 0.4, 0.3), (2.5, -1.2, -0.8)])
def test_cart_pole_linearisation_matches_the_pendulum_jacobian(upright, hanging, t, theta, theta_dot):
    """A_eta in (theta, theta') against the closed-form Jacobian of the driven pendulum."""
    for derivation, sign in ((upright, 1.0), (hanging, -1.0)):
        lin = internal_linearisation(derivation, t, _on_manifold(t, theta, theta_dot))
        assert lin.coordinates == ("theta", "theta_dot")
        expected = np.array([[0.0, 1.0], [sign * G / L * np.cos(theta) + _xd_ddot(t) / L * np.sin(theta), 0.0]])
        # exact differentiation (complex step on the compiled blocks): rounding only
        assert np.allclose(lin.matrix, expected, rtol=1e-12, atol=1e-12 * G / L)
        assert lin.manifold_residual < 1e-12  # an exact state on the manifold: rounding only


def test_upright_pole_is_flagged_unstable_with_eigenvalues_plus_minus_sqrt_g_over_l(upright):
    """At theta = theta' = 0: eigenvalues +-sqrt(g/l) (Spong 1998), growth rate sqrt(g/l)."""
    lin = internal_linearisation(upright, 0.0, _on_manifold(0.0, 0.0, 0.0))
    omega = np.sqrt(G / L)
    # the exact Jacobian (above), a well-separated pair
    assert np.allclose(lin.eigenvalues, [omega, -omega], rtol=1e-13, atol=1e-13 * omega)
    assert lin.unstable and lin.growth_rate == pytest.approx(omega, rel=1e-13)
    assert "unstable" in lin.warning() and "theta" in lin.warning()


def test_hanging_pendulum_eigenvalues_are_plus_minus_i_sqrt_g_over_l_and_not_flagged(hanging):
    lin = internal_linearisation(hanging, 0.0, _on_manifold(0.0, 0.0, 0.0))
    omega = np.sqrt(G / L)
    # as for the upright pole: exact Jacobian
    assert np.allclose(sorted(lin.eigenvalues.imag), [-omega, omega], rtol=1e-13)
    assert np.max(np.abs(lin.eigenvalues.real)) < 1e-13 * omega
    assert not lin.unstable and lin.warning() is None


def test_damped_spring_masses_internal_eigenvalue_is_minus_k_over_d():
    """Internal dynamics d (x1' - y_d') + k (x1 - y_d) = m2 y_d'': eigenvalue -k/d = -8."""
    derivation = derive_controlled(spring_masses(damping=True))
    lin = internal_linearisation(derivation)
    assert lin.eigenvalues.shape == (1,)
    assert lin.eigenvalues[0] == pytest.approx(-4.0 / 0.5, rel=1e-13)  # exact Jacobian: rounding only
    assert not lin.unstable


def test_flat_chain_has_no_internal_dynamics_and_derive_prints_no_empty_section():
    """Flat output (relative degree 4 = state dimension): nothing to linearise, and the text
    says so instead of printing an empty 'internal dynamics:' header."""
    derivation = derive_controlled(spring_masses())
    assert internal_linearisation(derivation) is None
    text = appell.to_text(derivation)
    assert "internal dynamics: none" in text
    lines = text.splitlines()
    for i, line in enumerate(lines):  # no header left without an indented entry below it
        if line.endswith(":"):
            assert i + 1 < len(lines) and lines[i + 1].startswith("  "), line


def test_the_flagged_pole_falls_as_the_closed_form_pendulum_does(upright):
    """Evidence that the warning is right: appell's closed-loop simulation gives the same
    theta(t) as integrating theta'' = (g/l) sin(theta) - (x_d''/l) cos(theta) with SciPy, and
    the pole leaves its start (theta0 = 0.05) by more than a factor 10 within 1 s."""
    times = np.linspace(0.0, 1.0, 11)
    sol = simulate(upright, 1.0, t_eval=times, rtol=1e-10, atol=1e-12)
    ref = solve_ivp(
        lambda t, y: [y[1], G / L * np.sin(y[0]) - _xd_ddot(t) / L * np.cos(y[0])],
        (0.0, 1.0),
        [0.05, 0.0],
        t_eval=times,
        rtol=1e-11,
        atol=1e-13,
    )
    # both runs at rtol <= 1e-10, errors grow as exp(sqrt(g/l) t), about 80 over 1 s
    assert np.allclose(sol["theta"], ref.y[0], rtol=1e-6, atol=1e-8)
    assert abs(sol["theta"][-1]) > 10 * 0.05


def test_cli_flags_the_unstable_internal_dynamics_in_every_command(tmp_path):
    """derive (text and JSON), simulate, check and report warn on stderr and keep exit 0;
    the numbers are those of the closed form at the file's start (theta = 0.05, x_d'' = 0):
    +-sqrt((g/l) cos 0.05)."""
    runner = CliRunner()
    omega = np.sqrt(G / L * np.cos(0.05))
    result = runner.invoke(cli, ["derive", "cart_pole"])
    assert result.exit_code == 0
    assert "UNSTABLE" in result.stdout and "warning: the internal dynamics of 'cart_pole' are unstable" in result.stderr
    result = runner.invoke(cli, ["derive", "cart_pole", "--format", "json"])
    doc = json.loads(result.stdout)
    lin = doc["internal_linearisation"]
    assert lin["unstable"] and lin["coordinates"] == ["theta", "theta_dot"]
    # exact Jacobian (above); the JSON keeps 14 digits
    assert np.allclose(sorted(re for re, _ in lin["eigenvalues"]), [-omega, omega], rtol=1e-12)
    for args in (
        ["simulate", "cart_pole", "--t-end", "0.2"],
        ["check", "cart_pole"],
        ["report", "cart_pole", "-o", str(tmp_path / "pole.html"), "--t-end", "0.2"],
    ):
        result = runner.invoke(cli, args)
        assert result.exit_code == 0, result.output
        assert "internal dynamics of 'cart_pole' are unstable" in result.stderr, args
    page = (tmp_path / "pole.html").read_text(encoding="utf-8")
    assert "<h2 id='internal'>Internal dynamics</h2>" in page and "Unstable" in page
    quiet = runner.invoke(cli, ["derive", "spring_masses"])
    assert quiet.exit_code == 0 and "warning" not in quiet.stderr


def _central_internal_matrix(derivation, time, state, eta):
    """The independent route: central differences (relative step 1e-6) of the whole
    closed-loop solve ``F(t, y)`` and of the manifold residuals ``G``, on the chart ``eta``."""
    from appell.control.internal_dynamics import manifold_function

    model = numeric_model(derivation)
    pv, y0 = model.params(), np.asarray(state, float)
    steps = 1e-6 * np.maximum(1.0, np.abs(y0))

    def jac(fun):
        return np.column_stack([(fun(y0 + e) - fun(y0 - e)) / (2 * h) for h, e in zip(steps, np.diag(steps))])

    manifold = manifold_function(derivation)
    F = jac(lambda y: model.evaluate(time, y, pv).derivative)
    Gy = jac(lambda y: manifold(time, y, pv))
    dep = [j for j in range(y0.size) if j not in eta]
    Z = np.zeros((y0.size, len(eta)))
    Z[eta] = np.eye(len(eta))
    if dep:
        Z[dep] = -np.linalg.lstsq(Gy[:, dep], Gy[:, eta], rcond=None)[0]
    return F[eta] @ Z


@pytest.mark.parametrize(
    "builder",
    [appell_ball, lambda: spring_masses(damping=True), cart_pole],
    ids=["appell_ball", "spring_masses_damped", "cart_pole"],
)
def test_exact_internal_jacobian_agrees_with_central_differences_of_the_closed_loop_solve(builder):
    """A_eta by the exact route (implicit function theorem on E(y, a, xi, lambda) = 0, complex
    step on the compiled blocks) against central differences of the whole numeric solve:
    Appell's ball (two real constraints, two kinematic controls), the damped spring masses
    (underactuated, first-order internal dynamics) and the cart-pole at a moving state.
    Central differences at step 1e-6 carry ~1e-10 relative error (eps/h + h^2)."""
    derivation = derive_controlled(builder())
    model = numeric_model(derivation)
    state = model.initial_state()
    if derivation.system.name == "cart_pole":
        state = np.array(_on_manifold(1.3, 0.7, -0.4))
    lin = internal_linearisation(derivation, 1.3, state)
    eta = [model.state_names.index(c) for c in lin.coordinates]
    reference = _central_internal_matrix(derivation, 1.3, state, eta)
    scale = max(1.0, np.abs(reference).max())
    assert np.abs(lin.matrix - reference).max() < 1e-7 * scale
