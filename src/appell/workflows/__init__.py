"""The workflows of the command line, as Python functions: what each ``appell`` command does
between reading its arguments and printing, so that a command and its Python twin take the
same path and give the same numbers (tests/test_api_cli_agree.py runs both on every bundled
example).

Each command of :mod:`appell.io.cli` parses its arguments and calls these, in this order:

=======================  =================================================================
every command            :func:`load_system` (a model file or bundled example, ``--set``),
                         :func:`derive_model` (derive, or derive_controlled with servo
                         constraints; the inertia checked at the start)
``appell derive``        :func:`show_derivation` (text, LaTeX or :func:`derivation_json`)
``appell simulate``      :func:`run_simulation` (:func:`command_options`: the model's
                         ``[simulation]`` table, then the command's options; missing initial
                         values completed), :func:`save_simulation`
``appell animate``       :func:`run_simulation`, :func:`save_motion`
``appell inverse``       :func:`run_inverse`
``appell check``         :func:`check_model` (:func:`cross_check_model`, :func:`span_energy_balance`,
                         first integrals, :func:`verdict`)
``appell report``        :func:`report_model`
``appell sweep``         :func:`sweep_model`
``appell stability``     :func:`stability_analysis`, :func:`write_stability`
``appell cluster``       :func:`keep_cluster`
``appell examples``      :func:`example_listing`, :func:`copy_example`
=======================  =================================================================

What a command prints goes through ``echo(text, err=False)`` (the command passes
:func:`click.echo`; by default :func:`print` to stdout, or stderr with ``err=True``). Bad
input raises :class:`~appell.errors.ModelError`, a failed computation
:class:`~appell.errors.ComputationError`: the command line turns them into its exit codes.
A new command-line flag is an argument of one of these functions (and, for the integrator,
a field of :class:`~appell.simulation.options.SimulationOptions`).

Each group of workflows is a module of this package, every name importable from here:
:mod:`.load` (what every command does first: load, derive, the lines all commands print),
:mod:`.derive`, :mod:`.simulate` (also ``appell animate``), :mod:`.inverse`, :mod:`.check`,
:mod:`.report`, :mod:`.stability`, :mod:`.sweep` (also ``appell cluster``), :mod:`.examples`.
"""

from __future__ import annotations

from appell.workflows.check import check_model, cross_check_model, first_integrals, span_energy_balance, verdict
from appell.workflows.derive import derivation_json, show_derivation
from appell.workflows.examples import copy_example, example_listing
from appell.workflows.inverse import closed_chain_model, load_inverse_source, read_trajectory, run_inverse
from appell.workflows.load import (
    check_inertia_at_start,
    derive_model,
    internal_stability,
    load_derivation,
    load_system,
    resolve_model,
)
from appell.workflows.report import report_model
from appell.workflows.simulate import (
    OUTPUT_FORMATS,
    SOLVER_OPTIONS,
    check_movie_writer,
    check_output_memory,
    command_options,
    completion,
    export_solution,
    failed_path,
    keep_failed_motion,
    run_simulation,
    save_motion,
    save_simulation,
    solver_line,
)
from appell.workflows.stability import stability_analysis, stability_table, write_stability
from appell.workflows.sweep import keep_cluster, sweep_model

__all__ = [
    "OUTPUT_FORMATS",
    "SOLVER_OPTIONS",
    "check_inertia_at_start",
    "check_model",
    "check_movie_writer",
    "check_output_memory",
    "command_options",
    "completion",
    "copy_example",
    "cross_check_model",
    "derivation_json",
    "derive_model",
    "example_listing",
    "export_solution",
    "failed_path",
    "first_integrals",
    "internal_stability",
    "keep_cluster",
    "keep_failed_motion",
    "closed_chain_model",
    "load_derivation",
    "load_inverse_source",
    "load_system",
    "read_trajectory",
    "report_model",
    "resolve_model",
    "run_inverse",
    "run_simulation",
    "save_motion",
    "save_simulation",
    "show_derivation",
    "solver_line",
    "span_energy_balance",
    "stability_analysis",
    "stability_table",
    "sweep_model",
    "verdict",
    "write_stability",
]
