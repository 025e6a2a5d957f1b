"""Truths through and around the poles: the ground attitude and the turn rate stay defined.

Oracles: the transverse local level (North towards an axis other than the Earth's) is the
geographic one for the Earth's axis and turns at the derivative of its own axes (finite
difference) at and near a pole; a car driving through the South Pole and one circling the North
Pole are their analytic routes, close to <= 1e-6 m, keep the non-holonomic constraint (no body
lateral or vertical speed), agree with their increments and raise no warning; their turn rate
(body rate about the local vertical) is the geodesic curvature of the path times the speed,
re-derived from the truth's velocity: 0 on the straight road, v / 300 m on the circle; an
airliner flying over the North Pole turns at ~0 deg/s (the yaw from geographic North swings
180 deg there). Evaluated through the pole, a leftward accelerometer bias gives the closed-form
cross-track error, and the flight's map figure is drawn projected without a streak.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from imugen import truth
from imugen.closure import closure_of_truth
from imugen.core import earth as E
from imugen.core.errors import InputError
from imugen.core.rotations import quat_to_dcm
from imugen.navigate import local_errors as L
from imugen.navigate import mechanize as M
from imugen.tables import truth as col
from imugen.truth.attitude import POLE_MARGIN_RAD, EarthField, _sphere_directions
from imugen.truth.report import turn_rate

Z = np.array([0.0, 0.0, 1.0])


def route(lat_deg, lon_deg, heading_deg, radius_m, speed_mps, height_m):
    """ECEF position ``(t) -> (m, 3)`` of a vehicle at constant speed and ellipsoidal height
    above a circle of geocentric directions through (lat, lon), leaving it at ``heading_deg``:
    a great circle (``radius_m`` None) or a left-turning circle of ``radius_m``."""
    lat, lon, az = map(math.radians, (lat_deg, lon_deg, heading_deg))
    C = E.C_en_from_geodetic(lat, lon)
    u0 = E.ecef_from_geodetic(lat, lon, 0.0)
    u0 = u0 / np.linalg.norm(u0)
    b = math.sin(az) * C[0] + math.cos(az) * C[1]
    b = b - u0 * (b @ u0)
    b /= np.linalg.norm(b)
    left = np.cross(u0, b)
    th0 = math.pi / 2 if radius_m is None else math.asin(radius_m / E.R_MEAN)
    n = math.cos(th0) * u0 + math.sin(th0) * left
    a = math.sin(th0) * u0 - math.cos(th0) * left

    def position(t):
        s = speed_mps * np.asarray(t, float) / (E.R_MEAN * math.sin(th0))
        u = math.cos(th0) * n + math.sin(th0) * (np.cos(s)[:, None] * a + np.sin(s)[:, None] * b)
        glat = np.arctan2(u[:, 2], (1.0 - E.E2_WGS84) * np.hypot(u[:, 0], u[:, 1]))
        return E.ecef_from_geodetic(glat, np.arctan2(u[:, 1], u[:, 0]), height_m)

    return position


def build(position, duration_s, rate_hz, earth, vehicle, suspension="auto"):
    """Truth from the route's exact points at 1 Hz, the origin at its start (``suspension``:
    the vehicle's model, ``auto`` its class's)."""
    t = np.arange(0.0, duration_s + 1e-9, 1.0)
    lat0, lon0, h0 = (float(x[0]) for x in E.geodetic_from_ecef(position(t[:1])))
    origin = E.OriginFrame(lat0, lon0, h0, "wgs84")
    enu, meta = truth.enu_table(
        origin.n_from_ecef(position(t)), t, (math.degrees(lat0), math.degrees(lon0), h0)
    )
    vehicle_params = None if suspension == "auto" else {"suspension": suspension}
    return truth.build_truth(
        enu, meta, rate_hz=rate_hz, earth=earth, vehicle=vehicle, grade="tactical", verbose=False,
        vehicle_params=vehicle_params,
    )  # fmt: skip


def curvature_turn_rate(df, frame):
    """Turn rate re-derived from the path alone: ``((v x a) . u) / |v_h|^2`` (geodesic
    curvature times speed), velocity and acceleration by central differences in ECEF."""
    t = df[col.TIME].to_numpy()
    r = frame.ecef_from_n(df[list(col.POS)].to_numpy())
    v = df[list(col.VEL)].to_numpy() @ frame.C_en
    a = np.gradient(v, t, axis=0)
    lat, lon, _ = E.geodetic_from_ecef(r)
    u = E.C_en_from_geodetic(lat, lon)[:, 2]
    vu = np.einsum("ki,ki->k", v, u)
    vh2 = np.einsum("ki,ki->k", v, v) - vu * vu
    return np.einsum("ki,ki->k", np.cross(v, a), u) / vh2


def test_transverse_level_with_the_earth_axis_is_enu():
    """North towards the Earth's axis: the frame, velocity and transport rate of ENU."""
    rng = np.random.default_rng(7)
    for model in ("wgs84", "geodetic"):
        Ef = EarthField(E.OriginFrame.from_deg(40.0, 10.0, 100.0, model))
        lat = np.radians(rng.uniform(-85.0, 85.0, 40))
        p = Ef.frame.n_from_geodetic(lat, np.radians(rng.uniform(-180, 180, 40)), 5e3)
        v = rng.normal(size=(40, 3)) * 100.0
        for geo, trans in zip(Ef.local(p, v), Ef.local(p, v, Z), strict=True):
            np.testing.assert_allclose(trans, geo, rtol=0, atol=1e-12 * np.abs(geo).max())


