"""Bounded symbolic work (issue 20): model files whose expressions swell under expansion,
simplification or differentiation finish -- with a correct derivation or a clear
ModelError naming the expression -- instead of running for minutes.

Before the bound (:mod:`appell.core.simplification`), ``appell derive`` ran past 20 s on
e.g. a potential ``(sin(x) + cos(x) + 1)^30`` (``simplify`` of the printed formulas
expanded the power), a constraint times ``(sin(x) + cos(y) + 1)^50`` or a chain of 40
nested ``exp``/``sin`` (the partition's ``tidy`` of the block determinant), a constraint
times a product of 40 sums (its second time derivative) and the bundled rolling disc
(376 s: the cancelling 2 x 2 minors of the printed closed-form solve).

Closed forms: a particle of mass m with T = m/2 x'^2 in a potential V(x) moves by
m x'' = -V'(x); with T = m/2 g(x) x'^2 (no potential), x'' = -g'(x)/(2 g(x)) x'^2. A
constraint F = 0 rewritten as F phi = 0 (phi nonzero) leaves the motion unchanged and
divides the multiplier by phi (its gradient on F = 0 is phi grad F). The pendulum released
at rest at theta = pi/3 from the vertical has x'' = -g sin(theta) cos(theta),
y'' = -g sin(theta)^2 and rod tension m g cos(theta) (src/appell/examples/pendulum.toml).

Every command runs in-process under a hang guard of :data:`GUARD` seconds (SIGALRM): a
guard against unbounded work, not a timed assertion.
"""

from __future__ import annotations

import json
import math
import signal
from contextlib import contextmanager

import numpy as np
import pytest
import sympy as sp
from click.testing import CliRunner

from appell import ModelError, derive, loads_model, numeric_model
from appell.core import simplification as S
from appell.core.kinematics import derivative
from appell.examples import example_path
from appell.io.cli import cli
from appell.io.printing import read_json

#: seconds a command may run before the guard stops the test (a hang guard, not a benchmark)
GUARD = 60

PARTICLE = """\
[model]
name = "well"
coordinates = ["x"]

[parameters]
m = 2.0

[mechanics]
kinetic_energy = "{T}"
potential_energy = "{V}"

[initial]
x = 0.3
"x'" = 0.0
"""

PENDULUM = example_path("pendulum").read_text()
ROD = 'expr = "(L^2 - x^2 - y^2)/(2*L)"'


class Hang(BaseException):
    pass


@contextmanager
def guard(seconds=GUARD):
    def stop(signum, frame):
        raise Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, stop)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def run(tmp_path, text, *args):
    path = tmp_path / "model.toml"
    path.write_text(text, encoding="utf-8")
    with guard():
        return CliRunner().invoke(cli, [*args, str(path)])


def derived_json(tmp_path, text):
    """``appell derive --format json`` of ``text``, read back exactly; the text form too."""
    printed = run(tmp_path, text, "derive")
    assert printed.exit_code == 0, printed.output
    assert "(1.4)" in printed.output
    result = run(tmp_path, text, "derive", "--format", "json")
    assert result.exit_code == 0, result.output
    return read_json(json.loads(result.output))


def value(expr, **values):
    """``expr`` at the named values (symbols matched by name)."""
    return float(sp.sympify(expr).xreplace({s: values[s.name] for s in expr.free_symbols}))


def chain(depth):
    """``exp(sin(exp(sin(... x))))`` of ``depth`` functions (model text) and its value and
    derivative at x (chain rule, in floats)."""
    names = ["exp" if k % 2 == 0 else "sin" for k in range(depth)]
    text = "".join(f"{n}(" for n in names) + "x" + ")" * depth

    def closed(x):
        v, d = x, 1.0
        for n in reversed(names):
            d *= math.exp(v) if n == "exp" else math.cos(v)
            v = math.exp(v) if n == "exp" else math.sin(v)
        return v, d

    return text, closed


def power(n):
    return (
        f"(sin(x) + cos(x) + 1)^{n}",
        lambda x: n * (math.sin(x) + math.cos(x) + 1) ** (n - 1) * (math.cos(x) - math.sin(x)),
    )


def product(k):
    factors = [f"(x + {i})" for i in range(1, k + 1)]
    return "*".join(
        factors
    ), lambda x: math.prod(x + i for i in range(1, k + 1)) * sum(1 / (x + i) for i in range(1, k + 1))


