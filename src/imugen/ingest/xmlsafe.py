"""Parse untrusted XML (KML, GPX) safely.

Route files never need a DTD, so any document type declaration, entity declaration or
external entity reference is refused outright. This closes both external-entity
(XXE) reads and entity-expansion bombs without a third-party dependency. The same first
pass counts elements and nesting depth against :mod:`imugen.ingest.limits`, so no tree is built
for a document that would exhaust memory or the readers' recursion.
"""

from __future__ import annotations

import codecs
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.parsers import expat

from imugen.core.errors import InputError
from imugen.ingest import limits


class _Forbidden(Exception):
    pass


def _forbid_doctype(*_args) -> None:
    raise _Forbidden("a DOCTYPE declaration (DTDs and entities are not allowed in route files)")


def _forbid_entity(*_args) -> None:
    raise _Forbidden("an entity declaration (entities are not allowed in route files)")


def _forbid_external(*_args) -> None:
    raise _Forbidden("an external entity reference (not allowed in route files)")


_BOMS = (
    (codecs.BOM_UTF8, "utf-8"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)
# applied to the first 300 characters only: bounded time whatever the document
_DECLARED = re.compile(
    r"\ufeff?<\?xml[^>]{0,200}?encoding\s{0,20}=\s{0,20}[\"']([^\"']{0,40})[\"']"
)


def _bom_conflict(data: bytes) -> str | None:
    """A byte-order mark contradicting the declared encoding (expat would follow the latter)."""
    for bom, family in _BOMS:
        if data.startswith(bom):
            head = data[:600].decode(family, errors="replace")[:300]
            m = _DECLARED.match(head)
            if m is None:
                return None
            try:
                declared = codecs.lookup(m.group(1)).name
            except LookupError:
                declared = m.group(1)
            if not declared.startswith(family):
                return (
                    f"starts with a {family.upper()} byte-order mark but declares encoding "
                    f"{m.group(1)!r}: remove the mark or correct the declaration"
                )
    return None


def parse_xml(data: bytes, source: str | Path) -> ET.Element:
    """Parse XML bytes into an element tree, refusing DTDs and entities.

    A first pass with a bare expat parser whose DOCTYPE/entity handlers raise stops at the
    first declaration, before anything is expanded or fetched; only a document without
    any of them is then built into a tree.

    Parameters
    ----------
    data : bytes
        The document; its declared encoding is honoured by expat.
    source : str or Path
        Name used in error messages.

    Returns
    -------
    xml.etree.ElementTree.Element
        The root element.
    """
    if b"\x00" in data and not data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(source, "contains NUL bytes: not a text route file")
    conflict = _bom_conflict(data)
    if conflict:
        raise InputError(source, conflict)
    bounds = limits.current()
    depth = 0
    count = 0

    def start(*_args) -> None:
        nonlocal depth, count
        depth += 1
        count += 1
        if depth > bounds.depth:
            limits.check(source, "depth", depth, f"line {guard.CurrentLineNumber}")
        if count > bounds.xml_elements:
            limits.check(source, "xml_elements", count)

    def end(*_args) -> None:
        nonlocal depth
        depth -= 1

    guard = expat.ParserCreate()
    guard.StartDoctypeDeclHandler = _forbid_doctype
    guard.EntityDeclHandler = _forbid_entity
    guard.UnparsedEntityDeclHandler = _forbid_entity
    guard.ExternalEntityRefHandler = _forbid_external
    guard.StartElementHandler = start
    guard.EndElementHandler = end
    try:
        guard.Parse(data, True)
        return ET.fromstring(data)
    except _Forbidden as exc:
        raise InputError(source, f"refused: the XML contains {exc}") from None
    except (expat.ExpatError, ET.ParseError) as exc:
        raise InputError(source, f"is not well-formed XML ({exc})") from None
    except (UnicodeError, LookupError) as exc:
        raise InputError(source, f"has a wrong or unknown text encoding ({exc})") from None
    except ValueError as exc:  # expat: "multi-byte encodings are not supported" (UTF-32)
        raise InputError(source, f"has an unsupported text encoding ({exc})") from None


def local(tag: str) -> str:
    """Local name of an element tag, without its ``{namespace}``."""
    return tag.rsplit("}", 1)[-1]
