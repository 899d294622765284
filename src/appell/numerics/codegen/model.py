"""The compiled numeric model: the library's functions behind the
:class:`~appell.numerics.numeric.NumericModel` interface, and :func:`compile_c`, the backend
choice."""

from __future__ import annotations

import ctypes
import threading
import warnings
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from appell._cache import Cache
from appell.errors import ComputationError, ModelError, ResourceError
from appell.numerics import fastcall
from appell.numerics.codegen.build import CACHE_ENV, COMPILER_ENV, build_library, cache_dir, find_compiler, load_library
from appell.numerics.codegen.source import c_source
from appell.numerics.dynamics import Evaluation
from appell.numerics.numeric import KEEP_CONDITION, NumericModel, StateSolution, compile_model
from appell.numerics.redundant import with_redundancy

BACKENDS = ("numpy", "c", "auto")


_D, _P, _I = ctypes.c_double, ctypes.c_void_p, ctypes.c_int
_EMPTY = np.zeros(0)
_EMPTY.flags.writeable = False


def caller():
    """The fast-call extension (:mod:`appell.numerics.fastcall`), built into the cache on first
    use, or None (ctypes is used then)."""

    def build(source, command):
        path, _ = build_library(source, command)
        return load_library(path, source, command)[1]

    return fastcall.caller(build, find_compiler())


def _ptr(x: np.ndarray) -> int:
    return x.ctypes.data


def _vec(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=float)


class _Scratch(threading.local):
    """Arrays at fixed addresses, one set per thread: the inputs of a C call copied in and its
    outputs. Taking a NumPy array's address through ctypes costs more than the call itself
    (about 3 us each, against 0.5 us for a copy), so the addresses are taken once."""

    def __init__(self, sizes, shapes=()):
        self.inputs = [np.empty(k) for k in sizes]
        self.outputs = [np.empty(shape) for shape in shapes]
        self.in_addr = tuple(a.ctypes.data for a in self.inputs)
        self.out_addr = tuple(a.ctypes.data for a in self.outputs)


def _fill(buffer: np.ndarray, x) -> bool:
    """Copy ``x`` into ``buffer`` when it is a flat sequence of the buffer's length (never
    broadcast: a wrong size is left to the checks of the slow path, which name it)."""
    try:
        if len(x) != buffer.shape[0]:
            return False
        buffer[:] = x
    except (TypeError, ValueError):
        return False
    return True


