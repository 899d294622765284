"""appell — reactions and controls of constrained mechanical systems by Do Shan's method.

Pipeline: :class:`System` -> :func:`derive` -> :class:`Derivation` (reduced equations
(1.4), reaction formulas (1.5): symbolic data) -> :func:`numeric_model` (the numeric
functions and the split solve, NumPy or C) -> :func:`simulate`, :func:`cross_check`;
:func:`to_text`, :func:`to_latex`, :func:`to_json` print a derivation.
"""

import importlib
import sys
from typing import TYPE_CHECKING

#: public name -> the module that defines it, imported on first use (PEP 562): ``import appell``
#: costs no SymPy, SciPy, xarray, pandas or matplotlib; ``from appell import simulate`` imports
#: what the simulation needs
_LAZY = {
    **dict.fromkeys(("numeric_model",), "appell.numerics.boundary"),
    **dict.fromkeys(("CrossCheckReport", "augmented_solve", "cross_check"), "appell.numerics.crosscheck"),
    # the pipeline's derive and derive_controlled through the derivation cache (a system derived
    # before, in any process, is read back): appell.core.derive.derive derives every time
    **dict.fromkeys(("derive", "derive_controlled", "derive_file"), "appell.io.derivation_cache"),
    **dict.fromkeys(("Derivation", "ReactionFormulas", "ReducedEquations"), "appell.core.equations"),
    **dict.fromkeys(
        ("AppellError", "ComputationError", "InitialValueError", "ModelError", "PainleveError", "ResourceError"),
        "appell.errors",
    ),
    **dict.fromkeys(
        (
            "AppliedForce",
            "AppliedTorque",
            "Constraint",
            "Control",
            "FirstIntegral",
            "Output",
            "Friction",
            "Parameter",
            "Particle",
            "Program",
            "RigidBody",
            "System",
            "acceleration_constraint",
            "holonomic",
            "nonholonomic",
        ),
        "appell.model",
    ),
    **dict.fromkeys(("load_model", "loads_model"), "appell.io.modelfile"),
    **dict.fromkeys(("NumericModel", "StateSolution"), "appell.numerics.numeric"),
    **dict.fromkeys(("LinearModel", "linearise", "steady_motion"), "appell.numerics.linearise"),
    **dict.fromkeys(("StabilitySweep", "stability_sweep"), "appell.numerics.stability"),
    **dict.fromkeys(("Event",), "appell.simulation.events"),
    **dict.fromkeys(("InitialState", "check_initial", "complete_initial"), "appell.simulation.initial"),
    **dict.fromkeys(("EnergyBalance", "energy_balance"), "appell.simulation.energy_balance"),
    **dict.fromkeys(("simulate",), "appell.simulation.simulate"),
    **dict.fromkeys(("Contact", "InverseDynamics", "inverse_dynamics"), "appell.simulation.inverse"),
    **dict.fromkeys(("LoopModel", "loop_model"), "appell.numerics.loops"),
    **dict.fromkeys(("Solution",), "appell.simulation.solution"),
    **dict.fromkeys(("RouthReduction", "cyclic_coordinates", "routh_reduction"), "appell.reduction.cyclic"),
    **dict.fromkeys(
        ("FirstIntegralCheck", "FirstIntegralReport", "check_first_integrals"), "appell.reduction.first_integrals"
    ),
    **dict.fromkeys(("derivative_symbol", "t"), "appell.symbols"),
    **dict.fromkeys(("compile_c",), "appell.numerics.codegen"),
    **dict.fromkeys(("SweepResult", "parameter_grid", "sweep", "sweep_cluster"), "appell.simulation.sweep"),
    **dict.fromkeys(("ControlledDerivation",), "appell.control.servo"),
    **dict.fromkeys(
        ("ControlledModel", "augmented_controlled_solve", "cross_check_controlled"), "appell.control.servo_numeric"
    ),
    **dict.fromkeys(("display_latex", "read_json", "to_json", "to_latex", "to_text"), "appell.io.printing"),
    **dict.fromkeys(("render_report", "write_report"), "appell.io.report"),
    **dict.fromkeys(("write_csv", "write_hdf5", "write_netcdf"), "appell.io.results"),
    **dict.fromkeys(("MotionView", "view_motion"), "appell.io.viewer"),
    **dict.fromkeys(("from_sympy",), "appell.mechanism.sympy_system"),
}

