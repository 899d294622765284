"""Derivations kept on disk, beside the compiled-code cache: a second run of a model file goes
straight to numbers.

:func:`derive_file` reads a model file (TOML, URDF, MJCF: :func:`appell.io.modelfile.load_model`)
and derives it (:func:`appell.core.derive.derive`, or :func:`appell.control.servo.derive_controlled` for
servo constraints), or reads the derivation stored for the same input. The entry's key is the
SHA-256 of

* the bytes of the model file and of the files it names (a model file's ``[mechanism] urdf``,
  an MJCF's ``<include file=...>``),
* the overrides, the floating base and the chosen dependent accelerations (the partition),
* the axes of the joint reactions (``reactions_in``),
* appell's version and the digest of its source files (:func:`appell._cache.source_digest`), SymPy's and
  Python's versions and :data:`FORMAT`.

An entry is plain data that cannot run code when read (not pickle): one JSON document with a
symbol table, a table of expression nodes (each node written once, its arguments referring to
earlier nodes; the whitelisted heads of :mod:`appell.io.expression_tree`, read back without
evaluation) and the derivation's dataclasses by field (``module:class``, only dataclasses and
enums of appell's own modules are rebuilt, field by field, without calling their constructors).
The first line holds the key and the SHA-256 of the document: an entry that is truncated,
tampered with (its bytes no longer those written), written for another key or by another
format is ignored with a note (:class:`~appell.errors.AppellNote`) and derived again.

:func:`derive` and :func:`derive_controlled` (:func:`appell.derive`, :func:`appell.derive_controlled`)
do the same for a :class:`~appell.model.System` built in Python: the key is the system's content
(:func:`content_key`: every field as an entry writes it, each symbol with its assumptions, each
number exactly) with the partition asked for, and the entries are kept in ``derivations/systems``
(with a size bound of their own); a system the format cannot write is derived every time.
:func:`appell.core.derive.derive` is the pipeline itself and derives every time.

A check given to :func:`derive_file` (the command line's: the inertia at the start,
:func:`appell.workflows.check_inertia_at_start`) runs on a fresh derivation before it is
stored; an entry records that it passed, and is not checked again when read (an entry stored
without it is). A derivation the check refuses is not stored.

Entries are written under a per-entry file lock to a temporary name and renamed (two processes
filling the same entry: one derives, the other waits and reads it), kept in
``$APPELL_CACHE_DIR/derivations`` (:func:`appell._cache.cache_dir`), at most
``$APPELL_DERIVATION_CACHE_MB`` (default 512) MB in all, the least recently used removed first.
``$APPELL_NO_CACHE=1`` (``cache=False``) derives every time and writes nothing.

What is printed from a derivation (its equations as a paper prints them, its JSON document:
seconds of readable forms and ``simplify`` for the larger models) is kept the same way in
``derivations/printed`` (:func:`remembered`), under a key of the derivation's content
(:func:`content_key`: its fields as written here, not the formulas computed from them since)
and of appell's source: a model printed before, in any process, is printed from its entry.
"""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import hashlib
import importlib
import json
import os
import re
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from appell._cache import NO_CACHE_ENV, cache_dir, cache_enabled, size_limit, source_digest, write_checked
from appell._cache import evict as evict_least_recent
from appell.errors import AppellNote
from appell.io.expression_tree import (
    HEADS,
    expression_from_tree,
    expression_tree,
    symbol_assumptions,
    symbol_from_table,
)
from appell.numerics.codegen.build import _cache_lock

if TYPE_CHECKING:
    from appell.control.servo import ControlledDerivation
    from appell.core.equations import Derivation
    from appell.model import System

#: bumped when the layout of an entry changes (part of the key)
FORMAT = 1
SIZE_ENV = "APPELL_DERIVATION_CACHE_MB"
DEFAULT_SIZE_MB = 512
_MAGIC = "appell-derivation"

__all__ = [
    "FORMAT",
    "NO_CACHE_ENV",
    "SIZE_ENV",
    "cache_enabled",
    "content_key",
    "decode",
    "derive",
    "derive_controlled",
    "derive_file",
    "encode",
    "entry_key",
    "remembered",
]


