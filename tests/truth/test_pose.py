"""Pose trajectories as truth (imugen.truth.pose): the given attitude, exact increments."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen.closure import closure_of_truth
from imugen.core import rotations as rot
from imugen.tables import enu as tenu
from imugen.tables import truth as col
from imugen.truth.build import build_truth, enu_table
from imugen.truth.pose import PoseSettings

from helpers import SHARED

G = 9.80665


def flight(t):
    """An analytic 6-DoF motion: position (m), velocity, acceleration in ENU, ``q_nb`` and
    ``omega_nb_b`` (central differences of the closed-form attitude, ~1e-9 rad/s)."""
    w1, w2 = 2 * math.pi / 6.0, 2 * math.pi / 4.0
    p = np.column_stack([3 * np.sin(w1 * t), 2 * np.sin(w2 * t), 1.5 + 0.5 * np.sin(w1 * t)])
    v = np.column_stack(
        [3 * w1 * np.cos(w1 * t), 2 * w2 * np.cos(w2 * t), 0.5 * w1 * np.cos(w1 * t)]
    )
    a = np.column_stack(
        [-3 * w1**2 * np.sin(w1 * t), -2 * w2**2 * np.sin(w2 * t), -0.5 * w1**2 * np.sin(w1 * t)]
    )

    def q_of(tt):
        return rot.dcm_to_quat(
            rot.euler_to_dcm(
                0.3 * np.sin(w2 * tt), 0.2 * np.cos(w1 * tt), 0.5 * tt + np.sin(w1 * tt)
            )
        )

    h = 1e-5
    q = q_of(t)
    qd = (q_of(t + h) - q_of(t - h)) / (2 * h)
    qd = qd * np.sign(np.sum(q * q_of(t + h), axis=1))[:, None]
    w = 2.0 * rot.quat_mul(rot.quat_conj(q), qd)[:, 1:]
    return p, v, a, q, w


def poses(rate_hz=200.0, duration_s=12.0, sigma_m=0.0, sigma_rad=0.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    p, _, _, q, _ = flight(t)
    p = p + sigma_m * rng.standard_normal(p.shape)
    q = rot.quat_mul(q, rot.exp_quat(sigma_rad * rng.standard_normal(p.shape)))
    q[::7] *= -1.0  # sign flips, as trackers write them
    return t, p, q


def table(t, p, q, origin=(47.4, 8.5, 400.0)):
    df, meta = enu_table(p, t, origin)
    for i, c in enumerate(tenu.ATTITUDE):
        df[c] = q[:, i]  # attitude relative to the local ENU: near the origin, the origin's
    return df, meta


def test_noisy_mocap_gives_the_motion_and_closes():
    t, p, q = poses(duration_s=8.0, sigma_m=5e-4, sigma_rad=math.radians(0.1))
    df, meta = table(t, p, q)
    tr, tm = build_truth(df, meta, rate_hz=200.0, earth="flat", vehicle="multirotor", verbose=False)
    fit = tm["fit"]
    assert fit["sign_flips"] > 100
    assert fit["attitude_noise_rad"] == pytest.approx(math.radians(0.1), rel=0.15)
    assert fit["position_noise_m"][0] == pytest.approx(5e-4, rel=0.15)
    assert fit["position_residual_rms_m"] < 2 * math.sqrt(3) * 5e-4
    ts = tr[col.TIME].to_numpy()
    inner = (ts > 1.0) & (ts < ts[-1] - 1.0)
    _, _, aa, qa, wa = flight(ts)
    dq = rot.log_quat(rot.quat_mul(rot.quat_conj(qa), tr[list(col.QUAT)].to_numpy()))
    att = np.linalg.norm(dq, axis=1)[inner]
    assert np.sqrt(np.mean(att**2)) < 1e-3
    gyro = tr[list(col.GYRO)].to_numpy() - wa
    assert np.sqrt(np.mean(np.sum(gyro[inner] ** 2, 1))) < 0.01
    f_b = np.einsum("mji,mj->mi", rot.quat_to_dcm(qa), aa + np.array([0.0, 0.0, G]))
    acc = tr[list(col.ACCEL)].to_numpy() - f_b
    assert np.sqrt(np.mean(np.sum(acc[inner] ** 2, 1))) < 0.04
    res = closure_of_truth(tr, tm)
    assert res["final_position_error_m"] < 1e-6
    assert res["max_position_error_m"] < 1e-3
    assert res["max_attitude_error_rad"] < 1e-9
    assert tm["plausibility"]["max_rate_radps"] < 5.0
    assert tm["plausibility"]["specific_force_off_z_max_rad"] > 0.0


@pytest.mark.parametrize("earth", ["wgs84", "geodetic"])
def test_closure_in_the_earth_models(earth):
    t, p, q = poses(rate_hz=100.0, duration_s=4.0)
    df, meta = table(t, p, q)
    tr, tm = build_truth(df, meta, rate_hz=200.0, earth=earth, vehicle="multirotor", verbose=False)
    res = closure_of_truth(tr, tm)
    assert res["final_position_error_m"] < 1e-6
    assert res["max_position_error_m"] < 1e-3
    assert res["max_attitude_error_rad"] < 1e-9


def test_extrinsics_and_time_offset_give_the_imu():
    """Poses of an FRD body with the IMU rotated, off the marker, on a clock 0.37 s late:
    the truth is the IMU's motion."""
    t = np.arange(0.0, 5.0, 1.0 / 100.0)
    off = 0.37
    C_sb = np.diag([1.0, -1.0, -1.0]) @ rot.euler_to_dcm(0.1, -0.05, 0.2)
    lever, marker = np.array([0.05, -0.02, 0.1]), np.array([-0.1, 0.03, 0.02])
    p_b, _, _, q_nb, _ = flight(t + off)  # the IMU at the IMU clock
    C_ns = rot.quat_to_dcm(q_nb) @ C_sb.T
    p_s = p_b - C_ns @ (lever - marker)
    df, meta = table(t, p_s, rot.dcm_to_quat(C_ns))
    s = PoseSettings(
        pose_body="frd", imu_rotation_rad=(0.1, -0.05, 0.2), lever_arm_m=tuple(lever),
        marker_offset_m=tuple(marker), time_offset_s=off,
    )  # fmt: skip
    tr, _ = build_truth(
        df, meta, rate_hz=200.0, earth="flat", vehicle="multirotor", pose=s, verbose=False
    )
    ts = tr[col.TIME].to_numpy()
    assert ts[0] == pytest.approx(off)
    pa, _, _, qa, wa = flight(ts)
    inner = (ts > off + 0.5) & (ts < ts[-1] - 0.5)
    assert np.abs(tr[list(col.POS)].to_numpy() - pa)[inner].max() < 1e-4
    dq = rot.log_quat(rot.quat_mul(rot.quat_conj(qa), tr[list(col.QUAT)].to_numpy()))
    assert np.linalg.norm(dq, axis=1)[inner].max() < 1e-4
    assert np.abs(tr[list(col.GYRO)].to_numpy() - wa)[inner].max() < 5e-3


