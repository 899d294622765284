"""The boundary between the symbolic and the numeric halves: :func:`numeric_model`.

A derivation (:class:`appell.core.equations.Derivation`, or a controlled one from
:mod:`appell.control.servo`) is plain symbolic data; it knows nothing of numbers. Every
layer above that wants numbers asks here, once::

    model = numeric_model(derivation)              # 'auto': compiled C where a compiler is found
    model = numeric_model(derivation, "numpy")     # NumPy/math functions, the split solve
    model = numeric_model(derivation, "c")         # compiled C, refused without a compiler

What comes back implements :class:`appell.numerics.dynamics.Dynamics` (and, for a plain
derivation, the :class:`~appell.numerics.numeric.NumericModel` interface); with redundant
constraints it is wrapped in :class:`~appell.numerics.redundant.RedundantModel`.

Building numeric functions costs seconds on a large model, so a model is kept for the
:data:`KEEP` most recently used derivations, in this module, never on the (frozen,
picklable) derivation itself: a derivation pickles the same before and after numeric use.
Other kinds of derivation register their builder with ``numeric_model.register(kind)``
(:func:`functools.singledispatch`); the controlled derivation does so where it is defined.
"""

from __future__ import annotations

import os
from functools import singledispatch

from appell._cache import Cache
from appell.core.equations import Derivation
from appell.errors import ModelError

#: how many derivations keep their numeric models here (least recently used dropped first)
KEEP = 32

#: the backends a plain derivation takes: 'numpy', 'c' (compiled, refused without a compiler),
#: 'auto' (C when a compiler is found, else NumPy with a warning)
BACKENDS = ("numpy", "c", "auto")

#: the backend of ``numeric_model(derivation)`` without one, and so of every entry that takes a
#: derivation (simulate, cross_check, linearise, ...): 'auto', the command line's default, so that
#: the API is as fast as the command line without asking (``$APPELL_BACKEND`` sets another; the
#: test suite sets it to its backend, tests/conftest.py)
DEFAULT_BACKEND = os.environ.get("APPELL_BACKEND") or "auto"

#: the numeric models of each derivation, by backend
_models: Cache[dict] = Cache(KEEP, identity=True)


def cached(derivation, backend: str, build):
    """``build()`` for ``(derivation, backend)``, kept for the :data:`KEEP` most recently used
    derivations (:class:`appell._cache.Cache`, by the derivation's identity)."""
    model = _kept(derivation, backend)
    if model is not None:
        return model
    model = build()
    return _models.get_or_make(derivation, dict).setdefault(backend, model)


def _kept(derivation, backend: str):
    """The model kept for ``(derivation, backend)`` (marked most recently used), or None."""
    return _models.get(derivation, {}).get(backend)


def forget(derivation=None) -> None:
    """Drop the numeric models kept for ``derivation`` (all of them when None)."""
    if derivation is None:
        _models.clear()
    else:
        _models.pop(derivation)


@singledispatch
def numeric_model(derivation, backend: str | None = None):
    """The numeric model of ``derivation`` for ``backend`` ('numpy', 'c', 'auto'; None:
    :data:`DEFAULT_BACKEND`), built once and kept (see the module's docstring)."""
    raise ModelError(
        f"numeric_model needs a derivation (from appell.derive or appell.derive_controlled), "
        f"not {type(derivation).__name__}",
        hint="derive the system first: numeric_model(appell.derive(system))",
    )


@numeric_model.register
def _plain(derivation: Derivation, backend: str | None = None):
    backend = DEFAULT_BACKEND if backend is None else backend
    if backend not in BACKENDS:
        raise ModelError(f"unknown numeric backend {backend!r}", hint="choose one of " + ", ".join(BACKENDS))

    def build():
        if backend == "numpy":
            from appell.numerics.numeric import compile_model
            from appell.numerics.redundant import with_redundancy

            return with_redundancy(compile_model(derivation))
        from appell.numerics.codegen.model import compile_c

        return compile_c(derivation, backend)

    if backend == "auto":
        # kept under 'c' when it compiled, so that 'auto' and 'c' share one library; a fallback
        # to NumPy is not kept (its warning is given at every call, and a compiler may come)
        model = _kept(derivation, "c")
        if model is not None:
            return model
        model = build()
        if _compiled(model):
            model = cached(derivation, "c", lambda: model)
        return model
    return cached(derivation, backend, build)


def _compiled(model) -> bool:
    from appell.numerics.codegen.model import CompiledNumericModel

    return isinstance(getattr(model, "inner", model), CompiledNumericModel)
