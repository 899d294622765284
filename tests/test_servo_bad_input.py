"""Controlled systems that cannot be realised (method.md §4 needs k = r, a full-rank
stacked Jacobian, and a control that appears within the differentiation bound): each is a
ModelError that names the constraints and says what to do."""

import pytest
import sympy as sp

from appell import Control, ModelError, System, acceleration_constraint, holonomic, nonholonomic
from appell.control.servo import derive_controlled
from appell.examples.servo_examples import appell_ball

x, y = sp.symbols("x y")
xd, yd = sp.symbols("x_dot y_dot")
F, m = sp.symbols("F m")


def particle(**kw):
    base = dict(
        coordinates=(x, y),
        parameters={m: 1.0},
        kinetic_energy=m / 2 * (xd**2 + yd**2),
        generalized_forces=(F, 0),
        controls=(Control(F, "force"),),
    )
    base.update(kw)
    return System(**base)


def test_more_servo_constraints_than_controls():
    sysm = particle(servo_constraints=(nonholonomic("vx", xd - 1), nonholonomic("vy", yd - 2)))
    with pytest.raises(ModelError, match=r"2 servo constraints \(vx, vy\) but only 1 control") as exc:
        derive_controlled(sysm)
    assert "add controls" in str(exc.value)


def test_fewer_servo_constraints_than_controls():
    sysm = appell_ball()
    sysm = sysm.replace(servo_constraints=sysm.servo_constraints[:1])
    with pytest.raises(ModelError, match=r"controls \(u, v\) for 1 servo constraint"):
        derive_controlled(sysm)


def test_servo_constraint_contradicting_a_real_one():
    sysm = particle(
        constraints=(nonholonomic("guide", xd - 1),),
        servo_constraints=(nonholonomic("speed", xd - 2),),
        generalized_forces=(0, F),
    )
    with pytest.raises(ModelError, match="contradictory or redundant") as exc:
        derive_controlled(sysm)
    assert "guide" in str(exc.value) and "speed" in str(exc.value)


def test_controls_that_cannot_realise_the_servo_constraint():
    """The force acts on x, the servo constraint prescribes the decoupled y: the control
    never appears, however often (2.3) is differentiated."""
    yref = sp.Symbol("y_ref")
    sysm = particle(programs={yref: sp.sin(sp.Symbol("t"))}, servo_constraints=(holonomic("track_y", y - yref),))
    with pytest.raises(ModelError, match=r"cannot realise servo constraint 'track_y'.*after 6 differentiations"):
        derive_controlled(sysm)
    with pytest.raises(ModelError, match="after 2 differentiations"):
        derive_controlled(sysm, max_differentiations=2)


def test_servo_constraint_on_a_control_only():
    """A servo constraint that fixes a kinematic control directly restricts no acceleration
    of the system: the joint partition cannot take it; the hint says to use a program."""
    u = sp.Symbol("u")
    sysm = particle(
        controls=(Control(u, "kinematic"),),
        generalized_forces=(0, 0),
        servo_constraints=(acceleration_constraint("plate", sp.Symbol("u_ddot") - 1),),
    )
    with pytest.raises(ModelError, match="plate") as exc:
        derive_controlled(sysm)
    assert "program" in str(exc.value)


def test_no_servo_constraints():
    with pytest.raises(ModelError, match="no servo constraints"):
        derive_controlled(particle(controls=(), generalized_forces=(0, 0)))


def test_controls_without_servo_constraints_in_a_model_file_name_the_control_and_line():
    """[controls] kept, [servo_constraints] deleted: nothing determines the control (its symbol
    used to reach the numeric code undefined: "internal error: NameError: name 'u' is not defined")."""
    from appell import loads_model
    from appell.examples import example_path

    text = example_path("spring_masses").read_text(encoding="utf-8")
    start = text.index("[servo_constraints.track]")
    text = text[:start] + text[text.index("[initial]") :]
    line = next(i for i, row in enumerate(text.splitlines(), 1) if row.startswith("[controls]"))
    with pytest.raises(ModelError) as exc:
        loads_model(text, "spring.toml")
    assert exc.value.where == f"spring.toml:{line}"
    assert "control u is declared but no servo constraint is given" in exc.value.message
    assert "[servo_constraints.NAME]" in exc.value.hint


def test_controls_without_servo_constraints_on_the_command_line(tmp_path):
    from click.testing import CliRunner

    from appell.examples import example_path
    from appell.io.cli import cli

    text = example_path("overhead_crane").read_text(encoding="utf-8")
    kept = []
    skipping = False
    for row in text.splitlines():
        if row.startswith("["):
            skipping = row.startswith("[servo_constraints")
        if not skipping:
            kept.append(row)
    path = tmp_path / "crane.toml"
    path.write_text("\n".join(kept) + "\n", encoding="utf-8")
    for command in ("derive", "simulate"):
        result = CliRunner().invoke(cli, [command, str(path)], catch_exceptions=False)
        assert result.exit_code == 2, result.output
        assert "controls F_T, F_W are declared but no servo constraint is given" in result.stderr
        assert "internal error" not in result.stderr and str(path) in result.stderr


def test_a_controlled_coordinate_without_inertia_is_named():
    """The first mass of the spring-mass chain without kinetic energy: the reduced mass matrix
    (2.4) has a zero row for x1_ddot (SymPy's NonInvertibleMatrixError used to escape)."""
    from appell import loads_model
    from appell.examples import example_path

    text = (
        example_path("spring_masses")
        .read_text(encoding="utf-8")
        .replace("kinetic_energy = \"m1/2*x1'^2 + m2/2*y'^2\"", 'kinetic_energy = "m2/2*y\'^2"')
    )
    with pytest.raises(
        ModelError,
        match=r"C\^T M C of the controlled system 'spring_masses' is singular: "
        r"it has a zero row for x1_ddot",
    ):
        derive_controlled(loads_model(text, "spring.toml"))


def test_a_control_law_that_divides_by_zero_at_the_start_is_bad_input():
    """m1 = 0: the dynamic conditions solved for the control divide by m1 (the force acts on the
    first mass); refused at the start with the time, exit 2."""
    from click.testing import CliRunner

    from appell.io.cli import cli

    result = CliRunner().invoke(cli, ["simulate", "spring_masses", "--set", "m1=0"], catch_exceptions=False)
    assert result.exit_code == 2, result.output
    assert "cannot start: the control law" in result.stderr and "(t = 0)" in result.stderr
