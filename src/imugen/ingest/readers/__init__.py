"""Route file readers, one module per format family.

Every reader returns *all* candidate paths of a file as :class:`imugen.ingest.route.RoutePath`
objects; choosing one and validating its numbers is :mod:`imugen.ingest.stage`'s job.

A file is read once, by :func:`imugen.ingest.limits.read_input` (regular files only, bounded size),
and its bytes are handed to the reader; the bounds on points (all candidates together) and
on name length are checked here for every reader.
"""

from __future__ import annotations

from pathlib import Path

from imugen.core.errors import InputError
from imugen.ingest import limits
from imugen.ingest.formats import GPSBABEL
from imugen.ingest.route import RoutePath

_SNIFF_BYTES = 4096
_WIDE_BOMS = (
    (b"\xff\xfe\x00\x00", "utf-32"),
    (b"\x00\x00\xfe\xff", "utf-32"),
    (b"\xff\xfe", "utf-16"),
    (b"\xfe\xff", "utf-16"),
)


def read_route_file(
    path: str | Path, data: bytes | None = None, *, navsatfix_status: str = "lenient"
) -> list[RoutePath]:
    """Read every candidate path of a route file, choosing the reader by content.

    KMZ is recognised by its zip signature, KML and GPX by their XML root element, NMEA by
    ``$GP``/``$GN``/... sentences, a 70mai dashcam log by its ``$V0`` session line
    (:mod:`imugen.ingest.readers.dashcam`), IGC by its A record and ``HFDTE``, GeoJSON by ``{``; the
    suffixes of :data:`imugen.ingest.formats.GPSBABEL` go through GPSBabel; NUL bytes, ROS
    NavSatFix and hemisphere-lettered CSV go to :mod:`imugen.ingest.readers.gnsscsv`; pose
    trajectories (TUM, EuRoC ground truth, CSV with named pose columns, ROS 2 bags) to
    :mod:`imugen.ingest.readers.pose`; anything else is
    read as delimited text (CSV with a header, or E N U rows). ``data`` is
    the file's content when the caller has already read it with
    :func:`imugen.ingest.limits.read_input`. ``navsatfix_status``: what a ROS NavSatFix dump
    whose every row has status -1 gets (:data:`imugen.ingest.readers.gnsscsv.NAVSATFIX_STATUS`).
    """
    path = Path(path)
    if data is None:
        data = limits.read_input(path)
    paths = _dispatch(path, data, navsatfix_status)
    limits.check(path, "points", sum(p.n_points for p in paths), "all paths together")
    for p in paths:
        limits.check(path, "name_chars", len(p.name), "a path name")
    return paths


def _dispatch(path: Path, data: bytes, navsatfix_status: str = "lenient") -> list[RoutePath]:
    from imugen.ingest.readers import (
        babel,
        dashcam,
        geojson,
        gnsscsv,
        gpx,
        igc,
        kml,
        nmea,
        pose,
        text,
    )  # fmt: skip

    head = data[:_SNIFF_BYTES]
    if not head:
        raise InputError(path, "is empty")
    suffix = path.suffix.lower()
    if head.startswith(b"PK\x03\x04") or suffix == ".kmz":
        return kml.read_kmz(path, data)
    if suffix in GPSBABEL:
        return babel.read_with_gpsbabel(path)
    if pose.is_bag(path, head):
        return pose.read_ros2_bag(path)
    wide = next((enc for bom, enc in _WIDE_BOMS if head.startswith(bom)), None)
    if wide:
        head = head.decode(wide, errors="replace").encode("utf-8", errors="replace")
    elif b"\x00" in head:
        # NUL-padded fields, or a binary file (refused)
        return gnsscsv.read_gnss_csv(path, data, navsatfix_status)
    start = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    if start.startswith(b"$V0") and dashcam.claims(start.decode("utf-8", errors="replace")):
        return dashcam.read_70mai(path, data)
    if suffix == ".nmea" or start.startswith((b"$GP", b"$GN", b"$GL", b"$GA", b"$BD")):
        return nmea.read_nmea(path, data)
    if suffix == ".igc" or (start.startswith(b"A") and b"\nHFDTE" in head):
        return igc.read_igc(path, data)
    if suffix in (".geojson", ".json") or start.startswith(b"{"):
        return geojson.read_geojson(path, data)
    kind = pose.claims(head)
    if kind is not None:
        return {"tum": pose.read_tum, "euroc": pose.read_euroc, "csv": pose.read_pose_csv}[kind](
            path, data
        )
    if gnsscsv.claims(head):
        return gnsscsv.read_gnss_csv(path, data, navsatfix_status)
    lowered = head.lower()
    if suffix == ".gpx" or b"<gpx" in lowered:
        return gpx.read_gpx(path, data)
    if suffix == ".kml" or b"<kml" in lowered:
        return kml.read_kml(path, data)
    if head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"<"):
        raise InputError(path, "is XML but neither KML (<kml>) nor GPX (<gpx>)")
    return text.read_text(path, data)