class Unstorable(Exception):
    """A derivation holds something the format does not write (a callable, a Dummy symbol):
    it is derived every time."""


def derivations_dir() -> Path:
    return cache_dir() / "derivations"


# ------------------------------------------------------------------ encoding
class _Encoder:
    """``computed``: the values of cached properties are written too (an entry); without them,
    and with the items of sets in a fixed order, the document is a key of the value's content
    (:func:`content_key`)."""

    def __init__(self, computed: bool = True):
        self.computed = computed
        self.nodes: list = []
        self.index: dict = {}
        self.symbols: dict[str, dict] = {}
        self.symbol_of: dict[str, sp.Symbol] = {}

    def expr(self, e: sp.Basic) -> int:
        """The index of ``e`` in the node table (its arguments written before it)."""
        found = self.index.get(e)
        if found is not None:
            return found
        stack = [(e, False)]
        while stack:
            node, ready = stack.pop()
            if node in self.index:
                continue
            if node.args and not ready:
                stack.append((node, True))
                stack.extend((a, False) for a in reversed(node.args) if a not in self.index)
                continue
            self.index[node] = len(self.nodes)
            self.nodes.append(self._node(node))
        return self.index[e]

    def _node(self, e):
        if e.is_Symbol:
            if type(e) is not sp.Symbol:
                raise Unstorable(f"{type(e).__name__} {e}")
            known = self.symbol_of.setdefault(e.name, e)
            if known is not e and known != e:
                raise Unstorable(f"two symbols named {e.name!r}")
            self.symbols[e.name] = symbol_assumptions(e)
            return ["Symbol", e.name]
        if not e.args:
            try:
                return expression_tree(e)
            except Exception as exc:
                raise Unstorable(str(exc)) from None
        if type(e) is sp.Tuple:
            return ["Tuple", *(["Ref", self.index[a]] for a in e.args)]
        head = next((name for name, cls in HEADS.items() if type(e) is cls), None)
        if head is None:
            raise Unstorable(f"{type(e).__name__} ({e.func})")
        return [head, *(["Ref", self.index[a]] for a in e.args)]

    def value(self, v):
        if v is None or isinstance(v, (bool, str)):
            return v
        if isinstance(v, int) and type(v) is int:
            return v
        if type(v) is float:
            return {"$": "f", "v": v.hex()}
        if isinstance(v, sp.MatrixBase):
            if type(v) not in (sp.ImmutableDenseMatrix, sp.MutableDenseMatrix):
                raise Unstorable(type(v).__name__)
            return {
                "$": "M",
                "m": type(v) is sp.ImmutableDenseMatrix,
                "r": v.rows,
                "c": v.cols,
                "v": [self.expr(x) for x in v],
            }
        if isinstance(v, sp.Basic):
            return {"$": "e", "v": self.expr(v)}
        if type(v) is tuple:
            return {"$": "t", "v": [self.value(x) for x in v]}
        if type(v) is list:
            return [self.value(x) for x in v]
        if type(v) is dict:
            return {"$": "d", "v": [[self.value(k), self.value(x)] for k, x in v.items()]}
        if type(v) in (frozenset, set):
            items = [self.value(x) for x in v]
            if not self.computed:  # (a set's order changes from one process to the next)
                items.sort(key=lambda x: json.dumps(x, sort_keys=True))
            return {"$": "fs" if type(v) is frozenset else "set", "v": items}
        if type(v) is np.ndarray and v.dtype.kind in "fib" and v.dtype.isnative:
            flat = v.ravel().tolist()
            return {
                "$": "a",
                "t": v.dtype.str,
                "s": list(v.shape),
                "v": [x.hex() for x in flat] if v.dtype.kind == "f" else flat,
            }
        if isinstance(v, np.generic) and v.dtype.kind in "fib":
            return {"$": "a", "t": v.dtype.str, "s": None, "v": [float(v).hex()] if v.dtype.kind == "f" else [v.item()]}
        cls = type(v)
        name = f"{cls.__module__}:{cls.__qualname__}"
        if not _own(cls):
            raise Unstorable(f"a {name}")
        if isinstance(v, enum.Enum):
            return {"$": "enum", "c": name, "v": v.name}
        if dataclasses.is_dataclass(v):
            fields = {name: self.value(getattr(v, name)) for name in _stored_fields(cls)}
            extra = {}
            for key, x in getattr(v, "__dict__", {}).items() if self.computed else ():  # cached properties
                if key not in fields:
                    with contextlib.suppress(Unstorable):
                        extra[key] = self.value(x)
            return {"$": "o", "c": name, "v": fields, "x": extra}
        raise Unstorable(f"a {name}")


