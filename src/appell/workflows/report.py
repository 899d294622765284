"""``appell report``: one self-contained HTML page (:func:`report_model`)."""

from __future__ import annotations

from pathlib import Path

from appell.errors import ComputationError
from appell.files import default_file_name, output_target
from appell.workflows.check import cross_check_model, first_integrals, span_energy_balance, verdict
from appell.workflows.load import _is_controlled, _print, _warn_internal, internal_stability
from appell.workflows.simulate import run_simulation
from appell.workflows.stability import stability_analysis


def report_model(
    derivation,
    output=None,
    t_end=None,
    simulation: bool = True,
    data: bool = True,
    backend: str = "auto",
    solver=None,
    echo=None,
    expand: bool = False,
    **options,
) -> Path:
    """``appell report``: the cross-check (with the C code compiled meanwhile), the simulation
    (:func:`run_simulation` with ``solver`` and ``options``) unless left out or impossible,
    the energy balance and the ``[stability]`` table, written as one HTML page (default
    ``<model name>-report.html``) with the motion's data beside it (``data``), the reactions
    also in the state (t, q, w) where ``expand``; raises
    :class:`~appell.errors.ComputationError` after writing when a check fails."""
    from appell.io.report import write_report
    from appell.io.results import write_csv
    from appell.simulation.energy_balance import ENERGY_TOLERANCE

    echo = echo or _print
    system = derivation.system
    compiling = None
    if backend != "numpy" and simulation and (system.initial or system.settings):
        from appell.numerics.codegen.model import compile_in_background

        compiling = compile_in_background(derivation)  # the compiler runs while the routes are checked
    try:
        check_report = cross_check_model(derivation)
    except BaseException:
        if compiling is not None:
            compiling.join()  # the compiler's temporary files go before the error is shown
        raise
    solution, note = None, None
    if not simulation:
        note = "Left out (--no-simulation)."
    elif not system.initial and not system.settings:
        note = "Left out: the model gives neither initial values ([initial]) nor a [simulation] table."
    else:
        solution = run_simulation(derivation, t_end, backend, solver, **options)
    linearisation, internal_note = internal_stability(derivation, solution)
    _warn_internal(linearisation, internal_note, echo)
    energy = span_energy_balance(derivation, t_end)
    path = Path(output) if output else default_file_name(system.name, "-report.html")
    output_target(path)
    sweep = None if _is_controlled(derivation) else stability_analysis(derivation)  # the [stability] table
    data_path = path.with_suffix(".csv") if data and solution is not None else None
    if data_path is not None:
        output_target(data_path)
        write_csv(solution, data_path)
    write_report(
        path,
        derivation,
        solution,
        check_report,
        simulation_note=note,
        integrals=first_integrals(derivation),
        internal=linearisation,
        energy=energy,
        stability=sweep,
        data_file=data_path.name if data_path is not None else None,
        expand=expand,
    )
    if data_path is not None:
        echo(f"wrote {data_path}")
    echo(f"wrote {path}")
    ok, line = verdict(check_report, energy, 1e-9, ENERGY_TOLERANCE)
    if not ok:
        raise ComputationError(f"check failed (see the report): {line}")
    return path
