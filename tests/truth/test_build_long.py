"""The truth builder on routes of any length (``geodetic``: ECEF navigation coordinates).

Oracles: the truth built from 1 Hz points of an analytic route must be that route (positions
and velocities against the closed form); its ideal increments mechanized back close to <= 1e-6 m;
its rate columns converge at order 2; its attitude is level relative to the LOCAL vertical on a
level road however far from the origin; its plausibility report holds. Stand-ins of issue 11's
scenes (a 264 km road, a 429 km flight to 6.8 km at 770 km/h, a 7,600 km airliner route across
the antimeridian) are windows of analytic routes whose origin is the route's start, so the
window lies hundreds to thousands of kilometres from it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen import truth
from imugen.closure import closure_of_truth
from imugen.core import earth as E
from imugen.navigate import mechanize as M
from imugen.tables import truth as col


class Route:
    """Vehicle on a circle of directions ``u(s) = cos th0 n + sin th0 (cos s a + sin s b)``,
    ``s = D(t) / (R sin th0)``, at ellipsoidal height ``h(t)`` above the surface point whose
    geocentric direction is ``u`` (``th0 = pi/2``: a great circle; smaller: a left-turning
    small circle of radius ``R sin th0``). ECEF positions in closed form."""

    def __init__(self, lat_deg, lon_deg, heading_deg, theta0, dist, height):
        lat, lon, az = map(math.radians, (lat_deg, lon_deg, heading_deg))
        C = E.C_en_from_geodetic(lat, lon)
        u0 = E.ecef_from_geodetic(lat, lon, 0.0)
        u0 = u0 / np.linalg.norm(u0)
        t0 = math.sin(az) * C[0] + math.cos(az) * C[1]
        t0 = t0 - u0 * (t0 @ u0)
        t0 /= np.linalg.norm(t0)
        l0 = np.cross(u0, t0)
        self.n = math.cos(theta0) * u0 + math.sin(theta0) * l0
        self.a = math.sin(theta0) * u0 - math.cos(theta0) * l0
        self.b = t0
        self.th0 = theta0
        self.rs = E.R_MEAN * math.sin(theta0)
        self.dist, self.height = dist, height

    def position(self, t):
        t = np.asarray(t, dtype=float)
        s = self.dist(t) / self.rs
        u = math.cos(self.th0) * self.n + math.sin(self.th0) * (
            np.cos(s)[:, None] * self.a + np.sin(s)[:, None] * self.b
        )
        # geodetic latitude of the surface point along u (well conditioned at the poles)
        lat = np.arctan2(u[:, 2], (1.0 - E.E2_WGS84) * np.hypot(u[:, 0], u[:, 1]))
        return E.ecef_from_geodetic(lat, np.arctan2(u[:, 1], u[:, 0]), self.height(t))

    def velocity(self, t, h=1e-3):
        """Central difference (error ~ h^2 |jerk| / 6: 1e-7 m/s)."""
        return (self.position(t + h) - self.position(t - h)) / (2.0 * h)


def road():
    # left-turning circle of 150 km radius, 25 +- 8 m/s, hills of +-50 m over 22.5 km
    w, wh = 2 * math.pi / 300, 2 * math.pi / 900
    return Route(
        45.05, 9.69, 110.0, math.asin(150e3 / E.R_MEAN),
        lambda t: 25.0 * t - 8.0 / w * (np.cos(w * t) - 1.0),
        lambda t: 100.0 + 50.0 * np.sin(wh * t),
    )  # fmt: skip


def level_road():
    """The same road at a constant ellipsoidal height: level everywhere."""
    w = 2 * math.pi / 300
    return Route(
        45.05, 9.69, 110.0, math.asin(150e3 / E.R_MEAN),
        lambda t: 25.0 * t - 8.0 / w * (np.cos(w * t) - 1.0),
        lambda t: np.full_like(t, 100.0),
    )  # fmt: skip


def _ramp(V, t1, tau):
    """Distance of a speed ramp V/2 (1 + tanh((t - t1)/tau)) from rest."""

    def D(t):
        x = (t - t1) / tau
        lc = np.abs(x) + np.log1p(np.exp(-2.0 * np.abs(x))) - math.log(2.0)
        x0 = -t1 / tau
        lc0 = abs(x0) + math.log1p(math.exp(-2.0 * abs(x0))) - math.log(2.0)
        return 0.5 * V * ((t + tau * lc) - tau * lc0)

    return D


def flight():
    # 770 km/h, climbing from 200 m to 6,800 m (top of climb at ~700 s); 429 km take ~2,000 s
    return Route(
        45.63, 8.72, 95.0, math.pi / 2, _ramp(770 / 3.6, 150.0, 40.0),
        lambda t: 200.0 + 3300.0 * (1.0 + np.tanh((t - 400.0) / 150.0)),
    )  # fmt: skip


def airliner():
    # Tokyo north-east over the Pacific at 250 m/s, 11 km: 7,600 km cross 180 deg at ~14,450 s
    return Route(
        35.55, 139.78, 55.0, math.pi / 2, _ramp(250.0, 200.0, 50.0),
        lambda t: 10.0 + 5495.0 * (1.0 + np.tanh((t - 900.0) / 300.0)),
    )  # fmt: skip


def polar():
    # north over the North Pole at 250 m/s, 9 km: passes within metres of it at ~2,350 s
    return Route(
        85.05, 30.0, 0.0, math.pi / 2, _ramp(250.0, 150.0, 60.0),
        lambda t: 10.0 + 4500.0 * (1.0 + np.tanh((t - 300.0) / 100.0)),
    )  # fmt: skip


# stand-in, vehicle, window of input times (s): far from the origin (the route's start)
SCENES = {
    "road 264 km": (road, "car", 10_000.0),  # 250 km from the start
    "flight 429 km": (flight, "aircraft", 1_700.0),  # 330 km out, 6.8 km up
    "airliner 7,600 km": (airliner, "aircraft", 14_300.0),  # crossing 180 deg
    "polar 1,100 km": (polar, "aircraft", 2_200.0),  # over the North Pole
}
SPAN_S = 240.0


def enu_input(rt, t):
    """The route's points at times ``t`` as an ENU table with the origin at the route's start."""
    lat0, lon0, h0 = (float(x[0]) for x in E.geodetic_from_ecef(rt.position(np.array([0.0]))))
    origin = E.OriginFrame(lat0, lon0, h0, "wgs84")
    return truth.enu_table(
        origin.n_from_ecef(rt.position(t)), t, (math.degrees(lat0), math.degrees(lon0), h0)
    )


def build(name, rate_hz, earth="auto", span=SPAN_S):
    make, vehicle, t0 = SCENES[name]
    rt = make()
    enu, meta = enu_input(rt, t0 + np.arange(0.0, span + 1e-9, 1.0))
    df, tm = truth.build_truth(
        enu, meta, rate_hz=rate_hz, earth=earth, vehicle=vehicle, grade="tactical", verbose=False
    )
    return rt, df, tm


@pytest.fixture(scope="module")
def truths():
    return {name: build(name, 20.0) for name in SCENES}


@pytest.mark.parametrize("name", list(SCENES))
def test_truth_is_the_route_far_from_the_origin(truths, name):
    """``auto`` picks geodetic; the ECEF truth is the analytic motion (fit of exact 1 Hz points);
    the lat/lon/alt columns are its geodetic position; metadata names the frame."""
    rt, df, tm = truths[name]
    assert tm["earth"] == "geodetic" and tm["nav_frame"] == "ECEF"
    t = df[col.TIME].to_numpy()
    r = df[list(col.POS)].to_numpy()
    v = df[list(col.VEL)].to_numpy()
    inner = (t > t[0] + 10.0) & (t < t[-1] - 10.0)  # away from the spline's free ends
    assert np.max(np.linalg.norm(r - rt.position(t), axis=1)[inner]) < 1e-3
    assert np.max(np.linalg.norm(v - rt.velocity(t), axis=1)[inner]) < 1e-3
    lat, lon, h = E.geodetic_from_ecef(r)
    g = df[list(col.GEODETIC)].to_numpy()
    assert np.allclose(g[:, 0], np.degrees(lat), atol=1e-12)
    assert np.allclose(g[:, 1], np.degrees(lon), atol=1e-12)
    assert np.allclose(g[:, 2], h, atol=1e-6)
    far = np.linalg.norm(r[0] - E.ecef_from_geodetic(*np.radians([tm["origin"][k] for k in ("lat_deg", "lon_deg")]), tm["origin"]["alt_m"]))  # fmt: skip
    assert far > 200e3
    if name.startswith("airliner"):
        assert g[:, 1].max() > 179.9 and g[:, 1].min() < -179.9  # across the antimeridian
        assert far > 3000e3  # 3,580 km flown
    if name.startswith("polar"):
        assert g[:, 0].max() > 89.9999  # within 11 m of the pole
        # yaw relative to the local North turns by 180 deg as the pole is passed
        yaw = df["yaw_rad"].to_numpy()
        assert abs(abs(yaw[-1] - yaw[0]) - math.pi) < 1e-3
    assert tm["units"]["lat_deg"] == "deg"


@pytest.mark.parametrize("name", list(SCENES))
def test_zero_error_closure_far_from_the_origin(truths, name):
    _, df, tm = truths[name]
    res = closure_of_truth(df, tm)
    print(f"{name}: max closure {res['max_position_error_m']:.2e} m, attitude "
          f"{res['max_attitude_error_rad']:.1e} rad")  # fmt: skip
    assert res["max_position_error_m"] <= 1e-6
    assert res["max_attitude_error_rad"] <= 1e-9


@pytest.mark.parametrize("name", list(SCENES))
def test_rate_columns_converge_second_order(name):
    """The truth's instantaneous gyro/accel columns, mechanized with the 2nd-order rate scheme
    at 5, 10, 20 Hz: the final error (East/North/Up at the true position) falls 4x per halving.
    The car rocks on its suspension at 1.2-1.5 Hz, which 5 Hz does not resolve (order 2.4
    there): 10, 20, 40 Hz for it."""
    errs = []
    rates = (10.0, 20.0, 40.0) if SCENES[name][1] == "car" else (5.0, 10.0, 20.0)
    for rate in rates:
        _, df, tm = build(name, rate, earth="geodetic", span=120.0)
        frame = col.origin_frame(tm)
        r = df[list(col.POS)].to_numpy()
        v = df[list(col.VEL)].to_numpy()
        q = df[list(col.QUAT)].to_numpy()
        w = df[list(col.GYRO)].to_numpy()
        f = df[list(col.ACCEL)].to_numpy()
        nav = M.mechanize_rates(w, f, 1.0 / rate, r[0], v[0], q[0], frame)
        errs.append(float(np.linalg.norm(E.errors_local_level(r[-1], nav.p_end_n, v[-1])[:3])))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print(name, "final errors", errs, "orders", orders)
    assert np.all(np.abs(orders - 2.0) < 0.3)


@pytest.mark.parametrize("name", list(SCENES))
def test_plausibility_holds(truths, name):
    _, _, tm = truths[name]
    rep = tm["plausibility"]
    assert rep["warnings"] == []
    assert rep["max_rate_increment_radps"] < 1e-6
    assert rep["length_ratio"] == pytest.approx(1.0, abs=1e-3)
    if name.startswith("road"):
        # a car on its suspension: the roll of its 150 km circle's lateral acceleration (at
        # most 33^2 / 150e3 m/s^2) x the roll gradient; yaw rate within speed x curvature
        # (horizontal speed at the vehicle)
        a_lat = 33.0**2 / 150e3
        K = truth.VEHICLES["car"].roll_gradient_radpmps2
        assert 0.5 * K * a_lat < math.radians(rep["max_abs_roll_deg"]) < 1.05 * K * a_lat
        assert rep["max_yaw_rate_excess_dps"] == 0.0
        assert rep["max_abs_pitch_deg"] < 1.0  # 50 m hills over 22.5 km: 0.8 deg


@pytest.mark.parametrize("suspension", ["rigid", "damped"])
def test_level_car_is_level_in_the_local_level_all_along(suspension):
    """A car on a level road (constant ellipsoidal height), the whole 264 km: roll and
    pitch relative to the LOCAL vertical stay ~0 everywhere (the origin's vertical tilts by
    2.4 deg at the far end), and the yaw is the local heading of the velocity (points 5 s apart,
    truth at 1 Hz). Rigid: the path's attitude exactly; on its suspension (the car's default)
    the body rolls by the roll gradient x v^2 / 150 km and pitches by the pitch gradient x
    dv/dt (25 +- 8 m/s over 300 s: quasi-static, the lag of a 1.2 Hz mode ~1e-6 rad)."""
    rt = level_road()
    T = 264e3 / 25.0
    enu, meta = enu_input(rt, np.arange(0.0, T + 1e-9, 5.0))
    df, tm = truth.build_truth(
        enu, meta, rate_hz=1.0, earth="auto", vehicle="car", verbose=False,
        vehicle_params={"suspension": suspension},
    )  # fmt: skip
    assert tm["earth"] == "geodetic"
    r = df[list(col.POS)].to_numpy()
    v = df[list(col.VEL)].to_numpy()
    _, _, h, v_l, _ = E.local_level(r, v)
    assert np.ptp(h) < 0.05  # the truth stays on the level road (within the fit floor)
    vh = np.hypot(v_l[:, 0], v_l[:, 1])
    vp = truth.VEHICLES["car"]
    phi_s, theta_s = np.zeros(len(df)), np.zeros(len(df))
    if suspension == "damped":
        w = 2 * math.pi / 300
        tt = df[col.TIME].to_numpy() - df[col.TIME].iloc[0]
        # the lateral acceleration of the path: v_h x its turn rate about the local vertical
        # (~v_h^2 / 150 km; the circle's radius on the ellipsoid varies by ~2 % along it)
        from imugen.core import rotations as rot
        from imugen.truth.report import turn_rate

        C_nb = rot.quat_to_dcm(df[list(col.QUAT)].to_numpy())
        yaw_rate = turn_rate(r, df[list(col.GYRO)].to_numpy(), C_nb, col.origin_frame(tm))
        phi_s = vp.roll_gradient_radpmps2 * vh * yaw_rate
        np.testing.assert_allclose(
            phi_s[20:-20], (vp.roll_gradient_radpmps2 * vh**2 / 150e3)[20:-20], rtol=0.03
        )
        theta_s = vp.pitch_gradient_radpmps2 * 8.0 * w * np.cos(w * tt)
    inner = slice(20, -20)  # away from the spline's free ends
    np.testing.assert_allclose(
        df["roll_rad"].to_numpy()[inner], phi_s[inner], rtol=0, atol=1e-12 + 0.01 * phi_s.max()
    )
    assert np.max(np.abs(df["roll_rad"] - phi_s)) < 1e-12 + 0.1 * phi_s.max()
    # pitch: that of the velocity in the local level (a car moves along body x); the fit's
    # height wiggle between fixes (< 5 cm, above) is all there is of it; on the suspension
    # plus the dive and squat theta_s
    pitch_v = np.arctan2(v_l[:, 2], vh)
    atol = 1e-9 if suspension == "rigid" else 5e-6
    np.testing.assert_allclose(
        df["pitch_rad"][inner], (pitch_v + theta_s)[inner], rtol=0, atol=atol
    )
    assert np.max(np.abs(df["pitch_rad"] - theta_s)) < 1e-3
    heading = np.arctan2(v_l[:, 1], v_l[:, 0])
    dyaw = np.angle(np.exp(1j * (df["yaw_rad"].to_numpy() - heading)))
    assert np.max(np.abs(dyaw[20:-20])) < 1e-4
    tilt = np.arccos(np.clip(r[-1] @ r[0] / np.linalg.norm(r[-1]) / np.linalg.norm(r[0]), -1, 1))
    assert tilt > math.radians(2.0)  # far: the origin's ENU is no local level there


def test_auto_picks_geodetic_by_distance_only():
    """``auto``: geodetic once the origin's vertical tilts by > 0.01 rad at the farthest point,
    for any grade; a short scene stays flat."""
    fig = E.GradeFigures("consumer", gyro_bias_radps=10 * E.DEG_PER_H, accel_bias_mps2=1e-2)
    t = np.linspace(0.0, 600.0, 601)
    for d_km, model in ((0.7, "flat"), (60.0, "wgs84"), (70.0, "geodetic"), (7600.0, "geodetic")):
        p = np.zeros((601, 3))
        p[:, 0] = np.linspace(0.0, d_km * 1e3, 601)
        b = E.choose_earth_model(t, p, 0.8, fig)
        assert b.model == model, (d_km, b.lines)


def test_truth_file_carries_the_frame(truths, tmp_path):
    """Written and read back: metadata names the frame, ``Truth.geodetic`` reads the columns (and
    converts the position of an origin-frame truth), ``origin_frame`` is the ECEF model."""
    _, df, tm = truths["road 264 km"]
    col.write(df, tm, tmp_path / "t.parquet")
    tr = col.read(tmp_path / "t.parquet")
    assert tr.meta["nav_frame"] == "ECEF" and tr.origin_frame().model == "geodetic"
    lat, lon, h = tr.geodetic()
    lat2, lon2, h2 = E.geodetic_from_ecef(tr.p_n)
    assert np.allclose(lat, lat2, atol=1e-12) and np.allclose(lon, lon2, atol=1e-12)
    assert np.allclose(h, h2, atol=1e-6)
    flat = col.Truth(df[list(col.COLUMNS)], {**tm, "earth": "wgs84", "nav_frame": "ECEF"})
    lat3 = flat.geodetic()[0]  # no columns: converted through the (here wrong) origin frame
    assert not np.allclose(lat3, lat, atol=1e-3)


def test_short_route_unchanged_in_origin_frames():
    """flat and wgs84 truths keep ENU of the origin and no geodetic columns."""
    t = np.arange(0.0, 60.0 + 1e-9, 1.0)
    enu = np.column_stack([10.0 * t, 2.0 * t, np.zeros_like(t)])
    df_in, meta = truth.enu_table(enu, t, (45.0, 9.0, 100.0))
    for model in ("flat", "wgs84"):
        df, tm = truth.build_truth(df_in, meta, rate_hz=10.0, earth=model, verbose=False)
        assert tm["nav_frame"] == "ENU of the origin"
        assert list(df.columns) == list(col.COLUMNS)
        assert np.allclose(df[list(col.POS)].to_numpy()[::10][5:-5], enu[5:-5], atol=1e-6)


def test_whole_flight_from_a_gpx_file(tmp_path):
    """Route file -> ingest -> truth -> mechanization (``imugen closure``): a 417 km flight at
    770 km/h climbing to 6.8 km, logged at 1 Hz, whole 35 min unaided at 20 Hz: <= 1e-6 m."""
    from datetime import UTC, datetime, timedelta

    from pyproj import Geod

    from imugen.closure import closure

    t = np.arange(0.0, 2100.0, 1.0)
    lon, lat, _ = Geod(ellps="WGS84").fwd(
        np.full_like(t, 8.72),
        np.full_like(t, 45.63),
        np.full_like(t, 95.0),
        _ramp(770 / 3.6, 150.0, 40.0)(t),
    )
    h = 200.0 + 3300.0 * (1.0 + np.tanh((t - 400.0) / 150.0))
    t0 = datetime(2024, 5, 1, 10, 0, 0, tzinfo=UTC)
    stamp = [(t0 + timedelta(seconds=float(s))).isoformat().replace("+00:00", "Z") for s in t]
    pts = "".join(
        f'<trkpt lat="{a:.9f}" lon="{o:.9f}"><ele>{e:.3f}</ele><time>{s}</time></trkpt>'
        for a, o, e, s in zip(lat, lon, h, stamp, strict=True)
    )
    src = tmp_path / "flight.gpx"
    src.write_text(f"<gpx><trk><trkseg>{pts}</trkseg></trk></gpx>")
    res = closure(src, rate_hz=20.0, earth="auto", vehicle="aircraft", grade="tactical")
    print(f"whole flight from GPX: final {res['final_position_error_m']:.1e} m, max "
          f"{res['max_position_error_m']:.1e} m, attitude {res['max_attitude_error_rad']:.1e} rad")  # fmt: skip
    assert res["earth"] == "geodetic"
    assert res["max_position_error_m"] <= 1e-6
    assert res["max_attitude_error_rad"] <= 1e-9


def test_geodetic_and_wgs84_truths_are_one_motion_near_the_origin():
    """On a 3 km drive both models describe one physical motion: identical ECEF positions and
    velocities; attitude, body-frame gyro and accelerometer columns agree but for the distance
    travelled, measured in the origin's level (wgs84) or the local one (geodetic): they differ by
    ``v_up d / R`` (0.35 m/s x 4.7e-4 over 120 s: 2 cm), turning heading and grade by at most
    2 cm x (1/150 km) ~ 1.3e-7 rad."""
    from imugen.core.rotations import quat_to_dcm

    rt = road()
    enu, meta = enu_input(rt, np.arange(0.0, 120.0 + 1e-9, 1.0))
    out = {}
    for model in ("wgs84", "geodetic"):
        df, tm = truth.build_truth(enu, meta, rate_hz=10.0, earth=model, verbose=False)
        fr = col.origin_frame(tm)
        C_en = fr.C_en
        out[model] = (
            fr.ecef_from_n(df[list(col.POS)].to_numpy()),
            df[list(col.VEL)].to_numpy() @ C_en,
            C_en.T @ quat_to_dcm(df[list(col.QUAT)].to_numpy()),
            df[list(col.EULER)].to_numpy(),
            df[list(col.GYRO)].to_numpy(),
            df[list(col.ACCEL)].to_numpy(),
        )
    diff = [
        float(np.max(np.abs(a - b))) for a, b in zip(out["wgs84"], out["geodetic"], strict=True)
    ]
    assert diff[0] < 1e-8 and diff[1] < 1e-10  # the same motion
    assert diff[2] < 2e-7 and diff[3] < 2e-7  # C_eb, Euler angles [rad]
    assert diff[4] < 1e-8 and diff[5] < 9.81 * 2e-7  # gyro [rad/s], accel (g x attitude)