if TYPE_CHECKING:  # the names of _LAZY as a type checker sees them (tests/test_typing.py: the same)
    from appell.control.servo import ControlledDerivation
    from appell.control.servo_numeric import ControlledModel, augmented_controlled_solve, cross_check_controlled
    from appell.core.equations import Derivation, ReactionFormulas, ReducedEquations
    from appell.errors import AppellError, ComputationError, InitialValueError, ModelError, PainleveError, ResourceError
    from appell.io.derivation_cache import derive, derive_controlled, derive_file
    from appell.io.modelfile import load_model, loads_model
    from appell.io.printing import display_latex, read_json, to_json, to_latex, to_text  # noqa: F401 (display_latex: not in __all__)
    from appell.io.report import render_report, write_report
    from appell.io.results import write_csv, write_hdf5, write_netcdf
    from appell.io.viewer import MotionView, view_motion
    from appell.mechanism.sympy_system import from_sympy
    from appell.model import (
        AppliedForce,
        AppliedTorque,
        Constraint,
        Control,
        FirstIntegral,
        Friction,
        Output,
        Parameter,
        Particle,
        Program,
        RigidBody,
        System,
        acceleration_constraint,
        holonomic,
        nonholonomic,
    )
    from appell.numerics.boundary import numeric_model
    from appell.numerics.codegen import compile_c
    from appell.numerics.crosscheck import CrossCheckReport, augmented_solve, cross_check
    from appell.numerics.linearise import LinearModel, linearise, steady_motion
    from appell.numerics.loops import LoopModel, loop_model
    from appell.numerics.numeric import NumericModel, StateSolution
    from appell.numerics.stability import StabilitySweep, stability_sweep
    from appell.reduction.cyclic import RouthReduction, cyclic_coordinates, routh_reduction
    from appell.reduction.first_integrals import FirstIntegralCheck, FirstIntegralReport, check_first_integrals
    from appell.simulation.energy_balance import EnergyBalance, energy_balance
    from appell.simulation.events import Event
    from appell.simulation.initial import InitialState, check_initial, complete_initial
    from appell.simulation.inverse import Contact, InverseDynamics, inverse_dynamics
    from appell.simulation.simulate import simulate
    from appell.simulation.solution import Solution
    from appell.simulation.sweep import SweepResult, parameter_grid, sweep, sweep_cluster
    from appell.symbols import derivative_symbol, t

__version__ = "0.1.0"


#: subpackages and modules reached as attributes (``appell.io.printing``) after ``import appell``
_SUBMODULES = {
    "arguments",
    "control",
    "core",
    "errors",
    "examples",
    "files",
    "io",
    "mechanism",
    "model",
    "numerics",
    "reduction",
    "rigid_tree",
    "simulation",
    "symbols",
    "view",
}


def __getattr__(name: str):
    """A public name imported on first use (PEP 562), then kept in the module."""
    module = _LAZY.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


def _register_display() -> None:
    """In Jupyter (IPython already running), show derivations as their equations: the
    ``text/latex`` formatter of IPython's registry gets :func:`appell.io.printing.display_latex`
    for both kinds of derivation. Nothing is attached to the classes themselves."""
    ipython = sys.modules.get("IPython")
    shell = getattr(ipython, "get_ipython", lambda: None)() if ipython is not None else None
    if shell is None or not hasattr(shell, "display_formatter"):
        return
    from appell.control.servo import ControlledDerivation
    from appell.core.equations import Derivation
    from appell.io.printing import display_latex

    formatter = shell.display_formatter.formatters["text/latex"]
    for kind in (Derivation, ControlledDerivation):
        formatter.for_type(kind, display_latex)


_register_display()

__all__ = [
    "AppellError",
    "AppliedForce",
    "AppliedTorque",
    "ComputationError",
    "Constraint",
    "Control",
    "CrossCheckReport",
    "Derivation",
    "FirstIntegral",
    "Friction",
    "ModelError",
    "NumericModel",
    "Output",
    "PainleveError",
    "Parameter",
    "Particle",
    "Program",
    "ReactionFormulas",
    "ReducedEquations",
    "ResourceError",
    "RigidBody",
    "StateSolution",
    "System",
    "acceleration_constraint",
    "augmented_solve",
    "cross_check",
    "derivative_symbol",
    "derive",
    "derive_file",
    "holonomic",
    "load_model",
    "loads_model",
    "nonholonomic",
    "t",
    "Event",
    "InitialState",
    "InitialValueError",
    "Solution",
    "check_initial",
    "complete_initial",
    "simulate",
    "Contact",
    "InverseDynamics",
    "inverse_dynamics",
    "LoopModel",
    "loop_model",
    "EnergyBalance",
    "energy_balance",
    "LinearModel",
    "StabilitySweep",
    "linearise",
    "stability_sweep",
    "steady_motion",
    "FirstIntegralCheck",
    "FirstIntegralReport",
    "RouthReduction",
    "check_first_integrals",
    "cyclic_coordinates",
    "routh_reduction",
    "SweepResult",
    "compile_c",
    "parameter_grid",
    "sweep",
    "sweep_cluster",
    "ControlledDerivation",
    "ControlledModel",
    "augmented_controlled_solve",
    "cross_check_controlled",
    "derive_controlled",
    "render_report",
    "write_report",
    "write_csv",
    "write_hdf5",
    "write_netcdf",
    "MotionView",
    "view_motion",
    "from_sympy",
    "numeric_model",
    "read_json",
    "to_json",
    "to_latex",
    "to_text",
]