@pytest.mark.parametrize(
    "potential, gradient",
    [
        power(9),
        power(30),
        power(100),
        (chain(30)[0], lambda x: chain(30)[1](x)[1]),
        product(40),
    ],
    ids=["power9", "power30", "power100", "chain30", "product40"],
)
def test_a_swelling_potential_derives_to_m_x_ddot_equal_minus_its_gradient(tmp_path, potential, gradient):
    doc = derived_json(tmp_path, PARTICLE.format(T="m/2*x'^2", V=potential))
    x = 0.3
    (mass,) = doc["reduced_mass_matrix"][0]
    (force,) = doc["reduced_forcing"]
    expected = -gradient(x)
    assert value(mass, x=x, m=2.0) == pytest.approx(2.0, rel=1e-12)
    # the formula evaluated in double precision against the chain rule in double precision:
    # a few rounding errors of each factor, relative
    assert value(force, x=x, m=2.0) == pytest.approx(expected, rel=1e-9)


def test_a_kinetic_energy_with_a_large_power_derives_to_its_closed_form(tmp_path):
    doc = derived_json(tmp_path, PARTICLE.format(T="m/2*(1 + x^2)^30*x'^2", V="0"))
    x, w = 0.3, 0.7
    (mass,) = doc["reduced_mass_matrix"][0]
    (force,) = doc["reduced_forcing"]
    acc = value(force, x=x, x_dot=w, m=2.0) / value(mass, x=x, m=2.0)
    assert acc == pytest.approx(-30 * x / (1 + x * x) * w * w, rel=1e-10)


