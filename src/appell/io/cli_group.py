"""The ``appell`` click group's handling of errors: every error ends as ``error: <message>``
(and a hint) on stderr and one of the exit codes below, never a traceback (the table of exit
codes: :mod:`appell.io.cli`). Standard library and click only.
"""

from __future__ import annotations

import os
import signal
import sys

import click

from appell.errors import AppellError, ModelError
from appell_interrupts import interrupt_received

EXIT_OK, EXIT_FAILURE, EXIT_BAD_INPUT = 0, 1, 2
#: exit codes of a command stopped by Ctrl-C (SIGINT) or SIGTERM: 128 + the signal number
EXIT_INTERRUPTED, EXIT_TERMINATED = 128 + signal.SIGINT, 128 + signal.SIGTERM

_NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())


class _AppellGroup(click.Group):
    """Turns every error into ``error: ...`` on stderr and the exit codes of the module."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        try:
            rv = super().main(
                args=args, prog_name=prog_name or "appell", complete_var=complete_var, standalone_mode=False, **extra
            )
        except _NO_ARGS_IS_HELP as exc:  # click >= 8.2: a bare 'appell' prints the help
            click.echo(exc.ctx.get_help())
            code = EXIT_BAD_INPUT
        except click.UsageError as exc:
            hint = f"run '{exc.ctx.command_path} --help'" if exc.ctx is not None else "run 'appell --help'"
            code = _report_error(exc.format_message(), hint, EXIT_BAD_INPUT)
        except click.exceptions.Exit as exc:
            code = exc.exit_code
        except Interrupted:
            code = _interrupted()
        except click.Abort as exc:  # click turns Ctrl-C into Abort (while it reads the arguments)
            interrupted = isinstance(exc.__context__, KeyboardInterrupt)
            code = _interrupted() if interrupted else _report_error("aborted", None, EXIT_FAILURE)
        except Terminated:
            code = _report_error("terminated (SIGTERM)", None, EXIT_TERMINATED)
        except click.ClickException as exc:
            code = _report_error(exc.format_message(), None, EXIT_BAD_INPUT)
        except ModelError as exc:
            code = _report_error(str(exc), None, EXIT_BAD_INPUT)
        except AppellError as exc:
            code = _report_error(str(exc), None, getattr(exc, "exit_code", EXIT_FAILURE))
        except (FileNotFoundError, IsADirectoryError, PermissionError, NotADirectoryError) as exc:
            code = _report_error(
                f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc), None, EXIT_BAD_INPUT
            )
        except OSError as exc:  # the environment (a full disk, a read-only file system, I/O), not a bug
            reason = (exc.strerror or str(exc)).strip()
            code = _report_error(
                f"{exc.filename}: {reason}" if exc.filename else reason,
                "the operating system refused (see the reason above); the previous output files are unchanged",
                EXIT_FAILURE,
            )
        except MemoryError:
            code = _out_of_memory()
        except KeyboardInterrupt:
            code = _interrupted()
        except SystemError as exc:  # an extension module that failed to allocate, else a bug
            if interrupt_received():
                code = _interrupted()
            elif not isinstance(exc.__cause__ or exc.__context__, MemoryError):
                code = _internal_error(exc)
            else:
                code = _out_of_memory()
        except Exception as exc:  # a bug, not the user's input: no traceback unless asked for
            # unless a Ctrl-C came first (raised inside a C extension's import, it arrives as an
            # ImportError: appell_interrupts.interrupt_received)
            code = _interrupted() if interrupt_received() else _internal_error(exc)
        else:
            code = rv if isinstance(rv, int) else EXIT_OK
        if standalone_mode:
            sys.exit(code)
        return code

    def invoke(self, ctx):
        """The command; Ctrl-C inside it leaves as :class:`Interrupted`, past click's own
        handling (which writes a blank line on stderr before its Abort)."""
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            raise Interrupted() from exc


class Interrupted(BaseException):
    """Ctrl-C (SIGINT) inside a command (:meth:`_AppellGroup.invoke`); exit :data:`EXIT_INTERRUPTED`."""


def _interrupted() -> int:
    """``error: interrupted``, the one line of a command stopped by Ctrl-C (on a terminal
    after a line break that closes the terminal's ``^C``)."""
    if _is_terminal(sys.stderr):
        click.echo("", err=True)
    return _report_error("interrupted", None, EXIT_INTERRUPTED)


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class Terminated(BaseException):
    """Raised in the main thread by SIGTERM (see :func:`main`), so that a write under way
    removes its temporary file before the command exits with :data:`EXIT_TERMINATED`."""


def _terminate(signum, frame):
    raise Terminated()


def _internal_error(exc: Exception) -> int:
    """The report of an exception appell did not raise on purpose (a bug): one line and a
    hint, the traceback only with ``APPELL_DEBUG=1``."""
    if os.environ.get("APPELL_DEBUG"):
        raise exc
    return _report_error(
        f"internal error: {type(exc).__name__}: {exc}",
        "this is a bug in appell; rerun with APPELL_DEBUG=1 for the traceback and report it with the model file",
        EXIT_FAILURE,
    )


def _out_of_memory() -> int:
    """The report of a :class:`MemoryError` (an allocation refused while the command ran)."""
    return _report_error(
        "out of memory: the machine (or the process's limit, ulimit -v) refused an allocation",
        "try a smaller problem: fewer output times (--samples, --output-step), a shorter --t-end, fewer sweep runs",
        EXIT_FAILURE,
    )


def _report_error(message: str, hint: str | None, code: int) -> int:
    text = message.strip()
    click.echo(f"error: {text}", err=True)
    if hint:
        click.echo(f"  hint: {hint}", err=True)
    return code
