"""Seed Example 1 (Dobronravov's car, Do Shan 1974) against its closed form.

Source of every expected value: shared/method.md §6, Example 1 (closed form re-derived
independently and verified against an augmented solve), and §7 for the two misprints of
the printed paper in (1.9) and (1.10). The closed forms are written out here from that
note, not taken from appell.
"""

import json

import numpy as np
import pytest
import sympy as sp

import appell
from appell import derive, load_model, numeric_model
from appell.examples import catalog, example_path
from appell.io.printing import read_json

PARAMS = [  # M, J, a, b, F: the example's values and another car
    {"M": 1200.0, "J": 1500.0, "a": 1.2, "b": 1.5, "F": 800.0},
    {"M": 900.0, "J": 2100.0, "a": 1.6, "b": 0.9, "F": -350.0},
]
# (t, phi, phi_dot): the steering program theta = 0.2 + 0.05 t gives theta = 0.2 ... 1.7
STATES = [(0.0, 0.3, 0.1), (3.0, -1.1, 0.8), (10.0, 2.4, -0.5), (30.0, 0.0, 1.7)]


def closed_form(P, phi, phid, th, thd):
    """method.md §6, Example 1: phi'', x'', y'', lambda_rear, lambda_front (l = a + b)."""
    M, J, a, b, F = P["M"], P["J"], P["a"], P["b"], P["F"]
    l = a + b
    s, c = np.sin(th), np.cos(th)
    phidd = c * (F * l * s**2 + M * l**2 * phid * thd) / (s * (J * s**2 + M * (l**2 * c**2 + b**2 * s**2)))
    A = b * phidd + l * c / s * phid**2
    B = a * c * phidd - a * s * thd * phid - (phid + thd) * phid * (l * c**2 + b * s**2) / s
    xdd = (A * np.cos(phi + th) + B * np.cos(phi)) / s
    ydd = (B * np.sin(phi) + A * np.sin(phi + th)) / s
    lam_rear = F * c / s - M * (xdd * np.cos(phi + th) + ydd * np.sin(phi + th)) / s
    lam_front = (M * (xdd * np.cos(phi) + ydd * np.sin(phi)) - F) / s
    return np.array([xdd, ydd, phidd]), np.array([lam_rear, lam_front])


def admissible_velocity(P, phi, phid, th):
    """(x', y') from the two no-slip constraints of method.md §6 for the given phi'."""
    A = np.array([[np.sin(phi), -np.cos(phi)], [np.sin(phi + th), -np.cos(phi + th)]])
    return np.linalg.solve(A, [-P["b"] * phid, P["a"] * np.cos(th) * phid])


def _cases():
    for P in PARAMS:
        for t, phi, phid in STATES:
            th, thd = 0.2 + 0.05 * t, 0.05
            xd, yd = admissible_velocity(P, phi, phid, th)
            yield P, t, phi, phid, th, thd, [0.4, -0.7, phi], [xd, yd, phid]


@pytest.mark.parametrize("source", ["builder", "model file"])
def test_car_numeric_accelerations_and_axle_forces_match_method_md_closed_form(source):
    """NumPy split solve of catalog.car / examples/car.toml against method.md §6 Example 1."""
    system = catalog.car() if source == "builder" else load_model(example_path("car"))
    model = numeric_model(derive(system))
    for P, t, _phi, _phid, th, thd, q, w in _cases():
        acc, lam = closed_form(P, q[2], w[2], th, thd)
        sol = model.solve(t, q, w, P)
        # rounding, amplified in the closed form by 1/sin(theta) (theta >= 0.2) and by the cancellation
        # of its reaction terms (up to 50 times lambda at theta = 0.2): ~2e-14 of the values
        assert np.allclose(sol.accelerations, acc, rtol=1e-12, atol=1e-12 * np.max(np.abs(acc)))
        assert np.allclose(sol.multipliers, lam, rtol=1e-12, atol=1e-12 * np.max(np.abs(lam)))


def _symbolic_results(exprs, P, t, q, w):
    """Evaluate derived expressions: phi'' from the reduced equation (1.4) (linear in it),
    then x'', y'' from f = 0, then the reaction formulas (1.5)."""
    vals = {sp.Symbol(k): v for k, v in P.items()}
    vals.update(
        {
            sp.Symbol("x"): q[0],
            sp.Symbol("y"): q[1],
            sp.Symbol("phi"): q[2],
            sp.Symbol("x_dot"): w[0],
            sp.Symbol("y_dot"): w[1],
            sp.Symbol("phi_dot"): w[2],
            sp.Symbol("theta"): 0.2 + 0.05 * t,
            sp.Symbol("theta_dot"): 0.05,
            sp.Symbol("t"): t,
        }
    )
    xdd, ydd, phidd = sp.symbols("x_ddot y_ddot phi_ddot")
    dep = exprs["dependent_accelerations"]
    eq = exprs["reduced_equations"][0].xreplace({xdd: dep["x_ddot"], ydd: dep["y_ddot"]}).xreplace(vals)
    phidd_val = float(sp.solve(eq, phidd)[0])
    acc = [float(dep[n].xreplace(vals).xreplace({phidd: phidd_val})) for n in ("x_ddot", "y_ddot")] + [phidd_val]
    at = {**vals, xdd: acc[0], ydd: acc[1], phidd: phidd_val}
    lam = [float(exprs["multipliers"][n].xreplace(at)) for n in ("rear", "front")]
    return np.array(acc), np.array(lam)