@pytest.mark.parametrize("lat_deg", [90.0, 89.99999, -90.0, -60.0])
def test_transverse_level_turns_at_its_rate_at_the_pole(lat_deg):
    """d/dt C_le = -[omega_l x] C_le along a motion through the point (central difference)."""
    Ef = EarthField(E.OriginFrame.from_deg(89.0, 10.0, 0.0, "geodetic"))
    k = np.array([0.6, 0.8, 0.0])
    r0 = E.ecef_from_geodetic(math.radians(lat_deg), 0.3, 500.0)[None, :]
    v = np.array([[30.0, -20.0, 5.0]])
    h = 1e-3
    Cp = Ef.local(r0 + v * h, v, k)[0][0]
    Cm = Ef.local(r0 - v * h, v, k)[0][0]
    C0, v_l, w = Ef.local(r0, v, k)
    S = (Cp - Cm) / (2.0 * h) @ C0[0].T  # -[w x]
    w_fd = -np.array([S[2, 1], S[0, 2], S[1, 0]])
    np.testing.assert_allclose(w[0], w_fd, rtol=0, atol=1e-6 * np.abs(w).max())
    np.testing.assert_allclose(v_l[0], C0[0] @ v[0], rtol=0, atol=1e-12)
    assert np.allclose(C0[0] @ C0[0].T, np.eye(3), atol=1e-14)


def _check_ground_truth(position, df, tm, tol_closure_m=1e-6):
    rep = tm["plausibility"]
    assert rep["warnings"] == []
    assert rep["max_rate_increment_radps"] < 1e-6
    assert rep["max_attitude_step_excess_rad"] == 0.0
    assert rep["max_body_lateral_speed_mps"] < 1e-9  # non-holonomic: along body x only
    if "suspension" in tm["ground_attitude"]:
        # on a suspension the body only rolls and pitches: vertical body speed -|v| sin
        # theta_s, theta_s within the pitch gradient x the largest dv/dt (with overshoot)
        vp = truth.VEHICLES["car"]
        t = df[col.TIME].to_numpy()
        speed = np.linalg.norm(df[list(col.VEL)].to_numpy(), axis=1)
        theta_max = 1.3 * vp.pitch_gradient_radpmps2 * np.abs(np.gradient(speed, t)).max()
        assert rep["max_body_vertical_speed_mps"] <= speed.max() * theta_max + 1e-9
        assert rep["max_abs_roll_deg"] <= np.degrees(vp.max_roll_rad)
    else:
        assert rep["max_body_vertical_speed_mps"] < 1e-9
        assert rep["max_abs_roll_deg"] < 1e-9
    assert tm["ground_attitude"]["heading_reference"].startswith("transverse pole")
    frame = col.origin_frame(tm)
    t = df[col.TIME].to_numpy()
    r = frame.ecef_from_n(df[list(col.POS)].to_numpy())
    inner = (t > t[0] + 5.0) & (t < t[-1] - 5.0)  # away from the spline's free ends
    # the route, to the fit of its 1 Hz points (1 mm floor; a few on a 300 m circle)
    assert np.max(np.linalg.norm(r - position(t), axis=1)[inner]) < 5e-3
    res = closure_of_truth(df, tm)
    assert res["max_position_error_m"] <= tol_closure_m
    assert res["max_attitude_error_rad"] <= 1e-9
    return t, inner, frame, res


