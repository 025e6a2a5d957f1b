"""Oracles for imugen.core.earth: published WGS-84 values, pyproj, geometry of the ellipsoid."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from imugen.core import earth as E


def somigliana(lat_rad):
    """Somigliana's closed form of normal gravity on the ellipsoid [m/s^2] (the oracle)."""
    s2 = np.sin(lat_rad) ** 2
    return E.GAMMA_E * (1.0 + E.K_SOMIGLIANA * s2) / np.sqrt(1.0 - E.E2_WGS84 * s2)


ORIGIN = E.OriginFrame.from_deg(40.78, -73.97, 30.0, model="wgs84")


def test_normal_gravity_published_equator_pole():
    # WGS-84 (NIMA TR8350.2) published normal gravity on the ellipsoid
    assert E.normal_gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert E.normal_gravity(math.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-10)
    assert E.normal_gravity(-math.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-10)
    # derived constants as published (TR8350.2 tables 3.3-3.4)
    assert E.K_SOMIGLIANA == pytest.approx(0.00193185265241, abs=1e-11)
    assert E.E2_WGS84 == pytest.approx(0.00669437999014, abs=1e-14)
    assert E.M_WGS84 == pytest.approx(0.00344978650684, abs=1e-14)


def test_free_air_gradient():
    lat = math.radians(45.0)
    grad = (E.normal_gravity(lat, 1.0) - E.normal_gravity(lat, -1.0)) / 2.0
    assert grad == pytest.approx(-3.086e-6, abs=2e-9)
    # second-order term: gradient at 10 km is smaller in magnitude by ~6 g h / a^2
    grad10 = (E.normal_gravity(lat, 10001.0) - E.normal_gravity(lat, 9999.0)) / 2.0
    assert grad10 - grad == pytest.approx(6 * 9.806 * 1e4 / E.A_WGS84**2, rel=1e-3)


def test_geodetic_round_trip_against_pyproj():
    pyproj = pytest.importorskip("pyproj")
    tr = pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    rng = np.random.default_rng(1)
    lat = rng.uniform(-89.99, 89.99, 5000)
    lon = rng.uniform(-180.0, 180.0, 5000)
    h = rng.uniform(-1000.0, 50000.0, 5000)
    x, y, z = tr.transform(lon, lat, h)
    r_e = np.stack([x, y, z], axis=-1)
    np.testing.assert_allclose(
        E.ecef_from_geodetic(np.radians(lat), np.radians(lon), h), r_e, rtol=0, atol=1e-6
    )
    la, lo, hh = E.geodetic_from_ecef(r_e)
    assert np.max(np.abs(la - np.radians(lat))) * E.A_WGS84 < 1e-4  # < 0.1 mm
    assert np.max(np.abs(hh - h)) < 1e-6
    dlon = np.angle(np.exp(1j * (lo - np.radians(lon))))
    assert np.max(np.abs(dlon)) < 1e-14


def _normal_potential(x, y, z):
    """Closed-form normal potential of the level ellipsoid in ellipsoidal harmonic coordinates
    (NIMA TR8350.2 ch. 4, Heiskanen & Moritz 1967 ch. 2), written independently of imugen with
    arctan closed forms; works on complex arguments (complex-step differentiation)."""
    a, b, gm, w = E.A_WGS84, E.B_WGS84, E.GM_WGS84, E.OMEGA_IE
    el = math.sqrt(a * a - b * b)

    def q(u):
        return 0.5 * ((1 + 3 * u * u / el**2) * np.arctan(el / u) - 3 * u / el)

    r2 = x * x + y * y + z * z
    s = r2 - el**2
    u2 = 0.5 * (s + np.sqrt(s * s + 4 * el**2 * z * z))
    u = np.sqrt(u2)
    return (
        gm / el * np.arctan(el / u)
        + 0.5 * w * w * a * a * q(u) / q(b) * (z * z / u2 - 1 / 3)
        + 0.5 * w * w * (x * x + y * y)
    )


