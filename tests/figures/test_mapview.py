"""Map figures of long routes (imugen.figures.mapview): projection choice, scale bar, antimeridian.

Oracles: pyproj.Geod distances (the scale bar's endpoints, inverse-projected, are as far apart
as its label says, to 1 %; distances from the centre are true in the azimuthal equidistant
projection); a route across the antimeridian has no projected step larger than its largest
geodesic step; navigated positions rebuilt from local-level errors give those errors back.
Properties of the drawn artists, not pixel snapshots.
"""

import math

import numpy as np
import pandas as pd
import pytest
from pyproj import Geod

from imugen.core import earth as E
from imugen.core.io import write_parquet
from imugen.evaluate.stage import sequence_metrics
from imugen.figures import mapview as MV
from imugen.figures import stage as fg
from imugen.navigate import local_errors as L
from imugen.tables import truth as ttruth

GEOD = Geod(ellps="WGS84")


def _route(lon0, lat0, lon1, lat1, n=400, h=10_000.0):
    """Points (lat, lon in rad, h) along the geodesic, and ECEF."""
    mid = GEOD.npts(lon0, lat0, lon1, lat1, n - 2)
    lon = np.radians([lon0, *(p[0] for p in mid), lon1])
    lat = np.radians([lat0, *(p[1] for p in mid), lat1])
    hh = np.full(n, h)
    return lat, lon, hh, E.ecef_from_geodetic(lat, lon, hh)


# trans-Pacific (~7,600 km, across 180 deg), a 264 km road, a 40 km drive
PACIFIC = (150.0, 35.0, -140.0, 45.0)
ROAD = (9.69, 45.05, 12.57, 44.06)
SHORT = (7.0, 45.0, 7.4, 45.15)


def test_projection_chosen_by_extent():
    for coords, kind in ((SHORT, "tangent"), (ROAD, "aeqd"), (PACIFIC, "aeqd")):
        lat, lon, _, r = _route(*coords, h=100.0)
        for model in ("wgs84", "geodetic"):
            f = E.OriginFrame(lat[0], lon[0], 0.0, model)
            assert MV.RouteMap.for_route(f, f.n_from_ecef(r)).kind == kind, (coords, model)


def test_aeqd_true_distance_from_centre_and_centre_across_180():
    lat, lon, h, r = _route(*PACIFIC)
    f = E.OriginFrame(lat[0], lon[0], 0.0, "geodetic")
    m = MV.RouteMap.for_route(f, r)
    c_lat, c_lon = m.centre_deg
    assert abs(c_lon) > 160.0  # centred near the antimeridian, not near 0 deg
    xyz = m.xyz(r)
    _, _, d = GEOD.inv(np.full(len(lat), c_lon), np.full(len(lat), c_lat), np.degrees(lon),
                       np.degrees(lat))  # fmt: skip
    np.testing.assert_allclose(np.hypot(xyz[:, 0], xyz[:, 1]), d, rtol=1e-6)
    np.testing.assert_allclose(xyz[:, 2], h, atol=1e-3)  # ellipsoidal height


def test_no_jump_across_the_antimeridian():
    lat, lon, _, r = _route(*PACIFIC, n=2000)
    assert np.any(np.diff(np.sign(np.degrees(lon))) != 0)  # it crosses 180 deg
    _, _, step = GEOD.inv(np.degrees(lon[:-1]), np.degrees(lat[:-1]), np.degrees(lon[1:]),
                          np.degrees(lat[1:]))  # fmt: skip
    for model in ("wgs84", "geodetic"):
        f = E.OriginFrame(lat[0], lon[0], 0.0, model)
        m = MV.RouteMap.for_route(f, f.n_from_ecef(r))
        xy = m.xyz(f.n_from_ecef(r))[:, :2]
        jump = np.hypot(*np.diff(xy, axis=0).T)
        # the projected step is at most the scale factor (< 1.07 here) times the true one
        assert jump.max() <= 1.07 * step.max(), model


@pytest.mark.parametrize("coords", [ROAD, PACIFIC])
def test_scale_bar_is_true_to_one_percent(coords):
    from matplotlib.figure import Figure

    lat, lon, _, r = _route(*coords)
    f = E.OriginFrame(lat[0], lon[0], 0.0, "geodetic")
    m = MV.RouteMap.for_route(f, r)
    xy = m.xyz(r)
    ax = Figure().subplots()
    ax.plot(xy[:, 0], xy[:, 1])
    ax.set_aspect("equal", adjustable="box")
    bar = MV.add_scale_bar(ax, m)
    lon_b, lat_b = m.lonlat([bar["x0"], bar["x1"]], [bar["y"], bar["y"]])
    _, _, d = GEOD.inv(lon_b[0], lat_b[0], lon_b[1], lat_b[1])
    assert d == pytest.approx(bar["km"] * 1000.0, rel=0.01)
    w = np.diff(ax.get_xlim())[0]
    assert 0.05 * w < bar["x1"] - bar["x0"] <= 0.3 * w  # a readable bar
    line = next(a for a in ax.lines if a.get_gid() == "scale_bar")
    np.testing.assert_allclose(line.get_xdata(), [bar["x0"], bar["x1"]])
    assert f"{bar['km']:g} km" in [t.get_text() for t in ax.texts]


def test_nice_length():
    assert [MV.nice_length_km(x) for x in (0.7, 1.0, 3.0, 7.9, 230.0, 1999.0)] == [
        0.5, 1.0, 2.0, 5.0, 200.0, 1000.0,
    ]  # fmt: skip