def _stored_fields(cls) -> list[str]:
    """The dataclass fields of ``cls`` held on its instances (a field that a subclass turns
    into a property is computed, not stored)."""
    import inspect

    return [
        f.name
        for f in dataclasses.fields(cls)
        if not hasattr(type(inspect.getattr_static(cls, f.name, None)), "__set__")
    ]


def _own(cls) -> bool:
    return cls.__module__ == "appell" or cls.__module__.startswith("appell.")


def encode(derivation) -> dict:
    """The JSON document of ``derivation`` (:class:`Unstorable` when it holds a value the
    format does not write)."""
    enc = _Encoder()
    root = enc.value(derivation)
    return {"symbols": enc.symbols, "nodes": enc.nodes, "root": root}


class _Decoder:
    def __init__(self, doc: dict):
        if (
            not isinstance(doc, dict)
            or not isinstance(doc.get("symbols"), dict)
            or not isinstance(doc.get("nodes"), list)
        ):
            raise ValueError("not a derivation document")
        self.symbols = {name: symbol_from_table(name, a) for name, a in doc["symbols"].items()}
        self.nodes: list = []
        for tree in doc["nodes"]:
            if isinstance(tree, list) and tree and tree[0] == "Tuple":
                self.nodes.append(sp.Tuple(*(self._ref(r) for r in tree[1:])))
            else:
                self.nodes.append(expression_from_tree(tree, self.symbols, shared=self.nodes))

    def _ref(self, r):
        if not (
            isinstance(r, list) and len(r) == 2 and r[0] == "Ref" and type(r[1]) is int and 0 <= r[1] < len(self.nodes)
        ):
            raise ValueError(f"a bad reference {r!r}")
        return self.nodes[r[1]]

    def _node(self, k):
        if type(k) is not int or not 0 <= k < len(self.nodes):
            raise ValueError(f"a bad node index {k!r}")
        return self.nodes[k]

    def value(self, v, depth: int = 0):
        if depth > 200:
            raise ValueError("nested too deep")
        if v is None or isinstance(v, (bool, str, int)):
            return v
        if isinstance(v, list):
            return [self.value(x, depth + 1) for x in v]
        if not isinstance(v, dict) or not isinstance(v.get("$"), str):
            raise ValueError(f"an unknown value {str(v)[:80]}")
        tag, body = v["$"], v.get("v")
        if tag == "f":
            return float.fromhex(body)
        if tag == "e":
            return self._node(body)
        if tag == "a":
            dtype = np.dtype(v["t"])
            if dtype.kind not in "fib" or not isinstance(body, list):
                raise ValueError("a bad array")
            items = [float.fromhex(x) for x in body] if dtype.kind == "f" else body
            if v["s"] is None:
                return dtype.type(items[0])
            return np.array(items, dtype=dtype).reshape([int(n) for n in v["s"]])
        if tag == "M":
            rows, cols = v["r"], v["c"]
            if type(rows) is not int or type(cols) is not int or not isinstance(body, list) or len(body) != rows * cols:
                raise ValueError("a bad matrix")
            cls = sp.ImmutableDenseMatrix if v.get("m") else sp.MutableDenseMatrix
            return cls(rows, cols, [self._node(k) for k in body])
        if tag in ("t", "fs", "set"):
            items = [self.value(x, depth + 1) for x in body]
            return {"t": tuple, "fs": frozenset, "set": set}[tag](items)
        if tag == "d":
            return {self.value(k, depth + 1): self.value(x, depth + 1) for k, x in body}
        if tag == "enum":
            cls = _own_class(v.get("c"))
            if not issubclass(cls, enum.Enum):
                raise ValueError(f"{v.get('c')} is not an enum")
            return cls[body]
        if tag == "o":
            cls = _own_class(v.get("c"))
            if not dataclasses.is_dataclass(cls):
                raise ValueError(f"{v.get('c')} is not a dataclass")
            names = set(_stored_fields(cls))
            if not isinstance(body, dict) or set(body) != names:
                raise ValueError(f"the fields of {v.get('c')} differ")
            obj = object.__new__(cls)  # no constructor runs: the fields are set as stored
            for name, x in body.items():
                object.__setattr__(obj, name, self.value(x, depth + 1))
            extra = v.get("x") or {}
            if extra and not hasattr(obj, "__dict__"):
                raise ValueError(f"{v.get('c')} keeps no computed values")
            for name, x in extra.items():
                if (
                    not isinstance(name, str)
                    or not name.isidentifier()
                    or name in names
                    or hasattr(type(getattr(cls, name, None)), "__set__")
                ):
                    raise ValueError(f"{name!r} is not a computed value of {v.get('c')}")
                obj.__dict__[name] = self.value(x, depth + 1)
            return obj
        raise ValueError(f"an unknown tag {tag!r}")


