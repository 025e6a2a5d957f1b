"""Route file readers, one module per format family.

Every reader returns *all* candidate paths of a file as :class:`imugen.route.RoutePath`
objects; choosing one and validating its numbers is :mod:`imugen.ingest`'s job.
"""

from __future__ import annotations

from pathlib import Path

from imugen.errors import InputError
from imugen.route import RoutePath

_SNIFF_BYTES = 4096


def read_route_file(path: str | Path) -> list[RoutePath]:
    """Read every candidate path of a route file, choosing the reader by content.

    KMZ is recognised by its zip signature, KML and GPX by their XML root element, and
    anything else is read as delimited text (CSV with a header, or E N U rows).
    """
    from imugen.readers import gpx, kml, text

    path = Path(path)
    try:
        with path.open("rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except IsADirectoryError:
        raise InputError(path, "is a directory, not a route file") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror})") from None
    if not head:
        raise InputError(path, "is empty")
    suffix = path.suffix.lower()
    if head.startswith(b"PK\x03\x04") or suffix == ".kmz":
        return kml.read_kmz(path)
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):  # UTF-16 with a byte-order mark
        head = head.decode("utf-16", errors="replace").encode("utf-8", errors="replace")
    elif b"\x00" in head:
        raise InputError(path, "contains NUL bytes: not a text route file")
    lowered = head.lower()
    if suffix == ".gpx" or b"<gpx" in lowered:
        return gpx.read_gpx(path)
    if suffix == ".kml" or b"<kml" in lowered:
        return kml.read_kml(path)
    if head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"<"):
        raise InputError(path, "is XML but neither KML (<kml>) nor GPX (<gpx>)")
    return text.read_text(path)
