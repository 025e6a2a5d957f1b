"""Oracles for imugen.earth: published WGS-84 values, pyproj, geometry of the ellipsoid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen import earth as E

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


def test_numpy_and_numba_gravity_identical():
    rng = np.random.default_rng(2)
    p_n = rng.normal(size=(2000, 3)) * np.array([2e4, 2e4, 3e3])
    for frame in (ORIGIN, ORIGIN.with_model("flat"), E.OriginFrame.from_deg(-33.9, 151.2, 5.0)):
        a = E.gravity_n(p_n, frame)
        b = E.gravity_n_numba(p_n, frame)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-15)
        a = E.gravitation_n(p_n, frame)
        b = E.gravity_n_numba(p_n, frame, gravitation=True)
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-15)


def test_gravity_at_origin_points_down():
    g = E.gravity_n(np.zeros(3), ORIGIN)
    assert np.hypot(g[0], g[1]) < 1e-14
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
    assert np.linalg.norm(gn) == pytest.approx(E.normal_gravity(lat, h), rel=1e-15)


def test_gravitation_equator_pole():
    # at the equator on the ellipsoid the centrifugal term Omega^2 a points straight up
    eq = E.OriginFrame(0.0, 0.3, 0.0)
    G = E.gravitation_n(np.zeros(3), eq)
    assert G[2] == pytest.approx(-(E.GAMMA_E + E.OMEGA_IE**2 * E.A_WGS84), rel=1e-14)
    assert abs(G[0]) < 1e-13 and abs(G[1]) < 1e-13
    pole = E.OriginFrame(math.pi / 2 - 1e-12, 0.0, 0.0)
    G = E.gravitation_n(np.zeros(3), pole)
    assert G[2] == pytest.approx(-E.GAMMA_P, rel=1e-12)


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
    # local up at each point is minus the gravity direction
    g = E.gravity_n(p_n, ORIGIN)
    up_n = C[:, 2, :]
    np.testing.assert_allclose(up_n, -g / np.linalg.norm(g, axis=1)[:, None], atol=1e-15)


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
    # an hour-long 100 km drive: the dropped terms (Schuler, tilt) are large for any grade
    t, p = _line(3600.0, 1e5)
    for fig in (NAV, CONSUMER):
        assert E.choose_earth_model(t, p, lat, fig).model == "wgs84"
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
    from imugen.grades import budget_figures

    t, p = _line(600.0, 6000.0)
    lat = math.radians(31.6)
    assert E.choose_earth_model(t, p, lat, budget_figures("consumer")).model == "flat"
    assert E.choose_earth_model(t, p, lat, budget_figures("navigation")).model == "wgs84"
    # a white-noise-only grade (the paper's) still has a finite, positive effect
    assert E.choose_earth_model(t, p, lat, budget_figures("paper_low_cost")).grade_effect_m > 0
