"""Truth motion: sign conventions, increment definitions, speed profile, fitting, stability.

Oracles: closed forms (still IMU, circle, climb), an independent fine quadrature of the rates
for the increments, the stated limits of the speed profile and of the fit.
"""

from __future__ import annotations

import numpy as np
import pytest

from imugen import truth
from imugen.core import earth as ea
from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.core.io import METADATA_KEY
from imugen.tables import truth as col

from helpers import SHARED_TRAJ

ORIGIN = (45.0, 7.0, 300.0)
SHARED = SHARED_TRAJ
PAPER = SHARED / "seed_reference_trajectory_enu.txt"


def _arr(tr, cols):
    return tr[list(cols)].to_numpy()


def _build(enu, t=None, **kw):
    df, meta = truth.enu_table(enu, t, ORIGIN)
    return truth.build_truth(df, meta, **kw)


def _mechanize_flat(tr, g0):
    """Reference flat mechanization of the increments (exact by definition)."""
    dt = np.diff(tr[col.TIME].to_numpy())
    q = _arr(tr, col.QUAT)
    v = _arr(tr, col.VEL)
    dth = _arr(tr, col.DTHETA)[1:]
    dv = _arr(tr, col.DV)[1:]
    C = rot.quat_to_dcm(q[:-1])
    q_next = rot.quat_mul(q[:-1], rot.exp_quat(dth))
    v_next = v[:-1] + np.einsum("kij,kj->ki", C, dv) + np.outer(dt, [0.0, 0.0, -g0])
    return q_next, v_next


def _sane(tr):
    a = tr.to_numpy()
    assert np.all(np.isfinite(a))
    q = _arr(tr, col.QUAT)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-14)


# ------------------------------------------------------------------------------------------
# sign conventions
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("earth", ["flat", "wgs84"])
def test_still_level_reads_plus_g_and_earth_rate(earth):
    tr, meta = _build(np.zeros((10, 3)), np.arange(10.0), rate_hz=10, earth=earth)
    lat0 = np.radians(ORIGIN[0])
    g0 = float(ea.normal_gravity(lat0, ORIGIN[2]))
    f = _arr(tr, col.ACCEL)
    # body axes = ENU at the origin; in wgs84 the normal plumb line leans north off the
    # ellipsoid (-8.14e-9 h sin 2 lat m/s^2), so a level IMU at h0 reads that too
    f_n = -ea.gravity_n(np.zeros(3), ea.OriginFrame.from_deg(*ORIGIN, model=earth))
    assert np.linalg.norm(f_n) == pytest.approx(g0, rel=1e-15)
    np.testing.assert_allclose(f, np.tile(f_n, (len(f), 1)), rtol=0, atol=1e-12)
    w = _arr(tr, col.GYRO)
    C = rot.quat_to_dcm(_arr(tr, col.QUAT))
    if earth == "flat":
        assert np.all(w == 0)
        expect_w = np.zeros(3)
    else:
        omega_n = ea.OMEGA_IE * np.array([0, np.cos(lat0), np.sin(lat0)])
        np.testing.assert_allclose(np.linalg.norm(w, axis=1), ea.OMEGA_IE, rtol=1e-12)
        expect_w = C[0].T @ omega_n
        np.testing.assert_allclose(w, np.tile(expect_w, (len(w), 1)), atol=1e-18)
    assert np.all(_arr(tr, col.VEL) == 0)
    # exact increments of a constant rate and a constant body force (closed form):
    # dtheta = w dt; dv = f dt + 1/2 w x f dt^2 + 1/6 w x (w x f) dt^3
    dt = 0.1
    fb = f_n
    dv = fb * dt + 0.5 * np.cross(expect_w, fb) * dt**2
    dv += np.cross(expect_w, np.cross(expect_w, fb)) * dt**3 / 6
    np.testing.assert_allclose(
        _arr(tr, col.DTHETA)[1:], np.tile(expect_w * dt, (9 * 10, 1)), atol=1e-19
    )
    np.testing.assert_allclose(_arr(tr, col.DV)[1:], np.tile(dv, (90, 1)), rtol=0, atol=1e-15)
    assert np.all(_arr(tr, col.DTHETA)[0] == 0) and np.all(_arr(tr, col.DV)[0] == 0)
    assert meta["fit"]["stops"] == [[0.0, 9.0]]