_CLASS = re.compile(r"appell(\.[A-Za-z_][A-Za-z0-9_]*)*:[A-Za-z_][A-Za-z0-9_.]*")


def _own_class(name):
    """The class ``module:qualname`` of one of appell's own modules (imported as usual)."""
    if not isinstance(name, str) or not _CLASS.fullmatch(name):
        raise ValueError(f"{name!r} is not a class of appell")
    module, qualname = name.split(":")
    cls = importlib.import_module(module)
    for part in qualname.split("."):
        cls = getattr(cls, part)
    if not isinstance(cls, type) or not _own(cls):
        raise ValueError(f"{name!r} is not a class of appell")
    return cls


def decode(doc: dict):
    """The derivation of a document written by :func:`encode` (ValueError, KeyError or
    ModelError for anything else)."""
    dec = _Decoder(doc)
    return dec.value(doc.get("root"))


# ------------------------------------------------------------------ keys and files
_INCLUDE = re.compile(rb"<include\s+file\s*=\s*[\"']([^\"']+)[\"']")


def _named_files(path: Path, raw: bytes) -> list[Path]:
    """The files a model file names: a TOML's ``[mechanism] urdf``, an MJCF's includes."""
    found = []
    if path.suffix == ".toml":
        import tomllib

        with contextlib.suppress(Exception):
            urdf = tomllib.loads(raw.decode("utf-8")).get("mechanism", {}).get("urdf")
            if isinstance(urdf, str):
                found.append(path.parent / urdf)
    elif path.suffix == ".xml":
        found = [path.parent / m.decode("utf-8", "replace") for m in _INCLUDE.findall(raw)]
    return found


def entry_key(
    path: Path,
    overrides=None,
    floating_base: bool = False,
    dependent=None,
    reactions_in: str | None = None,
    reader=None,
) -> str:
    """The SHA-256 key of a model file's derivation (see the module's docstring)."""
    digest = hashlib.sha256(_versions())
    seen, todo = set(), [path]
    while todo:
        file = todo.pop(0).resolve()
        if file in seen:
            continue
        seen.add(file)
        raw = file.read_bytes()
        digest.update(f"file {len(raw)}\n".encode() + raw)
        todo.extend(_named_files(file, raw))
    given = sorted((str(k), repr(v)) for k, v in dict(overrides or {}).items())
    digest.update(
        repr(
            (given, bool(floating_base), None if dependent is None else [str(d) for d in dependent], reactions_in)
            + ((sorted((str(k), str(v)) for k, v in dict(reader).items()),) if reader else ())
        ).encode()
    )
    return digest.hexdigest()[:32]


def _versions() -> bytes:
    """The first line of every key: the format, appell's version and source digest, SymPy's and
    Python's versions (an entry of other code is another entry)."""
    from appell import __version__

    return (
        f"{_MAGIC} {FORMAT} appell {__version__} {source_digest()} sympy {sp.__version__} "
        f"python {sys.version_info[:3]}\n"
    ).encode()


