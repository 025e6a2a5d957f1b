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

    KMZ is recognised by its zip signature, KML and GPX by their XML root element, NMEA by
    ``$GP``/``$GN``/... sentences, IGC by its A record and ``HFDTE``, GeoJSON by ``{``; the
    suffixes of :data:`imugen.readers.babel.FORMATS` go through GPSBabel; NUL bytes, ROS
    NavSatFix and hemisphere-lettered CSV go to :mod:`imugen.readers.gnsscsv`; anything else is
    read as delimited text (CSV with a header, or E N U rows).
    """
    from imugen.readers import babel, geojson, gnsscsv, gpx, igc, kml, nmea, text

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
    if suffix in babel.FORMATS:
        return babel.read_with_gpsbabel(path)
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):  # UTF-16 with a byte-order mark
        head = head.decode("utf-16", errors="replace").encode("utf-8", errors="replace")
    elif b"\x00" in head:
        return gnsscsv.read_gnss_csv(path)  # NUL-padded fields, or a binary file (refused)
    start = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    if suffix == ".nmea" or start.startswith((b"$GP", b"$GN", b"$GL", b"$GA", b"$BD")):
        return nmea.read_nmea(path)
    if suffix == ".igc" or (start.startswith(b"A") and b"\nHFDTE" in head):
        return igc.read_igc(path)
    if suffix in (".geojson", ".json") or start.startswith(b"{"):
        return geojson.read_geojson(path)
    if gnsscsv.claims(head):
        return gnsscsv.read_gnss_csv(path)
    lowered = head.lower()
    if suffix == ".gpx" or b"<gpx" in lowered:
        return gpx.read_gpx(path)
    if suffix == ".kml" or b"<kml" in lowered:
        return kml.read_kml(path)
    if head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"<"):
        raise InputError(path, "is XML but neither KML (<kml>) nor GPX (<gpx>)")
    return text.read_text(path)