def test_gravity_is_gradient_of_normal_potential():
    # complex-step gradient: no subtractive cancellation, ~1e-12 m/s^2 of the arctan forms
    rng = np.random.default_rng(2)
    lat = np.radians(rng.uniform(-90, 90, 300))
    lon = np.radians(rng.uniform(-180, 180, 300))
    h = rng.uniform(-1000.0, 40000.0, 300)
    h[:3] = (0.0, 10e3, 400e3)  # on the ellipsoid, airliner, low orbit
    r_e = E.ecef_from_geodetic(lat, lon, h)
    g = E.gravity_e(r_e)
    step = 1e-20
    for k in range(3):
        rc = r_e.astype(complex)
        rc[:, k] += 1j * step
        ref = np.imag(_normal_potential(rc[:, 0], rc[:, 1], rc[:, 2])) / step
        np.testing.assert_allclose(g[:, k], ref, rtol=0, atol=1e-10)
    # gravitation = gravity minus the centrifugal Omega^2 (x, y, 0)
    G = E.gravitation_e(r_e)
    np.testing.assert_allclose(g[:, :2] - G[:, :2], E.OMEGA_IE**2 * r_e[:, :2], atol=1e-15)
    assert np.all(g[:, 2] == G[:, 2])


def test_on_the_ellipsoid_somigliana_and_normal():
    lat = np.radians(np.linspace(-90.0, 90.0, 181))
    lon = np.radians(np.linspace(-180.0, 180.0, 181))
    r_e = E.ecef_from_geodetic(lat, lon, 0.0)
    g = E.gravity_e(r_e)
    # magnitude: Somigliana's closed form (published constants rounded at 1e-10)
    np.testing.assert_allclose(np.linalg.norm(g, axis=1), somigliana(lat), rtol=0, atol=1e-10)
    # direction: minus the ellipsoid normal (the ellipsoid is a level surface)
    up = E.C_en_from_geodetic(lat, lon)[:, 2, :]
    cos = -np.sum(up * g, axis=1) / np.linalg.norm(g, axis=1)
    assert np.max(np.linalg.norm(np.cross(up, g), axis=1) / np.linalg.norm(g, axis=1)) < 1e-15
    assert np.all(cos > 0)


def test_north_component_off_the_ellipsoid():
    # the normal plumb line curves: g_north = -8.1e-9 h sin(2 lat) m/s^2 (issue 11),
    # i.e. the deflection 0.17 arcsec per km of height times sin(2 lat)
    for lat_deg in (15.0, 45.0, 70.0, -45.0):
        lat = math.radians(lat_deg)
        for h in (1000.0, 10000.0):
            g_l = E.C_en_from_geodetic(lat, 0.4) @ E.gravity_e(E.ecef_from_geodetic(lat, 0.4, h))
            assert abs(g_l[0]) < 1e-14
            assert g_l[1] / (h * math.sin(2 * lat)) == pytest.approx(-8.14e-9, rel=0.01)
    # 8 ug at 10 km height and 45 deg
    g_l = E.C_en_from_geodetic(0.7854, 0.0) @ E.gravity_e(E.ecef_from_geodetic(0.7854, 0.0, 1e4))
    assert abs(g_l[1]) / E.MICRO_G == pytest.approx(8.3, abs=0.1)


def _zonal_potential(x, y, z, n_max=5):
    """Normal potential of the WGS-84 level ellipsoid as its zonal series, from the four
    defining constants alone (Heiskanen & Moritz 1967, eqs. 2-92, 2-58, 2-70): gravitational
    ``GM/r (1 - sum_n J2n (a/r)^2n P2n(z/r))`` plus centrifugal ``Omega^2 (x^2 + y^2) / 2``.
    Converges outside the focal sphere (r > E = 521 km); through J10 the truncation is below
    1e-13 m/s^2 at the surface (J2..J6 alone leave 1.3e-9). Complex-step safe."""
    a, f, gm, w = 6378137.0, 1.0 / 298.257223563, 3.986004418e14, 7.292115e-5
    b = a * (1.0 - f)
    e2 = f * (2.0 - f)
    ep = math.sqrt(e2 / (1.0 - e2))
    q0 = 0.5 * ((1.0 + 3.0 / ep**2) * math.atan(ep) - 3.0 / ep)
    m = w**2 * a**2 * b / gm
    j2 = e2 / 3.0 * (1.0 - 2.0 * m * ep / (15.0 * q0))
    r = np.sqrt(x * x + y * y + z * z)
    s = z / r
    total = 1.0
    for n in range(1, n_max + 1):
        j2n = (
            (-1) ** (n + 1) * 3.0 * e2**n / ((2 * n + 1) * (2 * n + 3)) * (1 - n + 5 * n * j2 / e2)
        )
        p2n = np.polynomial.legendre.legval(s, np.eye(2 * n + 1)[2 * n])
        total = total - j2n * (a / r) ** (2 * n) * p2n
    return gm / r * total + 0.5 * w * w * (x * x + y * y)


