"""Reading and deriving a model, what every command does first: :func:`load_system` (a model
file or bundled example, ``--set``), :func:`load_derivation` (through the derivation cache),
:func:`derive_model` (the inertia checked at the start), and the lines every command may print
(the model's notes, the internal dynamics, the redundant constraints).
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

from appell.errors import ComputationError, ModelError


def _print(text: str = "", err: bool = False) -> None:
    """The default ``echo``: a line on stdout (stderr with ``err``)."""
    stream = sys.stderr if err else sys.stdout
    print(text, file=stream)
    stream.flush()


def _is_controlled(derivation) -> bool:
    from appell.core.equations import is_controlled

    return is_controlled(derivation)


def resolve_model(model: str) -> Path:
    """The model file named by ``model``: an existing path, or a bundled example's or
    benchmark's name."""
    path = Path(model)
    if path.is_file():
        return path
    from appell.examples import example_path, list_benchmarks, list_examples

    if path.suffix == "" and (model in list_examples() or model in list_benchmarks()):
        return example_path(model)
    if path.exists():
        from appell.mechanism.formats import described

        raise ModelError(f"{model}: not a file", hint=f"give the path of {described()}")
    raise ModelError(
        f"{model}: no such model file",
        hint="give the path of a model file, or a bundled example: "
        + ", ".join(list_examples())
        + "; or a benchmark: "
        + ", ".join(list_benchmarks()),
    )


def load_system(
    model: str, overrides=None, floating_base: bool = False, echo=None, reactions_in: str | None = None, reader=None
):
    """Load a model file (or bundled example) with parameter / initial-value ``overrides``
    (``{name: value text}``, as ``--set NAME=VALUE``); ``floating_base`` puts a ``.urdf``
    robot's root link on a free joint; ``reactions_in`` the axes of the joint reactions of a
    ``[mechanism]`` model; ``reader`` the options of a robot file's reader (a MuJoCo model's
    ``frictionloss``, ``armature``, ``actuators``: :func:`appell.io.modelfile.load_model`).
    What the model's files hold that appell does not apply is one ``note:`` line each on
    ``echo(..., err=True)``."""
    from appell.io.modelfile import load_model

    with _notes_as_lines(echo or _print):
        return load_model(
            resolve_model(model),
            overrides=overrides or None,
            floating_base=floating_base,
            reactions_in=reactions_in,
            reader=reader,
        )


@contextlib.contextmanager
def _notes_as_lines(echo):
    """What the model's files hold that appell does not apply (:class:`AppellNote` warnings
    raised inside) as one ``note:`` line each on ``echo(..., err=True)``; other warnings are
    given again as they came."""
    import warnings

    from appell.errors import AppellNote

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", AppellNote)
            yield
    finally:  # also before an error raised inside (the model refused after its notes)
        for w in caught:
            if issubclass(w.category, AppellNote):
                echo(f"note: {w.message}", err=True)
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def load_derivation(
    model: str,
    overrides=None,
    floating_base: bool = False,
    dependent=None,
    formulas: bool = False,
    cache: bool | None = None,
    reactions_in: str | None = None,
    echo=None,
    reader=None,
):
    """:func:`load_system` and :func:`derive_model` in one step, through the derivation cache
    (:func:`appell.io.derivation_cache.derive_file`: a model file derived before is read back,
    not derived again; ``cache=False`` or ``$APPELL_NO_CACHE=1`` derives every time).
    ``reactions_in``: the axes of the joint reactions of a ``[mechanism]`` model
    (:func:`appell.io.modelfile.load_model`), ``reader`` the options of a robot file's reader
    (:func:`load_system`). The model's notes are ``note:`` lines on ``echo``,
    from the cache too; the inertia is checked at the start as :func:`derive_model` does."""
    from appell.io.derivation_cache import derive_file
    from appell.io.progress import status
    from appell.symbols import canonical_name

    echo = echo or _print
    path = resolve_model(model)
    dependent = [canonical_name(d) for d in dependent] if dependent else None
    with _notes_as_lines(echo), status(f"deriving {path.stem}"):
        # the inertia check runs before an entry is stored, not again on one stored after it
        return derive_file(
            path,
            overrides or None,
            floating_base=floating_base,
            dependent=dependent,
            cache=cache,
            formulas=formulas,
            reactions_in=reactions_in,
            reader=reader,
            check=_check_at_start,
        )


def _check_at_start(derivation) -> None:
    if not _is_controlled(derivation):
        check_inertia_at_start(derivation)