@dataclass(frozen=True)
class CompiledNumericModel(NumericModel):
    """A :class:`~appell.numerics.numeric.NumericModel` whose functions run in compiled C.

    ``blocks``, ``rates``, ``residuals`` and ``constraint_function`` keep the NumPy
    signatures; :meth:`solve` and :meth:`evaluate` do the split route (1.4)/(1.5) in one C
    call for constraints linear in ``a`` and fall back to the NumPy route on the compiled
    blocks when the partition has to switch. ``library_path`` is the cached shared library,
    ``freshly_compiled`` whether this call compiled it.
    """

    library_path: Path | None = None
    freshly_compiled: bool = False
    backend: str = "c"
    _lib: object = field(default=None, repr=False, compare=False)
    _default_dep: np.ndarray = field(default=None, repr=False, compare=False)
    _wrenches: object = field(default=None, repr=False, compare=False)
    _forward: object = field(default=None, repr=False, compare=False)

    def forward(self, t, q, w, p=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(a, lambda, wrenches)`` of a rigid-body tree at a state in one C call: the
        accelerations and multipliers of :meth:`solve` (default partition) and the joint
        reactions of :meth:`joint_wrenches` at them, as Pinocchio's ``aba`` and ``rnea`` give
        them; where that split fails, :meth:`solve` (which may switch the partition) and
        :meth:`joint_wrenches`."""
        if self._forward is not None:
            out = self._forward(t, q, w, self.default_parameters if p is None else p)
            if out is not None:
                return out
        sol = self.solve(t, q, w, p)
        return sol.accelerations, sol.multipliers, self.joint_wrenches(t, q, w, sol.accelerations, p)

    def joint_wrenches(self, t, q, w, a, p=None) -> np.ndarray:
        """Every joint's reaction of a rigid-body tree at a state and accelerations, one row
        ``(F_x, F_y, F_z, M_x, M_y, M_z)`` per body in the tree's order
        (``derivation.inertia.tree.nodes``): world axes, the moment about the joint's point,
        the parent's action on the subtree (RNEA's inward force, ``rigid.c``); the loads and
        constraint forces acting on the subtree are not in it. One C call."""
        if self._wrenches is None:
            raise ModelError(
                "joint_wrenches needs bodies on a joint tree (a mechanism or a URDF robot)",
                hint="use the outputs F_<joint>_x ... of Mechanism.system(reactions=...)",
            )
        return self._wrenches(t, q, w, a, self.default_parameters if p is None else p)[0]

    def __post_init__(self):
        # addresses of the arrays that do not change between calls (ctypes overhead)
        self._formula["dep"] = tuple(int(i) for i in self._default_dep)
        self._formula["addr"] = (self.default_parameters.ctypes.data, self._default_dep.ctypes.data)
        ny, s = len(self.state_names), len(self._default_dep)
        self._formula["evaluate_scratch"] = _Scratch((ny,), ((ny,), (s,)))
        self._formula["residual_scratch"] = _Scratch((ny,), ((s,), (s,)))
        self._formula["no_level"] = (np.flatnonzero(~self.has_position), np.flatnonzero(~self.has_velocity))
        lib, fast = self._lib, caller()
        if lib is not None and hasattr(lib, "appell_evaluate"):
            self._formula["evaluate"] = (
                lib.appell_evaluate
                if fast is None
                else partial(fast.evaluate, ctypes.cast(lib.appell_evaluate, _P).value)
            )
        if lib is not None:
            self._formula["residuals"] = (
                lib.appell_residuals
                if fast is None
                else partial(fast.expr, ctypes.cast(lib.appell_residuals, _P).value)
            )

    def _param_address(self, pv: np.ndarray) -> tuple[np.ndarray, int]:
        if pv is self.default_parameters:
            return pv, self._formula["addr"][0]
        last = self._formula.get("last_parameters")
        if last is not None and last[0] is pv:  # the same array again (a simulation's): its address holds
            return last
        given, pv = pv, _vec(pv)
        out = (pv, _ptr(pv))
        if pv is given:
            self._formula["last_parameters"] = out
        return out

    def solve(self, t, q, w, p=None, dependent=None, bias=None) -> StateSolution:
        """Accelerations (1.4) and every multiplier (1.5) at (t, q, w), in C; ``bias`` is
        added to the constraints (``f + bias = 0``) as in the NumPy model."""
        if self.constraint_function is not None:
            return self._fallback_solve(t, q, w, p, dependent, bias)
        pv = _vec(self.params(p))
        q, w = self.checked_state(q, w)
        n, s = len(w), len(self._default_dep)
        bv = None if bias is None else _bias(bias, s)
        dep = (
            self._default_dep
            if dependent is None
            else np.ascontiguousarray(self.checked_dependent(dependent), dtype=np.intc)
        )
        a, lam, R = np.empty(n), np.empty(s), np.empty(n)
        status = self._lib.appell_solve(
            float(t),
            _ptr(q),
            _ptr(w),
            _ptr(pv),
            None if bv is None else _ptr(bv),
            _ptr(dep),
            KEEP_CONDITION,
            _ptr(a),
            _ptr(lam),
            _ptr(R),
        )
        if status != 0:
            return self._fallback_solve(t, q, w, pv, dependent, bias)
        return StateSolution(a, lam, R, tuple(int(i) for i in dep), False)

    def _fallback_solve(self, t, q, w, p, dependent, bias):
        # the NumPy route on the compiled blocks: Newton, or a switch of the partition
        if bias is None:
            return super().solve(t, q, w, p, dependent)
        return super().solve(t, q, w, p, dependent, bias)

    def evaluate(self, t, y, p=None, dependent=None, bias=None) -> Evaluation:
        """``dy/dt = (K w + k, a)`` and the multipliers of (1.5), in one C call."""
        if self.constraint_function is not None or dependent is not None:
            q, w = self.split_state(y)
            pv = self.params(p)
            sol = self.solve(t, q, w, pv, dependent, bias)
            return Evaluation(
                np.concatenate([self.coordinate_rates(t, q, w, pv), sol.accelerations]),
                sol.multipliers,
                np.zeros(0),
                sol.dependent,
                sol.switched,
            )
        scratch = self._formula["evaluate_scratch"]
        if not _fill(scratch.inputs[0], y):
            y = _vec(y)
            self.checked_state(*self.split_state(y.reshape(-1)))  # names the sizes
            raise ModelError(f"the state of {self.name!r} has {len(self.state_names)} entries, got shape {y.shape}")
        pv, paddr = self._param_address(self.params(p))
        bv = None if bias is None else _bias(bias, len(self._default_dep))
        status = self._formula["evaluate"](
            float(t),
            scratch.in_addr[0],
            paddr,
            None if bv is None else _ptr(bv),
            self._formula["addr"][1],
            KEEP_CONDITION,
            *scratch.out_addr,
        )
        if status != 0:
            q, w = self.split_state(scratch.inputs[0].copy())
            sol = self._fallback_solve(t, q, w, pv, None, bias)
            return Evaluation(
                np.concatenate([self.coordinate_rates(t, q, w, pv), sol.accelerations]),
                sol.multipliers,
                np.zeros(0),
                sol.dependent,
                sol.switched,
            )
        dy, lam = scratch.outputs
        return Evaluation(dy.copy(), lam.copy(), _EMPTY, self._formula["dep"], False)

    def state_residuals(self, t, y, p=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`~appell.numerics.numeric.NumericModel.state_residuals` in one C call on the
        state vector (``q`` and ``w`` are its two parts, read in place)."""
        scratch = self._formula["residual_scratch"]
        if self._lib is None or not _fill(scratch.inputs[0], y):
            return super().state_residuals(t, y, p)
        _, paddr = self._param_address(self.params(p))
        y_addr = scratch.in_addr[0]
        self._formula["residuals"](
            float(t), y_addr, y_addr + 8 * len(self.coordinate_names), None, paddr, *scratch.out_addr
        )
        F, phi = scratch.outputs[0].copy(), scratch.outputs[1].copy()
        no_position, no_velocity = self._formula["no_level"]
        if no_position.size:
            F[no_position] = np.nan
        if no_velocity.size:
            phi[no_velocity] = np.nan
        return F, phi


