"""Building the generated C: the compiler, the on-disk cache keyed by the source and the
command (atomic, locked, checksummed), parallel compilation of the units, loading with
:mod:`ctypes` (the package docstring of :mod:`appell.numerics.codegen`)."""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import os
import shlex
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

from appell._cache import CACHE_ENV, Cache, cache_dir  # noqa: F401 (CACHE_ENV: named here for the codegen package)
from appell.errors import ComputationError
from appell.numerics.codegen.source import source_units

COMPILER_ENV = "APPELL_CC"
#: flags of the shared library (and the linking of one split into units); the optimisation level
#: of each unit is :func:`optimisation`'s
CFLAGS = ("-O2", "-shared", "-fPIC")


def find_compiler() -> list[str] | None:
    """The C compiler command (``$APPELL_CC``, ``$CC`` or ``cc``), or None if absent."""
    cmd = shlex.split(os.environ.get(COMPILER_ENV) or os.environ.get("CC") or "cc")
    if not cmd or shutil.which(cmd[0]) is None:
        return None
    return cmd


#: bumped when the layout of a cached library or the way it is compiled changes (part of the
#: cache key)
LIBRARY_FORMAT = 4
#: the C symbol holding a library's cache key, checked after loading
KEY_SYMBOL = "appell_library_key"


def _sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _verified(lib: Path) -> bool:
    """Whether ``lib`` and its checksum file agree (SHA-256 of the library's bytes)."""
    try:
        return _checksum_path(lib).read_text().strip() == _sha256_file(lib)
    except OSError:
        return False


def _checksum_path(lib: Path) -> Path:
    return lib.with_name(lib.name + ".sha256")


@contextlib.contextmanager
def _cache_lock(root: Path, key: str):
    """An exclusive lock on one cache entry (``fcntl.flock``; none where it is missing):
    concurrent processes compile, verify and replace an entry one at a time."""
    try:
        import fcntl
    except ImportError:  # not POSIX: atomic renames alone
        yield
        return
    with open(root / f"appell_{key}.lock", "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _discard(lib: Path) -> None:
    for path in (lib, _checksum_path(lib)):
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)


def build_library(source: str, compiler: list[str] | None = None, *, force: bool = False) -> tuple[Path, bool]:
    """Compile ``source`` to a shared library in the cache unless a verified one is there.

    Returns the library path and whether it was compiled now. The key is the SHA-256 of the
    source, the compile command and :data:`LIBRARY_FORMAT`. A cached library is used only
    when the SHA-256 of its bytes matches the checksum recorded beside it
    (``<library>.sha256``); a truncated, empty or foreign file is compiled again (with a
    warning), never loaded. The library also carries its key as the string
    :data:`KEY_SYMBOL`, checked after loading (:func:`load_library`). Entries are built
    under a per-entry file lock and written to temporary names, then renamed, so that
    concurrent processes never see a half-written library. ``force`` compiles even when a
    verified library is cached.
    """
    compiler = compiler or find_compiler()
    if compiler is None:
        raise ComputationError("no C compiler found", hint=f"install cc or set ${COMPILER_ENV}")
    command = " ".join(compiler + list(CFLAGS))
    key = hashlib.sha256(f"{command}\nformat {LIBRARY_FORMAT}\n{source}".encode()).hexdigest()[:24]
    root = cache_dir()
    root.mkdir(parents=True, exist_ok=True)
    lib = root / f"appell_{key}.so"
    with _cache_lock(root, key):
        if not force and _verified(lib):
            return lib, False
        if lib.exists() and not force:
            warnings.warn(
                f"the cached library {lib} does not match its checksum (truncated, empty or foreign); "
                "compiling it again",
                RuntimeWarning,
                stacklevel=3,
            )
        _discard(lib)
        _compile(source, compiler, root, key, lib)
    return lib, True


def optimisation(unit: str) -> str:
    """The optimisation flag of one translation unit: ``-O3`` for the rigid-body recursions
    (:data:`LOOPS_MARK`; their small fixed-size loops over 3- and 6-vectors are unrolled and
    vectorized: Baxter's forward dynamics and joint wrenches 20 us -> 13 us), else ``-O2``, or
    ``-O1`` above :data:`O1_ABOVE` characters (gcc's -O2 passes cost far more time and memory
    on huge units than they gain). None of them reorders floating-point arithmetic."""
    size = len(unit)
    if LOOPS_MARK in unit and size <= O3_UP_TO:
        return "-O3"
    return "-O1" if size > O1_ABOVE else "-O2"


#: units that hold this comment (the rigid-body recursions, ``rigid.c``) and at most
#: :data:`O3_UP_TO` characters are compiled with -O3; generated straight-line code gains nothing
#: from it and takes longer to compile
LOOPS_MARK = "/* appell: loops over 3- and 6-vectors */"
O3_UP_TO = 200_000
#: units longer than this (characters of C) are compiled with -O1
O1_ABOVE = 400_000