def _note(message: str) -> None:
    warnings.warn(message, AppellNote, stacklevel=3)


#: what is done in place of a cached entry that cannot be used, by its kind
_AGAIN = {"derivation": "deriving again", "printed form": "printing again"}


def read_entry(
    file: Path,
    key: str,
    quiet: bool = False,
    notes: list | None = None,
    checked: list | None = None,
    kind: str = "derivation",
):
    """The value (a derivation; ``kind``: what it is, for the note) stored in ``file`` for
    ``key``, or None (with a note for a bad entry,
    unless ``quiet``); the notes stored with it are given again (and added to ``notes``);
    whether the check of :func:`derive_file` passed before it was stored is appended to
    ``checked``."""
    try:
        raw = file.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        if not quiet:
            _note(f"the cached {kind} {file} cannot be read ({exc.strerror or exc}); {_AGAIN[kind]}")
        return None
    try:
        head, _, body = raw.partition(b"\n")
        header = json.loads(head)
        if header.get("magic") != _MAGIC or header.get("format") != FORMAT:
            raise ValueError("written by another format")
        if header.get("key") != key:
            raise ValueError("written for another model")
        if header.get("sha256") != hashlib.sha256(body).hexdigest():
            raise ValueError("its content does not match its checksum (truncated or changed)")
        doc = json.loads(body)
        stored = doc.get("notes", [])
        if not isinstance(stored, list) or not all(isinstance(n, str) for n in stored):
            raise ValueError("bad notes")
        derivation = decode(doc)
    except Exception as exc:  # noqa: BLE001 (whatever the file holds, it is not trusted)
        if not quiet:
            _note(f"the cached {kind} {file} is ignored ({str(exc)[:200]}); {_AGAIN[kind]}")
        return None
    with contextlib.suppress(OSError):
        os.utime(file)  # most recently used
    for note in stored:  # what reading the model file noted (a URDF's damping not applied), again
        warnings.warn(note, AppellNote, stacklevel=3)
    if notes is not None:
        notes.extend(stored)
    if checked is not None:
        checked.append(doc.get("checked") is True)
    return derivation


def write_entry(root: Path, file: Path, key: str, derivation, notes=(), checked: bool = False) -> bool:
    """Store ``derivation`` under ``key`` (atomically) with the ``notes`` that reading its model
    file gave (given again when it is read) and whether :func:`derive_file`'s check passed;
    False when it cannot be stored."""
    try:
        body = json.dumps(
            {**encode(derivation), "notes": list(notes), "checked": bool(checked)}, separators=(",", ":")
        ).encode()
    except Unstorable:
        return False
    write_checked(file, {"magic": _MAGIC, "format": FORMAT, "key": key}, body)
    evict(root)
    return True


def evict(root: Path, limit_bytes: int | None = None) -> None:
    """Remove the least recently used entries until the folder holds at most ``limit_bytes``
    (default ``$APPELL_DERIVATION_CACHE_MB`` MB)."""
    if limit_bytes is None:
        limit_bytes = size_limit(SIZE_ENV, DEFAULT_SIZE_MB)
    evict_least_recent(root, "*.json", limit_bytes)


# ------------------------------------------------------------------ printed forms
def content_key(value, what: str) -> str | None:
    """The SHA-256 key of the computation ``what`` (its name and options) of ``value`` (a
    derivation) by the value's content: its fields as :func:`encode` writes them (not the
    values computed from them since, which would change the key), appell's version and source
    digest, SymPy's and Python's versions; None when the format cannot write ``value``."""
    enc = _Encoder(computed=False)
    try:
        root = enc.value(value)
    except Unstorable:
        return None
    digest = hashlib.sha256(_versions() + f"{what}\n".encode())
    doc = {"symbols": enc.symbols, "nodes": enc.nodes, "root": root}
    digest.update(json.dumps(doc, separators=(",", ":"), sort_keys=True).encode())
    return digest.hexdigest()[:32]