def _bias(bias, s: int) -> np.ndarray:
    """The constraint bias as a contiguous float array of ``s`` entries (read by the C code)."""
    bv = _vec(bias).reshape(-1)
    if bv.size != s:
        raise ModelError(f"the constraint bias must have {s} entries (one per constraint), got {bv.size}")
    return bv


def _wrap(fn, shapes, sizes, with_acc=False):
    """A Python callable with the signature of the lambdified NumPy function; ``sizes`` are
    the lengths of the inputs ``q, w, (a,) p``, copied into per-thread arrays whose addresses
    are taken once (:class:`_Scratch`); inputs of other lengths go the slow way."""
    scratch = _Scratch(sizes, shapes)

    fast = caller()
    run = partial(fast.expr, ctypes.cast(fn, _P).value) if fast is not None else fn

    def call(t, q, w, *rest):
        work = scratch
        if all(_fill(b, x) for b, x in zip(work.inputs, (q, w, *rest))) and len(rest) == len(sizes) - 2:
            addr = work.in_addr
            run(float(t), addr[0], addr[1], addr[2] if with_acc else None, addr[-1], *work.out_addr)
            return [o.copy() for o in work.outputs]
        a, p = (rest[0], rest[1]) if with_acc else (None, rest[0])
        q, w, p = _vec(q), _vec(w), _vec(p)
        outs = [np.empty(shape) for shape in shapes]
        aa = _vec(a) if a is not None else None
        fn(float(t), _ptr(q), _ptr(w), None if aa is None else _ptr(aa), _ptr(p), *[_ptr(o) for o in outs])
        return outs

    return call