def test_gravity_matches_zonal_series_of_the_level_ellipsoid():
    """Independent oracle: the gradient (complex step) of the J2..J10 zonal series built from
    a, f, GM, Omega matches gravity_e, north component included, at 0, 1 and 10 km."""
    lat = np.radians([0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 89.9, -45.0, -70.0])
    for h in (0.0, 1e3, 1e4):
        r_e = E.ecef_from_geodetic(lat, 0.3, h)
        ref = np.zeros_like(r_e)
        for k in range(3):
            rc = r_e.astype(complex)
            rc[:, k] += 1e-20j
            ref[:, k] = np.imag(_zonal_potential(rc[:, 0], rc[:, 1], rc[:, 2])) / 1e-20
        g = E.gravity_e(r_e)
        np.testing.assert_allclose(g, ref, rtol=0, atol=1e-11)
        C = E.C_en_from_geodetic(lat, 0.3)
        north = np.einsum("ij,ij->i", C[:, 1, :], g)
        north_ref = np.einsum("ij,ij->i", C[:, 1, :], ref)
        np.testing.assert_allclose(north, north_ref, rtol=0, atol=1e-11)
        if h == 1e4:  # 8 ug at 45 deg, 10 km: the series' own value, not the module's
            assert north_ref[3] / E.MICRO_G == pytest.approx(-8.30, abs=0.01)


def test_navigation_frames_share_one_field():
    rng = np.random.default_rng(3)
    p_n = rng.normal(size=(500, 3)) * np.array([3e5, 3e5, 3e3])
    for frame in (ORIGIN, E.OriginFrame.from_deg(-33.9, 151.2, 5.0)):
        r_e = frame.ecef_from_n(p_n)
        np.testing.assert_allclose(
            E.gravity_n(p_n, frame), E.gravity_e(r_e) @ frame.C_en.T, rtol=0, atol=5e-14
        )
        np.testing.assert_allclose(
            E.gravitation_n(p_n, frame), E.gravitation_e(r_e) @ frame.C_en.T, rtol=0, atol=5e-14
        )
        geo = frame.with_model("geodetic")
        np.testing.assert_allclose(E.gravity_n(r_e, geo), E.gravity_e(r_e), rtol=0, atol=0)
        np.testing.assert_allclose(E.earth_rate_n(geo), [0, 0, E.OMEGA_IE], atol=0)
        np.testing.assert_allclose(geo.n_from_ecef(r_e), r_e, atol=0)
    # 3-D input keeps its shape; one vector too
    assert E.gravity_n(p_n.reshape(5, 100, 3), ORIGIN).shape == (5, 100, 3)
    assert E.gravity_n(np.zeros(3), ORIGIN).shape == (3,)


def test_gravity_at_origin_points_down():
    g = E.gravity_n(np.zeros(3), ORIGIN)
    assert abs(g[0]) < 1e-14
    # the only horizontal part is the normal plumb line's northward curvature at h0 = 30 m
    assert g[1] / (30.0 * math.sin(2 * ORIGIN.lat0_rad)) == pytest.approx(-8.14e-9, rel=0.01)
    assert g[2] == pytest.approx(-E.normal_gravity(ORIGIN.lat0_rad, ORIGIN.h0_m), rel=1e-15)
    flat = ORIGIN.with_model("flat")
    rng = np.random.default_rng(3)
    gf = E.gravity_n(rng.normal(size=(10, 3)) * 1e4, flat)
    assert np.all(gf[:, :2] == 0.0)
    assert np.all(gf[:, 2] == -flat.g0)
    assert np.all(E.earth_rate_n(flat) == 0.0)


def test_local_vertical_tilt_is_distance_over_radius():
    lat0 = ORIGIN.lat0_rad
    s = math.sin(lat0)
    n_rad = E.A_WGS84 / math.sqrt(1 - E.E2_WGS84 * s * s)  # prime vertical radius
    m_rad = n_rad * (1 - E.E2_WGS84) / (1 - E.E2_WGS84 * s * s)  # meridian radius
    d = 10e3
    # points on the ellipsoid-ish surface 10 km east / north (height dropped by d^2/2R)
    east = np.array([d, 0.0, -(d**2) / (2 * n_rad)])
    north = np.array([0.0, d, -(d**2) / (2 * m_rad)])
    ge = E.gravity_n(east, ORIGIN)
    gn = E.gravity_n(north, ORIGIN)
    # gravity leans back toward the origin by the angle d/R
    assert -ge[0] / -ge[2] == pytest.approx(d / (n_rad + ORIGIN.h0_m), rel=2e-3)
    assert -gn[1] / -gn[2] == pytest.approx(d / (m_rad + ORIGIN.h0_m), rel=2e-3)
    assert abs(ge[1]) / abs(ge[2]) < 1e-5 * d / n_rad * 100  # no spurious north lean
    # magnitude is normal gravity of the point's own latitude/height
    lat, _, h = ORIGIN.geodetic_from_n(north)
    assert np.linalg.norm(gn) == pytest.approx(E.normal_gravity(lat, h), rel=1e-14)