def test_car_through_the_south_pole():
    """A straight road (great circle) over the South Pole at 20 m/s, 2.2 km; geodetic."""
    position = route(-89.99, 30.0, 180.0, None, 20.0, 2800.0)
    df, tm = build(position, 110.0, 20.0, "geodetic", "car")
    _, inner, frame, res = _check_ground_truth(position, df, tm)
    print(f"South Pole road: closure {res['max_position_error_m']:.1e} m")
    assert df[col.LAT].min() < -89.99999  # within 1.1 m of the pole
    # a straight road does not turn; the yaw from geographic North swings by 180 deg
    assert tm["plausibility"]["max_yaw_rate_dps"] < 1e-6
    assert np.max(np.abs(curvature_turn_rate(df, frame)[inner])) < 1e-6
    yaw = df["yaw_rad"].to_numpy()
    assert abs(abs(yaw[-1] - yaw[0]) - math.pi) < 1e-3


@pytest.mark.parametrize("suspension", ["rigid", "damped"])
def test_car_stopping_at_the_south_pole(suspension):
    """20 m/s, a smooth stop 3 cm from the South Pole for ~16 s, then on: plausible, and the
    attitude (ECEF) exactly constant while stopped, where no heading can be read off (on
    its suspension, once the body has settled from the braking)."""
    tf = np.linspace(0.0, 140.0, 140_001)
    v = 10.0 * (2.0 - np.tanh((tf - 52.0) / 3.0) + np.tanh((tf - 78.0) / 3.0))
    d = np.r_[0.0, np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(tf))]
    road = route(-89.99, 30.0, 180.0, None, 1.0, 2800.0)  # position at distance "t"
    shift = 1111.95 - np.interp(65.0, tf, d)  # the pole ~1,112 m along, reached at 65 s
    df, tm = build(
        lambda t: road(np.interp(t, tf, d) + shift), 140.0, 20.0, "geodetic", "car", suspension
    )
    rep = tm["plausibility"]
    assert rep["warnings"] == [] and rep["time_stopped_s"] > 10.0
    assert rep["max_rate_increment_radps"] < 1e-6 and rep["max_body_lateral_speed_mps"] < 1e-9
    assert df[col.LAT].min() < -89.9999
    t = df[col.TIME].to_numpy()
    q = df[list(col.QUAT)].to_numpy()
    still = (t > 62.0) & (t < 68.0)
    if suspension == "damped":
        # the braking (up to 3.3 m/s^2) pitched the body, which then rocks on its suspension,
        # to 1e-12 after ln(1e12) / (zeta w_n) of the slowest mode (pitch: 9.2 s)
        vp = truth.VEHICLES["car"]
        assert np.abs(df["pitch_rad"].to_numpy()).max() > np.radians(0.2)
        sigma = 2 * np.pi * min(vp.roll_hz * vp.roll_damping, vp.pitch_hz * vp.pitch_damping)
        (a, b), *_ = [s for s in tm["fit"]["stops"] if s[0] < 65.0 < s[1]]
        still = (t > a + np.log(1e12) / sigma) & (t < b)
        assert np.ptp(t[still]) > 2.0  # 2.75 s: the stop holds from its first still fix
    q = q[still]
    assert np.max(np.abs(q - q[0])) < 1e-12


