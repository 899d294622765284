"""Redundant constraints (statically indeterminate supports): detection, consistency,
motion from the independent rows, minimum-norm and compliant multipliers.

Closed forms (named per test): the plane fit of a rigid cap on equal elastic supports
(pile-group formula, Bowles, Foundation Analysis and Design), the door on two hinges
(moments about a hinge, Meriam & Kraige, Statics), the rigid beam on elastic supports
(Timoshenko, Strength of Materials I), a block sliding on a frictionless incline.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from appell import ModelError, Parameter, System, cross_check, derive, holonomic, numeric_model, simulate
from appell.examples.support_examples import door_two_hinges, shaft_three_bearings, table_four_legs

G = 9.81


def _at_start(d, backend="numpy"):
    model = numeric_model(d) if backend == "numpy" else numeric_model(d, backend)
    q0 = np.array([d.system.initial_values[s.name] for s in d.kinematics.coordinates])
    sol = model.solve(0.0, q0, np.zeros(len(d.kinematics.speeds)))
    return dict(zip(model.constraint_names, sol.multipliers)), sol


def _plane_fit(m, xc, yc, corners):
    """N_i = m g/4 + m g x_c x_i / sum x^2 + m g y_c y_i / sum y^2 (rectangle centred at 0)."""
    sx = sum(x * x for x, _ in corners)
    sy = sum(y * y for _, y in corners)
    return [m * G / 4 + m * G * xc * x / sx + m * G * yc * y / sy for x, y in corners]


CORNERS = [(0.6, 0.4), (-0.6, 0.4), (-0.6, -0.4), (0.6, -0.4)]


def test_table_redundancy_is_reported_with_rank_names_and_null_space():
    d = derive(table_four_legs())
    red = d.redundancy
    assert (red.rank, red.dimension) == (3, 1)
    assert red.named("independent") == ("leg_1", "leg_2", "leg_3")
    assert red.named("redundant") == ("leg_4",)
    assert red.named("involved") == ("leg_1", "leg_2", "leg_3", "leg_4")
    # null(J^T) at rest: rows (1, y_i, -x_i); the alternating vector (1, -1, 1, -1) annihilates J^T
    n = red.null_space[:, 0]
    # SVD of the row-scaled J (singular values 2, 1.2, 0.8): rounding only (measured 2e-16)
    assert np.allclose(n / n[0], [1, -1, 1, -1], rtol=0, atol=1e-12)
    assert d.constraints.names == ("leg_1", "leg_2", "leg_3")
    text = "\n".join(red.summary())
    assert "dim null(J^T) = 1" in text
    assert "rigid-body mechanics fixes only J^T lambda, not how it is shared" in text
    assert "minimum-norm solution" in text and "row-scaled norm" in text


def test_table_symmetric_load_each_leg_carries_a_quarter():
    """Mass centre at the plate's centre: each leg m g / 4 (symmetry)."""
    s = table_four_legs()
    s = s.replace(
        parameters=tuple(
            p if p.symbol.name not in ("x_c", "y_c") else Parameter(p.symbol, 0.0, p.unit) for p in s.parameters
        )
    )
    lam, _ = _at_start(derive(s))
    # the split and the null-space step, J of condition 2.5: rounding only (measured 7e-15 N)
    assert np.allclose(list(lam.values()), 20.0 * G / 4, rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_table_offset_load_minimum_norm_is_the_plane_fit_and_sums_to_mg(backend):
    """Offset mass centre (0.15, 0.05): the legs sum to m g to 1e-12 (the determined part)
    and the minimum-norm split equals the plane fit (Bowles' rigid-cap formula): the rows
    (1, y_i, -x_i) have equal scales, so the minimum norm is the equal-stiffness solution
    lambda = J dq."""
    lam, _ = _at_start(derive(table_four_legs()), backend)
    values = np.array([lam[f"leg_{i}"] for i in range(1, 5)])
    # J of condition 2.5: rounding only (measured 1.5e-16 relative, 2e-14 N)
    assert abs(values.sum() - 20.0 * G) <= 1e-12 * 20.0 * G
    assert np.allclose(values, _plane_fit(20.0, 0.15, 0.05, CORNERS), rtol=0, atol=1e-11)


def test_table_equal_compliance_is_the_plane_fit_and_unequal_compliance_is_not():
    """Equal leg stiffness k: N_i = k (dz + y_i dphi - x_i dtheta), the plane fit. Unequal
    stiffness k_i: the same three equilibrium equations, sum k_i (A + B x_i + C y_i)(1, x_i, y_i)
    = m g (1, x_c, y_c), solved here by hand (independent of the library's null space)."""
    lam_eq, _ = _at_start(derive(table_four_legs(compliance=1e-6)))
    # equal weights: the minimum-norm step again, rounding only (measured 1.4e-14 N)
    assert np.allclose(
        [lam_eq[f"leg_{i}"] for i in range(1, 5)], _plane_fit(20.0, 0.15, 0.05, CORNERS), rtol=0, atol=1e-9
    )
    s = table_four_legs()
    c = [1e-6, 2e-6, 1e-6, 4e-6]
    s = s.replace(constraints=tuple(holonomic(k.name, k.expr, compliance=ci) for k, ci in zip(s.constraints, c)))
    lam, _ = _at_start(derive(s))
    k = [1 / ci for ci in c]
    A = np.array(
        [
            [
                sum(ki * f(x, y) * g(x, y) for ki, (x, y) in zip(k, CORNERS))
                for f in (lambda x, y: 1, lambda x, y: x, lambda x, y: y)
            ]
            for g in (lambda x, y: 1, lambda x, y: x, lambda x, y: y)
        ]
    )
    coef = np.linalg.solve(A, 20.0 * G * np.array([1.0, 0.15, 0.05]))
    expected = [ki * (coef[0] + coef[1] * x + coef[2] * y) for ki, (x, y) in zip(k, CORNERS)]
    got = [lam[f"leg_{i}"] for i in range(1, 5)]
    # the hand 3 x 3 (condition 9) against the weighted null-space step: rounding only
    # (measured 1e-15 relative)
    assert np.allclose(got, expected, rtol=1e-10, atol=0)
    assert not np.allclose(got, _plane_fit(20.0, 0.15, 0.05, CORNERS), rtol=1e-3)  # 39 to 85 % apart
    assert abs(sum(got) - 20.0 * G) <= 1e-12 * 20.0 * G  # rounding only (measured exact)


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_door_horizontal_couple_is_mgd_over_h_and_vertical_split_is_reported_undetermined(backend):
    """Door of mass 30 kg, mass centre 0.45 m from the hinge line, hinges 1.6 m apart:
    moments about the lower hinge give the horizontal couple m g d / h = 82.771875 N
    exactly; only the sum of the vertical forces (m g) is determined."""
    d = derive(door_two_hinges())
    lam, _ = _at_start(d, backend)
    couple = 30.0 * G * 0.45 / 1.6
    # J of condition 1.25, M of 6: rounding only, a few ulp (measured at most 1 ulp of
    # 294 N, 5.7e-14, on the sum)
    assert lam["bottom_x"] == pytest.approx(couple, abs=1e-12)
    assert lam["top_x"] == pytest.approx(-couple, abs=1e-12)
    assert lam["top_z"] + lam["bottom_z"] == pytest.approx(30.0 * G, abs=1e-12)
    assert lam["top_z"] == pytest.approx(30.0 * G / 2, abs=1e-11)  # minimum norm: equal shares
    red = d.redundancy
    assert red.named("involved") == ("top_z", "bottom_z")
    assert red.named("determined") == ("top_x", "bottom_x")


def test_shaft_in_three_elastic_bearings_matches_the_beam_on_springs():
    """N_i = k_i (dy + x_i dpsi) with sum N_i = m g, sum N_i x_i = m g x_G (Timoshenko);
    the 2 x 2 system solved by Cramer's rule."""
    lam, _ = _at_start(derive(shaft_three_bearings()))
    x, c = [0.0, 0.5, 1.2], [2e-8, 1e-8, 4e-8]
    k = [1 / ci for ci in c]
    S0, S1, S2 = sum(k), sum(ki * xi for ki, xi in zip(k, x)), sum(ki * xi * xi for ki, xi in zip(k, x))
    W, M = 40.0 * G, 40.0 * G * 0.7
    det = S0 * S2 - S1 * S1
    dy, dpsi = (W * S2 - S1 * M) / det, (S0 * M - S1 * W) / det
    expected = [ki * (dy + xi * dpsi) for ki, xi in zip(k, x)]
    # Cramer's rule on a 2 x 2 of condition 11 against the weighted null-space step: rounding
    # only (measured 3e-15 relative)
    assert np.allclose([lam[f"bearing_{i}"] for i in (1, 2, 3)], expected, rtol=1e-11, atol=0)


def test_rigid_shaft_minimum_norm_differs_from_the_elastic_split():
    """Without compliances the rows (1, x_i) have scales max(1, x_i): bearing 3's row is
    scaled by 1/1.2, so the minimum row-scaled norm is not the equal-stiffness split."""
    lam_r, _ = _at_start(derive(shaft_three_bearings(rigid=True)))
    lam_e, _ = _at_start(derive(shaft_three_bearings()))
    assert sum(lam_r.values()) == pytest.approx(40.0 * G, abs=1e-11)  # rounding (measured 6e-14 N)
    assert not np.allclose(list(lam_r.values()), list(lam_e.values()), rtol=1e-3)  # 31 to 240 % apart


@pytest.mark.parametrize("build", [table_four_legs, door_two_hinges, shaft_three_bearings])
def test_cross_check_against_least_squares_of_the_whole_systems(build):
    """The split's multipliers against the KKT system of min lambda^T W lambda (augmented
    blocks and Lagrange's blocks, all constraints, solved by least squares)."""
    rep = cross_check(derive(build()))
    # cross_check's own tolerance; the routes differ by rounding only (measured at most 9e-15)
    assert rep.largest[0] < 1e-9, rep


def test_inconsistent_redundant_legs_are_refused_naming_the_leg():
    """A leg 1 cm short under a rigid plate: the four corners are not coplanar (L1 + L3 != L2 + L4)."""
    s = table_four_legs()
    cons = list(s.constraints)
    cons[3] = holonomic("leg_4", cons[3].expr + 0.01)
    with pytest.raises(ModelError, match=r"inconsistent.*leg_4 \(position residual 0\.01"):
        derive(s.replace(constraints=tuple(cons)))


def test_compliance_on_part_of_the_undetermined_set_is_refused():
    s = table_four_legs()
    cons = list(s.constraints)
    cons[0] = holonomic("leg_1", cons[0].expr, compliance=1e-6)
    with pytest.raises(ModelError, match="leg_2, leg_3, leg_4 have none"):
        derive(s.replace(constraints=tuple(cons)))


def _sliding_table():
    """A planar plate on three vertical legs (x_i = -0.5, 0.1, 0.7) whose feet slide without
    friction on an incline of slope angle alpha: leg_i = z - x_i sin(th) - L - tan(alpha)
    (x + x_i cos(th)); three constraints of rank 2, one degree of freedom. The plate moves
    as a block on the incline: x'' = -g sin(alpha) cos(alpha), and the legs' vertical
    multipliers sum to m (g + z'') = m g cos^2(alpha)."""
    x, z, th = sp.symbols("x z theta")
    xd, zd, thd = sp.symbols("x_dot z_dot theta_dot")
    m, g, L, al, I = sp.symbols("m g L alpha I")
    legs = [
        holonomic(f"leg_{i + 1}", z - xi * sp.sin(th) - L - sp.tan(al) * (x + xi * sp.cos(th)))
        for i, xi in enumerate((-0.5, 0.1, 0.7))
    ]
    a0 = 0.3
    return System(
        name="sliding_table",
        coordinates=(x, z, th),
        parameters=(Parameter(m, 5.0), Parameter(g, G), Parameter(L, 0.8), Parameter(al, a0), Parameter(I, 0.4)),
        kinetic_energy=m / 2 * (xd**2 + zd**2) + I / 2 * thd**2,
        potential_energy=m * g * z,
        constraints=tuple(legs),
        initial={"x": 0.0, "z": 0.8, "theta": -a0, "x_dot": 0.2, "z_dot": 0.2 * np.tan(a0), "theta_dot": 0.0},
    ), a0


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_sliding_table_motion_keeps_the_redundant_leg_and_matches_the_incline(backend):
    """Motion from legs 1 and 2 only; leg 3 (redundant) stays satisfied along the run
    (its recorded residuals), and the motion is the incline's closed form."""
    system, a0 = _sliding_table()
    d = derive(system)
    assert d.redundancy.named("redundant") == ("leg_3",)
    model = numeric_model(d) if backend == "numpy" else numeric_model(d, "c")
    sol = simulate(model, 1.0, rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 1.0, 21))
    t = np.asarray(sol.t)
    # the accelerations are constant: DOP853 integrates the parabola exactly, rounding only
    # (measured 2e-15); so are leg 3's residuals (1e-15) and the legs' sum (7e-15 N)
    assert np.allclose(sol.states["x"], 0.2 * t - 0.5 * G * np.sin(a0) * np.cos(a0) * t**2, rtol=0, atol=1e-8)
    total = sum(np.asarray(sol.multipliers[f"leg_{i}"]) for i in (1, 2, 3))
    assert np.allclose(total, 5.0 * G * np.cos(a0) ** 2, rtol=1e-8)
    assert np.max(np.abs(sol.position_residuals["leg_3"])) < 1e-9
    assert np.max(np.abs(sol.velocity_residuals["leg_3"])) < 1e-9


