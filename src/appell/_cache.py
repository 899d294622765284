"""The one in-memory cache of appell: what a process keeps per derivation or per key.

:class:`Cache` is a bounded map in least-recently-used order: a lookup that finds its key
marks the entry most recently used, a new entry beyond ``size`` drops the least recently
used one. Every operation holds one lock, so threads (a background compilation, a sweep's
threaded workers) may share a cache. ``identity=True`` compares keys by identity (``is``),
for objects that are costly to hash or compare, such as a derivation: the entry holds its
key, so the key's ``id`` cannot be reused by another object while the entry lives.

The caches on disk live under :func:`cache_dir` and keep their own bound (the derivation
cache a size in MB, :mod:`appell.io.derivation_cache`; the lambdified code,
:mod:`appell.numerics.lambdified`) with the same order: :func:`evict` removes the least
recently used first.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator
from pathlib import Path
from typing import Any, Generic, TypeVar

V = TypeVar("V")

__all__ = [
    "CACHE_ENV",
    "NO_CACHE_ENV",
    "Cache",
    "cache_dir",
    "cache_enabled",
    "evict",
    "size_limit",
    "source_digest",
    "write_checked",
]

#: the folder of appell's caches on disk
CACHE_ENV = "APPELL_CACHE_DIR"
#: set (to anything but '' or '0'): the derivation cache and the lambdified code are neither read nor written
NO_CACHE_ENV = "APPELL_NO_CACHE"

_MISSING: Any = object()


class Cache(Generic[V]):
    """A thread-safe map of at most ``size`` entries, the least recently used dropped first
    (``identity``: keys compared by ``is``, see the module's docstring)."""

    def __init__(self, size: int, *, identity: bool = False):
        if size < 1:
            raise ValueError(f"a cache holds at least one entry, not {size}")
        self.size = size
        self.identity = identity
        self._entries: OrderedDict[Hashable, tuple[Any, V]] = OrderedDict()
        self._lock = threading.Lock()

    def _slot(self, key: Any) -> Hashable:
        return id(key) if self.identity else key

    def _find(self, key: Any) -> V:
        """The value of ``key`` marked most recently used, or ``_MISSING`` (lock held)."""
        slot = self._slot(key)
        entry = self._entries.get(slot)
        if entry is None or (self.identity and entry[0] is not key):
            return _MISSING
        self._entries.move_to_end(slot)
        return entry[1]

    def get(self, key: Any, default: Any = None) -> Any:
        """The value kept for ``key`` (now the most recently used), else ``default``."""
        with self._lock:
            value = self._find(key)
        return default if value is _MISSING else value

    def put(self, key: Any, value: V) -> V:
        """Keep ``value`` for ``key`` unless a value is kept for it already; returns the kept
        one (so that of two threads that made a value, both use the first one kept)."""
        with self._lock:
            kept = self._find(key)
            if kept is not _MISSING:
                return kept
            self._entries[self._slot(key)] = (key, value)
            while len(self._entries) > self.size:
                self._entries.popitem(last=False)
            return value

    def get_or_make(self, key: Any, make: Callable[[], V]) -> V:
        """The value kept for ``key``, else ``make()`` kept. ``make`` runs without the lock
        (a compilation must not stop other threads' lookups): two threads that miss at once
        both make a value and both get the first one kept."""
        value = self.get(key, _MISSING)
        if value is _MISSING:
            value = self.put(key, make())
        return value

    def pop(self, key: Any, default: Any = None) -> Any:
        """Remove ``key`` and return its value, else ``default``."""
        with self._lock:
            value = self._find(key)
            if value is _MISSING:
                return default
            del self._entries[self._slot(key)]
            return value

    def clear(self) -> None:
        """Drop every entry."""
        with self._lock:
            self._entries.clear()

    def keys(self) -> list:
        """The keys, from the least to the most recently used."""
        with self._lock:
            return [key for key, _ in self._entries.values()]

    def __iter__(self) -> Iterator:
        return iter(self.keys())

    def __contains__(self, key: Any) -> bool:
        with self._lock:
            entry = self._entries.get(self._slot(key))
            return entry is not None and (not self.identity or entry[0] is key)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Cache(size={self.size}, identity={self.identity}, entries={len(self)})"


def cache_dir() -> Path:
    """``$APPELL_CACHE_DIR`` or ``~/.cache/appell`` (created on demand)."""
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "appell")


def cache_enabled(cache: bool | None = None) -> bool:
    """``cache`` when given, else not ``$APPELL_NO_CACHE`` (set to anything but '' or '0')."""
    if cache is not None:
        return bool(cache)
    return os.environ.get(NO_CACHE_ENV, "") in ("", "0")


def size_limit(env: str, default_mb: float) -> int:
    """The bound in bytes of a cache on disk: ``$env`` MB, else (unset or not a number) ``default_mb``."""
    try:
        return int(float(os.environ.get(env) or default_mb) * 2**20)
    except ValueError:
        return int(default_mb * 2**20)


_SOURCE: list[str] = []


def source_digest() -> str:
    """SHA-256 of appell's own source files (formed once per process), part of the keys of the
    caches on disk: what other code of the same version number (a development checkout between
    releases) stored is another entry, never read as this code's."""
    if not _SOURCE:
        digest = hashlib.sha256()
        package = Path(__file__).resolve().parent
        for file in sorted(package.rglob("*")):
            if file.suffix in (".py", ".c", ".toml", ".urdf", ".xml") and file.is_file():
                digest.update(f"{file.relative_to(package).as_posix()} {file.stat().st_size}\n".encode())
                digest.update(file.read_bytes())
        _SOURCE.append(digest.hexdigest()[:16])
    return _SOURCE[0]


def evict(root: Path, pattern: str, limit_bytes: int) -> None:
    """Remove the files of ``root`` matching ``pattern``, the least recently used (modified)
    first, until they hold at most ``limit_bytes`` in all."""
    entries = []
    for file in root.glob(pattern):
        with contextlib.suppress(OSError):
            st = file.stat()
            entries.append((st.st_mtime, st.st_size, file))
    total = sum(size for _, size, _ in entries)
    for _, size, file in sorted(entries, key=lambda e: e[0]):
        if total <= limit_bytes:
            break
        with contextlib.suppress(OSError):
            file.unlink()
            total -= size


def write_checked(file: Path, header: dict, body: bytes) -> None:
    """Write ``file`` atomically (a temporary name beside it, renamed): one JSON line, ``header``
    with the SHA-256 of ``body`` added, then ``body`` (an entry of a cache on disk: a reader that
    finds the body changed or truncated ignores it)."""
    head = json.dumps({**header, "sha256": hashlib.sha256(body).hexdigest()}).encode()
    fd, tmp = tempfile.mkstemp(prefix=f"{file.stem}_", suffix=".tmp", dir=file.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(head + b"\n" + body)
        os.replace(tmp, file)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