def test_gravitation_equator_pole():
    # at the equator on the ellipsoid the centrifugal term Omega^2 a points straight up
    eq = E.OriginFrame(0.0, 0.3, 0.0)
    G = E.gravitation_n(np.zeros(3), eq)
    assert G[2] == pytest.approx(-(E.GAMMA_E + E.OMEGA_IE**2 * E.A_WGS84), abs=1e-10)
    assert abs(G[0]) < 1e-13 and abs(G[1]) < 1e-13
    pole = E.OriginFrame(math.pi / 2 - 1e-12, 0.0, 0.0)
    G = E.gravitation_n(np.zeros(3), pole)
    assert G[2] == pytest.approx(-E.GAMMA_P, abs=1e-10)


def test_earth_rate_matches_ecef_axis():
    w_n = E.earth_rate_n(ORIGIN)
    np.testing.assert_allclose(w_n, ORIGIN.C_en @ np.array([0, 0, E.OMEGA_IE]), atol=1e-20)
    assert np.linalg.norm(w_n) == pytest.approx(7.292115e-5, rel=1e-15)


def test_frame_conversions_round_trip():
    rng = np.random.default_rng(4)
    p_n = rng.normal(size=(100, 3)) * 1e4
    lat, lon, h = ORIGIN.geodetic_from_n(p_n)
    np.testing.assert_allclose(ORIGIN.n_from_geodetic(lat, lon, h), p_n, atol=1e-7)
    C = ORIGIN.C_ln(p_n)
    np.testing.assert_allclose(
        C @ np.swapaxes(C, -1, -2), np.broadcast_to(np.eye(3), C.shape), atol=1e-15
    )
    # on the ellipsoid, local up at each point is minus the gravity direction
    lat, lon, _ = ORIGIN.geodetic_from_n(p_n)
    p0 = ORIGIN.n_from_geodetic(lat, lon, 0.0)
    g = E.gravity_n(p0, ORIGIN)
    up_n = ORIGIN.C_ln(p0)[:, 2, :]
    np.testing.assert_allclose(up_n, -g / np.linalg.norm(g, axis=1)[:, None], atol=2e-15)


def _line(T, L, n=200):
    t = np.linspace(0.0, T, n)
    p = np.zeros((n, 3))
    p[:, 0] = np.linspace(0.0, L, n)
    return t, p


NAV = E.GradeFigures(
    "navigation-like",
    gyro_bias_radps=0.003 * E.DEG_PER_H,
    accel_bias_mps2=25 * E.MICRO_G,
    gyro_scale_factor=5e-6,
)
CONSUMER = E.GradeFigures(
    "consumer-like",
    gyro_bias_radps=10 * E.DEG_PER_H,
    accel_bias_mps2=50 * E.MICRO_G,
    gyro_scale_factor=5e-3,
)


def test_auto_budget_picks_by_grade_and_scene():
    lat = math.radians(45.0)
    # a 2-minute walk with a consumer IMU: Coriolis on 150 m is far below the bias effect
    t, p = _line(120.0, 150.0)
    assert E.choose_earth_model(t, p, lat, CONSUMER).model == "flat"
    # an hour-long 50 km drive: the dropped terms (Schuler, tilt) are large for any grade
    t, p = _line(3600.0, 5e4)
    for fig in (NAV, CONSUMER):
        assert E.choose_earth_model(t, p, lat, fig).model == "wgs84"
    # 100 km from the origin: its vertical tilts by 0.016 rad there -> geodetic, any grade
    t, p = _line(3600.0, 1e5)
    for fig in (NAV, CONSUMER):
        assert E.choose_earth_model(t, p, lat, fig).model == "geodetic"
    # a 10-minute car scene: consumer -> flat, navigation grade -> wgs84
    t, p = _line(600.0, 6000.0)
    assert E.choose_earth_model(t, p, lat, CONSUMER).model == "flat"
    b = E.choose_earth_model(t, p, lat, NAV)
    assert b.model == "wgs84"
    text = "\n".join(b.lines)
    for name in b.terms_m:
        assert name in text
    assert text.endswith("wgs84")
    # the decision is the stated rule
    assert (b.model == "flat") == all(v < b.fraction * b.grade_effect_m for v in b.terms_m.values())
    # the Coriolis term is Omega * L * T (constant speed along a line)
    assert b.terms_m["Coriolis 2*Omega x v"] == pytest.approx(E.OMEGA_IE * 6000.0 * 600.0)