@pytest.mark.parametrize("model", ["flat", "wgs84", "geodetic"])
def test_navigated_positions_from_local_errors(model):
    lat, lon, _, r = _route(*ROAD, n=50)
    f = E.OriginFrame(lat[0], lon[0], 0.0, model)
    p = f.n_from_ecef(r) if model != "flat" else np.cumsum(np.ones((50, 3)), axis=0)
    err = np.random.default_rng(0).normal(0, 300.0, (50, 3))
    p_nav = MV.RouteMap(f).navigated_n(p, err)
    back = L.local_errors(f, p, np.ones((50, 3)), p_nav - p)[:, :3]
    np.testing.assert_allclose(back, err, atol=1e-6)


# --- Figure 8 and the 3-D figure of a long route ---------------------------------------------
@pytest.fixture(scope="module")
def pacific(tmp_path_factory):
    """A geodetic (ECEF) truth across the antimeridian, two grades of nav errors."""
    d = tmp_path_factory.mktemp("pacific")
    lat, lon, _, r = _route(*PACIFIC, n=600)
    t = np.linspace(0.0, 9.0 * 3600.0, len(lat))
    df = pd.DataFrame({ttruth.TIME: t})
    for i, c in enumerate(ttruth.POS):
        df[c] = r[:, i]
    meta = {"origin": {"lat_deg": math.degrees(lat[0]), "lon_deg": math.degrees(lon[0]),
                       "alt_m": 0.0}, "earth": "geodetic", "rate_hz": len(t) / t[-1]}  # fmt: skip
    truth = write_parquet(df, meta, d / "truth.parquet")
    te = np.arange(0.0, t[-1], 600.0)
    nav, metrics = {}, {}
    for g, k in (("consumer", 3e5), ("navigation", 2e3)):
        parts = []
        for s in range(3):
            g2 = (1 + 0.3 * s) * k * (te / te[-1]) ** 2
            parts.append(pd.DataFrame({"sequence": s, "time_s": te, "err_e_m": g2,
                                       "err_n_m": -0.5 * g2, "err_u_m": 0.0,
                                       "err_att_rad": 0.0}))  # fmt: skip
        p = pd.concat(parts, ignore_index=True)
        nav[g] = [write_parquet(p, {"grade": g}, d / f"nav-{g}.parquet")]
        m = sequence_metrics(p, 7.6e6).reset_index()
        metrics[g] = write_parquet(m, {"grade": g}, d / f"metrics-{g}.parquet")
    return truth, nav, metrics


def test_figure8_long_route_has_scale_bar_and_no_streak(pacific):
    truth, nav, metrics = pacific
    fig = fg.figure8_figure(truth, nav, metrics)
    ax_a, ax_b, _ = fig.axes[:3]
    for ax in (ax_a, ax_b):
        assert any(a.get_gid() == "scale_bar" for a in ax.lines)
        assert "azimuthal equidistant" in ax.get_xlabel()
    ref = ax_a.lines[0]  # the truth, drawn first
    x, y = np.asarray(ref.get_xdata()), np.asarray(ref.get_ydata())
    lat, lon, _, _ = _route(*PACIFIC, n=600)
    _, _, step = GEOD.inv(np.degrees(lon[:-1]), np.degrees(lat[:-1]), np.degrees(lon[1:]),
                          np.degrees(lat[1:]))  # fmt: skip
    drawn = np.hypot(np.diff(x), np.diff(y))
    assert drawn.max() <= 1.07 * step.max()
    # the drawn length is the route's (scale factor 1 to 1.07), not a 360 deg streak
    assert step.sum() <= drawn.sum() * (1 + 1e-9) and drawn.sum() <= 1.07 * step.sum()


def test_short_route_keeps_tangent_plane(tmp_path):
    """A 40 km drive: East/North of the origin in metres, no scale bar, as before."""
    lat, lon, _, r = _route(*SHORT, n=100, h=200.0)
    f = E.OriginFrame(lat[0], lon[0], 0.0, "wgs84")
    p = f.n_from_ecef(r)
    t = np.arange(100.0)
    df = pd.DataFrame({ttruth.TIME: t, **{c: p[:, i] for i, c in enumerate(ttruth.POS)}})
    meta = {"origin": {"lat_deg": math.degrees(lat[0]), "lon_deg": math.degrees(lon[0]),
                       "alt_m": 0.0}, "earth": "wgs84", "rate_hz": 1.0}  # fmt: skip
    truth = write_parquet(df, meta, tmp_path / "truth.parquet")
    nv = pd.DataFrame({"sequence": 0, "time_s": t, "err_e_m": 5.0, "err_n_m": 0.0,
                       "err_u_m": 0.0, "err_att_rad": 0.0})  # fmt: skip
    nav = {"tactical": [write_parquet(nv, {}, tmp_path / "nav.parquet")]}
    met = {"tactical": write_parquet(sequence_metrics(nv, 4e4).reset_index(), {},
                                     tmp_path / "m.parquet")}  # fmt: skip
    fig = fg.figure8_figure(truth, nav, met)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "East [m]" and not any(a.get_gid() == "scale_bar" for a in ax.lines)
    np.testing.assert_allclose(ax.lines[0].get_xdata()[[0, -1]], p[[0, -1], 0], atol=1e-6)
    # the navigated track: truth + C_ln^T err, 5 m East of the vehicle
    e_nav = np.asarray(ax.lines[1].get_xdata()) - p[:, 0]
    np.testing.assert_allclose(e_nav, 5.0, atol=0.01)