def _forward_call(fn, sizes, outputs):
    """``(t, q, w, p) -> (a, lambda, wrenches)`` or None where the split fails, by
    ``appell_forward``: through the fast-call extension on the arrays themselves (no copies in
    or out), else by ctypes (:func:`_wrap`). Inputs that are not float64 arrays of their
    lengths are converted, and wrong lengths left to the caller's checks (None)."""
    n, (s, nb) = sizes[1], outputs
    fast = caller()
    if fast is None:
        call = _wrap(fn, [(n,), (s,), (nb, 6)], sizes)

        def slow(t, q, w, p):
            a, lam, wrench = call(t, q, w, p)
            return (a, lam, wrench) if not len(a) or np.isfinite(a[0]) else None

        return slow
    address, run = ctypes.cast(fn, _P).value, fast.forward
    counts = (*sizes, s, nb)

    def forward(t, q, w, p):
        out = run(address, t, q, w, p, *counts)
        if out == 1:  # not float64 arrays of their lengths: converted, or the caller names them
            try:
                out = run(address, t, _vec(q).reshape(-1), _vec(w).reshape(-1), _vec(p).reshape(-1), *counts)
            except (TypeError, ValueError):
                return None
        return out if type(out) is tuple else None

    return forward


#: C sources formed by :func:`compile_in_background` for :func:`compile_c` to take up once (by
#: the derivation's identity)
_STARTED_KEEP = 4
_STARTED: Cache[str] = Cache(_STARTED_KEEP, identity=True)


def _source_for(derivation) -> str:
    """The C source of ``derivation``: the one :func:`compile_in_background` formed (taken
    once), else :func:`~appell.numerics.codegen.source.c_source` now."""
    source = _STARTED.pop(derivation)
    return c_source(derivation) if source is None else source


def compile_in_background(derivation) -> threading.Thread | None:
    """Start building the compiled code of ``derivation`` while the caller goes on with other
    work: the C source is formed here (Python), the compiler runs in a thread (a child
    process: both cores work). A later :func:`compile_c` takes the source up and waits for
    the library under the cache entry's lock, then loads it. Returns the thread, or None
    where there is nothing to start (no C compiler, a controlled derivation: NumPy only).
    A failure here is left for :func:`compile_c` to meet again and report."""
    from appell.core.equations import is_controlled

    compiler = find_compiler()
    if compiler is None or is_controlled(derivation):
        return None
    try:
        source = c_source(derivation)
    except (ComputationError, ModelError):
        return None  # compile_c meets it again and reports
    _STARTED.pop(derivation)
    _STARTED.put(derivation, source)

    def build():
        try:
            build_library(source, compiler)
        except (ComputationError, OSError):
            pass  # compile_c builds again and reports

    thread = threading.Thread(target=build, name=f"appell-cc {derivation.system.name}", daemon=True)
    thread.start()
    return thread


