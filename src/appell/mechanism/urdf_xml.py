"""The XML under the URDF (and SDF) readers, read safely: :func:`_xml_tree` reads a document
with the standard library's expat, every document type declaration (and hence every entity
declaration) refused, into :class:`_Element` nodes that keep their line; :func:`_numbers`
reads an attribute of numbers, every error a :class:`~appell.errors.ModelError` with the
file and line (:mod:`appell.mechanism.urdf` states the rules).
"""

from __future__ import annotations

import math
import xml.parsers.expat
from dataclasses import dataclass, field

from appell.errors import ModelError

#: elements nested deeper than this are refused
_MAX_DEPTH = 64


def _show(text: str) -> str:
    """``repr(text)``, shortened to its start and its length when long (a hostile name of
    millions of characters must not fill the message)."""
    return repr(text) if len(text) <= 80 else f"{text[:40]!r}... ({len(text)} characters)"


@dataclass(frozen=True)
class _Element:
    tag: str
    attrib: dict
    line: int
    children: list = field(default_factory=list)

    def find(self, tag: str) -> _Element | None:
        return next((c for c in self.children if c.tag == tag), None)

    def findall(self, tag: str) -> list[_Element]:
        return [c for c in self.children if c.tag == tag]


# --------------------------------------------------------------------------- XML
def _xml_tree(text: str | bytes, source: str) -> _Element:
    """The element tree of ``text``, with line numbers, read by expat with every document
    type declaration (and hence every entity declaration) refused. Bytes are decoded by
    expat as the XML declaration (or byte-order mark) says, UTF-8 by default; an encoding
    it cannot read is refused."""
    parser = xml.parsers.expat.ParserCreate()
    root: list[_Element] = []
    stack: list[_Element] = []

    def refuse(what):
        def handler(*_args):
            raise ModelError(
                f"the URDF contains {what}, which is not read (entities could expand without bound "
                f"or read other files)",
                where=f"{source}:{parser.CurrentLineNumber}",
                hint="remove the <!DOCTYPE ...> and <!ENTITY ...> declarations; URDF needs none",
            )

        return handler

    def start(tag, attrib):
        if len(stack) >= _MAX_DEPTH:
            raise ModelError(f"elements nested deeper than {_MAX_DEPTH}", where=f"{source}:{parser.CurrentLineNumber}")
        element = _Element(tag, dict(attrib), parser.CurrentLineNumber)
        (stack[-1].children if stack else root).append(element)
        stack.append(element)

    def end(_tag):
        stack.pop()

    parser.StartDoctypeDeclHandler = refuse("a document type declaration")
    parser.EntityDeclHandler = refuse("an entity declaration")
    parser.ExternalEntityRefHandler = refuse("an external entity reference")
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.SetParamEntityParsing(xml.parsers.expat.XML_PARAM_ENTITY_PARSING_NEVER)
        parser.Parse(text, True)
    except xml.parsers.expat.ExpatError as exc:
        raise ModelError(
            f"invalid XML: {xml.parsers.expat.ErrorString(exc.code)}",
            where=f"{source}:{exc.lineno}",
            hint=_ENCODING_HINT
            if exc.code in _ENCODING_ERRORS
            else "correct the XML on this line (control characters, even as &#...;, are not XML)",
        ) from None
    except (LookupError, ValueError) as exc:  # Python's codecs: an unknown or multi-byte declared encoding
        raise ModelError(
            f"the XML declaration names an encoding that is not read ({exc})",
            where=f"{source}:{parser.CurrentLineNumber}",
            hint=_ENCODING_HINT,
        ) from None
    if not root:
        raise ModelError("the URDF has no elements", where=source)
    return root[0]


_ENCODING_ERRORS = {
    xml.parsers.expat.errors.codes[m]
    for m in (
        xml.parsers.expat.errors.XML_ERROR_INVALID_TOKEN,
        xml.parsers.expat.errors.XML_ERROR_INCORRECT_ENCODING,
        xml.parsers.expat.errors.XML_ERROR_UNKNOWN_ENCODING,
    )
}
_ENCODING_HINT = (
    'save the file as UTF-8 (with no encoding, or encoding="UTF-8", in <?xml ...?>); '
    'files in another encoding must declare it, e.g. <?xml version="1.0" encoding="ISO-8859-1"?>'
)


def _numbers(element: _Element, key: str, count: int, default, source: str, *, name: str | None = None):
    text = element.attrib.get(key)
    owner = f"{name!r}: " if name else ""
    what = f"{owner}<{element.tag} {key}={_show(text) if text is not None else ''}>"
    if text is None:
        if default is None:
            raise ModelError(
                f"{owner}<{element.tag}> has no {key}=",
                where=f"{source}:{element.line}",
                hint=f'give {key}="..." with {count} number(s)',
            )
        return default
    parts = text.split()
    hint = f'write {key}="..." as {count} finite number(s) separated by spaces'
    if len(parts) != count:
        raise ModelError(
            f"{what} must be {count} number(s), got {len(parts)}", where=f"{source}:{element.line}", hint=hint
        )
    values = []
    for part in parts:
        try:
            value = float(part)
        except ValueError:
            raise ModelError(
                f"{what}: {_show(part)} is not a number", where=f"{source}:{element.line}", hint=hint
            ) from None
        if not math.isfinite(value):
            raise ModelError(
                f"{what}: {_show(part)} is not a finite number", where=f"{source}:{element.line}", hint=hint
            )
        values.append(value)
    return tuple(values)


def _number(element: _Element, key: str, source: str, default=None, name: str | None = None) -> float:
    return _numbers(element, key, 1, None if default is None else (default,), source, name=name)[0]
