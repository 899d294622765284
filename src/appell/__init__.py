"""appell — reactions and controls of constrained mechanical systems by Do Shan's method.

Pipeline: :class:`System` -> :func:`derive` -> :class:`Derivation` (reduced equations
(1.4), reaction formulas (1.5), numeric functions) -> :func:`cross_check`.
"""

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
from appell.simulation.solution import Solution
from appell.reduction.cyclic import RouthReduction, cyclic_coordinates, routh_reduction
from appell.reduction.first_integrals import FirstIntegralCheck, FirstIntegralReport, check_first_integrals
from appell.symbols import derivative_symbol, t
from appell.numerics.codegen import compile_c
from appell.simulation.sweep import SweepResult, parameter_grid, sweep, sweep_cluster
from appell.control.servo import ControlledDerivation, derive_controlled
from appell.control.servo_numeric import ControlledModel, augmented_controlled_solve, cross_check_controlled
from appell.io.report import render_report, write_report
from appell.io.viewer import MotionView, view_motion
from appell.mechanism.sympy_system import from_sympy

__version__ = "0.1.0"


def _install_conveniences() -> None:
    """Attach the conveniences of the layers above to the plain data of the lower ones:
    ``Derivation.numeric`` (NumPy functions, built once), ``Derivation.compiled(backend)``
    (:func:`compile_c`), and the printed forms ``to_text``, ``to_latex``, ``to_json`` and
    ``_repr_latex_`` of :mod:`appell.io.printing`; ``ControlledDerivation.to_json``.
    The lower layers import none of these (tests/test_architecture.py)."""
    from functools import cached_property

    from appell.io import printing
    from appell.numerics import numeric as numeric_module
    from appell.numerics.redundant import with_redundancy

    def numeric(self):
        """Numeric functions of the split (:class:`appell.numerics.numeric.NumericModel`), built once;
        with redundant constraints wrapped in :class:`appell.numerics.redundant.RedundantModel`."""
        return with_redundancy(numeric_module.compile_model(self))

    def compiled(self, backend: str = "c"):
        """Numeric functions from a chosen backend: 'c' (C compiled and cached on disk), 'auto' or
        'numpy' (:func:`appell.numerics.codegen.compile_c`); not cached here."""
        return compile_c(self, backend)

    def to_text(self, only=None) -> str:
        """:func:`appell.io.printing.derivation_text`."""
        return printing.derivation_text(self, only)

    def to_latex(self, only=None) -> str:
        """:func:`appell.io.printing.derivation_latex`."""
        return printing.derivation_latex(self, only)

    def to_json(self) -> dict:
        """:func:`appell.io.printing.derivation_json`."""
        return printing.derivation_json(self)

    def _repr_latex_(self) -> str:
        return "$\\displaystyle " + self.to_latex().replace("\n", " ") + "$"

    def controlled_json(self) -> dict:
        """JSON-ready dict: each expression as a string for reading and as an exact tree under
        ``exact`` over the ``symbols`` table (:func:`appell.io.printing.read_json`)."""
        import json

        out = printing.json_document(self.json_expressions(), self)
        json.dumps(out)
        return out

    prop = cached_property(numeric)
    prop.__set_name__(Derivation, "numeric")
    Derivation.numeric = prop
    for fn in (compiled, to_text, to_latex, to_json, _repr_latex_):
        setattr(Derivation, fn.__name__, fn)
    ControlledDerivation.to_json = controlled_json


_install_conveniences()

__all__ = [
    "AppellError", "AppliedForce", "AppliedTorque", "ComputationError", "Constraint", "Control",
    "CrossCheckReport", "Derivation", "FirstIntegral", "Friction", "ModelError", "NumericModel", "Output",
    "PainleveError", "Parameter", "Particle",
    "Program", "ReactionFormulas", "ReducedEquations", "ResourceError", "RigidBody", "StateSolution", "System",
    "acceleration_constraint", "augmented_solve", "cross_check", "derivative_symbol", "derive", "holonomic",
    "load_model", "loads_model", "nonholonomic", "t",
    "Event", "InitialState", "InitialValueError", "Solution", "check_initial", "complete_initial", "simulate",
    "InverseDynamics", "inverse_dynamics",
    "EnergyBalance", "energy_balance",
    "LinearModel", "StabilitySweep", "linearise", "stability_sweep", "steady_motion",
    "FirstIntegralCheck", "FirstIntegralReport", "RouthReduction", "check_first_integrals", "cyclic_coordinates",
    "routh_reduction",
    "SweepResult", "compile_c", "parameter_grid", "sweep", "sweep_cluster",
    "ControlledDerivation", "ControlledModel", "augmented_controlled_solve", "cross_check_controlled",
    "derive_controlled",
    "render_report", "write_report", "MotionView", "view_motion",
    "from_sympy",
]