def compile_c(derivation, backend: str = "c") -> NumericModel:
    """Compiled numeric functions of a derivation (``backend`` 'c' or 'auto').

    Without a C compiler 'c' is refused (:class:`ModelError`) and 'auto' falls back to
    :func:`appell.numerics.numeric.compile_model` (NumPy) with a :class:`RuntimeWarning`; a
    failed compilation or an unusable cache raises for 'c' and falls back (with a warning)
    for 'auto'. A cached library is verified before and after loading (:func:`build_library`,
    :func:`load_library`).
    With redundant constraints (:mod:`appell.core.redundancy`) the C code solves the
    independent ones and :class:`~appell.numerics.redundant.RedundantModel` completes every
    multiplier in NumPy, the same step as for the NumPy backend.
    """
    if backend not in BACKENDS:
        raise ModelError(f"unknown numeric backend {backend!r}", hint="choose one of " + ", ".join(BACKENDS))
    if backend == "numpy":
        return with_redundancy(compile_model(derivation))
    compiler = find_compiler()
    if compiler is None:
        if backend == "c":
            raise ModelError(
                "the C backend needs a C compiler, and none was found",
                hint=f"install cc or set ${COMPILER_ENV}, or choose the backend 'auto' (C when a "
                "compiler is found, else NumPy) or 'numpy'",
            )
        warnings.warn(
            f"no C compiler found (set ${COMPILER_ENV} or $CC); using the NumPy backend", RuntimeWarning, stacklevel=2
        )
        return with_redundancy(compile_model(derivation))
    source = _source_for(derivation)
    try:
        path, fresh = build_library(source, compiler)
        lib, path, reloaded = load_library(path, source, compiler)
        fresh = fresh or reloaded
    except (ComputationError, OSError) as exc:
        if backend == "c":
            if isinstance(exc, OSError):
                raise ResourceError(
                    f"cannot use the compiled-code cache {cache_dir()}: {exc.strerror or exc}",
                    hint=f"set ${CACHE_ENV} to a writable directory, or use the backend 'numpy'",
                ) from exc
            raise
        warnings.warn(f"{exc}; using the NumPy backend", RuntimeWarning, stacklevel=2)
        return with_redundancy(compile_model(derivation))
    kin, cons = derivation.kinematics, derivation.constraints
    n, s, nq = len(kin.speeds), cons.count, len(kin.coordinates)
    npar = len(derivation.system.parameters)
    expr_args = [_D, _P, _P, _P, _P]
    lib.appell_blocks.argtypes = expr_args + [_P] * 4
    lib.appell_blocks.restype = None
    lib.appell_rates.argtypes = expr_args + [_P]
    lib.appell_rates.restype = None
    lib.appell_residuals.argtypes = expr_args + [_P] * 2
    lib.appell_residuals.restype = None
    cfun = None
    if cons.linear:
        lib.appell_solve.argtypes = [_D, _P, _P, _P, _P, _P, _D, _P, _P, _P]
        lib.appell_solve.restype = _I
        lib.appell_evaluate.argtypes = [_D, _P, _P, _P, _P, _D, _P, _P]
        lib.appell_evaluate.restype = _I
    else:
        lib.appell_constraint.argtypes = expr_args + [_P] * 2
        lib.appell_constraint.restype = None
        cfun = _wrap(lib.appell_constraint, [(s,), (s, n)], (nq, n, n, npar), with_acc=True)
    wrenches = forward = None
    if derivation.inertia.tree is not None:
        lib.appell_wrenches.argtypes = expr_args + [_P]
        lib.appell_wrenches.restype = None
        nb = len(derivation.inertia.tree.nodes)
        wrenches = _wrap(lib.appell_wrenches, [(nb, 6)], (nq, n, n, npar), with_acc=True)
        if cons.linear:
            lib.appell_forward.argtypes = expr_args + [_P] * 3
            lib.appell_forward.restype = None
            forward = _forward_call(lib.appell_forward, (nq, n, npar), (s, nb))
    system = derivation.system
    return with_redundancy(
        CompiledNumericModel(
            derivation=derivation,
            parameters=tuple(p.symbol for p in system.parameters),
            default_parameters=np.array([p.value for p in system.parameters], dtype=float),
            blocks=_wrap(lib.appell_blocks, [(n, n), (n,), (s, n), (s,)], (nq, n, npar)),
            constraint_function=cfun,
            rates=_wrap(lib.appell_rates, [(nq,)], (nq, n, npar)),
            residuals=_wrap(lib.appell_residuals, [(s,), (s,)], (nq, n, npar)),
            has_position=np.array([e is not None for e in cons.position_residual], dtype=bool),
            has_velocity=np.array([e is not None for e in cons.velocity_residual], dtype=bool),
            library_path=path,
            freshly_compiled=fresh,
            _lib=lib,
            _default_dep=np.ascontiguousarray(derivation.partition.dependent, dtype=np.intc),
            _wrenches=wrenches,
            _forward=forward,
        )
    )
