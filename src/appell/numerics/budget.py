"""A budget of evaluations for integrations that check a motion (the energy balance, the
first integrals' drift): a motion far too fast or stiff for its span (forces of 1e15, a
potential ``(sin q + cos q + 1)^30``) would otherwise keep an unattended check running for
minutes. The budget is a count, not a time, so a refusal is the same on every machine.

Every :data:`PROJECT_EVERY` evaluations the whole span's cost at the pace so far,

.. math::  N_{projected} = N \\, \\frac{t_{end} - t_0}{t - t_0},

is compared with the limit (``t`` the furthest time evaluated); a run whose projection
exceeds it stops there with a :class:`~appell.errors.ComputationError` that names the
check, the span, the time reached and what to do, and one that passes it stops at once.
"""

from __future__ import annotations

import math

from appell.errors import ComputationError

__all__ = ["EvaluationBudget", "PROJECT_EVERY"]

#: evaluations between two projections of the whole run's cost
PROJECT_EVERY = 1_000


class EvaluationBudget:
    """Counts the evaluations of an integration over ``[t0, t_end]``; call it with the time
    of each evaluation (module docstring). ``what`` names the check in the message."""

    def __init__(self, what: str, t0: float, t_end: float, limit: int,
                 hint: str = "check a shorter span (appell check --t-end T), or look for forces or potentials "
                             "that are far too large"):
        self.what, self.t0, self.t_end, self.limit, self.hint = what, float(t0), float(t_end), int(limit), hint
        self.calls, self.reached = 0, float(t0)

    def __call__(self, t: float) -> None:
        self.calls += 1
        self.reached = max(self.reached, float(t))
        if self.calls % PROJECT_EVERY == 0 or self.calls > self.limit:
            projected = self.projected()
            if self.calls > self.limit or projected > self.limit:
                pace = f"about {projected:.2g}" if math.isfinite(projected) else "an unbounded number of"
                raise ComputationError(
                    f"{self.what} would need {pace} evaluations over [{self.t0:g}, {self.t_end:g}], more than "
                    f"its budget of {self.limit} (stopped at t = {self.reached:.6g} after {self.calls}); the "
                    f"motion is too fast or stiff for this span", hint=self.hint)

    def projected(self) -> float:
        """Evaluations the whole span would take at the pace so far."""
        done = (self.reached - self.t0) / (self.t_end - self.t0)
        return self.calls / done if done > 0 else math.inf
