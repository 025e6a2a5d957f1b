"""The reader registry: every route-file format ingestion reads, and its reader module.

:func:`imugen.ingest.readers.read_route_file` chooses the reader by content (and suffix);
this table names each format for the help of ``imugen ingest`` and the documentation, and
tests/ingest/test_stage.py checks that it names every module of :mod:`imugen.ingest.readers`.
Imports nothing (the parser of ``imugen ingest`` reads it).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Format:
    """A route-file format: its name, usual file suffixes and reader module."""

    name: str
    suffixes: tuple[str, ...]
    reader: str
    """Module under :mod:`imugen.ingest.readers`."""


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
    Format("KML", (".kml",), "kml"),
    Format("KMZ", (".kmz",), "kml"),
    Format("GPX", (".gpx",), "gpx"),
    Format("CSV with a header", (".csv", ".txt"), "text"),
    Format("E N U text", (".txt",), "text"),
    Format(
        "GNSS logger CSV (ROS NavSatFix, hemisphere letters, NUL-padded Columbus)",
        (".csv",),
        "gnsscsv",
    ),
    Format("70mai dashcam GPS log", (".txt",), "dashcam"),
    Format("NMEA 0183", (".nmea",), "nmea"),
    Format("IGC", (".igc",), "igc"),
    Format("GeoJSON", (".geojson", ".json"), "geojson"),
    Format("GPSBabel conversions (FIT, TCX, GDB, OziExplorer, SBP, SBN)", tuple(GPSBABEL), "babel"),
)
"""Every format ingestion reads."""


def listing() -> str:
    """The formats as one line: ``KML, KMZ, GPX, ...``."""
    return ", ".join(f.name for f in FORMATS)
