"""Errors raised by appell.

Two families, matching the command line's exit codes:

* :class:`ModelError` (exit code 2) — the input is wrong: an undeclared symbol, a
  constraint without speeds, a singular partition, inconsistent initial values.
  The message names the culprit and says what to do.
* :class:`ComputationError` (exit code 1) — the input is acceptable but the computation
  failed: Newton's method did not converge, the integrator stopped.

:class:`MissingDependencyError` (exit code 1) says that a feature needs an optional package
that is not installed, with the command that installs it (:func:`import_optional`).
"""

from __future__ import annotations


class AppellError(Exception):
    """Base class of every error appell raises on purpose."""

    exit_code = 1

    def __init__(self, message: str, *, where: str | None = None, hint: str | None = None):
        self.message = message
        self.where = where
        self.hint = hint
        super().__init__(self.__str__())

    def __str__(self) -> str:
        text = self.message
        if self.where:
            text = f"{self.where}: {text}"
        if self.hint:
            text = f"{text}\n  hint: {self.hint}"
        return text


class MissingDependencyError(AppellError):
    """An optional package that a feature needs is not installed (not a bug in appell, nor bad
    input); exit code 1. The hint gives the command that installs it."""

    exit_code = 1


def import_optional(module: str, *, extra: str, feature: str):
    """Import ``module`` for ``feature``, or raise :class:`MissingDependencyError` saying so
    with the install command of the package's optional dependencies ``appell[extra]``
    (pyproject.toml ``[project.optional-dependencies]``)."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        missing = getattr(exc, "name", None) or module.split(".")[0]
        raise MissingDependencyError(
            f"{feature} needs the optional package {missing.split('.')[0]!r}, which is not installed",
            hint=f"install it with: pip install 'appell[{extra}]'",
        ) from None


class AppellNote(UserWarning):
    """Something of the input that appell reads past without using it (a URDF's
    transmissions, a joint's damping): a warning in Python, a ``note:`` line on the command
    line. Never an error: the model is what appell says it is."""


class ModelError(AppellError):
    """The model (or a value given with it) is invalid; exit code 2."""

    exit_code = 2


class FormulaUnavailable(ModelError):
    """A closed form is not formed: the dependent block ``J_h`` is larger than
    :data:`appell.core.equations.INVERSE_LIMIT` (its symbolic inverse would swell past use).
    The numbers come from the numeric split all the same."""


class ComputationError(AppellError):
    """A numeric or symbolic computation failed on a valid model; exit code 1."""

    exit_code = 1


class SingularConfigurationError(ModelError):
    """The motion reached a state where the constraint Jacobian lost rank: no partition
    satisfies condition (1.2), so the reactions are not determined there; exit code 2.
    The message names the constraints involved."""


class PainleveError(SingularConfigurationError):
    """Coulomb friction makes the normal force of a sliding contact undetermined (the
    Painlevé paradox): the coefficient of ``N`` in its own formula (1.5), with the
    friction that ``N`` causes, vanishes or changes sign, so no (or no unique) normal
    force exists for rigid bodies; exit code 2. The message names the contact."""


class InitialValueError(ModelError):
    """Initial values that violate constraints (exit code 2).

    ``violations``: ``(constraint, level, residual)`` for every residual over the
    tolerance; ``level`` is ``'position'`` (``F``) or ``'velocity'`` (``phi``).
    """

    def __init__(self, message: str, *, violations=(), where: str | None = None, hint: str | None = None):
        self.violations = tuple(violations)
        super().__init__(message, where=where, hint=hint)


class ResourceError(AppellError):
    """The environment failed, not the model nor appell: a full disk, a read-only file
    system, an unreachable Dask scheduler, lost workers; exit code 1. The message names the
    resource and the system's reason."""

    exit_code = 1