def _cli(*args):
    from click.testing import CliRunner

    from appell.io.cli import cli

    return CliRunner().invoke(cli, list(args), catch_exceptions=False)


def test_cli_derive_and_check_print_the_redundancy():
    from appell.examples import example_path

    out = _cli("derive", str(example_path("door_two_hinges")))
    assert out.exit_code == 0, out.output
    assert "rank J = 3 of 4 constraints; dim null(J^T) = 1" in out.output
    assert "undetermined split among: top_z, bottom_z" in out.output
    out = _cli("check", str(example_path("table_four_legs")))
    assert out.exit_code == 0, out.output
    assert "satisfied automatically: leg_4" in out.output and "minimum-norm" in out.output


def test_cli_refuses_inconsistent_legs_in_a_model_file_with_exit_2(tmp_path):
    from appell.examples import example_path

    text = example_path("table_four_legs").read_text()
    text = text.replace(
        'expr = "z - a*sin(theta) - b*sin(phi)*cos(theta) - L"',
        'expr = "z - a*sin(theta) - b*sin(phi)*cos(theta) - 0.74"',
    )
    path = tmp_path / "short_leg.toml"
    path.write_text(text)
    out = _cli("derive", str(path))
    assert out.exit_code == 2, out.output
    assert "inconsistent" in out.output and "leg_4" in out.output