COMMA = SHARED / "data" / "imu" / "comma2k19_segment"


@pytest.mark.shared
@pytest.mark.skipif(not COMMA.is_dir(), reason="../shared comma2k19 segment absent")
def test_real_ins_pose_through_ingest(tmp_path):
    """comma2k19's 20 Hz INS/GNSS poses (ECEF, device FRD) as a pose CSV through `imugen
    ingest` and the truth: small residuals, closure in wgs84, and body rates that follow the
    phone's own gyro."""
    from imugen.ingest.stage import ingest

    def load(name):
        return np.load(COMMA / name)

    t = load("global_pose/frame_times")
    r, q = load("global_pose/frame_positions"), load("global_pose/frame_orientations")
    rows = [f"{t[i] - t[0]:.6f},{r[i, 0]:.4f},{r[i, 1]:.4f},{r[i, 2]:.4f},{q[i, 0]:.12f},"
            f"{q[i, 1]:.12f},{q[i, 2]:.12f},{q[i, 3]:.12f}" for i in range(len(t))]  # fmt: skip
    src = tmp_path / "poses.csv"
    src.write_text("t,x,y,z,qw,qx,qy,qz\n" + "\n".join(rows) + "\n")
    ing = ingest(src, pose_world="ecef", vehicle="car")
    tr, tm = build_truth(
        ing.table, ing.meta, rate_hz=100.0, earth="wgs84", vehicle="car",
        pose=PoseSettings(pose_body="frd"), verbose=False,
    )  # fmt: skip
    fit = tm["fit"]
    assert fit["position_residual_rms_m"] < 1e-3 and fit["attitude_residual_rms_rad"] < 1e-3
    res = closure_of_truth(tr, tm)
    assert res["final_position_error_m"] < 1e-6 and res["max_attitude_error_rad"] < 1e-9
    tg = load("processed_log/IMU/gyro/t") - t[0]
    g = load("processed_log/IMU/gyro/value") * [1.0, -1.0, -1.0]  # the phone's FRD -> FLU
    ts = tr[col.TIME].to_numpy()
    ok = (tg > ts[0] + 1) & (tg < ts[-1] - 1)
    gyro = tr[list(col.GYRO)].to_numpy()
    corr = [np.corrcoef(g[ok, i], np.interp(tg[ok], ts, gyro[:, i]))[0, 1] for i in range(3)]
    assert min(corr) > 0.7
