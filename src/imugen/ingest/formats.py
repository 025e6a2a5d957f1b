"""The reader registry: every route-file format ingestion reads, and its reader module.

:func:`imugen.ingest.readers.read_route_file` chooses the reader by content (and suffix);
this table names each format and what of it is read, for the help of ``imugen ingest`` and
the documentation's table of formats (docs/hooks/generated.py); tests/ingest/test_stage.py
checks that it names every module of :mod:`imugen.ingest.readers`. Imports nothing beyond the
standard library (the parser of ``imugen ingest`` reads it).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Format:
    """A route-file format: its name, usual file suffixes, reader module and what is read."""

    name: str
    suffixes: tuple[str, ...]
    """File names it is usually found under; the content decides, except for GPSBabel's
    formats, which the suffix names."""
    reader: str
    """Module under :mod:`imugen.ingest.readers`."""
    what: str = ""
    """What of it is read (the documentation's table of formats)."""


GPSBABEL = {
    ".fit": "garmin_fit",
    ".tcx": "gtrnctr",  # Garmin Training Center (GPSBabel has no "gtrcrs")
    ".gdb": "gdb",
    ".plt": "ozi",
    ".sbp": "sbp",
    ".sbn": "sbn",
}
"""File suffix -> GPSBabel input format (:mod:`imugen.ingest.readers.babel`)."""

FORMATS = (
    Format(
        "KML", (".kml",), "kml",
        "Google Earth KML 2.0-2.3 or without namespace: LineString, gx:Track, OGC 2.3 Track, "
        "gx:MultiTrack, MultiGeometry; each path a candidate",
    ),
    Format("KMZ", (".kmz",), "kml", "zipped KML: doc.kml, else the first .kml at the root"),
    Format("GPX", (".gpx",), "gpx", "GPX 1.0 and 1.1: each track segment and each route"),
    Format(
        "CSV with a header", (".csv", ".txt"), "text",
        "a header naming latitude and longitude (height and time optional); , ; or TAB",
    ),
    Format(
        "E N U text", (".txt",), "text",
        "East North Up rows without a header, optional leading time column, placed on the "
        "Earth by --origin",
    ),
    Format(
        "GNSS logger CSV (ROS NavSatFix, hemisphere letters, NUL-padded Columbus)", (".csv",),
        "gnsscsv",
        "rostopic echo -p dumps of sensor_msgs/NavSatFix (status -1 rows read with a warning); "
        "CSV with hemisphere letters (30.2N, 097.6W); NUL-padded Columbus V-900 logs",
    ),
    Format(
        "70mai dashcam GPS log", (".txt",), "dashcam",
        "$V0x session lines and fixes; rows without a fix and repeated times dropped",
    ),
    Format(
        "NMEA 0183", (".nmea",), "nmea",
        "GGA and RMC sentences of any talker, merged per epoch",
    ),
    Format("IGC", (".igc",), "igc", "IGC flight logs: B records, date from HFDTE"),
    Format(
        "GeoJSON", (".geojson", ".json"), "geojson",
        "LineString, MultiLineString, Feature, FeatureCollection, GeometryCollection; times "
        "from a coordTimes property",
    ),
    Format(
        "TUM pose trajectory", (".txt", ".tum"), "pose",
        "t x y z qx qy qz qw rows (6-DoF truth with its attitude)",
    ),
    Format(
        "EuRoC ground truth CSV", (".csv",), "pose",
        "state_groundtruth_estimate0/data.csv (position and attitude)",
    ),
    Format(
        "CSV with named pose columns", (".csv",), "pose",
        "a header naming time, x y z and qw qx qy qz (a pose trajectory)",
    ),
    Format(
        "ROS 2 bag poses", (".db3", ".mcap"), "pose",
        "PoseStamped, PoseWithCovarianceStamped, Odometry, TransformStamped topics; each a candidate",
    ),
    Format(
        "GPSBabel conversions (FIT, TCX, GDB, OziExplorer, SBP, SBN)", tuple(GPSBABEL), "babel",
        "converted to GPX by GPSBabel when it is installed; the suffix names its input format: "
        + ", ".join(f"{suffix} ({fmt})" for suffix, fmt in GPSBABEL.items()),
    ),
)  # fmt: skip
"""Every format ingestion reads."""


def listing() -> str:
    """The formats as one line: ``KML, KMZ, GPX, ...``."""
    return ", ".join(f.name for f in FORMATS)
