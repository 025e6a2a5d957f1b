"""Bounds on untrusted input files, shared by every reader.

Each bound keeps one hostile or broken file from taking unbounded time or memory; crossing
one is a user's mistake (:class:`imugen.core.errors.InputError`, one line naming the bound and the
environment variable that raises it). Defaults, overridable per process by the environment:

=====================  ===========================  ==========  ==================================
field                  environment variable         default     what
=====================  ===========================  ==========  ==================================
``input_bytes``        ``IMUGEN_MAX_INPUT_BYTES``   64 MiB      size of a route file (and of the
                                                                KML inside a KMZ, decompressed)
``points``             ``IMUGEN_MAX_POINTS``        1,000,000   points of all paths of a file
``xml_elements``       ``IMUGEN_MAX_XML_ELEMENTS``  4,000,000   elements of a KML/GPX document
``depth``              ``IMUGEN_MAX_DEPTH``         100         XML element nesting depth
``token_chars``        ``IMUGEN_MAX_TOKEN_CHARS``   100         one number, time or CSV field
                                                                (40 characters always pass)
``name_chars``         ``IMUGEN_MAX_NAME_CHARS``    1,000       a path name or header field
=====================  ===========================  ==========  ==================================

A reader gets the bytes of its file from :func:`read_input` (regular files only, read with a
non-blocking open, never past the bound) and checks counts with :func:`check`; a new reader
only needs these two calls.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass, fields
from pathlib import Path

from imugen.core.errors import InputError

ENV = {
    "input_bytes": "IMUGEN_MAX_INPUT_BYTES",
    "points": "IMUGEN_MAX_POINTS",
    "xml_elements": "IMUGEN_MAX_XML_ELEMENTS",
    "depth": "IMUGEN_MAX_DEPTH",
    "token_chars": "IMUGEN_MAX_TOKEN_CHARS",
    "name_chars": "IMUGEN_MAX_NAME_CHARS",
}
_WHAT = {
    "input_bytes": "bytes",
    "points": "points",
    "xml_elements": "XML elements",
    "depth": "levels of XML nesting",
    "token_chars": "characters in one value",
    "name_chars": "characters in a name",
}
_CHUNK = 1 << 20


@dataclass(frozen=True)
class Limits:
    """Bounds on one input file (see the module docstring for their meaning)."""

    input_bytes: int = 64 << 20
    points: int = 1_000_000
    xml_elements: int = 4_000_000
    depth: int = 100
    token_chars: int = 100
    name_chars: int = 1_000


def current() -> Limits:
    """The bounds in force: defaults, overridden by the ``IMUGEN_MAX_*`` variables."""
    values = {}
    for f in fields(Limits):
        raw = os.environ.get(ENV[f.name])
        if raw is None or raw.strip() == "":
            continue
        try:
            value = int(raw)
        except ValueError:
            value = 0
        if value < 1:
            raise InputError(ENV[f.name], f"{raw!r} is not a positive integer")
        values[f.name] = value
    return Limits(**values)


def check(source, bound: str, value: int, where: str = "") -> None:
    """Refuse ``value`` when it exceeds the bound named ``bound`` (a :class:`Limits` field).

    Parameters
    ----------
    source : str or Path
        File named in the message.
    bound : str
        ``"points"``, ``"token_chars"``, ... (a field of :class:`Limits`).
    value : int
        The count reached (the reader may stop counting at bound + 1).
    where : str
        Optional place in the file, prefixed to the message (``"line 12"``).
    """
    limit = getattr(current(), bound)
    if value > limit:
        at = f"{where}: " if where else ""
        raise InputError(
            source,
            f"{at}more than {limit:,} {_WHAT[bound]} (the limit; set {ENV[bound]} to raise it)",
        )


def shorten(text: str, n: int = 60) -> str:
    """``text`` cut to ``n`` characters for an error message (``...`` marks a cut)."""
    return text if len(text) <= n else text[: n - 3] + "..."


def read_input(path: str | Path, limit: int | None = None) -> bytes:
    """The bytes of a route file, refusing what is not a regular file or is too large.

    The file is opened non-blocking (a FIFO or device never blocks the open), checked to be a
    regular file, and read in chunks that stop one byte past the bound.

    Parameters
    ----------
    path : str or Path
        The file.
    limit : int, optional
        Largest size in bytes (default :attr:`Limits.input_bytes`).
    """
    path = Path(path)
    default = limit is None
    limit = current().input_bytes if default else limit
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except IsADirectoryError:
        raise InputError(path, "is a directory, not a route file") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise InputError(path, "is a directory, not a route file")
        if not stat.S_ISREG(mode):
            kind = "a FIFO" if stat.S_ISFIFO(mode) else "a device or socket"
            raise InputError(path, f"is {kind}, not a regular file: refused")
        chunks = []
        total = 0
        while total <= limit:
            chunk = os.read(fd, min(_CHUNK, limit + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if total > limit:
        if default:
            check(path, "input_bytes", total)
        raise InputError(path, f"is larger than {limit:,} bytes: refused")
    return b"".join(chunks)