@pytest.mark.parametrize(
    "factor, phi",
    [
        ("(sin(x) + cos(y) + 1)^50", lambda x, y: (math.sin(x) + math.cos(y) + 1) ** 50),
        (chain(40)[0], lambda x, y: chain(40)[1](x)[0]),
        (product(10)[0], lambda x, y: math.prod(x + i for i in range(1, 11))),
    ],
    ids=["power50", "chain40", "product10"],
)
def test_a_swelling_constraint_keeps_the_motion_and_divides_the_reaction(tmp_path, factor, phi):
    """The pendulum's rod F = 0 written as F phi = 0: at the release the accelerations are
    the pendulum's and lambda is the tension divided by phi (module docstring)."""
    text = PENDULUM.replace(ROD, f'expr = "(L^2 - x^2 - y^2)/(2*L)*{factor}"')
    doc = derived_json(tmp_path, text)
    theta, g = math.pi / 3, 9.81
    x, y = math.sin(theta), -math.cos(theta)
    ax, ay = -g * math.sin(theta) * math.cos(theta), -g * math.sin(theta) ** 2
    state = dict(x=x, y=y, x_dot=0.0, y_dot=0.0, x_ddot=ax, y_ddot=ay, m=1.0, L=1.0, g=g, t=0.0)
    lam = value(doc["multipliers"]["rod"], **state)
    assert lam * phi(x, y) == pytest.approx(g * math.cos(theta), rel=1e-9)
    system = loads_model(text)
    sol = numeric_model(derive(system)).solve(0.0, [x, y], [0.0, 0.0])
    assert np.allclose(sol.accelerations, [ax, ay], rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(
    "where, text, name",
    [
        (
            "constraint",
            PENDULUM.replace(ROD, f'expr = "(L^2 - x^2 - y^2)/(2*L)*{product(150)[0]}"'),
            "holonomic constraint 'rod'",
        ),
        ("potential", PARTICLE.format(T="m/2*x'^2", V=product(400)[0]), "potential_energy"),
        ("kinetic", PARTICLE.format(T=f"m/2*x'^2*{product(300)[0]}", V="0"), "kinetic_energy"),
    ],
)
def test_a_derivative_beyond_the_bound_is_refused_naming_the_expression(tmp_path, where, text, name):
    for command in ("derive", "check"):
        result = run(tmp_path, text, command)
        assert result.exit_code == 2, result.output
        error = next(line for line in result.output.splitlines() if line.startswith("error:"))
        assert name in error and f"{S.NODE_LIMIT:,} nodes" in error, error
        if where == "constraint":
            assert "model.toml:" in error  # the constraint's line
        assert "hint: write the expression in a shorter form" in result.output
        assert "Traceback" not in result.output and "internal error" not in result.output


def test_the_rolling_disc_prints_its_closed_form_solve():
    """Its 3 x 3 reduced mass matrix was solved by cancelling every 2 x 2 minor (minutes);
    over the bound the adjugate is formed as it is. The values are checked against closed
    forms in tests/test_examples_mechanism_files.py."""
    with guard(120):
        result = CliRunner().invoke(cli, ["derive", "rolling_disc", "--only", "motion"])
    assert result.exit_code == 0, result.output
    assert result.output.count("\n  (1.4) ") == 3  # the three free accelerations, solved


# ------------------------------------------------------------------- the measure and the policy
x, y, z = sp.symbols("x y z")


def test_the_measure_sees_the_expanded_size():
    assert S.measure(x * y + 1) == S.Size(nodes=5, expanded=4)
    small, big = (x + y + 1) ** 2, (sp.sin(x) + sp.cos(x) + 1) ** 30
    # C(4, 2) = 6 terms of 2 factors of the sum's 4/3 nodes a term each
    assert S.measure(small) == S.Size(nodes=6, expanded=16)
    assert S.measure(big).nodes < 15 and S.measure(big).expanded == S.SWELL_LIMIT + 1
    assert not S.within_bound(big) and S.within_bound(small)
    assert S.expanded_size(sp.Mul(*[x + i for i in range(20)])) == S.SWELL_LIMIT + 1
    nested = x
    for _ in range(30):  # every level of functions of functions doubles: 2^30
        nested = sp.exp(sp.sin(nested))
    assert S.measure(nested).nodes == 61 and not S.within_bound(nested)


def test_the_measure_stops_early_on_a_huge_tree():
    """A DAG of 2000 levels whose tree has 2^2000 nodes: measured in one walk of the DAG."""
    e = x
    for _ in range(2000):
        e = sp.Add(e, sp.Mul(2, e, evaluate=False), evaluate=False)
    with guard(30):
        size = S.measure(e, limit=10_000)
        assert size.nodes == size.expanded == 10_001
        assert S.tree_size(e, 10_000) == 10_001


def test_tidy_leaves_an_expression_over_the_bound_as_it_is():
    big = sp.cos(x) * (sp.sin(x) + sp.cos(x) + 1) ** 30 - sp.sin(x) * (sp.sin(x) + sp.cos(x) + 1) ** 30
    assert sp.count_ops(big) <= S.TIDY_OPS
    with guard(10):
        assert S.tidy(big) is big
    assert S.tidy(sp.sin(x) ** 2 + sp.cos(x) ** 2) == 1


def test_determinant_and_adjugate_over_the_bound_keep_their_value():
    p = (sp.sin(x) + sp.cos(y) + 1) ** 12
    M = sp.Matrix([[p + x, y * p], [z - p, x * y + p * z]])
    assert not S.within_bound(M[0, 0] * M[1, 1])
    with guard(20):
        det, adj = S.determinant(M), S.adjugate(M)
    point = {x: 0.3, y: -0.4, z: 0.7}
    Mn = np.array(M.xreplace(point).evalf(), dtype=float)
    assert float(det.xreplace(point)) == pytest.approx(np.linalg.det(Mn), rel=1e-12)
    assert np.allclose(
        np.array(adj.xreplace(point).evalf(), dtype=float), np.linalg.det(Mn) * np.linalg.inv(Mn), rtol=1e-12
    )
    small = sp.Matrix([[x, y], [z, x * y]])
    assert S.determinant(small) == small.det(method="bareiss")


def test_the_derivative_estimate_bounds_the_derivative():
    """The estimate that decides before differentiating is an upper bound of SymPy's result."""
    cases = [
        sp.Mul(*[x + i for i in range(1, 12)]),
        (sp.sin(x) + sp.cos(y) + 1) ** 20 * (x - y),
        sp.exp(sp.sin(sp.exp(sp.sin(x * y)))),
        sp.atan(x / y) + sp.sqrt(1 - x**2) * sp.asin(x) + sp.log(x**2 + y**2) * sp.tan(z * x),
        sp.Abs(x * y + sp.sin(z)) * sp.sign(x) + sp.Max(x, y**2),
    ]
    for e in cases:
        actual = sum(S.tree_size(derivative(e, s)) + 2 for s in (x, y, z) if derivative(e, s) != 0)
        assert actual <= S.derivative_nodes(e, [x, y, z]), e


def test_naming_adds_the_expression_and_its_line():
    with pytest.raises(S.ExpressionSwell) as info:
        with S.naming("holonomic constraint 'rod'", "model.toml:21"):
            S.refuse_derivative(sp.Mul(*[x + i for i in range(1, 200)]) * y, [x, y])
    assert info.value.where == "model.toml:21"
    assert info.value.message.startswith("holonomic constraint 'rod': its time derivative would exceed")
    assert isinstance(info.value, ModelError)


def test_vanishes_decides_within_the_bound_exactly_and_over_it_at_random_points():
    """Within the bound, expand decides; over it (expanding (x + 1)^60 would take long) the
    values at random points do: sin^2 + cos^2 - 1 times a swelling factor is zero, a
    difference of two distinct powers is not."""
    assert S.vanishes(sp.expand((x + y) ** 2) - x**2 - 2 * x * y - y**2)
    assert not S.vanishes(x * y - y * x + z)
    swelling = (x + 1) ** 60
    assert not S.within_bound(swelling)
    assert S.vanishes((sp.sin(x) ** 2 + sp.cos(x) ** 2 - 1) * swelling)
    assert not S.vanishes(swelling - (x + 1) ** 59 * (x + 1.5))
    assert not S.vanishes(sp.sqrt(-2 - x**2) * swelling)  # no real value: not shown to vanish
    assert S.vanishes(sp.Matrix([0, (sp.sin(y) ** 2 + sp.cos(y) ** 2 - 1) * swelling]))
