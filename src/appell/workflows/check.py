"""``appell check``: the independent routes (:func:`cross_check_model`), the energy balance over
the simulation span (:func:`span_energy_balance`), the first integrals and the :func:`verdict`.
"""

from __future__ import annotations

from appell.errors import ComputationError
from appell.workflows.load import _echo_redundancy, _is_controlled, _print, _warn_internal, internal_stability
from appell.workflows.simulate import command_options


def first_integrals(derivation):
    """The verdicts on the model's candidate first integrals, or None when it has none
    (or is a controlled system, whose integrals are not checked)."""
    if not derivation.system.first_integrals or _is_controlled(derivation):
        return None
    from appell.reduction.first_integrals import check_first_integrals

    return check_first_integrals(derivation.system)


def cross_check_model(derivation):
    """:func:`appell.cross_check`, or :func:`appell.cross_check_controlled` for a
    controlled derivation (the augmented system with the controls as unknowns)."""
    if _is_controlled(derivation):
        from appell.control.servo_numeric import cross_check_controlled

        return cross_check_controlled(derivation)
    from appell.numerics.crosscheck import cross_check

    return cross_check(derivation)


def span_energy_balance(derivation, t_end=None):
    """:func:`appell.simulation.energy_balance.energy_balance` over the model's simulation
    span (``t_end`` overriding its final time), or not formed when the model gives no
    initial values."""
    from appell.simulation.energy_balance import EnergyBalance, energy_balance

    system = derivation.system
    if not system.initial:
        return EnergyBalance(None, "the model gives no initial values ([initial]) to start a motion from")
    opts = command_options(system, t_end)
    if not opts.t_end > opts.t0:
        return EnergyBalance(None, "the simulation span is empty (t_end = t0)")
    # a model that declares an implicit method may be stiff: its balance integrates implicitly
    # where the motion's Jacobian at the start says so ('auto')
    stiff = opts.method in ("Radau", "BDF", "LSODA")
    return energy_balance(derivation, opts.t_end, t0=opts.t0, method="auto" if stiff else "DOP853")


def verdict(check_report, energy, tolerance: float, energy_tolerance: float) -> tuple[bool, str]:
    """``(passed, one line)`` over every line of the cross-check and the energy balance."""
    failed = []
    if not check_report.passed(tolerance):
        failed.append(
            check_report.verdict(tolerance)
            if hasattr(check_report, "verdict")
            else f"cross-check: a relative difference exceeds {tolerance:g}"
        )
    if energy is not None and not energy.passed(energy_tolerance):
        failed.append(energy.verdict(energy_tolerance))
    if failed:
        return False, "; ".join(failed)
    checked = getattr(check_report, "checked", True)
    if not checked and (energy is None or not energy.formed):
        return True, "nothing to cross-check: no independent route applies to this model (see above)"
    parts = [f"every cross-check line is at most {tolerance:g}" if checked else "no cross-check line"]
    if energy is not None and energy.formed:
        parts.append(f"the energy balance holds within {energy_tolerance:g}")
    return True, "passed: " + " and ".join(parts)


def check_model(derivation, tolerance: float = 1e-9, energy_tolerance: float | None = None, t_end=None, echo=None):
    """``appell check``: the cross-check (:func:`cross_check_model`), the internal dynamics of a
    controlled system, the energy balance over the simulation span (:func:`span_energy_balance`)
    and the verdict on each candidate first integral, printed; raises
    :class:`~appell.errors.ComputationError` when a line exceeds its tolerance. Returns
    ``(cross-check report, energy balance)``."""
    from appell.simulation.energy_balance import ENERGY_TOLERANCE

    echo = echo or _print
    energy_tolerance = ENERGY_TOLERANCE if energy_tolerance is None else energy_tolerance
    report = cross_check_model(derivation)
    _echo_redundancy(derivation, echo)
    echo(str(report))
    linearisation, note = internal_stability(derivation)
    if linearisation is not None:
        echo("internal dynamics:\n" + linearisation.to_text())
    _warn_internal(linearisation, note, echo)
    energy = span_energy_balance(derivation, t_end)
    echo(str(energy))
    integrals = first_integrals(derivation)
    if integrals is not None:
        echo(integrals.to_text())
    ok, line = verdict(report, energy, tolerance, energy_tolerance)
    if not ok:
        raise ComputationError(
            f"check failed: {line}", hint="a route or the energy balance disagrees with the split; see the lines above"
        )
    echo(line)
    return report, energy
