"""Line numbers of the keys and values of a TOML document.

:mod:`tomllib` returns plain dictionaries without positions. :func:`key_lines` scans the
(already validated) source once more and records, for every key path, the line where its
value starts: ``("constraints", "rear", "expr") -> 23``. Arrays of tables get their index
in the path (``("bodies", 0, "mass")``) and so do array elements
(``("mechanics", "generalized_forces", 1)``), so that an element of a multi-line array is
reported on its own line.

The scanner assumes valid TOML (it runs after :func:`tomllib.loads` succeeded) and is
iterative apart from nested inline values, whose depth it bounds.
"""

from __future__ import annotations

__all__ = ["SourceMap", "key_lines", "source_map", "line_of"]

_BARE = set("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")
_MAX_NESTING = 200


class _Scanner:
    def __init__(self, text: str):
        self.s = text
        self.i = 0
        self.line = 1
        self.lines: dict[tuple, int] = {}
        self.content: dict[tuple, int] = {}  # line where a string value's text begins
        self.arrays_of_tables: dict[tuple, int] = {}

    # ----------------------------------------------------------- characters
    def peek(self, k: int = 0) -> str:
        j = self.i + k
        return self.s[j] if j < len(self.s) else ""

    def advance(self, k: int = 1):
        for _ in range(k):
            if self.i < len(self.s):
                if self.s[self.i] == "\n":
                    self.line += 1
                self.i += 1

    def skip_space(self, newlines: bool):
        while self.i < len(self.s):
            c = self.s[self.i]
            if c in " \t" or (newlines and c in "\r\n"):
                self.advance()
            elif c == "#":
                while self.i < len(self.s) and self.s[self.i] != "\n":
                    self.i += 1
            else:
                break

    def skip_string(self) -> str:
        """Skip a string literal; return its text (escapes left as written)."""
        q = self.peek()
        triple = self.s.startswith(q * 3, self.i)
        delim = q * 3 if triple else q
        self.advance(len(delim))
        start = self.i
        while self.i < len(self.s):
            if q == '"' and self.s[self.i] == "\\":
                self.advance(2)
                continue
            if self.s.startswith(delim, self.i):
                end = self.i
                self.advance(len(delim))
                if triple:  # up to two extra quotes belong to the content
                    while self.peek() == q and self.i - end < 2 + len(delim):
                        self.advance()
                return self.s[start:end]
            self.advance()
        return self.s[start:]

    # ---------------------------------------------------------------- keys
    def key(self) -> tuple[str, ...]:
        parts = []
        while True:
            self.skip_space(False)
            c = self.peek()
            if c in ('"', "'"):
                raw = self.skip_string()
                parts.append(_unescape(raw) if c == '"' else raw)
            else:
                start = self.i
                while self.peek() in _BARE and self.peek():
                    self.i += 1
                parts.append(self.s[start : self.i])
            self.skip_space(False)
            if self.peek() == ".":
                self.advance()
                continue
            return tuple(parts)

    def resolve(self, path: tuple) -> tuple:
        """Insert the current index after every prefix that is an array of tables."""
        out: list = []
        for part in path:
            out.append(part)
            key = tuple(out)
            if key in self.arrays_of_tables:
                out.append(self.arrays_of_tables[key])
        return tuple(out)

    # --------------------------------------------------------------- values
    def value(self, path: tuple, depth: int):
        self.lines.setdefault(path, self.line)
        c = self.peek()
        if depth > _MAX_NESTING:
            raise ValueError("nested too deeply")
        if c in ('"', "'"):
            line = self.line
            if self.s.startswith(c * 3, self.i) and self.s[self.i + 3 : self.i + 5].lstrip("\r")[:1] == "\n":
                line += 1  # TOML drops a newline right after the opening delimiter
            self.content[path] = line
            self.skip_string()
        elif c == "[":
            self.advance()
            index = 0
            while True:
                self.skip_space(True)
                if self.peek() in ("]", ""):
                    self.advance()
                    return
                start = self.i
                self.value(path + (index,), depth + 1)
                self.skip_space(True)
                if self.peek() == ",":
                    self.advance()
                elif self.i == start:  # not TOML after all: make progress
                    self.advance()
                index += 1
        elif c == "{":
            self.advance()
            while True:
                self.skip_space(True)
                if self.peek() in ("}", ""):
                    self.advance()
                    return
                start = self.i
                self.keyval(path, depth + 1)
                self.skip_space(True)
                if self.peek() == ",":
                    self.advance()
                elif self.i == start:
                    self.advance()
        else:
            while self.peek() and self.peek() not in ",]}#\n":
                self.advance()

    def keyval(self, prefix: tuple, depth: int = 0):
        line = self.line
        keys = self.key()
        path = prefix + keys
        for k in range(1, len(keys) + 1):
            self.lines.setdefault(prefix + keys[:k], line)
        if self.peek() == "=":
            self.advance()
        self.skip_space(False)
        self.value(path, depth)

    def document(self) -> dict[tuple, int]:
        table: tuple = ()
        while True:
            self.skip_space(True)
            if self.i >= len(self.s):
                return self.lines
            line, start = self.line, self.i
            if self.s.startswith("[[", self.i):
                self.advance(2)
                raw = self.key()
                base = self.resolve(raw[:-1]) + raw[-1:]
                self.arrays_of_tables[base] = self.arrays_of_tables.get(base, -1) + 1
                table = base + (self.arrays_of_tables[base],)
                self.advance(2)
                self.lines.setdefault(base, line)
                self.lines.setdefault(table, line)
            elif self.peek() == "[":
                self.advance()
                table = self.resolve(self.key())
                self.advance()
                self.lines.setdefault(table, line)
            else:
                self.keyval(table)
            # the rest of the line holds at most a comment
            self.skip_space(False)
            if self.i == start:
                self.advance()


def _unescape(raw: str) -> str:
    if "\\" not in raw:
        return raw
    try:
        return raw.encode("latin-1", "backslashreplace").decode("unicode_escape")
    except UnicodeError:
        return raw


def source_map(text: str) -> SourceMap:
    """Lines of every key and string value of a valid TOML document (best effort)."""
    scanner = _Scanner(text)
    try:
        scanner.document()
    except (ValueError, RecursionError, IndexError):
        pass
    return SourceMap(scanner.lines, scanner.content)


def key_lines(text: str) -> dict[tuple, int]:
    """``{key path: line of its value}`` for a valid TOML document (best effort)."""
    return source_map(text).lines


class SourceMap:
    """Where the keys (``lines``) and string values (``content``) of a document start."""

    def __init__(self, lines: dict[tuple, int], content: dict[tuple, int]):
        self.lines = lines
        self.content = content
        #: ``{first two steps of a path: those of the written entry}`` for the copies of a
        #: repeated entry or key (:mod:`.repeat`), which have no lines of their own
        self.aliases: dict[tuple, tuple] = {}

    def _written(self, path) -> tuple:
        path = tuple(path)
        head = self.aliases.get(path[:2])
        return head + path[2:] if head is not None else path

    def line(self, path) -> int | None:
        """Line of ``path`` or of its longest recorded prefix."""
        return line_of(self.lines, self._written(path))

    def content_line(self, path) -> int | None:
        """Line where the text of the string at ``path`` begins (else :meth:`line`)."""
        return self.content.get(self._written(path)) or self.line(path)


def line_of(lines: dict[tuple, int], path: tuple) -> int | None:
    """The line of ``path``, or of its longest recorded prefix; ``None`` if none is known."""
    path = tuple(path)
    while path:
        if path in lines:
            return lines[path]
        path = path[:-1]
    return None
