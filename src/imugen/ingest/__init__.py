"""Ingest stage: a route file -> geodetic table + exact local ENU (:mod:`imugen.tables.enu`).

:mod:`~imugen.ingest.stage` is the face (``imugen ingest``); :mod:`~imugen.ingest.readers`
holds one reader per file format (KML/KMZ, GPX, text/CSV, NMEA, IGC, GeoJSON, GNSS CSV, GPSBabel
conversions), :mod:`~imugen.ingest.route` the path they return, :mod:`~imugen.ingest.clean`
the per-vehicle cleaning, :mod:`~imugen.ingest.segments` the gap handling,
:mod:`~imugen.ingest.limits` the size limits and :mod:`~imugen.ingest.xmlsafe` safe XML parsing.
"""
