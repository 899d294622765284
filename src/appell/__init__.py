"""appell — reactions and controls of constrained mechanical systems by Do Shan's method.

Pipeline: :class:`System` -> :func:`derive` -> :class:`Derivation` (reduced equations
(1.4), reaction formulas (1.5), numeric functions) -> :func:`cross_check`.
"""

from appell.numerics.crosscheck import CrossCheckReport, augmented_solve, cross_check
from appell.core.derive import derive
from appell.core.equations import Derivation, ReactionFormulas, ReducedEquations
from appell.errors import AppellError, ComputationError, ModelError, ResourceError
from appell.model import (
    AppliedForce,
    AppliedTorque,
    Constraint,
    Control,
    FirstIntegral,
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
from appell.simulation.events import Event
from appell.simulation.initial import InitialState, check_initial, complete_initial
from appell.simulation.simulate import simulate
from appell.simulation.solution import Solution
from appell.reduction.cyclic import RouthReduction, cyclic_coordinates, routh_reduction
from appell.reduction.first_integrals import FirstIntegralCheck, FirstIntegralReport, check_first_integrals
from appell.symbols import derivative_symbol, t
from appell.numerics.codegen_c import compile_c
from appell.simulation.sweep import SweepResult, parameter_grid, sweep
from appell.control.servo import ControlledDerivation, derive_controlled
from appell.control.servo_numeric import ControlledModel, augmented_controlled_solve, cross_check_controlled
from appell.io.report import render_report, write_report

__version__ = "0.1.0"

__all__ = [
    "AppellError", "AppliedForce", "AppliedTorque", "ComputationError", "Constraint", "Control",
    "CrossCheckReport", "Derivation", "FirstIntegral", "ModelError", "NumericModel", "Parameter", "Particle",
    "Program", "ReactionFormulas", "ReducedEquations", "ResourceError", "RigidBody", "StateSolution", "System",
    "acceleration_constraint", "augmented_solve", "cross_check", "derivative_symbol", "derive", "holonomic",
    "load_model", "loads_model", "nonholonomic", "t",
    "Event", "InitialState", "Solution", "check_initial", "complete_initial", "simulate",
    "FirstIntegralCheck", "FirstIntegralReport", "RouthReduction", "check_first_integrals", "cyclic_coordinates",
    "routh_reduction",
    "SweepResult", "compile_c", "parameter_grid", "sweep",
    "ControlledDerivation", "ControlledModel", "augmented_controlled_solve", "cross_check_controlled",
    "derive_controlled",
    "render_report", "write_report",
]
