"""Ground vehicles move along body x: the non-holonomic constraint of a car in its truth.

Oracles: the body-frame velocity ``C_nb^T v_n`` has no y and no z component wherever the path
is plausible for the vehicle (closed form: zero), the gyro columns against an independent
4th-order quadrature of the increments, and the plausibility report's own slip figures against
a re-derivation from the table; on the paper trajectory and the shared car tracks, the
departures are confined to the places where the fitted path itself is beyond the vehicle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen import truth
from imugen.core import rotations as rot
from imugen.tables import truth as col
from imugen.truth.report import _integral

from helpers import SHARED_TRAJ

ORIGIN = (31.63, -7.99, 480.6)
RIGID = {"suspension": "rigid"}  # the path's own attitude: the constraint of the path
SHARED = SHARED_TRAJ if SHARED_TRAJ.is_dir() else None


def _arr(tr, cols):
    return tr[list(cols)].to_numpy()


def _body_velocity(tr):
    return np.einsum("kji,kj->ki", rot.quat_to_dcm(_arr(tr, col.QUAT)), _arr(tr, col.VEL))


def _road(T=240.0, v=10.0):
    """An S-curved road (curvature <= 0.05 /m, car limit 0.2) over hills (grade <= 8 %,
    vertical curvature <= 0.0008 /m), driven at a constant 10 m/s, 1 Hz fixes, no noise."""
    t = np.arange(0.0, T + 0.5, 1.0)
    x = v * t
    return t, np.column_stack(
        [x, 80.0 * np.sin(x / 40.0), 12.0 * np.sin(x / 150.0) + 4.0 * np.cos(x / 90.0)]
    )


def _suspension_pitch(tr, vp):
    """Pitch on the suspension re-derived from the table: the damped second-order response
    (:class:`imugen.truth.suspension.Response`) to ``K_pitch dv_h/dt`` of the truth's own
    velocity (finite differences), from rest."""
    from imugen.truth.suspension import Response

    tt = tr[col.TIME].to_numpy()
    v = _arr(tr, col.VEL)
    if col.LAT in tr:  # geodetic: velocity in ECEF, up from the geodetic latitude, longitude
        lat, lon = np.radians(tr[col.LAT].to_numpy()), np.radians(tr[col.LON].to_numpy())
        up = np.column_stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
        v_up = np.einsum("ki,ki->k", v, up)
        v_h = np.sqrt(np.maximum(np.einsum("ki,ki->k", v, v) - v_up**2, 0.0))
    else:
        v_h = np.hypot(v[:, 0], v[:, 1])
    a_lon = np.gradient(v_h, tt)
    return Response(tt, vp.pitch_gradient_radpmps2 * a_lon, vp.pitch_hz, vp.pitch_damping)(tt)[0]


@pytest.mark.parametrize("suspension", ["rigid", "damped"])
@pytest.mark.parametrize("earth", ["flat", "wgs84", "geodetic"])
def test_smooth_road_body_velocity_is_along_x(earth, suspension):
    """Rigid: the body velocity is along x exactly. Damped: the
    suspension only rotates the body, so no y either, and z is the dive and squat of the
    body, ``-|v| sin theta_s`` with ``theta_s`` the second-order response to ``dv_h/dt``."""
    t, enu = _road()
    df, meta = truth.enu_table(enu, t, ORIGIN)
    tr, meta = truth.build_truth(
        df, meta, rate_hz=50, earth=earth, vehicle="car", verbose=False,
        vehicle_params={"suspension": suspension},
    )  # fmt: skip
    vb = _body_velocity(tr)
    assert np.abs(vb[:, 1]).max() < 1e-6
    if suspension == "damped":
        speed = np.linalg.norm(_arr(tr, col.VEL), axis=1)
        vz = -speed * np.sin(_suspension_pitch(tr, truth.VEHICLES["car"]))
        assert np.abs(vz).max() > 1e-3  # the road's speed changes pitch the body
        assert np.abs(vb[:, 2] - vz).max() < 0.02 * np.abs(vz).max(), np.abs(vb[:, 2] - vz).max()
        rep = meta["plausibility"]
        assert rep["warnings"] == []
        assert rep["max_body_vertical_speed_mps"] == pytest.approx(
            np.abs(vb[:, 2]).max(), abs=1e-12
        )
        roll = tr["roll_rad"].to_numpy()
        assert 0.0 < np.abs(roll).max() <= truth.VEHICLES["car"].max_roll_rad
        return
    assert np.abs(vb[:, 2]).max() < 1e-6
    assert vb[:, 0].min() > 9.0
    rep = meta["plausibility"]
    assert rep["warnings"] == []
    assert rep["slip_fraction"] == 0.0
    assert rep["max_sideslip_deg"] < 1e-5 and rep["max_vertical_slip_deg"] < 1e-5
    assert rep["rms_body_lateral_speed_mps"] < 1e-6
    assert rep["max_body_vertical_speed_mps"] == pytest.approx(np.abs(vb[:, 2]).max(), abs=1e-12)
    # the attitude really turns and pitches with the road, and the gyro is its exact rate
    assert np.ptp(tr["pitch_rad"]) > 0.1 and np.ptp(tr["yaw_rad"]) > 2.0
    tt = tr[col.TIME].to_numpy()
    i4, _ = _integral(_arr(tr, col.GYRO), np.diff(tt))
    err = np.linalg.norm(_arr(tr, col.DTHETA)[1:] - i4, axis=1) / np.diff(tt)
    assert err[1:-1].max() < 1e-6


def test_over_tight_turn_is_refitted_within_the_radius():
    """A timed hairpin of 3 m radius at 2 m/s (curvature 0.33 > 0.2 /m): the heading keeps to
    the car's turning limit (no turning on the spot); before session 33 the path kept the
    hairpin and the body slid sideways (the report showed the sideslip), now the bend is
    refitted within the car's radius (:mod:`imugen.truth.timed_bends`) and the body follows
    its velocity."""
    t = np.arange(0.0, 60.5, 0.5)
    R, v = 3.0, 2.0
    ang = np.clip((t - 20.0) * v / R, 0.0, math.pi)  # 20 s straight, a half circle, straight
    s_after = np.clip(t - 20.0 - math.pi * R / v, 0.0, None) * v
    x = np.where(t < 20.0, v * t, 40.0 + R * np.sin(ang) - s_after)
    y = np.where(t < 20.0, 0.0, R * (1.0 - np.cos(ang)))
    enu = np.column_stack([x, y, 0.0 * t])
    df, meta = truth.enu_table(enu, t, ORIGIN)
    tr, meta = truth.build_truth(df, meta, rate_hz=50, earth="flat", vehicle="car", verbose=False)
    rep = meta["plausibility"]
    assert rep["max_yaw_rate_excess_dps"] < math.degrees(1e-3)
    bends = meta["fit"]["curvature_bound"]
    assert bends["refitted"] >= 1 and bends["left"] == 0
    assert bends["max_curvature_ratio_before"] > 1.5 and bends["max_curvature_ratio"] <= 1.0
    assert rep["max_body_lateral_speed_mps"] < 1e-6 and meta["gate"] == []
    vb = _body_velocity(tr)
    lat = np.abs(vb[:, 1])
    assert rep["max_body_lateral_speed_mps"] == pytest.approx(lat.max(), rel=1e-12)
    # more than 20 m of path away from where the path is beyond the car: along x laterally;
    # vertically within 2e-3 m/s (the refitted stretch's pitch follows the grade model there,
    # measured 1.4e-3 m/s)
    worst, kept = _departure_outside_implausible(tr, truth.VEHICLES["car"], window_m=20.0)
    assert kept > 0.5
    assert worst[0] < 1e-6 and worst[1] < 2e-3, worst


def _departure_outside_implausible(tr, vp, window_m=12.0):
    """Largest body lateral and vertical speeds more than ``window_m`` of path away from any
    sample where the truth's own path is beyond the vehicle (slow, horizontal curvature above
    the limit, vertical curvature above the pitch model's), from finite differences."""
    tt = tr[col.TIME].to_numpy()
    v = _arr(tr, col.VEL)
    a = np.gradient(v, tt, axis=0)
    vh = np.hypot(v[:, 0], v[:, 1])
    vhs = np.maximum(vh, 1e-9)
    kap = np.abs(v[:, 0] * a[:, 1] - v[:, 1] * a[:, 0]) / vhs**3
    vh_d = (v[:, 0] * a[:, 0] + v[:, 1] * a[:, 1]) / vhs
    kv = np.abs(vhs * a[:, 2] - v[:, 2] * vh_d) / ((vhs**2 + v[:, 2] ** 2) * vhs)
    from imugen.truth.attitude import SLIP_PITCH_FACTOR

    bad = (
        (vh < 2.0 * vp.stop_speed_mps)
        | (kap > 0.95 * vp.max_curvature_1pm)
        | (kv > 0.95 * SLIP_PITCH_FACTOR * vp.max_pitch_rad / vp.grade_smooth_m)
    )
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(_arr(tr, col.POS)[:, :2], axis=0), axis=1))]
    sb = s[bad]
    near = np.zeros(len(s), bool)
    if sb.size:
        j = (
            np.clip(np.searchsorted(sb, s), 1, len(sb) - 1)
            if len(sb) > 1
            else np.zeros(len(s), int)
        )
        d = np.minimum(np.abs(s - sb[j]), np.abs(s - sb[np.maximum(j - 1, 0)]))
        near = d < window_m
    vb = _body_velocity(tr)
    keep = ~near
    return np.abs(vb[keep, 1:]).max(axis=0) if keep.any() else np.zeros(2), keep.mean()


