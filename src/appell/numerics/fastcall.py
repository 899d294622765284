"""Calls into a compiled model from Python at less cost than :mod:`ctypes` (``fastcall.c``).

ctypes converts each argument of a foreign call through its ``argtypes`` (about 0.3 us
each, 3 us for the eight of ``appell_evaluate``). ``fastcall.c`` is a small CPython
extension, compiled once into the cache like the models
(:func:`~appell.numerics.codegen.build_library`, with the interpreter's headers), whose
functions take the C function's address and the arrays' addresses as plain integers, or
(``forward``) the NumPy arrays themselves, read and allocated through NumPy's C API.
Where it cannot be built (no Python headers) :func:`caller` returns None and the callers keep
ctypes.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sysconfig
import warnings
from pathlib import Path

import numpy

from appell.errors import ComputationError

__all__ = ["caller"]

SOURCE = Path(__file__).with_name("fastcall.c")
_MODULE: list = []


def caller(build, compiler):
    """The extension module (functions ``expr``, ``evaluate`` and ``forward``), or None where it cannot
    be built or loaded here (ctypes is used then). ``build(source, command)`` compiles a
    source into the cache and returns the verified library's path; ``compiler`` is the C
    compiler command (None: none found)."""
    if _MODULE:
        return _MODULE[0]
    module = None
    include = sysconfig.get_paths().get("include")
    if compiler is not None and include and (Path(include) / "Python.h").exists():
        try:
            path = build(
                SOURCE.read_text(),
                list(compiler)
                + [
                    "-I",
                    include,
                    "-I",
                    numpy.get_include(),
                    # the cache is keyed by the command: a NumPy of another
                    # version builds its own extension
                    f"-DAPPELL_NUMPY={numpy.__version__}",
                ],
            )
            loader = importlib.machinery.ExtensionFileLoader("_appell_fastcall", str(path))
            spec = importlib.util.spec_from_file_location("_appell_fastcall", str(path), loader=loader)
            module = importlib.util.module_from_spec(spec)
            loader.exec_module(module)
        except (ComputationError, OSError, ImportError) as exc:
            warnings.warn(
                f"the fast-call extension could not be built ({exc}); using ctypes", RuntimeWarning, stacklevel=2
            )
            module = None
    _MODULE.append(module)
    return module