@pytest.mark.parametrize("suspension", ["rigid", "damped"])
@pytest.mark.parametrize("earth", ["flat", "wgs84"])
def test_left_turn_lateral_force_and_yaw_rate(earth, suspension):
    R, v = 50.0, 10.0
    w = v / R
    t = np.arange(0, 60, 0.1)
    enu = np.column_stack([R * np.sin(w * t), R * (1 - np.cos(w * t)), 0 * t])
    tr, _ = _build(enu, t, rate_hz=100, earth=earth, vehicle_params={"suspension": suspension})
    mid = ((tr[col.TIME] > 20) & (tr[col.TIME] < 40)).to_numpy()
    f = _arr(tr, col.ACCEL)[mid]
    g = _arr(tr, col.GYRO)[mid]
    roll = tr["roll_rad"].to_numpy()[mid]
    # rigid: level; on its suspension (damped) the body rolls outwards (right side
    # down, roll > 0) by the roll gradient x the lateral acceleration v w, settled by t = 20 s
    K = truth.VEHICLES["car"].roll_gradient_radpmps2 if suspension == "damped" else 0.0
    phi = K * v * w
    assert suspension == "rigid" or phi > np.radians(1.0)
    g0 = float(ea.normal_gravity(np.radians(ORIGIN[0]), ORIGIN[2]))
    # Coriolis (2 Omega v ~ 1e-3 m/s^2) and Earth rate (~5e-5 rad/s) only in wgs84
    tol_f, tol_w = (1e-6, 1e-7) if earth == "flat" else (2e-3, 1e-4)
    # the rolled body: f_y = v w cos(phi) + g sin(phi) (gravity leaks into the lateral axis),
    # f_z = g cos(phi) - v w sin(phi); the turn rate w splits onto z (cos) and y (sin)
    np.testing.assert_allclose(f[:, 1], v * w * np.cos(phi) + g0 * np.sin(phi), atol=tol_f)
    np.testing.assert_allclose(f[:, 2], g0 * np.cos(phi) - v * w * np.sin(phi), atol=tol_f)
    np.testing.assert_allclose(g[:, 2], w * np.cos(phi), atol=tol_w)
    np.testing.assert_allclose(g[:, 1], w * np.sin(phi), atol=tol_w)
    np.testing.assert_allclose(roll, phi, atol=1e-9 if earth == "flat" else 1e-6)
    # yaw increases (counter-clockwise seen from above = turning left)
    assert np.all(np.diff(tr["yaw_rad"].to_numpy()[mid]) > 0)


def test_climb_pitch_is_atan_grade():
    grade = 0.1
    gam = np.arctan(grade)
    t = np.arange(0, 30, 0.5)
    enu = np.column_stack([10 * t * np.cos(gam), 0 * t, 10 * t * np.sin(gam)])
    tr, _ = _build(enu, t, rate_hz=50, earth="flat")
    # pitch from the grade of the height-against-distance fit (its solve: ~1e-8)
    np.testing.assert_allclose(tr["pitch_rad"], gam, atol=1e-7)
    g0 = float(ea.normal_gravity(np.radians(ORIGIN[0]), ORIGIN[2]))
    f_expected = np.tile([g0 * np.sin(gam), 0, g0 * np.cos(gam)], (len(tr), 1))
    np.testing.assert_allclose(_arr(tr, col.ACCEL), f_expected, atol=1e-6)


