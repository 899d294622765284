"""A budget of evaluations for integrations that check a motion (the energy balance, the
first integrals' drift): a motion far too fast or stiff for its span (forces of 1e15, a
potential ``(sin q + cos q + 1)^30``) would otherwise keep an unattended check running for
minutes. The budget is first a count, not a time, so that a refusal for the pace of a motion
is the same on every machine; the seconds below bound only runs whose evaluations are slow.

Every :data:`PROJECT_EVERY` evaluations the whole span's cost at the pace so far,

.. math::  N_{projected} = N \\, \\frac{t_{end} - t_0}{t - t_0},

is compared with the limit (``t`` the furthest time evaluated); a run whose projection
exceeds it stops there with a :class:`~appell.errors.ComputationError` that names the
check, the span, the time reached and what to do, and one that passes it stops at once.
(The bundled examples' energy balances project at most 6,900 evaluations from the 100th
on, and up to 3.3 million at the 25th, while a motion at rest has barely started.)

The count does not bound the time where one evaluation is slow (a Newton solve of
constraints nonlinear in the accelerations per evaluation, with forces of 1e14: 1.5 ms
each, 50,000 in 63 s); ``seconds`` does, checked at the same points: past it the run stops
with the same error. It is far above what a model whose check is meant to run takes (the
bundled examples' balances take at most 2 s), so it decides only runs that would
otherwise take minutes.
"""

from __future__ import annotations

import math
import time

from appell.errors import ComputationError

__all__ = ["EvaluationBudget", "PROJECT_EVERY"]

#: evaluations between two projections of the whole run's cost (the first at this count)
PROJECT_EVERY = 100


class EvaluationBudget:
    """Counts the evaluations of an integration over ``[t0, t_end]``; call it with the time
    of each evaluation (module docstring). ``what`` names the check in the message."""

    def __init__(
        self,
        what: str,
        t0: float,
        t_end: float,
        limit: int,
        seconds: float | None = None,
        hint: str = "check a shorter span (appell check --t-end T), or look for forces or potentials "
        "that are far too large",
        first: int = PROJECT_EVERY,
    ):
        self.what, self.t0, self.t_end, self.limit, self.hint = what, float(t0), float(t_end), int(limit), hint
        #: evaluations before the first projection: an implicit method's start on a stiff motion
        #: takes steps far shorter than its later ones, and a projection there says nothing
        self.first = int(first)
        self.calls, self.reached = 0, float(t0)
        self.seconds, self.start = seconds, time.perf_counter()

    def __call__(self, t: float) -> None:
        self.calls += 1
        self.reached = max(self.reached, float(t))
        if (self.calls >= self.first and self.calls % PROJECT_EVERY == 0) or self.calls > self.limit:
            projected = self.projected()
            if self.calls > self.limit or projected > self.limit:
                pace = f"about {projected:.2g}" if math.isfinite(projected) else "an unbounded number of"
                raise ComputationError(
                    f"{self.what} would need {pace} evaluations over [{self.t0:g}, {self.t_end:g}], more than "
                    f"its budget of {self.limit} (stopped at t = {self.reached:.6g} after {self.calls}); the "
                    f"motion is too fast or stiff for this span",
                    hint=self.hint,
                )
            spent = time.perf_counter() - self.start
            if self.seconds is not None and spent > self.seconds:
                raise ComputationError(
                    f"{self.what} has run {spent:.0f} s, more than its budget of {self.seconds:g} s (stopped at "
                    f"t = {self.reached:.6g} of [{self.t0:g}, {self.t_end:g}] after {self.calls} evaluations, "
                    f"at a pace of {self.projected():.2g} for the span); each evaluation is slow here",
                    hint=self.hint,
                )

    def projected(self) -> float:
        """Evaluations the whole span would take at the pace so far."""
        done = (self.reached - self.t0) / (self.t_end - self.t0)
        return self.calls / done if done > 0 else math.inf