def compile_workers() -> int:
    """How many compilers run at once: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _run_compilers(commands: list[list[str]]) -> None:
    """Run the compile commands, at most :func:`compile_workers` at a time; the first
    failure raises :class:`ComputationError` with the compiler's message."""
    pending, running, failure = list(commands), [], None
    while (pending and failure is None) or running:
        while pending and failure is None and len(running) < compile_workers():
            running.append(subprocess.Popen(pending.pop(0), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
        proc = running.pop(0)
        _, err = proc.communicate()
        if proc.returncode != 0 and failure is None:
            failure = err
    if failure is not None:
        raise ComputationError(
            f"C compilation failed: {failure.strip()[:2000]}",
            hint="use backend='numpy', or set $APPELL_CC to a working C compiler",
        )


def _compile(source: str, compiler: list[str], root: Path, key: str, lib: Path) -> None:
    """Compile ``source`` plus the key symbol into ``lib`` and record its checksum. A source
    with several translation units (:func:`source_units`) is compiled unit by unit in
    parallel (:func:`compile_workers` at a time, each at :func:`optimisation`'s level) and
    linked; a single unit in one command, at its :func:`optimisation` level."""
    temporaries = []

    def temporary(suffix: str) -> str:
        fd, name = tempfile.mkstemp(prefix=f"appell_{key}_", suffix=suffix, dir=root)
        os.close(fd)
        temporaries.append(name)
        return name

    try:
        src_tmp, key_tmp, lib_tmp, sum_tmp = (
            temporary(".c"),
            temporary("_key.c"),
            temporary(".so.tmp"),
            temporary(".sha"),
        )
        Path(src_tmp).write_text(source)
        Path(key_tmp).write_text(f'const char {KEY_SYMBOL}[] = "{key}";\n')
        units = source_units(source)
        if len(units) == 1:
            flags = [optimisation(source), *CFLAGS[1:]]
            proc = subprocess.run(
                compiler + flags + ["-o", lib_tmp, src_tmp, key_tmp, "-lm"], capture_output=True, text=True
            )
            if proc.returncode != 0:
                raise ComputationError(
                    f"C compilation failed ({' '.join(compiler)}): {proc.stderr.strip()[:2000]}",
                    hint="use backend='numpy', or set $APPELL_CC to a working C compiler",
                )
        else:
            objects, commands = [], []
            for unit in units:
                unit_src, obj = temporary(".c"), temporary(".o")
                Path(unit_src).write_text(unit)
                objects.append(obj)
                commands.append(compiler + [optimisation(unit), "-fPIC", "-c", "-o", obj, unit_src])
            _run_compilers(commands)
            _run_compilers([compiler + list(CFLAGS) + ["-o", lib_tmp, *objects, key_tmp, "-lm"]])
        Path(sum_tmp).write_text(_sha256_file(Path(lib_tmp)) + "\n")
        os.replace(src_tmp, root / f"appell_{key}.c")
        os.replace(lib_tmp, lib)
        os.replace(sum_tmp, _checksum_path(lib))
    finally:
        for tmp in temporaries:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)


#: libraries loaded by this process, by (path, checksum): the dynamic loader caches by
#: path, so a library rebuilt at the path of a rejected one is reached through this table
#: (one dropped from it is loaded again by path and checked: a stale one is rebuilt)
LOADED_KEEP = 256
_LOADED: Cache[ctypes.CDLL] = Cache(LOADED_KEEP)


def _library_key(lib, key: str) -> str | None:
    """The string :data:`KEY_SYMBOL` of a loaded library (None when it has none)."""
    try:
        return (ctypes.c_char * (len(key) + 1)).in_dll(lib, KEY_SYMBOL).value.decode("ascii", "replace")
    except ValueError:  # no such symbol
        return None


def load_library(path: Path, source: str, compiler: list[str]) -> tuple[ctypes.CDLL, Path, bool]:
    """Load the cached library ``path`` and check its key symbol; on a mismatch (or a file
    the loader rejects) compile it again and load the new one. Returns the library, its path
    and whether it was compiled here."""
    key = path.stem.removeprefix("appell_")
    checksum = _checksum_path(path).read_text().strip()
    lib = _LOADED.get((str(path), checksum))
    if lib is not None:
        return lib, path, False
    try:
        lib = ctypes.CDLL(str(path))
        found = _library_key(lib, key)
    except OSError:
        found = None
    if found == key:
        return _LOADED.put((str(path), checksum), lib), path, False
    warnings.warn(
        f"the cached library {path} is not the one compiled for this model (key {found!r}); compiling it again",
        RuntimeWarning,
        stacklevel=3,
    )
    path, _ = build_library(source, compiler, force=True)
    # the dynamic loader caches libraries by name: load the new one through a fresh name
    fd, fresh = tempfile.mkstemp(prefix=f"appell_{key}_load_", suffix=".so", dir=path.parent)
    os.close(fd)
    try:
        shutil.copyfile(path, fresh)
        lib = ctypes.CDLL(fresh)
    finally:
        os.unlink(fresh)
    found = _library_key(lib, key)
    if found != key:
        raise ComputationError(
            f"the compiled library {path} does not carry its key {key!r}",
            hint="remove the cache directory ($APPELL_CACHE_DIR) and try again",
        )
    return _LOADED.put((str(path), _checksum_path(path).read_text().strip()), lib), path, True
