"""Pytest plugin: how close every numerical comparison of the suite comes to its tolerance.

Enabled with ``-p tolerance_margins`` (``scripts/test-matrix.sh --margins``). It records,
for each ``pytest.approx`` comparison and each ``numpy.testing.assert_allclose`` call made
from a test file, the *use* of the tolerance

    use = |actual - expected| / tolerance        (pass: use <= 1)

and, at the end of the session, prints the comparisons whose use exceeds
``$APPELL_MARGIN_REPORT`` (default 0.1, i.e. a margin below 10x) with their file and
line, worst first; with ``$APPELL_MARGIN_FILE`` set, every record is also written there as
tab-separated lines (test, place, use) so that runs under several BLAS kernels can be
compared. A comparison that uses most of its tolerance on one machine is the one that
fails on the next (issue 26); a tolerance must follow from the computation, with the
reason written beside it.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

try:  # pytest >= 9
    from _pytest import approx as python_api
except ImportError:  # pytest 8
    from _pytest import python_api

TESTS = str(Path(__file__).resolve().parent)
_records: dict[tuple[str, str], float] = {}
_current = {"test": ""}


def _place() -> str:
    """file:line of the innermost caller in the tests folder (not this plugin)."""
    frame = sys._getframe(2)
    while frame is not None:
        name = frame.f_code.co_filename
        if name.startswith(TESTS) and not name.endswith("tolerance_margins.py"):
            return f"{Path(name).name}:{frame.f_lineno}"
        frame = frame.f_back
    return "?"


def _note(use: float) -> None:
    if not math.isfinite(use):
        use = float("inf")
    key = (_current["test"], _place())
    _records[key] = max(use, _records.get(key, 0.0))


_scalar_eq = python_api.ApproxScalar.__eq__


def _approx_scalar_eq(self, actual):
    result = _scalar_eq(self, actual)
    try:
        tol = self.tolerance
        diff = abs(complex(actual) - complex(self.expected))
        _note(diff / tol if tol > 0 else (0.0 if diff == 0 else float("inf")))
    except Exception:  # a non-numeric comparison: nothing to measure
        pass
    return result


_allclose = np.testing.assert_allclose


def _assert_allclose(actual, desired, rtol=1e-7, atol=0, *args, **kwargs):
    try:
        a = np.asarray(actual, dtype=complex)
        d = np.asarray(desired, dtype=complex)
        bound = atol + rtol * np.abs(d)
        diff = np.abs(a - d)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(bound > 0, diff / np.where(bound > 0, bound, 1.0), np.where(diff == 0, 0.0, np.inf))
        ratio = ratio[np.isfinite(a) & np.isfinite(d) | ~np.isfinite(ratio)] if ratio.ndim else ratio
        if np.size(ratio):
            _note(float(np.max(ratio)))
    except Exception:
        pass
    return _allclose(actual, desired, rtol, atol, *args, **kwargs)


def pytest_configure(config):
    python_api.ApproxScalar.__eq__ = _approx_scalar_eq
    np.testing.assert_allclose = _assert_allclose


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    _current["test"] = item.nodeid
    yield
    _current["test"] = ""


def pytest_terminal_summary(terminalreporter):
    limit = float(os.environ.get("APPELL_MARGIN_REPORT", "0.1"))
    out = os.environ.get("APPELL_MARGIN_FILE")
    if out:
        with open(out, "a", encoding="utf-8") as fh:
            for (test, place), use in sorted(_records.items()):
                fh.write(f"{test}\t{place}\t{use:.3e}\n")
    close = sorted(((use, test, place) for (test, place), use in _records.items() if use > limit), reverse=True)
    tr = terminalreporter
    tr.section(
        f"tolerance margins: {len(_records)} comparisons, {len(close)} use more than {limit:g} of their tolerance"
    )
    for use, test, place in close:
        tr.write_line(f"{use:9.3g}  {place:40s} {test}")