@pytest.mark.shared
@pytest.mark.skipif(SHARED is None, reason="shared trajectories absent")
def test_paper_trajectory_nhc():
    """Measured before this model (heading smoothed over 2 m, pitch from the grade): body
    lateral speed RMS 0.031 m/s, vertical 0.075 m/s."""
    path = SHARED / "seed_reference_trajectory_enu.txt"
    if not path.exists():
        pytest.skip("paper trajectory absent")
    from imugen.ingest.stage import ingest

    ing = ingest(path, origin="31.63,-7.99,480.6", dt=1.0, vehicle="car")
    df, meta = ing.table, ing.meta
    tr, meta = truth.build_truth(
        df, meta, rate_hz=50, earth="flat", vehicle="car", verbose=False, vehicle_params=RIGID
    )
    rep = meta["plausibility"]
    assert rep["warnings"] == []
    assert rep["rms_body_vertical_speed_mps"] < 0.075 / 100
    assert rep["rms_body_lateral_speed_mps"] < 0.031 / 2
    assert rep["slip_fraction"] < 0.05
    vp = truth.VEHICLES["car"]
    worst, kept = _departure_outside_implausible(tr, vp)
    assert kept > 0.9
    assert worst.max() < 1e-6, worst


def test_stepped_heights_become_a_road_profile_without_vertical_slip():
    """An altimeter's stepped record (level 17 s, then 2 m in 2 s, 20 steps, 0.2 m rounding) on
    a straight road at 6 m/s: the truth climbs the road profile (heights against distance,
    smoothed over the car's 50 m vertical curves), not the steps: its velocity's pitch is the
    grade, so the body has no vertical velocity, the pitch stays near the mean slope (1/60) and
    the path keeps within one step of the record and climbs its 40 m."""
    t = np.arange(0.0, 401.0, 1.0)
    x = 6.0 * t
    h = 2.0 * (t // 20.0) + 2.0 * np.clip((np.mod(t, 20.0) - 17.0) / 2.0, 0.0, 1.0)
    h = np.round(h / 0.2) * 0.2
    df, meta = truth.enu_table(np.column_stack([x, 0.0 * x, h]), t, ORIGIN)
    tr, meta = truth.build_truth(df, meta, rate_hz=20, earth="flat", vehicle="car", verbose=False)
    vb = _body_velocity(tr)
    assert np.abs(vb[:, 2]).max() < 1e-6
    tt = tr[col.TIME].to_numpy()
    pitch = tr["pitch_rad"].to_numpy()
    mid = (tt > 40.0) & (tt < 360.0)
    assert np.abs(pitch[mid] - math.atan(1.0 / 60.0)).max() < 0.02  # steps were 0.32 rad
    u = tr[col.POS[2]].to_numpy()
    assert np.abs(np.interp(t, tt, u) - h).max() < 2.0
    assert abs(u[-1] - u[0] - (h[-1] - h[0])) < 1.0


def _stepped_noisy_path():
    """A 3 km untimed polyline, a vertex every 10 m on an S-curve (curvature <= 0.0005 /m),
    climbing 4 % with 3 m hills, its heights rounded to 2 m steps (an altimeter) plus 0.5 m
    of white noise: raw vertex-to-vertex grades up to ~30 %."""
    rng = np.random.default_rng(1)
    s = np.arange(0.0, 3000.0, 10.0)
    h = 0.04 * s + 3.0 * np.sin(s / 300.0)
    h = np.round(h / 2.0) * 2.0 + rng.normal(scale=0.5, size=len(s))
    return np.column_stack([s, 80.0 * np.sin(s / 400.0), h])


@pytest.mark.parametrize("earth", ["flat", "wgs84", "geodetic"])
def test_untimed_path_climbs_its_road_profile_without_vertical_slip(earth):
    """An untimed path's vertical is its road profile: the input heights against horizontal
    distance smoothed over the car's 50 m vertical curves, built into the geometry before the
    speed profile. So the velocity's pitch is the grade, the pitch follows it everywhere the
    vehicle moves (no blend to a separately fitted grade) and the body has no vertical
    velocity; the truth's heights at the input points are within the profile's own residual
    of the input heights, and it climbs their total."""
    y = _stepped_noisy_path()
    df, meta = truth.enu_table(y, None, ORIGIN)
    tr, meta = truth.build_truth(
        df, meta, rate_hz=20, earth=earth, vehicle="car", verbose=False, vehicle_params=RIGID
    )
    rep, vert = meta["plausibility"], meta["fit"]["vertical"]
    assert rep["warnings"] == []
    assert rep["max_rate_increment_radps"] < 1e-5
    assert vert["max_departure_m"] < 1e-6  # the geometry's height is H(s_h)
    grade = vert["grade"]
    assert grade["rms_residual_m"] < 1.0  # the noise and steps' own RMS: 0.76 m
    if earth == "geodetic":
        frame = truth.attitude.ea.OriginFrame.from_deg(*ORIGIN, "wgs84")
        height = tr[col.ALT].to_numpy()
        p_n = frame.n_from_geodetic(np.radians(tr[col.LAT]), np.radians(tr[col.LON]), height)
    else:
        p_n = _arr(tr, col.POS)
        frame = truth.attitude.ea.OriginFrame.from_deg(*ORIGIN, earth)
        height = p_n[:, 2] if earth == "flat" else frame.geodetic_from_n(p_n)[2]
    h_in = y[:, 2] if earth == "flat" else frame.geodetic_from_n(y)[2]
    # the truth's height at the sample horizontally nearest each input point
    from scipy.spatial import cKDTree

    _, k = cKDTree(p_n[:, :2]).query(y[:, :2])
    dh = height[k] - h_in
    assert np.sqrt(np.mean(dh**2)) <= 1.02 * grade["rms_residual_m"] + 0.01
    assert abs(height[-1] - height[0] - (h_in[-1] - h_in[0])) < 1.0
    if earth == "geodetic":
        assert rep["max_vertical_slip_deg"] < 1e-3
        return
    vb = _body_velocity(tr)
    # flat: exactly none; wgs84: the grade is against distance in n's East-North plane, the
    # pitch in the local level at the vehicle (3 km from the origin: 5e-4 rad apart), which
    # the pitch blends to only near the rests at the ends (speed < 3 m/s)
    assert np.abs(vb[:, 2]).max() < (1e-6 if earth == "flat" else 1e-5)
    tt = tr[col.TIME].to_numpy()
    mid = (tt > 0.1 * tt[-1]) & (tt < 0.9 * tt[-1])
    pitch = tr["pitch_rad"].to_numpy()
    assert np.abs(pitch[mid] - math.atan(0.04)).max() < 0.03  # raw vertex grades ~0.3