@pytest.mark.parametrize("suspension", ["rigid", "damped"])
@pytest.mark.parametrize("earth", ["geodetic", "wgs84"])
def test_car_circling_the_north_pole(earth, suspension):
    """A circle of 300 m radius passing 1.1 m from the North Pole (the pole inside it) at
    10 m/s: turn rate v / 300 m, the path's own curvature; on its suspension the body rolls
    outwards by the roll gradient x v^2 / 300 m."""
    position = route(89.99999, 30.0, 90.0, 300.0, 10.0, 50.0)
    df, tm = build(position, 200.0, 20.0, earth, "car", suspension)
    t, inner, frame, _ = _check_ground_truth(position, df, tm)
    _, lon, _ = frame.geodetic_from_n(df[list(col.POS)].to_numpy())
    assert np.ptp(np.unwrap(lon)) > 2.0 * math.pi  # around the pole
    C_nb = quat_to_dcm(df[list(col.QUAT)].to_numpy())
    w = turn_rate(df[list(col.POS)].to_numpy(), df[list(col.GYRO)].to_numpy(), C_nb, frame)
    kappa_v = curvature_turn_rate(df, frame)
    np.testing.assert_allclose(w[inner], kappa_v[inner], rtol=0, atol=1e-6)
    mid = (t > 15.0) & (t < t[-1] - 15.0)  # the fit's free ends bend the path a little
    np.testing.assert_allclose(w[mid], 10.0 / 300.0, rtol=1e-3)
    K = truth.VEHICLES["car"].roll_gradient_radpmps2 if suspension == "damped" else 0.0
    roll = df["roll_rad"].to_numpy()[mid]
    np.testing.assert_allclose(roll, K * 10.0**2 / 300.0, rtol=0, atol=1e-9 + 2e-3 * K)


@pytest.fixture(scope="module")
def airliner():
    """Timed airliner at 250 m/s, 10 km, straight over the North Pole (110 km, 10 Hz)."""
    return build(route(89.5, 0.0, 0.0, None, 250.0, 10_000.0), 440.0, 10.0, "geodetic", "airliner")


def test_airliner_over_the_north_pole(airliner):
    """No false turn rate (the yaw from geographic North swings 180 deg within seconds)."""
    df, tm = airliner
    rep = tm["plausibility"]
    assert rep["warnings"] == []
    assert rep["time_airborne_s"] > 400.0
    assert df[col.LAT].max() > 89.9999
    assert rep["max_yaw_rate_airborne_dps"] < 1e-3
    yaw = df["yaw_rad"].to_numpy()
    assert abs(abs(yaw[-1] - yaw[0]) - math.pi) < 1e-3
    res = closure_of_truth(df, tm)
    assert res["max_position_error_m"] <= 1e-6


def test_heading_axis_choice():
    """Geographic North away from the poles; near one, an axis far from every vertical."""
    Ef = EarthField(E.OriginFrame.from_deg(0.0, 0.0, 0.0, "geodetic"))
    t = np.arange(0.0, 100.0)
    assert Ef.heading_axis(route(88.0, 0.0, 0.0, None, 20.0, 0.0)(t)) is None
    assert EarthField(E.OriginFrame.from_deg(0.0, 0.0, 0.0, "flat")).heading_axis(t) is None
    r = route(89.5, 0.0, 0.0, None, 1000.0, 0.0)(np.arange(0.0, 200.0))  # 200 km over the pole
    k = Ef.heading_axis(r)
    lat, lon, _ = E.geodetic_from_ecef(r)
    u = E.C_en_from_geodetic(lat, lon)[:, 2]
    assert np.max(np.abs(u @ k)) < 1e-6  # the normal of the route's plane
    # verticals all over the sphere: no axis keeps clear of them
    with pytest.raises(InputError, match="cover the globe"):
        Ef.heading_axis(6.4e6 * _sphere_directions(20_000))
    assert math.degrees(POLE_MARGIN_RAD) == pytest.approx(1.0)