def test_car_derived_and_printed_formulas_match_method_md_closed_form():
    """The symbolic (1.4), f = 0 and (1.5) of the derivation, and the same formulas read back
    from ``appell derive --format json``, evaluated at the states, against method.md §6."""
    d = derive(catalog.car(), dependent=["x_ddot", "y_ddot"])
    red = d.reduced
    direct = {
        "reduced_equations": list(red.equations),
        "dependent_accelerations": {a.name: e for a, e in zip(red.dependent, red.dependent_solution)},
        "multipliers": d.reactions.as_dict(),
    }
    printed = read_json(json.loads(json.dumps(appell.to_json(d))))
    for exprs in (direct, printed):
        for P, t, _phi, _phid, th, thd, q, w in _cases():
            acc, lam = closed_form(P, q[2], w[2], th, thd)
            got_acc, got_lam = _symbolic_results(exprs, P, t, q, w)
            # as above, and the derived formulas with 1/sin(theta) evaluated by SymPy: ~1e-13 of lambda
            assert np.allclose(got_acc, acc, rtol=1e-12, atol=1e-12 * np.max(np.abs(acc)))
            assert np.allclose(got_lam, lam, rtol=1e-12, atol=1e-12 * np.max(np.abs(lam)))


def test_car_reduced_equation_force_side_is_F_l_cot_theta_not_zero_as_printed_in_1_9():
    """method.md §7: the right-hand side of (1.9) is sum_h Q_h dq''_h/dphi'' = F l ctg(theta)
    (printed as 0 in the paper). appell exposes dq''_h/dphi'' as the projector C of the
    partition with x'', y'' dependent, and Q as the generalized forces."""
    d = derive(catalog.car(), dependent=["x_ddot", "y_ddot"])
    F, a, b, th, phi = sp.symbols("F a b theta phi")
    C = d.reduced.projector
    Q = d.inertia.generalized_forces
    assert list(d.reduced.independent) == [sp.Symbol("phi_ddot")]
    force_side = sum((Q[h] * C[h, 0] for h in range(3)), sp.S.Zero)  # Q_phi = 0, C[phi] = 1
    assert sp.simplify(force_side - F * (a + b) * sp.cot(th)) == 0

    # the whole corrected (1.9): J phi'' + M/sin(theta) {x'' [b cos(phi+theta) + a cos(theta) cos(phi)]
    #   + y'' [a cos(theta) sin(phi) + b sin(phi+theta)]} = F l ctg(theta)
    M, J = sp.symbols("M J")
    xdd, ydd, phidd = sp.symbols("x_ddot y_ddot phi_ddot")
    lhs = J * phidd + M / sp.sin(th) * (
        xdd * (b * sp.cos(phi + th) + a * sp.cos(th) * sp.cos(phi))
        + ydd * (a * sp.cos(th) * sp.sin(phi) + b * sp.sin(phi + th))
    )
    assert sp.simplify(d.reduced.equations[0] - (lhs - F * (a + b) * sp.cot(th))) == 0


def test_car_front_reaction_formula_has_F_over_sin_theta_not_F_as_printed_in_1_10():
    """method.md §7: the second line of (1.10) reads M/sin(theta) (x'' cos(phi) + y'' sin(phi))
    = F/sin(theta) + lambda_2 (printed with F); the first line M/sin(theta) [x'' cos(phi+theta)
    + y'' sin(phi+theta)] = F ctg(theta) - lambda_1 is as printed."""
    d = derive(catalog.car(), dependent=["x_ddot", "y_ddot"])
    F, M, th, phi = sp.symbols("F M theta phi")
    xdd, ydd = sp.symbols("x_ddot y_ddot")
    lam = d.reactions.as_dict()
    front = M / sp.sin(th) * (xdd * sp.cos(phi) + ydd * sp.sin(phi)) - F / sp.sin(th)
    rear = F * sp.cot(th) - M / sp.sin(th) * (xdd * sp.cos(phi + th) + ydd * sp.sin(phi + th))
    assert sp.simplify(lam["front"] - front) == 0
    assert sp.simplify(lam["rear"] - rear) == 0
    assert sp.simplify(lam["front"] - (front + F / sp.sin(th) - F)) != 0  # the printed line differs
