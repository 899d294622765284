"""The pipeline, in the order of the method (method.md §1–3).

``derive`` is the table of contents of appell::

    system
      -> validate                      every symbol declared          (validation)
      -> kinematics                    d/dt along the motion          (kinematics, §1)
      -> inertia blocks  M, h, Q       dS/da = M a + h                (energy, §1)
      -> constraint blocks  J, c       f = J a + c                    (constraints, §2)
      -> redundant rows set aside      rank J < s, consistency        (redundancy, §3)
      -> partition  a_nu | a_h         condition (1.2)                (partition, §3)
      => Derivation  .reduced (1.4)  .reactions (1.5)                 (equations)

and after it, in their own folders::

    numeric_model(derivation, backend)    blocks and split solve at a state     (numerics/)
    cross_check(derivation)                 the augmented system, independent    (numerics/crosscheck)
    simulate(derivation, t_end)             drift control, events, Solution     (simulation/)
    derive_controlled(system)               servo constraints (2.3)-(2.5)       (control/, §4)
    routh_reduction(system)                 cyclic coordinates, L* = T* - V      (reduction/, §5)
    to_text / to_latex / to_json, report    presentation, HTML, command line     (io/)
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from appell.core.constraints import second_order_blocks
from appell.core.energy import inertia_blocks
from appell.core.equations import Derivation
from appell.core.kinematics import kinematics_of
from appell.core.partition import choose_partition
from appell.core.redundancy import check_consistency, find_redundancy, split_outputs
from appell.core.validation import validate
from appell.errors import ModelError
from appell.model import System


def derive(system: System, dependent: Sequence | None = None) -> Derivation:
    """Derive the reduced equations (1.4) and the reaction formulas (1.5) of ``system``.

    Parameters
    ----------
    system : the constrained system.
    dependent : optional choice of dependent accelerations (symbols, names or indices);
        by default a partition satisfying condition (1.2) is chosen automatically.

    Returns
    -------
    Derivation
        with the blocks ``inertia`` (M, h, Q), ``constraints`` (J, c), the ``partition``
        and, on access, ``reduced``, ``reactions`` and ``numeric``.
    """
    validate(system)
    if dependent is not None and (isinstance(dependent, (str, bytes)) or not hasattr(dependent, "__iter__")):
        raise ModelError(f"dependent must be a list of accelerations (names, symbols or indices), got {dependent!r}")
    if system.servo_constraints:
        servo = ", ".join(c.name for c in system.servo_constraints)
        controls = ", ".join(c.name for c in system.controls) or "none"
        raise ModelError(
            f"system {system.name!r} has servo constraints ({servo}) realised by controls ({controls}): "
            "derive does not impose them",
            hint="use appell.derive_controlled(system) for the dynamic conditions (2.3), the controls and the "
            "reactions (2.5); the command line does so by itself",
        )
    kin = kinematics_of(system)
    inertia = inertia_blocks(system, kin)
    cons = second_order_blocks(system.constraints, kin)
    known = {**system.parameter_values, **{sp.Symbol(k): v for k, v in system.initial}}
    known.update(_programs_at_start(system, known))
    redundancy = find_redundancy(cons, system.constraints, known, coordinates=kin.coordinates)
    if redundancy is not None:  # statically indeterminate: the motion from independent rows
        check_consistency(redundancy, kin, known)
        redundancy = split_outputs(redundancy, system.outputs, known)
        cons = cons.subset(redundancy.independent)
    partition = choose_partition(sp.Matrix(cons.jacobian), cons.names, kin.accelerations, dependent, at=known)
    return Derivation(system, kin, inertia, cons, partition, redundancy)


def _programs_at_start(system: System, known: dict) -> dict:
    """Values of the programs (and their derivatives) at t = 0, where they are numbers:
    the partition is chosen at the model's initial state."""
    from appell.symbols import derivative_symbol, t

    out = {}
    for prog in system.programs:
        sym = prog.symbol
        for order in range(3):
            value = sp.sympify(prog.derivative(order).xreplace({**known, t: 0}))  # a bare parameter gives a float
            if value.is_number and value.is_real:
                out[sym] = float(value)
            sym = derivative_symbol(sym)
    return out
