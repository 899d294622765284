"""Memory for the recorded rows of a run, checked before the integration starts.

A simulation keeps every output row (states, accelerations, multipliers, controls, residuals,
outputs) until it returns; ``--samples 100000000`` used to integrate for minutes and then fail
with a ``MemoryError`` or a ``SystemError`` from inside NumPy. :func:`check_memory` estimates
what the rows need (rows x columns x 8 bytes, times :data:`COPIES` for the copies made while
recording, assembling and exporting, plus :data:`ROW_OVERHEAD` per row where rows are recorded
one by one from Python) and raises :class:`~appell.errors.ResourceError` when that exceeds
the memory available to the process (:func:`available_memory`).
"""

from __future__ import annotations

import os

from appell.errors import ResourceError
from appell.numerics.dynamics import ServoTracking, system_of

__all__ = ["available_memory", "check_memory", "check_run_memory", "row_bytes", "COPIES", "ROW_OVERHEAD"]

#: copies of the recorded numbers alive at once (recorded blocks, their concatenation, the
#: solution's columns and outputs, the export); measured: about 4 with the compiled loop
COPIES = 4
#: bytes per row recorded one by one from Python (small arrays and tuples per row; measured
#: about 2.7 kB per row of the pendulum with the NumPy backend)
ROW_OVERHEAD = 3000


def _meminfo_available() -> int | None:
    """``MemAvailable`` of ``/proc/meminfo`` in bytes (Linux), else None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _address_space_left() -> int | None:
    """What the soft ``RLIMIT_AS`` (``ulimit -v``) leaves to this process: the limit less its
    present virtual size; None without a limit (or where it cannot be read)."""
    try:
        import resource
    except ImportError:  # not on POSIX
        return None
    try:
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (OSError, ValueError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    used = 0
    try:
        with open("/proc/self/statm", encoding="ascii") as fh:
            used = int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        pass
    return max(0, soft - used)


def available_memory() -> tuple[int | None, str]:
    """``(bytes, what limits them)``: the smaller of the memory the system can still give
    (``MemAvailable``, else ``SC_AVPHYS_PAGES``) and what the address-space limit leaves;
    ``(None, "")`` where neither can be read."""
    found = []
    free = _meminfo_available()
    if free is None:
        try:
            free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            free = None
    if free is not None and free > 0:
        found.append((free, "the memory available on this machine"))
    left = _address_space_left()
    if left is not None:
        found.append((left, "what the address-space limit (ulimit -v) leaves to this process"))
    if not found:
        return None, ""
    return min(found)


def row_bytes(columns: int, row_by_row: bool) -> int:
    """Estimated bytes per recorded row of ``columns`` numbers (module docstring)."""
    return int(columns) * 8 * COPIES + (ROW_OVERHEAD if row_by_row else 0)


def check_memory(rows: int, columns: int, what: str, *, row_by_row: bool = True, hint: str | None = None) -> int:
    """Raise :class:`ResourceError` when ``rows`` recorded rows of ``columns`` numbers (``what``
    names them in the message) need more memory than is available; returns the estimate in
    bytes. ``row_by_row``: rows recorded one at a time from Python (the NumPy backend, SciPy's
    integrators), not in preallocated arrays (the compiled loop)."""
    need = int(rows) * row_bytes(columns, row_by_row)
    have, source = available_memory()
    if have is not None and need > have:
        raise ResourceError(
            f"out of memory: {what} would need about {_size(need)} ({int(rows):,} rows of {int(columns)} "
            f"columns), more than the {_size(have)} available ({source})",
            hint=hint
            or "record fewer output times (--samples, --output-step, [simulation] t_eval) or a shorter "
            "span (--t-end), or run where more memory is available",
        )
    return need


def check_run_memory(model, rows: int, compiled: bool = False) -> int:
    """:func:`check_memory` for ``rows`` output times of a run of ``model`` (a
    :class:`~appell.numerics.dynamics.Dynamics`): its columns are t, the states, the
    accelerations, per constraint the multiplier and two residuals, the controls, the tracked
    servo constraints and the system's outputs. ``compiled``: the compiled loop records the
    rows (no per-row overhead)."""
    system = system_of(model)
    outputs = len(system.outputs) if system is not None else 0
    servo = len(model.servo_names) if isinstance(model, ServoTracking) else 0
    columns = (
        1
        + len(model.state_names)
        + len(model.speed_names)
        + 3 * len(model.constraint_names)
        + len(model.control_names)
        + servo
        + outputs
    )
    return check_memory(
        rows, columns, f"recording {model.name!r} at {int(rows):,} output times", row_by_row=not compiled
    )


def _size(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} bytes"