def _nav_errors(df, tm, accel_bias_mps2):
    """Local-level errors (J, 5: East, North, Up, along, cross) of the truth's own increments
    mechanized with a body-y (leftward) accelerometer bias, at every sample."""
    frame = col.origin_frame(tm)
    dth = df[list(col.DTHETA)].to_numpy()[1:]
    dv = df[list(col.DV)].to_numpy()[1:].copy()
    dt = 1.0 / tm["rate_hz"]
    dv[:, 1] += accel_bias_mps2 * dt
    p = df[list(col.POS)].to_numpy()
    v = df[list(col.VEL)].to_numpy()
    q = df[list(col.QUAT)].to_numpy()
    nav = M.mechanize(dth, dv, dt, p[0], v[0], q[0], frame)
    return L.local_errors(frame, p, v, nav.p_n - p)


def test_errors_through_the_south_pole_are_along_and_cross_track():
    """A leftward accelerometer bias b on the road over the South Pole: cross-track error
    b t^2 / 2 (within Coriolis and Schuler terms, < 1 % over 110 s) smooth through the pole,
    along-track ~0, while East and North turn over as the pole is passed."""
    position = route(-89.99, 30.0, 180.0, None, 20.0, 2800.0)
    df, tm = build(position, 110.0, 20.0, "geodetic", "car")
    b = 1e-3
    err = _nav_errors(df, tm, b)
    assert np.all(np.isfinite(err))
    t = df[col.TIME].to_numpy() - df[col.TIME].iloc[0]
    late = t > 20.0
    np.testing.assert_allclose(err[late, 4], 0.5 * b * t[late] ** 2, rtol=1e-2)
    assert np.max(np.abs(err[late, 3])) < 0.02 * np.max(err[late, 4])
    # the East error turns over at the pole (a local-level axis reverses there)
    east = err[late, 0] / np.hypot(err[late, 0], err[late, 1])
    assert east.max() > 0.9 and east.min() < -0.9


def test_map_figure_of_a_polar_flight(airliner, tmp_path):
    """Figure 8 of the flight over the pole: projected (110 km, azimuthal equidistant), scale
    bar, the truth drawn without a step beyond its own, the navigated track finite."""
    from pyproj import Geod

    from imugen.core.io import write_parquet
    from imugen.evaluate.stage import sequence_metrics
    from imugen.figures import stage as fg

    df, tm = airliner
    err = _nav_errors(df, tm, 1e-3)
    t = df[col.TIME].to_numpy()
    nv = pd.DataFrame({"sequence": 0, "time_s": t, "err_att_rad": 0.0})
    for i, c in enumerate(("err_e_m", "err_n_m", "err_u_m", "err_along_m", "err_cross_m")):
        nv[c] = err[:, i]
    truth_path = tmp_path / "truth.parquet"
    col.write(df, tm, truth_path)
    nav = {"tactical": [write_parquet(nv, {"grade": "tactical"}, tmp_path / "nav.parquet")]}
    dist = float(np.sum(np.linalg.norm(np.diff(df[list(col.POS)].to_numpy(), axis=0), axis=1)))
    met = write_parquet(sequence_metrics(nv, dist).reset_index(), {}, tmp_path / "m.parquet")
    fig = fg.figure8_figure(truth_path, nav, {"tactical": met})
    ax = fig.axes[0]
    assert "azimuthal equidistant" in ax.get_xlabel()
    assert any(a.get_gid() == "scale_bar" for a in ax.lines)
    x, y = (np.asarray(a, float) for a in (ax.lines[0].get_xdata(), ax.lines[0].get_ydata()))
    lat, lon = df[col.LAT].to_numpy(), df[col.LON].to_numpy()
    step = Geod(ellps="WGS84").inv(lon[:-1], lat[:-1], lon[1:], lat[1:])[2]
    assert np.hypot(np.diff(x), np.diff(y)).max() <= 1.01 * step.max()
    assert all(np.all(np.isfinite(np.asarray(a.get_xydata(), float))) for a in ax.lines)