def test_model_file_compliance_must_be_positive(tmp_path):
    from appell import load_model
    from appell.examples import example_path

    text = example_path("shaft_three_bearings").read_text().replace("compliance = 1e-8", "compliance = -1e-8")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ModelError, match="compliance.*must be positive"):
        load_model(path)


def test_completing_a_start_uses_the_independent_legs_and_the_redundant_one_then_holds():
    """A start 1 cm too high and rolled is completed on legs 1-3 (Newton); leg 4 then holds
    too (consistent redundancy), and the plate sits at z = L, level."""
    from appell import complete_initial

    d = derive(table_four_legs())
    state = complete_initial(d, {"z": 0.76, "phi": 0.01, "theta": 0.0, "z_dot": 0.0, "phi_dot": 0.0, "theta_dot": 0.0})
    # Newton stops at residual 1e-12 (complete_initial's tol; the legs move by dz, unit gain)
    # and converges quadratically, so it ends far below (measured 1e-17)
    assert state.values["z"] == pytest.approx(0.75, abs=1e-12)
    assert abs(state.values["phi"]) < 1e-12 and abs(state.values["theta"]) < 1e-12
    assert set(state.position_residuals) == {"leg_1", "leg_2", "leg_3", "leg_4"}
    assert max(abs(v) for v in state.position_residuals.values()) < 1e-12


def test_sliding_table_with_baumgarte_stabilization_keeps_the_redundant_leg():
    """Baumgarte's bias of every constraint reaches the independent ones (the redundant
    one's holds by itself): the run matches the incline's closed form as with projection."""
    system, a0 = _sliding_table()
    sol = simulate(
        derive(system), 1.0, stabilization="baumgarte", rtol=1e-10, atol=1e-12, t_eval=np.linspace(0.0, 1.0, 11)
    )
    t = np.asarray(sol.t)
    # constant accelerations, the bias vanishing on the constraints: rounding only (measured
    # 7e-13 and 3e-13)
    assert np.allclose(sol.states["x"], 0.2 * t - 0.5 * G * np.sin(a0) * np.cos(a0) * t**2, rtol=0, atol=1e-8)
    assert np.max(np.abs(sol.position_residuals["leg_3"])) < 1e-9
