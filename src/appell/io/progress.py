"""Progress of the command line's long stages on stderr: a status line with the elapsed time.

Derivations of large models and C compilation give no intermediate counts, so a stage
shows ``appell: <what> ... 12 s`` on one line, redrawn every half second by a background
thread and erased when the stage ends. Only when stderr is a terminal: piped or
redirected output (scripts, CI, tests) stays quiet. Simulations and sweeps have their own
tqdm bars (:func:`appell.simulation.simulate.simulate`, :func:`appell.simulation.sweep.sweep`).
"""

from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager

__all__ = ["status", "is_terminal"]

#: seconds between redraws of the status line
REFRESH = 0.5


def is_terminal(stream) -> bool:
    """Whether ``stream`` is an interactive terminal (false for files, pipes, closed streams)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


@contextmanager
def status(what: str, stream=None, enabled: bool | None = None):
    """Show ``what`` with the elapsed seconds on ``stream`` (default ``sys.stderr``) while the
    block runs; ``enabled`` None: only when the stream is a terminal. The line is erased at
    the end, so the command's own output is unchanged."""
    stream = sys.stderr if stream is None else stream
    if enabled is None:
        enabled = is_terminal(stream)
    if not enabled:
        yield
        return
    start = time.perf_counter()
    done = threading.Event()
    width = [0]

    def draw():
        line = f"appell: {what} ... {time.perf_counter() - start:.0f} s"
        stream.write("\r" + line.ljust(width[0]))
        stream.flush()
        width[0] = len(line)

    def redraw():
        while not done.wait(REFRESH):
            draw()

    draw()
    thread = threading.Thread(target=redraw, name="appell-status", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        stream.write("\r" + " " * width[0] + "\r")
        stream.flush()
