"""appell — reactions and controls of constrained mechanical systems by Do Shan's method.

Pipeline: :class:`System` -> :func:`derive` -> :class:`Derivation` (reduced equations
(1.4), reaction formulas (1.5): symbolic data) -> :func:`numeric_model` (the numeric
functions and the split solve, NumPy or C) -> :func:`simulate`, :func:`cross_check`;
:func:`to_text`, :func:`to_latex`, :func:`to_json` print a derivation.
"""

import sys

from appell.numerics.boundary import numeric_model
from appell.numerics.crosscheck import CrossCheckReport, augmented_solve, cross_check
from appell.core.derive import derive
from appell.core.equations import Derivation, ReactionFormulas, ReducedEquations
from appell.errors import AppellError, ComputationError, InitialValueError, ModelError, PainleveError, ResourceError
from appell.model import (
    AppliedForce,
    AppliedTorque,
    Constraint,
    Control,
    FirstIntegral,
    Output,
    Friction,
    Parameter,
    Particle,
    Program,
    RigidBody,
    System,
    acceleration_constraint,
    holonomic,
    nonholonomic,
)
from appell.io.modelfile import load_model, loads_model
from appell.numerics.numeric import NumericModel, StateSolution
from appell.numerics.linearise import LinearModel, linearise, steady_motion
from appell.numerics.stability import StabilitySweep, stability_sweep
from appell.simulation.events import Event
from appell.simulation.initial import InitialState, check_initial, complete_initial
from appell.simulation.energy_balance import EnergyBalance, energy_balance
from appell.simulation.simulate import simulate
from appell.simulation.inverse import InverseDynamics, inverse_dynamics
from appell.numerics.loops import LoopModel, loop_model
from appell.simulation.solution import Solution
from appell.reduction.cyclic import RouthReduction, cyclic_coordinates, routh_reduction
from appell.reduction.first_integrals import FirstIntegralCheck, FirstIntegralReport, check_first_integrals
from appell.symbols import derivative_symbol, t
from appell.numerics.codegen import compile_c
from appell.simulation.sweep import SweepResult, parameter_grid, sweep, sweep_cluster
from appell.control.servo import ControlledDerivation, derive_controlled
from appell.control.servo_numeric import ControlledModel, augmented_controlled_solve, cross_check_controlled
from appell.io.printing import display_latex, read_json, to_json, to_latex, to_text
from appell.io.report import render_report, write_report
from appell.io.viewer import MotionView, view_motion
from appell.mechanism.sympy_system import from_sympy

__version__ = "0.1.0"


def _register_display() -> None:
    """In Jupyter (IPython already running), show derivations as their equations: the
    ``text/latex`` formatter of IPython's registry gets :func:`appell.io.printing.display_latex`
    for both kinds of derivation. Nothing is attached to the classes themselves."""
    ipython = sys.modules.get("IPython")
    shell = getattr(ipython, "get_ipython", lambda: None)() if ipython is not None else None
    if shell is None or not hasattr(shell, "display_formatter"):
        return
    formatter = shell.display_formatter.formatters["text/latex"]
    for kind in (Derivation, ControlledDerivation):
        formatter.for_type(kind, display_latex)


_register_display()

__all__ = [
    "AppellError", "AppliedForce", "AppliedTorque", "ComputationError", "Constraint", "Control",
    "CrossCheckReport", "Derivation", "FirstIntegral", "Friction", "ModelError", "NumericModel", "Output",
    "PainleveError", "Parameter", "Particle",
    "Program", "ReactionFormulas", "ReducedEquations", "ResourceError", "RigidBody", "StateSolution", "System",
    "acceleration_constraint", "augmented_solve", "cross_check", "derivative_symbol", "derive", "holonomic",
    "load_model", "loads_model", "nonholonomic", "t",
    "Event", "InitialState", "InitialValueError", "Solution", "check_initial", "complete_initial", "simulate",
    "InverseDynamics", "inverse_dynamics", "LoopModel", "loop_model",
    "EnergyBalance", "energy_balance",
    "LinearModel", "StabilitySweep", "linearise", "stability_sweep", "steady_motion",
    "FirstIntegralCheck", "FirstIntegralReport", "RouthReduction", "check_first_integrals", "cyclic_coordinates",
    "routh_reduction",
    "SweepResult", "compile_c", "parameter_grid", "sweep", "sweep_cluster",
    "ControlledDerivation", "ControlledModel", "augmented_controlled_solve", "cross_check_controlled",
    "derive_controlled",
    "render_report", "write_report", "MotionView", "view_motion",
    "from_sympy",
    "numeric_model", "read_json", "to_json", "to_latex", "to_text",
]
