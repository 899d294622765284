"""The code of lambdified blocks kept on disk: a process that needs the plain-Python or NumPy
function of blocks that another process (or an earlier run) turned into code reads that code
instead of forming it again (the shared subexpressions and the printing: seconds for the larger
models).

:func:`cached_lambdify` is :func:`appell.symbols.lambdify` whose generated source is kept in
``$APPELL_CACHE_DIR/lambdified`` (:func:`appell._cache.cache_dir`) under a key
of

* the expressions' structure (:func:`structural_digest`: each node's type, each atom as SymPy's
  exact ``srepr``: a symbol with its assumptions, a number with every digit) and the names of
  the arguments,
* the printer (``math`` or ``numpy``) and the shared-subexpression search,
* appell's version and the digest of its source files (:func:`appell._cache.source_digest`), SymPy's,
  NumPy's and Python's versions and :data:`FORMAT`,

so an entry holds the code this version of appell generates for these expressions: reading it
is forming it without the work. The modules the printer imported for the code (a SciPy special
function) are imported again by name, not by running text.

An entry is Python source, which runs when it is read, like the libraries of the compiled-code
cache beside it: it is as trusted as that folder (the user's own cache). Its first line holds
the key and the SHA-256 of the rest; an entry that is truncated, changed or written for another
key is ignored and written again. Entries are written to a temporary name and renamed, at most
``$APPELL_LAMBDIFIED_CACHE_MB`` (default 256) MB in all, the least recently used removed first;
``$APPELL_NO_CACHE=1`` forms the code every time and writes nothing.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import json
import linecache
import os
import sys
from pathlib import Path

import numpy as np
import sympy as sp

from appell._cache import NO_CACHE_ENV, cache_dir, cache_enabled, evict, size_limit, source_digest, write_checked

__all__ = ["FORMAT", "NO_CACHE_ENV", "cached_lambdify", "structural_digest"]

#: bumped when the layout of an entry changes (part of the key)
FORMAT = 1
SIZE_ENV = "APPELL_LAMBDIFIED_CACHE_MB"
DEFAULT_SIZE_MB = 256
_MAGIC = "appell-lambdified"

#: the namespace lambdify gives the code of each printer's module (an empty function's), per process
_NAMESPACES: dict[str, dict] = {}


def structural_digest(exprs) -> str:
    """The SHA-256 of the structure of ``exprs`` (nested lists and tuples of expressions and
    matrices): each compound node is its type's name and its arguments' digests in order, each
    atom SymPy's ``srepr`` (exact); every distinct node is visited once (a shared subexpression
    is not walked again)."""
    done: dict = {}

    def node_digest(e) -> bytes:
        stack = [(e, False)]
        while stack:
            node, ready = stack.pop()
            if node in done:
                continue
            if node.args and not ready:
                stack.append((node, True))
                stack.extend((a, False) for a in node.args if a not in done)
                continue
            h = hashlib.blake2b(digest_size=16)
            if node.args:
                h.update(f"{type(node).__name__}({len(node.args)})".encode())
                for a in node.args:
                    h.update(done[a])
            else:
                h.update(sp.srepr(node).encode())
            done[node] = h.digest()
        return done[e]

    out = hashlib.sha256()

    def walk(x) -> None:
        if isinstance(x, sp.MatrixBase):
            out.update(f"M{x.shape}".encode())
            for e in x:
                out.update(node_digest(sp.sympify(e)))
        elif isinstance(x, (list, tuple)):
            out.update(f"[{len(x)}".encode())
            for y in x:
                walk(y)
            out.update(b"]")
        else:
            out.update(node_digest(sp.sympify(x)))

    walk(exprs)
    return out.hexdigest()


def _key(args, exprs, modules: str, cse) -> str:
    from appell import __version__

    names = json.dumps(_names(args))
    cse_name = "none" if not cse else getattr(cse, "__qualname__", "sympy") if callable(cse) else "sympy"
    head = (
        f"{_MAGIC} {FORMAT} appell {__version__} {source_digest()} sympy {sp.__version__} numpy {np.__version__} "
        f"python {sys.version_info[:3]} {modules} cse={cse_name}\n{names}\n"
    )
    return hashlib.sha256(head.encode() + structural_digest(exprs).encode()).hexdigest()[:32]


def _names(args):
    if isinstance(args, (list, tuple)):
        return [_names(a) for a in args]
    return str(args)


def cache_folder() -> Path:
    """``$APPELL_CACHE_DIR/lambdified``."""
    return cache_dir() / "lambdified"


def cached_lambdify(args, exprs, modules: str = "math", cse=None):
    """:func:`appell.symbols.lambdify` ``(args, exprs, modules, cse)``, its code read from the
    cache when these expressions were turned into code before (module docstring)."""
    from appell.symbols import lambdify_with_printer

    if not cache_enabled():
        return lambdify_with_printer(args, exprs, modules, cse)[0]
    try:
        key = _key(args, exprs, modules, cse)
        root = cache_folder()
        root.mkdir(parents=True, exist_ok=True)
    except (OSError, TypeError, ValueError, sp.SympifyError):
        return lambdify_with_printer(args, exprs, modules, cse)[0]
    file = root / f"{key}.py"
    found = _read(file, key, modules)
    if found is not None:
        return found
    function, printer = lambdify_with_printer(args, exprs, modules, cse)
    source = "".join(linecache.getlines(function.__code__.co_filename))
    imports = {m: sorted(k) for m, k in (getattr(printer, "module_imports", None) or {}).items()}
    if source and function.__name__ == "_lambdifygenerated":
        with contextlib.suppress(OSError):
            _write(root, file, key, source, imports)
    return function


def _read(file: Path, key: str, modules: str):
    """The function stored in ``file`` for ``key``, or None (missing, or not an entry of this key)."""
    from appell.symbols import lambdify_with_printer

    try:
        raw = file.read_bytes()
    except OSError:
        return None
    try:
        head, _, body = raw.partition(b"\n")
        header = json.loads(head)
        if header.get("magic") != _MAGIC or header.get("format") != FORMAT or header.get("key") != key:
            return None
        if header.get("sha256") != hashlib.sha256(body).hexdigest():
            return None
        imports = header.get("imports", {})
        source = body.decode()
        # the namespace lambdify gives code of these modules (an empty function's), and the
        # names the printer imported for this code, by module and name
        if modules not in _NAMESPACES:
            _NAMESPACES[modules] = dict(lambdify_with_printer([], [], modules, None)[0].__globals__)
        namespace = dict(_NAMESPACES[modules])
        for module, names in imports.items():
            mod = importlib.import_module(module)
            for name in names:
                namespace.setdefault(name, getattr(mod, name))
        filename = f"<lambdified {key}>"
        code = compile(source, filename, "exec")
        exec(code, namespace)  # noqa: S102 (an entry of the user's own cache: module docstring)
        function = namespace["_lambdifygenerated"]
        linecache.cache[filename] = (len(source), None, source.splitlines(True), filename)
    except Exception:  # noqa: BLE001 (whatever the file holds, it is written again)
        return None
    with contextlib.suppress(OSError):
        os.utime(file)  # most recently used
    return function


def _write(root: Path, file: Path, key: str, source: str, imports: dict) -> None:
    write_checked(file, {"magic": _MAGIC, "format": FORMAT, "key": key, "imports": imports}, source.encode())
    evict(root, "*.py", size_limit(SIZE_ENV, DEFAULT_SIZE_MB))  # the least recently used beyond the bound