def remembered(derivation, what: str, compute):
    """``compute()``, a value formed from ``derivation`` alone (its printed equations, its
    JSON document), kept on disk beside the derivations (``printed/``: entries written, checked
    and evicted as theirs, with a size bound of its own) under :func:`content_key`: a model
    printed before is printed again from the entry (the bicycle's printed equations: 2.4 s of
    readable forms and ``simplify``), in this process or another; a process that finds another printing
    the same entry waits for it (the entry's lock) and reads it. ``what`` names the computation and its options. Without the
    cache (``$APPELL_NO_CACHE=1``), or for a derivation the format cannot write, ``compute()``."""
    if not cache_enabled():
        return compute()
    key = content_key(derivation, what)
    if key is None:
        return compute()
    return _kept("printed", key, compute, kind="printed form")[0]


def _kept(folder: str, key: str, compute, kind: str = "derivation"):
    """``(value, read)``: the entry ``key`` of ``derivations/<folder>`` (``read`` True), else
    ``compute()`` stored there (False; a ``compute`` that raises stores nothing). A process that
    finds another filling the same entry waits for it (the entry's lock) and reads it. Where the
    folder cannot be made, ``compute()``, not stored."""
    try:
        root = derivations_dir() / folder
        root.mkdir(parents=True, exist_ok=True)
    except OSError:
        return compute(), False
    file = root / f"{key}.json"
    found = read_entry(file, key, kind=kind)
    if found is not None:
        return found, True
    with _cache_lock(root, key):
        found = read_entry(file, key, quiet=file.exists(), kind=kind)  # filled meanwhile
        if found is not None:
            return found, True
        value = compute()
        with contextlib.suppress(OSError):
            write_entry(root, file, key, value)
    return value, False


# ------------------------------------------------------------------ systems built in Python
def derive(system: System, dependent: Sequence | None = None, *, cache: bool | None = None) -> Derivation:
    """:func:`appell.core.derive.derive` of ``system`` (the pipeline's own stages), read from
    the derivation cache when a system of the same content was derived before with the same
    ``dependent`` (in this process or another: a script run again goes straight to numbers),
    else derived and stored. This is :func:`appell.derive`.

    The entry's key is :func:`content_key` of ``(system, dependent)``: every field of the
    system as an entry writes it (each symbol's name and assumptions, each number exactly), and
    appell's, SymPy's and Python's versions, so a changed parameter value, constraint or body is
    another entry. A system the format cannot write (a ``Dummy``, a SymPy function of time, a
    Python object) is derived every time, as is every system with ``cache=False`` or
    ``$APPELL_NO_CACHE=1``. The derivation read back is the stored one with ``system`` the
    caller's own object; a system that cannot be derived raises as
    :func:`~appell.core.derive.derive` does and stores nothing."""
    from appell.core.derive import derive as derive_now

    return _derived(system, dependent, "derive", lambda dep: derive_now(system, dep), cache)


def derive_controlled(
    system: System,
    dependent: Sequence | None = None,
    max_differentiations: int | None = None,
    *,
    cache: bool | None = None,
) -> ControlledDerivation:
    """:func:`appell.control.servo.derive_controlled` of ``system`` through the derivation
    cache, as :func:`derive` (the key also names ``max_differentiations``). This is
    :func:`appell.derive_controlled`."""
    from appell.control.servo import derive_controlled as derive_now
    from appell.control.underactuated import MAX_DIFFERENTIATIONS

    most = MAX_DIFFERENTIATIONS if max_differentiations is None else max_differentiations
    what = f"derive_controlled max_differentiations={most!r}"
    return _derived(system, dependent, what, lambda dep: derive_now(system, dep, most), cache)


def _derived(system, dependent, what: str, compute, cache: bool | None):
    """``compute(dependent)`` kept under the content of ``(system, dependent)`` (:func:`derive`)."""
    if isinstance(dependent, (list, tuple)):
        dependent = list(dependent)  # (a tuple and a list of the same choice: one key)
    if not cache_enabled(cache) or not _is_system(system):
        return compute(dependent)
    key = content_key((system, dependent), what)
    if key is None:
        return compute(dependent)
    derivation, read = _kept("systems", key, lambda: compute(dependent))
    if read:
        object.__setattr__(derivation, "system", system)  # the caller's object (the stored one is equal to it)
    return derivation


