"""Untimed aircraft paths: a logger's stale first fix is not flown (issue 27)."""

from __future__ import annotations

import numpy as np
from pyproj import Geod

from imugen import truth
from imugen.ingest.stage import ingest
from imugen.tables import truth as col


def _logger_kml(tmp_path, stale=True):
    """A light aircraft's logger path without times (a KML LineString): 40 km north-east at
    1,000-1,600 m over 800 m terrain, a point every 200 m with 3 m of noise; ``stale``: the
    file starts with the logger's last known position, where this path ends."""
    rng = np.random.default_rng(5)
    d = np.arange(0.0, 40_000.0, 200.0)
    lon, lat, _ = Geod(ellps="WGS84").fwd(
        np.full(d.size, 8.0), np.full(d.size, 46.0), np.full(d.size, 45.0), d
    )
    h = 1000.0 + 600.0 * np.sin(np.pi * d / d[-1]) + rng.normal(0.0, 3.0, d.size)
    coords = [f"{o:.7f},{a:.7f},{e:.1f}" for o, a, e in zip(lon, lat, h, strict=True)]
    if stale:
        coords.insert(0, f"{lon[-1]:.7f},{lat[-1]:.7f},0.0")
    f = tmp_path / "logger.kml"
    f.write_text(
        '<kml xmlns="http://www.opengis.net/kml/2.2"><Placemark><name>flight</name><LineString>'
        "<altitudeMode>absolute</altitudeMode><coordinates>"
        + " ".join(coords)
        + "</coordinates></LineString></Placemark></kml>"
    )
    return f


def test_a_stale_first_fix_of_an_untimed_flight_is_dropped(tmp_path):
    """Issue 27: a logger's untimed flight starting with its last known position (the
    destination, at 0 m) was flown to the destination and back, 2x the distance and at 0 m
    where the terrain is higher; the point is dropped and said."""
    ing = ingest(_logger_kml(tmp_path), vehicle="aircraft")
    assert ing.meta["points_out"] == 200 and ing.meta["cleaning"]["stale_first_removed"]
    assert any("last known position" in w for w in ing.warnings)
    clean = ingest(_logger_kml(tmp_path, stale=False), vehicle="aircraft")
    assert np.allclose(ing.table["u_m"], clean.table["u_m"])
    tr, _ = truth.build_truth(ing.table, ing.meta, rate_hz=10.0, vehicle="aircraft", verbose=False)
    pos = tr[list(col.POS)].to_numpy()
    flown = np.linalg.norm(np.diff(pos, axis=0), axis=1).sum()
    assert flown < 1.1 * ing.meta["length_3d_m"]