# ------------------------------------------------------------------------------------------
# increments against an independent fine quadrature of the rates
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("earth", ["flat", "wgs84"])
def test_increments_match_fine_quadrature_of_rates(earth):
    # smooth 3-D aircraft motion (coordinated turns, climbs): all three rates non-zero
    t = np.arange(0, 40.01, 0.05)
    enu = np.column_stack(
        [
            60 * t + 300 * np.sin(t / 8),
            400 * np.sin(t / 10),
            50 * np.sin(t / 6) + 2 * t,
        ]
    )
    rate, fine_rate = 10.0, 4000.0
    coarse, _ = _build(enu, t, rate_hz=rate, earth=earth, vehicle="aircraft")
    fine, _ = _build(enu, t, rate_hz=fine_rate, earth=earth, vehicle="aircraft")
    q_c = _arr(coarse, col.QUAT)
    w_f = _arr(fine, col.GYRO)
    f_f = _arr(fine, col.ACCEL)
    m = int(fine_rate / rate)
    h = 1 / fine_rate
    sel = range(5, 395, 37)  # a spread of coarse intervals
    H = 2 * h

    def qd(qq, ww):
        return 0.5 * rot.quat_mul(qq, np.r_[0.0, ww])

    for k in sel:
        i0 = k * m
        # classical RK4 for q(t) = C_{b_k b(t)} (body relative to inertial space), step 2h,
        # rate nodes at the fine samples t, t + h, t + 2h
        q = np.array([1.0, 0, 0, 0])
        qs = [q]
        for s in range(m // 2):
            a, b, c = w_f[i0 + 2 * s], w_f[i0 + 2 * s + 1], w_f[i0 + 2 * s + 2]
            k1 = qd(q, a)
            k2 = qd(q + 0.5 * H * k1, b)
            k3 = qd(q + 0.5 * H * k2, b)
            k4 = qd(q + H * k3, c)
            q = q + H / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            q = q / np.linalg.norm(q)
            qs.append(q)
        dtheta_ref = rot.log_quat(q)
        dtheta = _arr(coarse, col.DTHETA)[k + 1]
        scale = np.linalg.norm(dtheta)
        assert np.linalg.norm(dtheta - dtheta_ref) < 1e-10 * scale, (k, dtheta, dtheta_ref)
        # dv: composite Simpson (spacing 2h) of C_{b_k b} f_b
        Cs = rot.quat_to_dcm(np.array(qs))
        integrand = np.einsum("kij,kj->ki", Cs, f_f[i0 : i0 + m + 1 : 2])
        wts = np.ones(len(qs))
        wts[1:-1:2] = 4
        wts[2:-1:2] = 2
        dv_ref = H / 3 * (wts @ integrand)
        dv = _arr(coarse, col.DV)[k + 1]
        assert np.linalg.norm(dv - dv_ref) < 1e-10 * np.linalg.norm(dv), (k, dv, dv_ref)
        # the coarse attitude is the fine attitude at the same time
        np.testing.assert_allclose(q_c[k], _arr(fine, col.QUAT)[i0], atol=1e-13)


def test_flat_increments_reconstruct_the_next_sample():
    t = np.arange(0, 30, 0.2)
    enu = np.column_stack([8 * t, 30 * np.sin(t / 5), 0.5 * t])
    tr, _meta = _build(enu, t, rate_hz=50, earth="flat")
    g0 = float(ea.normal_gravity(np.radians(ORIGIN[0]), ORIGIN[2]))
    q_next, v_next = _mechanize_flat(tr, g0)
    q = _arr(tr, col.QUAT)[1:]
    dots = np.abs(np.einsum("ki,ki->k", q, q_next))
    assert np.all(1 - dots < 1e-15)
    np.testing.assert_allclose(v_next, _arr(tr, col.VEL)[1:], atol=1e-13)


# ------------------------------------------------------------------------------------------
# speed profile of untimed paths
# ------------------------------------------------------------------------------------------
POLY = np.array(
    [
        [0, 0, 0],
        [300, 0, 0],
        [300, 200, 4],
        [0, 200, 0],
        [0, 60, 0],
        [150, 60, 0],
        [150, 70, 0],
        [20, 70, 0],
    ],
    float,
)  # right angles and a 10 m hairpin


@pytest.mark.parametrize("vehicle", ["car", "pedestrian", "aircraft"])
def test_speed_profile_limits(vehicle):
    vp = truth.VEHICLES[vehicle]
    scale = {"car": 1.0, "pedestrian": 0.1, "aircraft": 30.0}[vehicle]
    G, L, rep = truth.fit_path(POLY * scale, vp)
    s_pp, _prof = truth.speed_profile(
        G,
        L,
        cruise_mps=vp.cruise_mps,
        accel_mps2=vp.accel_mps2,
        lat_accel_mps2=vp.lat_accel_mps2,
        jerk_mps3=vp.jerk_mps3,
    )
    T = s_pp.x[-1]
    tt = np.linspace(0, T, 200_001)
    s = s_pp(tt)
    v, a, j = (s_pp.derivative(n)(tt) for n in (1, 2, 3))
    assert abs(s[0]) < 1e-12 and abs(s[-1] - L) < 1e-9 * L
    assert abs(v[0]) < 1e-12 and abs(v[-1]) < 1e-9 * vp.cruise_mps
    assert abs(a[0]) < 1e-12 and abs(a[-1]) < 1e-9
    assert v.min() > -1e-9 * vp.cruise_mps
    tol = 1e-5  # the distance rescaling (documented) moves limits by < 1e-5 relative
    assert v.max() <= vp.cruise_mps * (1 + tol)
    assert np.abs(a).max() <= vp.accel_mps2 * (1 + tol)
    assert np.abs(j).max() <= vp.jerk_mps3 * (1 + tol)
    lat = truth.profile.curvature(G, np.clip(s, 0, L)) * v**2
    assert lat.max() <= vp.lat_accel_mps2 * 1.01 + 1e-9
    # plausible total time: no faster than cruising all along, no slower than a few times
    assert L / vp.cruise_mps < T < 4 * L / vp.cruise_mps + 60
    # corner rounding: the path stays within a few corner lengths of the polyline vertices
    assert rep["max_distance_m"] < 0.6 * vp.corner_m


@pytest.mark.parametrize("suspension", ["rigid", "damped"])
def test_untimed_truth_starts_and_ends_at_rest(suspension):
    vp = truth.VEHICLES["car"]
    tr, meta = _build(
        POLY, None, rate_hz=100, earth="flat", vehicle_params={"suspension": suspension}
    )
    _sane(tr)
    v = np.linalg.norm(_arr(tr, col.VEL), axis=1)
    assert v[0] < 1e-12 and v[-1] < 1e-3
    assert meta["timing"]["timed"] is False
    assert v.max() <= vp.cruise_mps * (1 + 1e-5)
    # heading along the first leg (East) at the start
    assert abs(tr["yaw_rad"].iloc[0]) < 1e-3
    roll = tr["roll_rad"].to_numpy()
    if suspension == "rigid":  # roll zero throughout
        np.testing.assert_allclose(roll, 0, atol=1e-12)
    else:
        # on its suspension: no roll at rest (start) nor after the straight last leg (end);
        # in the corners the roll gradient x at most the cornering acceleration of the speed
        # profile (lat_accel_mps2), with the step response's overshoot
        z = vp.roll_damping
        peak = (
            vp.roll_gradient_radpmps2
            * vp.lat_accel_mps2
            * (1 + np.exp(-np.pi * z / np.sqrt(1 - z * z)))
        )
        assert abs(roll[0]) < 1e-15 and abs(roll[-1]) < 1e-9
        assert np.radians(0.5) < np.abs(roll).max() <= peak


def test_right_angle_corner_radius_is_corner_length():
    vp = truth.VEHICLES["car"]
    G, L, _ = truth.fit_path(np.array([[0, 0, 0], [300, 0, 0], [300, 300, 0.0]]), vp)
    k = truth.profile.curvature(G, np.linspace(0, L, 100_001))
    assert 0.8 * vp.corner_m < 1 / k.max() < 1.5 * vp.corner_m


# ------------------------------------------------------------------------------------------
# fitting timed routes
# ------------------------------------------------------------------------------------------
@pytest.mark.shared
@pytest.mark.skipif(not PAPER.exists(), reason="shared trajectories absent")
def test_paper_trajectory_fit_and_plausible_acceleration():
    y = np.loadtxt(PAPER)
    y = y - y[0]
    raw = np.diff(y[:, :2], 2, axis=0)
    raw_rms = np.sqrt(np.mean(np.sum(raw**2, axis=1)))
    assert 0.9 < raw_rms < 1.3  # the jitter the issue describes
    tr, meta = _build(y, np.arange(len(y), dtype=float), rate_hz=100, earth="flat")
    _sane(tr)
    fit = meta["fit"]
    target = np.linalg.norm(fit["target_rms_m"][:2])
    assert fit["rms_horizontal_distance_m"] <= 1.05 * target <= truth.VEHICLES["car"].fit_tol_max_m
    # the vertical is the road profile (heights against distance, smoothed over >= 50 m): it
    # leaves the heights' short wiggles, no more than the profile's own residual
    grade = fit["vertical"]["grade"]
    assert fit["rms_vertical_distance_m"] <= 1.02 * grade["rms_residual_m"] < 1.0
    assert fit["vertical"]["max_departure_m"] < 1e-2
    assert fit["max_distance_m"] < 6 * fit["rms_distance_m"]
    mot = meta["motion"]
    assert mot["accel_rms_mps2"] < 0.35 * raw_rms
    assert mot["accel_max_mps2"] < 3.0  # a car, not GPS jitter
    gyro = np.abs(_arr(tr, col.GYRO)).max()
    assert gyro < 1.0


def test_fit_tolerance_option_is_met():
    rng = np.random.default_rng(7)
    t = np.arange(0, 120, 1.0)
    clean = np.column_stack([5 * t, 40 * np.sin(t / 15), 0 * t])
    y = clean + rng.normal(scale=0.5, size=clean.shape)
    motion, rep = truth.fit_timed(t, y, truth.VEHICLES["car"], fit_tol_m=0.6)
    assert abs(rep["rms_distance_m"] - 0.6) < 0.01
    # the noise estimate recovers the simulated noise
    np.testing.assert_allclose(rep["noise_estimate_m"][:2], 0.5, rtol=0.3)
    # truth closer to the clean motion than the noisy points are
    err = np.linalg.norm(motion.position(t) - clean, axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.6 * np.sqrt(np.mean(np.sum((y - clean) ** 2, axis=1)))


# ------------------------------------------------------------------------------------------
# stability matrix
# ------------------------------------------------------------------------------------------
def _stop_route(t_stop0, t_stop1, t_end, speed=8.0):
    t = np.arange(0, t_end + 1e-9, 1.0)
    s = np.where(
        t < t_stop0,
        speed * t,
        np.where(t < t_stop1, speed * t_stop0, speed * (t - t_stop1 + t_stop0)),
    )
    enu = np.column_stack([s, 0.02 * s**1.2, 0 * s])
    return t, enu


def test_stationary_start_and_long_stop_are_real_stops():
    rng = np.random.default_rng(3)
    t, enu = _stop_route(60, 180, 260)
    # stationary start: hold the first 20 s
    enu[t < 20] = enu[t == 20]
    enu = enu + rng.normal(scale=0.2, size=enu.shape) * [1, 1, 0.3]
    tr, meta = _build(enu, t, rate_hz=50, earth="flat", vehicle_params={"suspension": "damped"})
    _sane(tr)
    stops = meta["fit"]["stops"]
    assert any(a <= 1 and b >= 18 for a, b in stops), stops
    assert any(a <= 65 and b >= 175 for a, b in stops), stops
    tt = tr[col.TIME].to_numpy()
    v = np.linalg.norm(_arr(tr, col.VEL), axis=1)
    g = np.abs(_arr(tr, col.GYRO)).max(axis=1)
    q = _arr(tr, col.QUAT)
    # the car on its suspension stops dead, but its body still rocks on the
    # suspension, decaying at the slowest mode's rate zeta w_n (pitch: 0.4 x 2 pi 1.2 Hz,
    # 3.0 /s): within 10x that envelope, and still to 1e-12 after ln(1e12) / sigma (9.2 s)
    vp = truth.VEHICLES["car"]
    sigma = 2 * np.pi * min(vp.roll_hz * vp.roll_damping, vp.pitch_hz * vp.pitch_damping)
    settle = np.log(1e12) / sigma
    rocked = 0
    for a, b in stops:
        inside = (tt > a) & (tt < b)
        assert v[inside].max() < 1e-9
        g0 = g[inside].max()
        rocked += g0 > 1e-6
        assert np.all(g[inside] <= 10.0 * g0 * np.exp(-sigma * (tt[inside] - a)) + 1e-15)
        still = inside & (tt > a + settle)
        assert g[still].max() < 1e-12
        assert np.abs(q[still] - q[still][0]).max() < 1e-12
    assert rocked == 1  # the stop after braking, not the stationary start
    assert np.abs(_arr(tr, col.GYRO)).max() < 1.0
    # a rigid car stands still from the first instant of each stop
    tr, meta = _build(enu, t, rate_hz=50, earth="flat", vehicle_params={"suspension": "rigid"})
    tt = tr[col.TIME].to_numpy()
    g = np.abs(_arr(tr, col.GYRO)).max(axis=1)
    q = _arr(tr, col.QUAT)
    for a, b in meta["fit"]["stops"]:
        inside = (tt > a) & (tt < b)
        assert g[inside].max() < 1e-12
        assert np.abs(q[inside] - q[inside][0]).max() < 1e-12


def test_hairpin_and_polyline_corners_untimed():
    hairpin = np.array([[0, 0, 0], [200, 0, 0], [200, 8, 0], [0, 8, 0]], float)
    tr, _meta = _build(hairpin, None, rate_hz=100, earth="wgs84")
    _sane(tr)
    yaw = tr["yaw_rad"].to_numpy()
    assert abs(abs(yaw[-1] - yaw[0]) - np.pi) < 0.05  # turned around, unwrapped
    # legs 8 m apart: a bulb taken at the lateral limit; the body rolls outward on its
    # suspension, and its y axis then reads that share of gravity too
    lat = np.abs(_arr(tr, col.ACCEL)[:, 1]).max()
    roll = np.abs(tr["roll_rad"].to_numpy()).max()
    assert lat < truth.VEHICLES["car"].lat_accel_mps2 * 1.05 + 9.81 * np.sin(roll)


def test_sparse_points_ten_seconds_apart():
    t = np.arange(0, 301, 10.0)
    w = 0.05
    enu = np.column_stack([200 * np.sin(w * t), 200 * (1 - np.cos(w * t)), 0 * t])
    tr, meta = _build(enu, t, rate_hz=100, earth="flat")
    _sane(tr)
    assert meta["fit"]["rms_distance_m"] <= 1.05 * truth.VEHICLES["car"].fit_tol_max_m
    mid = ((tr[col.TIME] > 50) & (tr[col.TIME] < 250)).to_numpy()
    np.testing.assert_allclose(_arr(tr, col.GYRO)[mid, 2], w, rtol=0.05)


def test_dense_jittery_points():
    rng = np.random.default_rng(11)
    t = np.arange(0, 60, 0.05)
    enu = np.column_stack([10 * t, 20 * np.sin(t / 6), 0 * t]) + rng.normal(
        scale=1.0, size=(len(t), 3)
    )
    tr, meta = _build(enu, t, rate_hz=100, earth="flat")
    _sane(tr)
    # the motion itself has 0.4 m/s^2 RMS; 1 m noise at 20 Hz must not become 10s of m/s^2
    assert meta["motion"]["accel_rms_mps2"] < 2.0
    assert meta["fit"]["rms_distance_m"] <= 1.05 * truth.VEHICLES["car"].fit_tol_max_m


@pytest.mark.parametrize(
    ("vehicle", "speed"),
    [("car", 0.1), ("pedestrian", 0.1), ("bicycle", 1.0), ("aircraft", 300.0)],
)
def test_very_slow_and_very_fast(vehicle, speed):
    t = np.arange(0, 120, 1.0)
    R = 40 * speed
    w = speed / R
    enu = np.column_stack([R * np.sin(w * t), R * (1 - np.cos(w * t)), 0.01 * speed * t])
    tr, meta = _build(enu, t, rate_hz=100, earth="wgs84", vehicle=vehicle)
    _sane(tr)
    v = np.linalg.norm(_arr(tr, col.VEL), axis=1)
    mid = slice(len(v) // 4, 3 * len(v) // 4)
    np.testing.assert_allclose(v[mid], speed * np.hypot(1, 0.01), rtol=0.01)
    assert meta["fit"]["stops"] == []
    yaw_rate = np.gradient(tr["yaw_rad"].to_numpy(), tr[col.TIME])
    gyro = np.linalg.norm(_arr(tr, col.GYRO), axis=1)
    if vehicle == "car":
        # a 4 m circle is tighter than a car turns (5 m): no turning on the spot, the heading
        # turns at speed x max curvature
        k = truth.VEHICLES["car"].max_curvature_1pm
        np.testing.assert_allclose(yaw_rate[mid], k * speed, rtol=0.01)
        return
    # turn rate: yaw rate of the unwrapped yaw (the aircraft banks, so not gyro z alone)
    np.testing.assert_allclose(yaw_rate[mid], w, rtol=0.05)
    np.testing.assert_allclose(gyro[mid], w, rtol=0.05, atol=1e-4)
    roll = tr["roll_rad"].to_numpy()[mid]
    if vehicle in ("aircraft", "bicycle"):  # coordinated turn: bank = atan(v w / g)
        bank = np.arctan(speed * w / 9.8)
        np.testing.assert_allclose(np.abs(roll), bank, rtol=0.02)
        lateral = _arr(tr, col.ACCEL)[mid, 1]
        np.testing.assert_allclose(lateral, 0, atol=1e-6 if vehicle == "aircraft" else 2e-4)
    else:
        np.testing.assert_allclose(roll, 0, atol=1e-9)


def _loop_route(V=100.0, R=500.0, vertical=False):
    w = V / R
    t_loop = (np.pi / 2 if vertical else 2 * np.pi) / w
    t = np.arange(-20, t_loop + 15, 0.1)
    th = np.clip(w * t, 0, w * t_loop)
    e = np.where(
        t < 0,
        V * t,
        R * np.sin(th) + np.where(t > t_loop, V * (t - t_loop), 0) * (0 if vertical else 1),
    )
    u = R * (1 - np.cos(th)) + (np.where(t > t_loop, V * (t - t_loop), 0) if vertical else 0)
    return t - t[0], np.column_stack([e, 0 * t, u])


@pytest.mark.parametrize("vertical", [False, True])
def test_aircraft_loop_and_vertical_climb(vertical):
    t, enu = _loop_route(vertical=vertical)
    tr, meta = _build(enu, t, rate_hz=100, earth="wgs84", vehicle="aircraft")
    _sane(tr)
    pitch = tr["pitch_rad"].to_numpy()
    assert pitch.max() > np.radians(89.9)
    # the pull-up is a 0.2 rad/s pitch rate; nothing else spins
    w = _arr(tr, col.GYRO)
    assert np.abs(w).max() < 0.25
    np.testing.assert_allclose(np.abs(w[:, 1]).max(), 0.2, rtol=0.08)
    if not vertical:
        # coordinated: no lateral specific force; body z carries the centripetal load
        np.testing.assert_allclose(_arr(tr, col.ACCEL)[:, 1], 0, atol=1e-9)
        q = _arr(tr, col.QUAT)
        up_body_z = rot.quat_to_dcm(q)[:, 2, 2]
        assert up_body_z.min() < -0.99  # inverted at the top
    assert meta["motion"]["max_blend_angle_rad"] < 0.01


def test_errors_are_input_errors():
    with pytest.raises(InputError):
        _build(np.zeros((2, 3)), np.arange(2.0))
    with pytest.raises(InputError):
        _build(np.zeros((4, 3)), np.array([0.0, 1.0, 1.0, 2.0]))
    with pytest.raises(InputError):
        _build(np.zeros((4, 3)), None)
    with pytest.raises(InputError):
        _build(POLY, None, vehicle="boat")
    with pytest.raises(InputError):
        _build(POLY, None, rate_hz=0)


def test_run_writes_parquet_atomically(tmp_path):
    import pyarrow.parquet as pq

    from imugen.tables import enu as tenu

    y = POLY.copy()
    y[6:, 1] += 10.0  # legs 20 m apart at the hairpin: a bend a car takes (10 m: refused)
    df, meta = truth.enu_table(y, None, ORIGIN)
    enu_path = tmp_path / "enu.parquet"
    tenu.write(df, meta, enu_path)
    out = tmp_path / "sub" / "truth.parquet"
    m = truth.run(enu_path, out, truth.TruthOptions(rate_hz=20, earth="auto", vehicle="car"))
    tbl = pq.read_table(out)
    assert tbl.column_names == list(col.COLUMNS)
    import json

    md = json.loads(tbl.schema.metadata[METADATA_KEY])
    assert md["earth"] in ("flat", "wgs84") and md["earth_budget"]["lines"]
    assert md["rate_hz"] == 20 and md["vehicle"] == "car" and m["source"] == str(enu_path)
    assert [p.name for p in out.parent.iterdir()] == ["truth.parquet"]


def test_auto_budget_takes_custom_grades(tmp_path):
    """A custom grade (FILE.yaml:NAME, Grade or figures) decides `--earth auto` like a preset:
    a navigation-grade custom part needs wgs84 on a route where consumer is flat."""
    from imugen.core.earth import GradeFigures
    from imugen.sensors import grades

    f = tmp_path / "g.yaml"
    f.write_text(
        "grades:\n"
        "  nav_mine:\n"
        "    id: 1201\n"
        "    gyro:\n"
        "      turn_on_bias: {value: 0.003, unit: deg_per_h, kind: one_sigma, source: test}\n"
        "    accel:\n"
        "      turn_on_bias: {value: 0.01, unit: mg, kind: one_sigma, source: test}\n"
    )
    t = np.arange(0, 601, 1.0)
    enu = np.column_stack([15 * t, 0 * t, 0 * t])
    kw = {"rate_hz": 1, "earth": "auto", "verbose": False}
    _, m_cons = _build(enu, t, grade="consumer", **kw)
    assert m_cons["earth"] == "flat"
    spec = f"{f}:nav_mine"
    for g in (spec, grades.get_grade(spec), truth.budget.grade_figures(spec)):
        _, m = _build(enu, t, grade=g, **kw)
        assert m["earth"] == "wgs84", m["earth_budget"]["lines"]
        assert m["earth_budget"]["grade"] == "nav_mine"
        assert m["earth_budget"]["grades_considered"] == [g if isinstance(g, str) else "nav_mine"]
    # the most demanding of several decides; figures with no error at all never pick flat
    _, m = _build(enu, t, grade=["consumer", spec], **kw)
    assert m["earth"] == "wgs84" and m["earth_budget"]["grade"] == "nav_mine"
    _, m = _build(enu, t, grade=GradeFigures(name="perfect"), **kw)
    assert m["earth"] == "wgs84"