def test_distance_from_origin_is_the_geodesic():
    """The auto budget's distance: points placed by ``Geod.fwd`` at known distances (up to
    15,000 km, beyond the 90 degrees where the origin's horizontal plane folds back), at 0 and
    10 km height, given in the origin's ENU by PROJ: their distance comes back to 1 mm."""
    from pyproj import Geod

    from imugen.core.frames import LocalFrame, Origin

    lat0, lon0 = 35.55, 139.78
    d = np.array([0.0, 1e3, 64e3, 1e6, 5e6, 1e7, 1.5e7])
    lon, lat, _ = Geod(ellps="WGS84").fwd(np.full(7, lon0), np.full(7, lat0), np.full(7, 55.0), d)
    for h in (0.0, 1e4):
        p = LocalFrame(Origin(lat0, lon0, 0.0)).to_enu(lat, lon, np.full(7, h))
        got = E.distance_from_origin_m(p, math.radians(lat0))
        np.testing.assert_allclose(got, d, rtol=0, atol=1e-3)
        assert np.hypot(p[-1, 0], p[-1, 1]) < 0.5 * d[-1]  # the plane's measure folds
    b = E.choose_earth_model(np.linspace(0.0, 3.6e4, 7), p, math.radians(lat0), CONSUMER)
    assert b.model == "geodetic" and "max distance 15000000.0 m (geodesic)" in b.lines[1]


def test_auto_budget_grade_effect_closed_forms():
    t, p = _line(600.0, 6000.0)
    lat = math.radians(45.0)
    ws = math.sqrt(E.normal_gravity(lat, 0.0) / E.R_MEAN)
    ba = E.GradeFigures("a", accel_bias_mps2=1e-3)
    assert E.choose_earth_model(t, p, lat, ba).grade_effect_m == pytest.approx(
        1e-3 * (1 - math.cos(ws * 600.0)) / ws**2
    )
    vrw = E.GradeFigures("v", vrw_mps_per_sqrt_s=1e-3)
    assert E.choose_earth_model(t, p, lat, vrw).grade_effect_m == pytest.approx(
        1e-3 * math.sqrt(600.0**3 / 3)
    )


def test_auto_budget_from_presets():
    from imugen.sensors.grades import budget_figures

    t, p = _line(600.0, 6000.0)
    lat = math.radians(31.6)
    assert E.choose_earth_model(t, p, lat, budget_figures("consumer")).model == "flat"
    assert E.choose_earth_model(t, p, lat, budget_figures("navigation")).model == "wgs84"
    # a white-noise-only grade (the paper's) still has a finite, positive effect
    assert E.choose_earth_model(t, p, lat, budget_figures("paper_low_cost")).grade_effect_m > 0


@pytest.mark.parametrize("config", ["config.yaml", "paper.yaml"])
def test_auto_keeps_the_paper_scene_flat(shared_file, config):
    """The real paper scene (619 s, 664 m from its origin) as config/paper.yaml ingests it, at
    the configured truth rate, under ``auto`` with the grades a shipped config passes to the
    truth (every configured grade, the workflow's ``auto_grades``): ``flat``, every dropped term
    below 10 % of the deciding grade's effect."""
    import yaml

    from imugen.ingest.stage import ingest
    from imugen.truth import build_truth

    repo = Path(__file__).resolve().parents[2]
    cfg = yaml.safe_load((repo / "config" / config).read_text())
    route = yaml.safe_load((repo / "config" / "paper.yaml").read_text())["routes"]["paper"]
    ing = ingest(
        shared_file("seed_reference_trajectory_enu.txt"),
        origin=",".join(map(str, route["origin"])),
        dt=route["dt_s"],
    )
    _, meta = build_truth(
        ing.table, ing.meta, rate_hz=cfg["truth"]["rate_hz"], earth=cfg["truth"]["earth"],
        vehicle=route["vehicle"], grade=list(cfg["grades"]), verbose=False,
    )  # fmt: skip
    b = meta["earth_budget"]
    assert meta["earth"] == "flat", b["lines"]
    assert b["grades_considered"] == list(cfg["grades"])
    assert max(b["terms_m"].values()) < b["fraction"] * b["grade_effect_m"]
