"""Output files: a result file is either complete or absent, never partial.

:func:`atomic_path` is the one writer every output goes through (CSV, HDF5, netCDF,
plots, reports, sweeps). It

* writes to a temporary file beside the target and renames it over the target only when
  the whole file was written (the previous file survives any failure);
* writes through a symbolic link to the file it points to (the link stays a link);
* refuses to replace anything but a regular file (a device, a FIFO, a socket, a
  directory): :class:`~appell.errors.ModelError` naming the path;
* keeps the permission bits of the file it replaces (a new file gets those of a plain
  ``open``);
* names its temporary files ``.<name>.appell-<pid>-<random><suffix>`` and removes those
  left behind by a process that no longer runs (killed with SIGKILL, power loss);
* reports an operating-system failure (a full disk, a read-only file system) as an
  :class:`OSError` carrying the target's path and the system's reason.

:func:`default_file_name` turns a model's name into one safe path component for default
output names.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import stat
import tempfile
from pathlib import Path

from appell.errors import ModelError

__all__ = ["atomic_path", "output_target", "default_file_name", "remove_stale_temporaries", "write_hdf5", "write_bytes"]

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
)


def output_target(path) -> tuple[Path, int | None]:
    """The file a write to ``path`` replaces and its permission bits (None: no file yet).

    A symbolic link is followed to its target (created if the link dangles); anything that
    is not a regular file is refused with :class:`ModelError` (exit code 2) naming ``path``.
    """
    path = Path(path)
    target = Path(os.path.realpath(path)) if os.path.islink(path) else path
    if os.path.islink(target):  # realpath stops at a loop
        raise OSError(errno.ELOOP, os.strerror(errno.ELOOP), str(path))
    try:
        st = os.stat(target)
    except FileNotFoundError:
        return target, None
    if not stat.S_ISREG(st.st_mode):
        kind = next((name for test, name in _KINDS if test(st.st_mode)), "not a regular file")
        shown = f"{path}" if target == path else f"{path} (-> {target})"
        raise ModelError(
            f"{shown} is {kind}; appell writes its results only to regular files",
            hint="give the path of a new or regular file",
        )
    return target, stat.S_IMODE(st.st_mode)


def _temporary_prefix(target: Path) -> str:
    return f".{target.name}.appell-"


def remove_stale_temporaries(target) -> list[Path]:
    """Remove the temporary files of writes to ``target`` whose process is gone; return them.

    A write interrupted by SIGKILL (or a crash of the machine) cannot clean up after
    itself; the next write to the same file does. Files of running processes are kept.
    """
    target = Path(target)
    directory = target.parent if str(target.parent) else Path(".")
    prefix = _temporary_prefix(target)
    pattern = re.compile(re.escape(prefix) + r"(\d+)-")
    removed = []
    try:
        names = os.listdir(directory)
    except OSError:
        return removed
    for name in names:
        m = pattern.match(name)
        if not m or _alive(int(m.group(1))):
            continue
        with contextlib.suppress(OSError):
            os.unlink(directory / name)
            removed.append(directory / name)
    return removed


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True
    return True


def _with_path(exc: OSError, path: Path) -> OSError:
    """``exc`` as an OSError naming ``path`` and the system's reason (same subclass)."""
    if exc.errno is None:
        return exc
    return OSError(exc.errno, os.strerror(exc.errno), str(path))


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None):
    """Yield a temporary path beside ``path``; on success move it over ``path``.

    See the module docstring: symbolic links are written through, non-regular files are
    refused, the replaced file's mode is kept. On any exception (KeyboardInterrupt and the
    SIGTERM of the command line included) the temporary file is removed and ``path`` is
    left as it was; an :class:`OSError` with an ``errno`` is raised again naming ``path``.
    """
    target, mode = output_target(path)
    directory = target.parent if str(target.parent) else Path(".")
    remove_stale_temporaries(target)
    try:
        fd, tmp = tempfile.mkstemp(
            prefix=f"{_temporary_prefix(target)}{os.getpid()}-",
            suffix=suffix if suffix is not None else target.suffix,
            dir=directory,
        )
    except OSError as exc:
        raise _with_path(exc, Path(path)) from exc
    os.close(fd)
    try:
        yield Path(tmp)
        if mode is None:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.errno is not None:
            raise _with_path(exc, Path(path)) from exc
        raise


def default_file_name(name: str, ending: str) -> Path:
    """``<name><ending>`` as one path component in the working directory.

    A model's name is free text (``name = "../x/evil"`` in a model file): every character
    other than a letter, a digit, ``.``, ``-`` or ``_`` becomes ``_``, and leading or
    trailing dots, dashes and underscores are dropped (no hidden file, no ``..``);
    an empty result becomes ``model``.
    """
    stem = re.sub(r"[^\w.-]+", "_", str(name), flags=re.ASCII).strip("._-")[:100] or "model"
    return Path(stem + ending)


def write_hdf5(path, fill, suffix: str | None = None) -> Path:
    """Write an HDF5 file: ``fill(file)`` builds it in memory, :func:`atomic_path` writes it.

    The HDF5 library never writes to the disk itself: on a full disk its failed writes
    left h5py in a state that crashed the interpreter (segmentation fault). Here the
    file's bytes are written by Python, so a full disk is one :class:`OSError` (ENOSPC)
    naming ``path``, and the previous file is kept.
    """
    import io

    import h5py

    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as f:
        fill(f)
    with atomic_path(path, suffix) as tmp:
        write_bytes(tmp, buffer.getbuffer())
    return Path(path)


def write_bytes(path, data) -> None:
    """Write ``data`` (bytes or a buffer) to ``path`` (the last step of :func:`write_hdf5`)."""
    with open(path, "wb") as fh:
        fh.write(data)
