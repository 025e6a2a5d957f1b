"""Geodesic densification of untimed routes (imugen.core.geodesic and its use in ingestion)."""

import itertools

import numpy as np
import pytest
from pyproj import Geod, Transformer

from imugen.core.geodesic import GEODESIC_STEP_M, densify, sagitta_m
from imugen.ingest.stage import ingest

GEOD = Geod(ellps="WGS84")
ECEF = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)

# Tokyo Narita -> Vancouver (crosses the antimeridian), a turn over the Aleutians, and back
PACIFIC = np.array([[35.76, 140.39], [52.0, 179.5], [49.19, -123.18]])


def _segments(lat, lon):
    az, _, d = GEOD.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])
    return np.asarray(az), np.asarray(d)


def test_points_lie_on_the_geodesic_across_the_antimeridian():
    lat, lon = PACIFIC.T
    alt = np.array([0.0, 10_000.0, 20.0])
    dl, do, da, vertex = densify(lat, lon, alt)
    np.testing.assert_array_equal(dl[vertex], lat)
    np.testing.assert_array_equal(do[vertex], lon)
    az0, d0 = _segments(lat, lon)
    # each vertex-to-vertex stretch: distances sum to the geodesic's, every inner point sits
    # at the start azimuth of its geodesic, and every part has the same length <= the step
    iv = np.flatnonzero(vertex)
    for k, (i0, i1) in enumerate(itertools.pairwise(iv)):
        _, d = _segments(dl[i0 : i1 + 1], do[i0 : i1 + 1])
        assert abs(d.sum() - d0[k]) <= 1e-6 * d0[k]
        assert d.max() <= GEODESIC_STEP_M and np.ptp(d) < 1e-6
        az, _, _ = GEOD.inv(
            np.full(i1 - i0 - 1, do[i0]),
            np.full(i1 - i0 - 1, dl[i0]),
            do[i0 + 1 : i1],
            dl[i0 + 1 : i1],
        )
        np.testing.assert_allclose(az, az0[k], atol=1e-9)
        # height linear in distance
        s = np.r_[0.0, np.cumsum(d)]
        np.testing.assert_allclose(da[i0 : i1 + 1], alt[k] + s / s[-1] * (alt[k + 1] - alt[k]))
    # continuous across the antimeridian: longitudes in [-180, 180], one wrap, unwrapped
    # longitude moving steadily east
    assert np.all(np.abs(do) <= 180.0)
    wraps = np.abs(np.diff(do)) > 180.0
    assert wraps.sum() == 1
    step_lon = np.diff(np.unwrap(np.radians(do)))
    assert np.all(step_lon > 0) and np.degrees(step_lon.max()) < 0.01


def test_chords_of_the_densified_route_stay_within_a_centimetre_of_the_surface():
    lat, lon = PACIFIC.T
    dl, do, da, _ = densify(lat, lon, np.zeros(3))
    _, d = _segments(dl, do)
    az, _ = _segments(dl, do)
    mlon, mlat, _ = GEOD.fwd(do[:-1], dl[:-1], az, d / 2)  # arc midpoints
    x = np.column_stack(ECEF.transform(do, dl, da))
    chord_mid = 0.5 * (x[1:] + x[:-1])
    arc_mid = np.column_stack(ECEF.transform(mlon, mlat, np.zeros_like(mlon)))
    gap = np.linalg.norm(chord_mid - arc_mid, axis=1)
    assert gap.max() <= sagitta_m(GEODESIC_STEP_M) < 0.01
    assert gap.max() > 0.5 * sagitta_m(GEODESIC_STEP_M)  # the bound is tight, not vacuous


def test_short_segments_are_unchanged():
    lat = np.array([45.0, 45.001, 45.003, 45.0031])
    lon = np.array([9.0, 9.002, 9.001, 9.004])
    alt = np.array([100.0, 101.0, 99.0, 98.0])
    assert _segments(lat, lon)[1].max() < GEODESIC_STEP_M
    out = densify(lat, lon, alt)
    for a, b in zip(out[:3], (lat, lon, alt), strict=True):
        np.testing.assert_array_equal(a, b)
    assert out[3].all()


def test_ingest_densifies_untimed_routes_only(tmp_path):
    def gpx(points, timed):
        t = "<time>2024-05-01T10:00:{:02d}Z</time>"
        pts = "".join(
            f'<trkpt lat="{a}" lon="{o}"><ele>0</ele>{t.format(i) if timed else ""}</trkpt>'
            for i, (a, o) in enumerate(points)
        )
        f = tmp_path / ("timed.gpx" if timed else "untimed.gpx")
        f.write_text(f"<gpx><trk><trkseg>{pts}</trkseg></trk></gpx>")
        return f

    pts = [(45.0, 9.0), (45.3, 9.4)]  # 44 km
    ing = ingest(gpx(pts, False))
    d = GEOD.inv(9.0, 45.0, 9.4, 45.3)[2]
    n = int(np.ceil(d / GEODESIC_STEP_M))
    assert len(ing.table) == n + 1 and ing.meta["geodesic"]["points_added"] == n - 1
    enu = ing.table[["e_m", "n_m", "u_m"]].to_numpy()
    # the route follows the Earth's curve: its middle lies d^2/(8R) above the chord
    mid = enu[n // 2] - 0.5 * (enu[0] + enu[-1])
    r_n = 6_388_838.0  # prime-vertical radius at 45 deg, a / sqrt(1 - e^2 sin^2)
    assert mid[2] == pytest.approx(d**2 / (8 * r_n), rel=0.01)
    seg = np.linalg.norm(np.diff(enu, axis=0), axis=1)
    assert abs(seg.sum() - d) < 1e-6 * d
    timed = ingest(gpx(pts, True), max_speed_kmh=1e6)
    assert len(timed.table) == 2 and timed.meta["geodesic"] is None
