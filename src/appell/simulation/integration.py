"""The integrator of a run: one :class:`Integration` object, restarted where the state jumps.

The integrator is driven step by step through SciPy's ``OdeSolver`` interface (the classes
behind ``scipy.integrate.solve_ivp``: ``DOP853`` by default, or ``RK45``, ``RK23``, ``Radau``,
``BDF``, ``LSODA``). With ``method="DOP853"`` on a compiled model whose constraints are linear in
``a`` the compiled loop of :mod:`appell.numerics.compiled_loop` takes SciPy's place: the same
scheme and step control in C, which runs the steps that need nothing of Python (no watched
events; projections onto the constraints it does itself) and records their output times
there. The implicit methods get the exact Jacobian of the motion
(:func:`~appell.numerics.linearise.motion_jacobian`) where the model is a plain split. Each
start also sets the rank watch of the active model (:mod:`appell.simulation.singular`).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from appell.errors import AppellError, ModelError

if TYPE_CHECKING:
    from appell.simulation.singular import RankWatch
# the rank watch (SciPy's optimize) is imported by the run that starts it: the numeric tree route
# (appell.io.cli_tree) takes only the integrators' names and classes from here

__all__ = ["IMPLICIT", "METHODS", "Integration", "Step", "method_name", "solver_class"]

#: methods that solve implicit stages with Newton's method and so take the Jacobian dG/dy
#: (names of SciPy's classes: ``scipy.integrate`` is imported where a run integrates in Python,
#: not by a run of the compiled loop)
IMPLICIT = ("Radau", "BDF", "LSODA")

#: integrators by name (the names of SciPy's OdeSolver classes); "DOP853" on a compiled model
#: runs the compiled loop (:mod:`appell.numerics.compiled_loop`), "DOP853-scipy" always SciPy's class
METHODS = {
    "DOP853": "DOP853",
    "DOP853-scipy": "DOP853",
    "RK45": "RK45",
    "RK23": "RK23",
    "Radau": "Radau",
    "BDF": "BDF",
    "LSODA": "LSODA",
}


def method_name(method) -> str:
    """The name of the ``OdeSolver`` class of ``method`` (a name in :data:`METHODS` or a
    class), without importing SciPy for a name; an unknown name is refused."""
    if isinstance(method, str):
        if method not in METHODS:
            raise ModelError(f"unknown integration method {method!r}", hint="methods: " + ", ".join(METHODS))
        return METHODS[method]
    return getattr(solver_class(method), "__name__", str(method))


def solver_class(method):
    """The ``OdeSolver`` class of ``method`` (a name in :data:`METHODS` or the class)."""
    import scipy.integrate as si

    solver_cls = getattr(si, METHODS[method]) if isinstance(method, str) and method in METHODS else method
    if not (isinstance(solver_cls, type) and issubclass(solver_cls, si.OdeSolver)):
        raise ModelError(f"unknown integration method {method!r}", hint="methods: " + ", ".join(METHODS))
    return solver_cls


def _implicit(solver_cls) -> bool:
    import scipy.integrate as si

    return isinstance(solver_cls, type) and issubclass(solver_cls, tuple(getattr(si, n) for n in IMPLICIT))


def exact_jacobian(model, solver_cls, cache: dict):
    """The exact Jacobian ``jac(t, y, p)`` of the motion of ``model`` for an implicit method,
    made once per model (``cache``); None for an explicit method and for models whose motion
    holds more than the split (friction modes, redundant supports, servo constraints: SciPy's
    finite differences there)."""
    if not _implicit(solver_cls):
        return None
    from appell.numerics.linearise import motion_jacobian
    from appell.numerics.numeric import NumericModel

    if not isinstance(model, NumericModel):
        return None
    if id(model) not in cache:
        cache[id(model)] = (model, motion_jacobian(model))
    return cache[id(model)][1]


#: largest magnitude of a state derivative the integrators take: their error norms square it
#: (1e300 squared overflows, with NumPy's warnings and then a failed step size)
LARGEST = 1e150


def _out_of_range(model, t, derivative, p) -> None:
    """Refuse a state derivative beyond :data:`LARGEST` or not finite, naming its entry and the
    parameters of extreme size."""
    from appell.errors import ComputationError
    from appell.numerics.inertia import extreme_parameters

    k = int(np.argmax(~(np.abs(derivative) <= LARGEST)))
    names = [f"{n}'" for n in model.state_names]  # the Dynamics protocol's members
    what = names[k] if k < len(names) else f"entry {k + 1} of the state's derivative"
    extreme = extreme_parameters(model.parameter_names, p) if p is not None else ""
    raise ComputationError(
        f"{what} is {derivative[k]:.3g} at t = {float(t):.10g}, beyond the floating range that "
        "the integrator's error norms can square (1e150)" + (f" ({extreme})" if extreme else ""),
        hint="give the parameters values of ordinary size, or rescale the model's units",
    )


@dataclass(frozen=True)
class Step:
    """One accepted step: its end ``(t, y)``, its dense output, and ``k`` the index of the next
    output time not yet recorded (the compiled loop records those it passes); or a failure
    with its ``message``."""

    t: float = 0.0
    y: np.ndarray | None = None
    dense: object = None
    k: int = 0
    failure: str | None = None


class Integration:
    """The integrator of a run from ``(t, y)`` of the ``active`` model to ``t_end``
    (module docstring); ``run`` (:class:`appell.simulation.recording.Run`) evaluates the model
    and counts evaluations and steps."""

    def __init__(self, run, method, options, compiled: bool):
        self.run, self.method, self.options, self.compiled = run, method, options, compiled
        self._solver_cls = None
        self.p = run.p
        self.active = None
        self.solver = None
        self.rank: RankWatch | None = None
        self.scales: dict = {}  # each constraint row's size at its first sight (appell.simulation.singular)
        self.jacobians: dict = {}  # the exact Jacobian of each model the implicit methods have used

    @property
    def solver_cls(self):
        """The ``OdeSolver`` class of the run's method, resolved (SciPy imported) at first use:
        a run the compiled loop takes whole never needs it."""
        if self._solver_cls is None:
            self._solver_cls = solver_class(self.method)
        return self._solver_cls

    def fun(self, t, y):
        self.run.nfev += 1
        derivative = self.run.evaluate(self.active, t, y).derivative
        if not np.all(np.abs(derivative) <= LARGEST):
            _out_of_range(self.active, t, derivative, self.p)
        return derivative

    def _tolerances(self) -> dict:
        return {"rtol": self.options.rtol, "atol": self.options.atol, "max_step": self.options.max_step}

    def _scipy_options(self) -> dict:
        """Tolerances of the run and, for the implicit methods, the exact Jacobian."""
        kw = self._tolerances()
        jac = exact_jacobian(self.active, self.solver_cls, self.jacobians)
        if jac is not None:
            kw["jac"] = lambda t_, y_: jac(t_, y_, self.p)
        return kw

    def start(self, active, t, y, first_step=None) -> None:
        """A fresh integrator of ``active`` from ``(t, y)`` (``first_step``: the step size to
        keep across a restart)."""
        self.active = active
        kw = self._tolerances()
        if first_step is not None:
            kw["first_step"] = min(first_step, self.options.t_end - t)
        from appell.simulation.singular import DIP, SINGULAR_LEVEL, TRUST, RankWatch

        if self.rank is None or self.rank.model is not active:
            self.rank = RankWatch(active, self.p, t, y, self.scales)
        loop = self.run.loop(active) if self.compiled else None
        if loop is not None and self.rank.active and getattr(loop, "scale", None) is None:
            loop.watch(self.rank.scale, max(10.0 * SINGULAR_LEVEL, 2.0 * TRUST * self.rank.band), DIP)
        if loop is None:
            self.solver = self.solver_cls(self.fun, t, y, self.options.t_end, **{**self._scipy_options(), **kw})
            return
        loop.set_switched(self.run.dependent is not None and self.run.dependent != loop.default_dependent)
        self.solver = loop.solver(t, y, self.options.t_end, **kw)
        self.run.nfev += self.solver.counts()[0]

    def restart(self, active, t, y, keep_step: bool = False) -> None:
        """:meth:`start` again after a jump of the state, keeping the step size (``keep_step``:
        also where the solver reports none but its current one)."""
        h = getattr(self.solver, "h_abs", None)
        if keep_step:
            h = h or self.solver.step_size
        self.start(active, t, y, h)
        self.run.restarts += 1

    def sub_solver(self, t, y, t_bound):
        """An integrator of the run's method and tolerances from (t, y) to t_bound (the
        approach to a singular configuration, :mod:`appell.simulation.passage`)."""
        return self.solver_cls(self.fun, t, y, t_bound, **self._scipy_options())

    def step(self, k: int, t_eval, single: bool) -> Step:
        """One accepted step (the compiled loop: as many as need nothing of Python, recording
        the output times they pass from ``k`` on, unless ``single``)."""
        solver, run = self.solver, self.run
        try:
            loops = sys.modules.get("appell.numerics.compiled_loop")  # imported where a compiled loop runs
            if loops is not None and isinstance(solver, loops.LoopSolver):
                k0, out = k, run.loop_outputs(self.active, t_eval)
                if single:
                    msg = solver.step()
                else:
                    tol = self.options.projection_tol if self.options.stabilization == "projection" else np.inf
                    budget = self.options.max_evaluations
                    k, msg = solver.advance(k, tol, None if budget is None else budget - run.nfev)
                    projected = solver.projections()  # done in C, each with its restart
                    run.projections += projected
                    run.restarts += projected
                if k > k0:
                    ys, acc, lam, F, phi = out.rows(k0, k)
                    run.add_block(self.active, t_eval[k0:k], ys, acc, lam, np.zeros((k - k0, 0)), F, phi)
                previous = None if single else solver.previous_dense_output()
                if previous is not None:  # the steps before this one ran in C: their last one
                    self.rank.seed(*previous)
                nfev, steps = solver.counts()
                run.nfev += nfev
                run.steps += steps - 1
            else:
                msg = solver.step()
        except AppellError as exc:
            return Step(failure=f"the model could not be evaluated near t = {solver.t:.10g}: {exc}")
        if solver.status == "failed":
            message = f"the integrator failed at t = {solver.t:.10g}: {msg}"
            from appell.simulation.singular import explain_failure

            why = explain_failure(self.active, solver.t, solver.y, self.p)
            return Step(failure=message if why is None else message.rstrip(".") + "; " + why)
        run.steps += 1
        return Step(float(solver.t), np.array(solver.y, float), solver.dense_output(), k)