def _is_system(system) -> bool:
    from appell.model import System

    return type(system) is System


def _derive(system, dependent):
    if system.servo_constraints:
        from appell.control.servo import derive_controlled

        return derive_controlled(system, dependent=dependent)
    from appell.core.derive import derive

    return derive(system, dependent=dependent)


def derive_file(
    path,
    overrides=None,
    *,
    floating_base: bool = False,
    dependent=None,
    cache: bool | None = None,
    formulas: bool = False,
    reactions_in: str | None = None,
    reader=None,
    check=None,
):
    """The derivation of the model file ``path`` (a bundled example's name too, as
    :func:`~appell.io.modelfile.load_model` takes), read from the derivation cache when the
    same input was derived before (see the module's docstring), else loaded, derived and
    stored. ``dependent``: the dependent accelerations of the partition; ``cache``: False
    (or ``$APPELL_NO_CACHE=1``) derives without reading or writing the cache; ``formulas``:
    the reduced equations (1.4) and the reaction formulas (1.5) are formed now and stored
    with the derivation where they exist in closed form; ``reactions_in``: the axes of the joint
    reactions, ``reader`` the options of a robot file's reader (:func:`~appell.io.modelfile.load_model`);
    ``check(derivation)``: a check that raises for a derivation not to be used (the inertia at
    the start, :func:`appell.workflows.check_inertia_at_start`), run on a fresh derivation
    before it is stored and on an entry stored without it; an entry stored after it passed is
    not checked again (the key covers everything it reads)."""
    path = Path(path)
    if not path.exists() and path.suffix == "" and len(path.parts) == 1:
        from appell.examples import example_path, list_benchmarks, list_examples

        if path.name in list_examples() or path.name in list_benchmarks():
            path = example_path(path.name)

    notes: list[str] = []

    def fresh():
        from appell.io.modelfile import (
            load_model,  # not imported when the cache answers
        )

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", AppellNote)
            system = load_model(path, overrides, floating_base=floating_base, reactions_in=reactions_in, reader=reader)
        for w in caught:  # given as they came, and kept with the entry
            if issubclass(w.category, AppellNote):
                notes.append(str(w.message))
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        derivation = _derive(system, dependent)
        if formulas:
            _formulas(derivation)
        return derivation

    def checked(derivation):
        if check is not None:
            check(derivation)
        return derivation

    if not cache_enabled(cache) or not path.is_file():
        return checked(fresh())
    try:
        key = entry_key(path, overrides, floating_base, dependent, reactions_in, reader)
        root = derivations_dir()
        root.mkdir(parents=True, exist_ok=True)
    except OSError:
        return checked(fresh())
    file = root / f"{key}.json"
    passed: list[bool] = []
    found = read_entry(file, key, checked=passed)
    if found is not None and (not formulas or _has_formulas(found)):
        return found if passed[-1] or check is None else checked(found)
    with _cache_lock(root, key):  # the compiled-code cache's lock, one file per entry
        found = read_entry(file, key, quiet=file.exists(), notes=notes, checked=passed)  # filled meanwhile
        if found is not None and (not formulas or _has_formulas(found)):
            return found if passed[-1] or check is None else checked(found)
        derivation = found if found is not None else fresh()
        if formulas:
            _formulas(derivation)
        checked(derivation)  # raises for a derivation not to be used: nothing is stored
        with contextlib.suppress(OSError):
            write_entry(root, file, key, derivation, notes, checked=check is not None)
    return derivation


def _closed_form(derivation) -> bool:
    from appell.core.equations import formulas_unavailable

    if getattr(derivation, "controlled", False):
        return True
    return formulas_unavailable(derivation.partition) is None and derivation.inertia.tree is None


def _formulas(derivation) -> None:
    if _closed_form(derivation):
        derivation.reduced, derivation.reactions  # noqa: B018 (computed and kept here)


def _has_formulas(derivation) -> bool:
    return not _closed_form(derivation) or {"reduced", "reactions"} <= set(vars(derivation))
