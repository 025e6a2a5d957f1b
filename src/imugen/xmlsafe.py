"""Parse untrusted XML (KML, GPX) safely.

Route files never need a DTD, so any document type declaration, entity declaration or
external entity reference is refused outright. This closes both external-entity
(XXE) reads and entity-expansion bombs without a third-party dependency.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from xml.parsers import expat

from imugen.errors import InputError


class _Forbidden(Exception):
    pass


def _forbid_doctype(*_args) -> None:
    raise _Forbidden("a DOCTYPE declaration (DTDs and entities are not allowed in route files)")


def _forbid_entity(*_args) -> None:
    raise _Forbidden("an entity declaration (entities are not allowed in route files)")


def _forbid_external(*_args) -> None:
    raise _Forbidden("an external entity reference (not allowed in route files)")


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
    guard = expat.ParserCreate()
    guard.StartDoctypeDeclHandler = _forbid_doctype
    guard.EntityDeclHandler = _forbid_entity
    guard.UnparsedEntityDeclHandler = _forbid_entity
    guard.ExternalEntityRefHandler = _forbid_external
    try:
        guard.Parse(data, True)
        return ET.fromstring(data)
    except _Forbidden as exc:
        raise InputError(source, f"refused: the XML contains {exc}") from None
    except (expat.ExpatError, ET.ParseError) as exc:
        raise InputError(source, f"is not well-formed XML ({exc})") from None
    except (UnicodeError, LookupError) as exc:
        raise InputError(source, f"has a wrong or unknown text encoding ({exc})") from None


def local(tag: str) -> str:
    """Local name of an element tag, without its ``{namespace}``."""
    return tag.rsplit("}", 1)[-1]
