"""The interrupt state of the ``appell`` command: how Ctrl-C and a swallowed
:class:`KeyboardInterrupt` are handled, from before appell is imported until the process ends.

A module of the standard library only, outside the package (importing anything under
``appell`` runs the package's ``__init__`` first), so that both the entry point
(:mod:`appell_entry`, which installs the handlers before appell is imported) and the command
line (:mod:`appell.io.cli`, which asks :func:`interrupt_received` and installs
:func:`rescue_interrupts`) import it, and neither imports the other: the entry point imports
the command line, never the reverse (tests/test_architecture.py guards the circle).

* while appell is imported, a Ctrl-C ends the process at once (nothing to clean up yet; a
  KeyboardInterrupt raised inside a C extension's import becomes an ImportError that an
  optional import may swallow);
* once the command runs, the first Ctrl-C raises :class:`KeyboardInterrupt` as Python's
  default handler does, so that the command cleans up (a write under way removes its temporary file, a sweep keeps its
  partial file and closes its cluster) and :mod:`appell.io.cli` reports it;
* a second one, or one after the command has finished, ends the process at once
  (:func:`os._exit`), printing the line unless it was printed already.

CPython runs a signal's handler at the next check of its interpreter loop, which may fall inside
a finalizer or a weak reference's callback (an import's module lock has one); what the handler
raises there is ignored ("Exception ignored in ..."), and the command went on as if no Ctrl-C
had come, ending with exit code 0 or sleeping on. :func:`rescue_interrupts` installs a
``sys.unraisablehook`` that sees such a :class:`KeyboardInterrupt` and sends SIGINT to the
process again a moment later, with the first Ctrl-C's handling restored, so that it is raised
where the command can clean up.
"""

import os
import signal
import sys

# nothing else at the top: until main() installs its handler, a Ctrl-C is Python's own (a
# traceback), so this module imports only what Python has loaded already or at once (``signal``:
# 1 ms; ``threading``, 1.5 ms more, is imported by the hook that needs it)

__all__ = ["run", "rescue_interrupts", "interrupt_received", "EXIT_INTERRUPTED"]

#: exit code of a command stopped by Ctrl-C: 128 + SIGINT
EXIT_INTERRUPTED = 128 + signal.SIGINT
_LINE = b"error: interrupted\n"
_reported = False
_received = False


def _report() -> None:
    """Print the line once (straight to the file descriptor: safe inside a signal handler)."""
    global _reported
    if not _reported:
        _reported = True
        try:
            os.write(2, (b"\n" if os.isatty(2) else b"") + _LINE)  # on a terminal, after its ^C
        except OSError:
            pass


def _flush() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass


def _exit_now(signum, frame) -> None:
    """A Ctrl-C while the first is handled, or after the command: exit at once."""
    _report()
    os._exit(EXIT_INTERRUPTED)


def _interrupt(signum, frame) -> None:
    """The first Ctrl-C: a :class:`KeyboardInterrupt` where the command is (module docstring)."""
    global _received
    _received = True
    _handle(_exit_now)
    raise KeyboardInterrupt


def interrupt_received() -> bool:
    """Whether the first Ctrl-C has come. A :class:`KeyboardInterrupt` raised inside the
    initialisation of a C extension that the command imports as it runs (as NumPy's import of
    ``datetime`` does) reaches the command as an :class:`ImportError` instead; an error that ends the command after a Ctrl-C is its
    consequence, and the command ends as interrupted (exit 130), not with a traceback."""
    return _received


def _handle(handler) -> None:
    try:
        signal.signal(signal.SIGINT, handler)
    except ValueError:  # not the main thread (an embedding program): leave its signals alone
        pass


#: seconds after a swallowed KeyboardInterrupt before SIGINT is sent again
RESEND_AFTER = 0.02


def _resend() -> None:
    try:
        os.kill(os.getpid(), signal.SIGINT)
    except OSError:
        pass


def rescue_interrupts() -> None:
    """Install the ``sys.unraisablehook`` of the module docstring (once; the hook in place
    before it handles everything else)."""
    previous = sys.unraisablehook
    if getattr(previous, "appell_rescue", False):
        return

    def hook(info):
        if isinstance(info.exc_value, KeyboardInterrupt):
            if signal.getsignal(signal.SIGINT) is _exit_now:
                _handle(_interrupt)  # the swallowed one was the first Ctrl-C: raise it again
            import threading

            timer = threading.Timer(RESEND_AFTER, _resend)
            timer.daemon = True
            timer.start()
            return
        previous(info)

    hook.appell_rescue = True
    sys.unraisablehook = hook


def run(argv=None, command=None, load=None) -> int:
    """Run ``command`` (called as ``command(argv, standalone=False)``) under the handling of
    the module docstring and return its exit code. Without ``command``, ``load()`` returns it:
    it is called while a Ctrl-C still ends the process at once (the import of appell)."""
    global _reported
    rescue_interrupts()
    try:
        if command is None:
            # while appell is imported there is nothing to clean up, and a KeyboardInterrupt
            # raised there can be lost: a C extension's initialisation reports it as an
            # ImportError, which a library's optional import then swallows (the command ran
            # on after a Ctrl-C 0.3 s after its start). A Ctrl-C here ends the process at once.
            _handle(_exit_now)
            command = load()
        _handle(_interrupt)
        code = command(argv, standalone=False)
        _flush()
        if code == EXIT_INTERRUPTED:
            _reported = True  # the command line has printed the line
        _handle(_exit_now)
    except KeyboardInterrupt:  # during the import, or outside the command line's own handling
        _handle(_exit_now)
        _flush()
        _report()
        code = EXIT_INTERRUPTED
    return code if isinstance(code, int) else 0