def derive_model(system, dependent=None, formulas: bool = False):
    """:func:`appell.derive`, or :func:`appell.control.servo.derive_controlled` when the system has
    servo constraints (method.md §4); ``formulas`` also computes the reduced equations (1.4)
    and the reaction formulas (1.5) now (they are otherwise built on first use). A status
    line shows the stage on a terminal (:func:`appell.io.progress.status`)."""
    from appell.core.equations import formulas_unavailable
    from appell.io.progress import status
    from appell.symbols import canonical_name

    dependent = [canonical_name(d) for d in dependent] if dependent else None
    with status(f"deriving {system.name}"):
        if system.servo_constraints:
            from appell.control.servo import derive_controlled

            derivation = derive_controlled(system, dependent=dependent)
        else:
            from appell.core.derive import derive

            derivation = derive(system, dependent=dependent)
            check_inertia_at_start(derivation)
        if formulas and (
            _is_controlled(derivation)
            or formulas_unavailable(derivation.partition) is None
            and derivation.inertia.tree is None
        ):
            derivation.reduced, derivation.reactions  # noqa: B018 (computed and cached here)
    return derivation


def check_inertia_at_start(derivation) -> None:
    """Refuse a derivation whose inertia is not positive on every admissible motion, before
    its formulas are formed (they would divide by zero: ``zoo`` in the printed equations, a
    singular matrix in the first solve): :func:`appell.numerics.inertia.check_inertia` at the
    model's initial state (its ``[simulation]`` t0), which names the motion without inertia
    as a combination of the speeds. Where the model gives no initial coordinates, a speed
    whose row of ``C^T M C`` vanishes identically (no inertia in any state) is named."""
    from appell.core.equations import formulas_unavailable
    from appell.numerics.boundary import numeric_model

    system = derivation.system
    values = system.initial_values
    if all(q.name in values for q in system.coordinates):
        from appell.numerics.inertia import check_inertia
        from appell.simulation.initial import check_blocks_at_start

        model = numeric_model(derivation, "numpy")  # one state's blocks: no compiler
        t0 = float(dict(system.settings).get("t0", 0.0))
        y = [float(values.get(name, 0.0)) for name in model.state_names]
        check_blocks_at_start(model, t0, y, model.default_parameters)  # entries beyond the range: named
        check_inertia(model, t0, y, model.default_parameters)
        return
    if formulas_unavailable(derivation.partition) is not None or derivation.inertia.tree is not None:
        return  # no closed form (or the recursive route): the inertia is checked where the numbers are computed
    reduced = derivation.reduced
    matrix = reduced.mass_matrix
    if matrix is None:
        return
    empty = [a.name for a, row in zip(reduced.independent, matrix.tolist()) if all(e == 0 for e in row)]
    if empty:
        raise ModelError(
            f"the reduced mass matrix C^T M C of {system.name!r} has a zero row for "
            f"{', '.join(empty)}: that motion has no inertia in any state, so its acceleration is "
            "not determined",
            hint="give it inertia (a mass or a moment of inertia in the kinetic energy), or constrain it",
        )


def internal_stability(derivation, solution=None):
    """``(linearisation, note)``: the internal dynamics of a controlled derivation linearised
    at its initial state (:func:`appell.control.internal_dynamics.internal_linearisation`), at
    the first row of ``solution`` when given; ``(None, None)`` without internal dynamics or
    initial values, ``(None, reason)`` when the linearisation cannot be computed there."""
    if not _is_controlled(derivation) or derivation.internal_dimension == 0 or not derivation.system.initial:
        return None, None
    from appell.control.internal_dynamics import internal_linearisation
    from appell.numerics.boundary import numeric_model

    time = state = None
    if solution is not None and solution.t.size:
        model = numeric_model(derivation)
        time, state = float(solution.t[0]), [float(solution.states[n][0]) for n in model.state_names]
    try:
        return internal_linearisation(derivation, time, state), None
    except ComputationError as exc:
        return None, f"the internal dynamics were not linearised at the initial state: {exc}"


def _warn_internal(linearisation, note, echo) -> None:
    """``warning: ...`` on stderr for an unstable internal dynamics (or one not linearised)."""
    message = linearisation.warning() if linearisation is not None else note
    if message:
        echo(f"warning: {message}", err=True)


def _echo_redundancy(derivation, echo) -> None:
    """Print which constraints are redundant and how their reactions are split
    (:meth:`appell.core.redundancy.Redundancy.summary`), when any are."""
    red = getattr(derivation, "redundancy", None)
    if red is not None:
        echo("\n".join(red.summary()))
