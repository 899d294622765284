"""The ``appell`` command's entry point (pyproject.toml ``[project.scripts]``): Ctrl-C from the
first instant.

Importing appell takes a second or more (SymPy, SciPy, NumPy); a Ctrl-C then used to print a
``KeyboardInterrupt`` traceback from deep inside an import. This module needs only the
standard library and is not part of the package (importing anything under ``appell`` runs the
package's ``__init__`` first, with its heavy imports), so :func:`main` installs the handler of
SIGINT before appell is imported. A Ctrl-C at any moment then ends the command with exit code
130 and one line on stderr, ``error: interrupted``, and no traceback (except in the few
milliseconds before :func:`main` runs: Python's own start-up, its site packages' ``.pth`` files
and the import of this module, where only Python's default handler can act):

* while appell is imported, a Ctrl-C ends the process at once (nothing to clean up yet; a
  KeyboardInterrupt raised inside a C extension's import becomes an ImportError that an
  optional import may swallow);
* once the command runs, the first Ctrl-C raises :class:`KeyboardInterrupt` as Python's
  default handler does, so that the command cleans up (a write under way removes its temporary file, a sweep keeps its
  partial file and closes its cluster) and :mod:`appell.io.cli` reports it;
* a second one, or one after the command has finished, ends the process at once
  (:func:`os._exit`), printing the line unless it was printed already.

The handling itself, and the state it keeps (whether the first Ctrl-C has come), is
:mod:`appell_interrupts`, which the command line imports too; this module only chooses the
command (:func:`appell.io.cli.main`, imported after the handler of SIGINT is installed).

Worker processes of a local Dask cluster do not receive Ctrl-C at all
(:mod:`appell.simulation.sweep`); the command that started them stops them.
"""

import sys

from appell_interrupts import EXIT_INTERRUPTED, interrupt_received, rescue_interrupts, run

# nothing else at the top: until main() installs its handler, a Ctrl-C is Python's own (a
# traceback), so this module imports only the standard library (appell_interrupts: ``os``,
# ``signal``, ``sys``, loaded already or at once)

__all__ = ["main", "rescue_interrupts", "interrupt_received", "EXIT_INTERRUPTED"]


def _command_line():
    from appell.io.cli import main as command

    return command


def main(argv=None, command=None) -> int:
    """Run the command line (``argv`` defaults to ``sys.argv[1:]``) and return its exit code.
    ``command``: the function that runs it (default :func:`appell.io.cli.main`, imported here,
    after the handler of SIGINT is installed), called as ``command(argv, standalone=False)``."""
    return run(argv, command, _command_line)


if __name__ == "__main__":
    sys.exit(main())
