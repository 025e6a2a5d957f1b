"""comma2k19 test oracle (issue 24): the IMU implied by the fused pose, the real phone IMU's residual
against it, and the free-inertial drift of the real phone IMU over the minute.

Frames: ECEF (e), the device frame (b: forward, right, down; the dataset's camera/device
frame), Hamilton quaternions ``[w, x, y, z]``. Which way the quaternion rotates is decided
from the data (:func:`orientation_convention`): the convention under which the pose-implied
specific force points up (reads ``-g`` on a down axis) and the implied body rates match the
gyro.

Implied IMU (at the pose times ``t_k``, 20 Hz, from the neighbours ``k -+ 1``, ``h = 50 ms``):

* specific force ``f_b = C_be [(v_{k+1} - v_{k-1}) / 2h + 2 Omega x v_k - g_e(p_k)]`` (ECEF is
  rotating: the kinematic acceleration plus Coriolis minus gravity, gravity = WGS84 normal
  gravity incl. centrifugal, along the ellipsoid normal);
* angular rate ``omega_ib = rotvec(C_be,{k-1} C_eb,{k+1}) / 2h + C_be Omega_ie``.

Both are means over ``[t_k - h, t_k + h]``: the real IMU is averaged over the same window before
comparing (a central difference is the boxcar mean of the derivative).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from helpers import SHARED

OMEGA_IE = 7.292115e-5
A_WGS, F_WGS = 6378137.0, 1 / 298.257223563
E2 = F_WGS * (2 - F_WGS)
G0 = 9.80665
DEG = math.pi / 180
DATA = SHARED / "data" / "imu" / "comma2k19_segment"


def load(root=DATA) -> dict:
    root = Path(root)

    def g(p):
        return np.load(root / p)

    return {
        "t_pose": g("global_pose/frame_times"),
        "p_e": g("global_pose/frame_positions"),
        "v_e": g("global_pose/frame_velocities"),
        "q": g("global_pose/frame_orientations"),
        "t_imu": g("processed_log/IMU/gyro/t"),
        "gyro": g("processed_log/IMU/gyro/value"),
        "gyro_uncal": g("processed_log/IMU/gyro_uncalibrated/value"),
        "gyro_bias": g("processed_log/IMU/gyro_bias/value"),
        "t_acc": g("processed_log/IMU/accelerometer/t"),
        "accel": g("processed_log/IMU/accelerometer/value"),
        "t_speed": g("processed_log/CAN/speed/t"),
        "speed": g("processed_log/CAN/speed/value")[:, 0],
    }


# --- Earth ------------------------------------------------------------------------------------
def ecef_to_geodetic(p):
    """(lat, lon, h) [rad, rad, m] of ECEF points (K, 3) (Bowring, 3 iterations)."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    lon = np.arctan2(y, x)
    r = np.hypot(x, y)
    lat = np.arctan2(z, r * (1 - E2))
    for _ in range(5):
        N = A_WGS / np.sqrt(1 - E2 * np.sin(lat) ** 2)
        h = r / np.cos(lat) - N
        lat = np.arctan2(z, r * (1 - E2 * N / (N + h)))
    N = A_WGS / np.sqrt(1 - E2 * np.sin(lat) ** 2)
    h = r / np.cos(lat) - N
    return lat, lon, h


def C_en(lat, lon):
    """Rotation ECEF -> NED (K, 3, 3)."""
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.stack(
        [
            np.stack([-sl * co, -sl * so, cl], -1),
            np.stack([-so, co, np.zeros_like(so)], -1),
            np.stack([-cl * co, -cl * so, -sl], -1),
        ],
        -2,
    )


def gravity_e(p):
    """WGS84 normal gravity (with centrifugal) in ECEF, along the ellipsoid normal (K, 3)."""
    lat, lon, h = ecef_to_geodetic(p)
    s2 = np.sin(lat) ** 2
    g = 9.7803253359 * (1 + 0.00193185265241 * s2) / np.sqrt(1 - E2 * s2)
    g = g * (
        1 - 2 / A_WGS * (1 + F_WGS + 0.00344978650684 - 2 * F_WGS * s2) * h + 3 * h * h / A_WGS**2
    )
    Cne = np.transpose(C_en(lat, lon), (0, 2, 1))
    return Cne @ np.array([0.0, 0.0, 1.0]) * g[:, None]


# --- orientation -------------------------------------------------------------------------------
def rot(q, convention):
    """C_eb (device -> ECEF) for quaternions [w, x, y, z]; convention "device_to_ecef" or
    "ecef_to_device" (then the quaternion's matrix is C_be)."""
    R = Rotation.from_quat(np.column_stack([q[:, 1], q[:, 2], q[:, 3], q[:, 0]])).as_matrix()
    return R if convention == "device_to_ecef" else np.transpose(R, (0, 2, 1))


def implied_imu(d: dict, convention: str, n: int = 1):
    """Pose-implied (f_b, omega_ib) at pose samples n..K-n-1 and their times: central
    differences over +-n pose samples (means over ``[t_k - n h, t_k + n h]``)."""
    t, p, v = d["t_pose"], d["p_e"], d["v_e"]
    Ceb = rot(d["q"], convention)
    W = np.array([0.0, 0.0, OMEGA_IE])
    c = slice(n, len(t) - n)
    h2 = t[2 * n :] - t[: -2 * n]
    a = (v[2 * n :] - v[: -2 * n]) / h2[:, None]
    f_e = a + 2 * np.cross(W, v[c]) - gravity_e(p[c])
    Cbe = np.transpose(Ceb[c], (0, 2, 1))
    f_b = np.einsum("kij,kj->ki", Cbe, f_e)
    dR = np.einsum("kji,kjl->kil", Ceb[: -2 * n], Ceb[2 * n :])  # C_be,{k-n} C_eb,{k+n}
    w_eb = Rotation.from_matrix(dR).as_rotvec() / h2[:, None]
    w_ib = w_eb + np.einsum("kij,j->ki", Cbe, W)
    return t[c], f_b, w_ib


def window_mean(t_src, x, t_c, half):
    """Mean of the samples of ``x`` with ``t`` in ``[t_c - half, t_c + half)`` (trapezoid-free
    boxcar; IMU samples are uniform at 104 Hz)."""
    c = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    i0 = np.searchsorted(t_src, t_c - half)
    i1 = np.searchsorted(t_src, t_c + half)
    n = np.maximum(i1 - i0, 1)
    return (c[i1] - c[i0]) / n[:, None], i1 - i0


def orientation_convention(d: dict) -> tuple[str, dict]:
    """The convention under which the implied specific force points up and the rates match."""
    out = {}
    for conv in ("device_to_ecef", "ecef_to_device"):
        tc, f_b, w_ib = implied_imu(d, conv)
        g_meas, _ = window_mean(d["t_imu"], d["gyro"], tc, 0.05)
        a_meas, _ = window_mean(d["t_acc"], d["accel"], tc, 0.05)
        out[conv] = {
            "mean_f_b": f_b.mean(0).tolist(),
            "rate_corr": [float(np.corrcoef(w_ib[:, i], g_meas[:, i])[0, 1]) for i in range(3)],
            "accel_rms_diff": float(np.sqrt(np.mean((a_meas - f_b) ** 2))),
        }
    best = min(out, key=lambda c: out[c]["accel_rms_diff"])
    return best, out


def time_offset(d: dict, conv: str, span=0.2, step=0.002) -> float:
    """IMU clock minus pose clock [s] maximising the match of the yaw rates."""
    tc, _, w_ib = implied_imu(d, conv)
    best = (np.inf, 0.0)
    for dtau in np.arange(-span, span + step / 2, step):
        g, _ = window_mean(d["t_imu"], d["gyro"], tc + dtau, 0.05)
        r = np.mean((g[:, 2] - g[:, 2].mean() - (w_ib[:, 2] - w_ib[:, 2].mean())) ** 2)
        if r < best[0]:
            best = (r, float(dtau))
    return best[1]


def residuals(d: dict, conv: str, offset: float = 0.0, n: int = 1) -> dict:
    """Per-axis residual of the real IMU against the pose-implied one.

    Model per axis ``meas = (1 + s) true + b + n`` (least squares, 20 Hz window means);
    also the full ``meas = (I + M) true + b`` with M's off-diagonal the misalignment.
    """
    tc, f_b, w_ib = implied_imu(d, conv, n)
    half = n * float(np.median(np.diff(d["t_pose"])))
    out = {}
    for name, tt, x in (
        ("gyro_uncal", d["t_imu"], d["gyro_uncal"]),
        ("gyro_android_calibrated", d["t_imu"], d["gyro"]),
        ("accel", d["t_acc"], d["accel"]),
    ):
        meas, cnt = window_mean(tt, x, tc + offset, half)
        ok = cnt >= 5 * n
        true = (w_ib if name.startswith("gyro") else f_b)[ok]
        meas = meas[ok]
        r = {"axis": [], "bias": [], "scale": [], "resid_std": [], "mean_diff": [], "true_std": []}
        for i in range(3):
            A = np.column_stack([true[:, i], np.ones(len(true))])
            coef, *_ = np.linalg.lstsq(A, meas[:, i], rcond=None)
            res = meas[:, i] - A @ coef
            r["axis"].append("frd"[i])
            r["scale"].append(float(coef[0] - 1))
            r["bias"].append(float(coef[1]))
            r["mean_diff"].append(float(np.mean(meas[:, i] - true[:, i])))
            r["resid_std"].append(float(np.std(res)))
            r["true_std"].append(float(np.std(true[:, i])))
        A = np.column_stack([true, np.ones(len(true))])
        coef, *_ = np.linalg.lstsq(A, meas, rcond=None)
        r["M_plus_I"] = coef[:3].T.tolist()  # meas_i = sum_j (I+M)_ij true_j + b_i
        r["b_full"] = coef[3].tolist()
        r["n_windows"] = int(ok.sum())
        out[name] = r
    return out


def raw_noise(d: dict, conv: str, offset: float = 0.0) -> dict:
    """High-frequency noise of the raw 104 Hz samples: the std of second differences / sqrt(6)
    (a white sequence's own std; the motion's second difference at 104 Hz is far smaller
    for a car on a highway except vibration) and the density it implies (std * sqrt(dt))."""
    out = {}
    for name, tt, x in (("gyro", d["t_imu"], d["gyro_uncal"]), ("accel", d["t_acc"], d["accel"])):
        dt = float(np.median(np.diff(tt)))
        d2 = x[2:] - 2 * x[1:-1] + x[:-2]
        s = d2.std(0) / math.sqrt(6)
        out[name] = {"sample_std": s.tolist(), "density_si": (s * math.sqrt(dt)).tolist(), "dt": dt}
    return out


# --- free inertial ---------------------------------------------------------------------------
def mechanize(t, gyro, accel, p0, v0, Ceb0):
    """Strapdown in ECEF (rates, first order with midpoint attitude): returns p, v, Ceb at t."""
    K = len(t)
    W = np.array([0.0, 0.0, OMEGA_IE])
    p = np.zeros((K, 3))
    v = np.zeros((K, 3))
    C = np.zeros((K, 3, 3))
    p[0], v[0], C[0] = p0, v0, Ceb0
    Wx = np.array([[0, -OMEGA_IE, 0], [OMEGA_IE, 0, 0], [0, 0, 0]])
    for k in range(1, K):
        dt = t[k] - t[k - 1]
        w = 0.5 * (gyro[k] + gyro[k - 1])
        f = 0.5 * (accel[k] + accel[k - 1])
        dR = Rotation.from_rotvec(w * dt).as_matrix()
        dE = Rotation.from_rotvec(-W * dt).as_matrix()
        Cmid = C[k - 1] @ Rotation.from_rotvec(w * dt / 2).as_matrix()
        C[k] = dE @ C[k - 1] @ dR
        g = gravity_e(p[k - 1][None])[0]
        a = Cmid @ f + g - 2 * Wx @ v[k - 1]
        v[k] = v[k - 1] + a * dt
        p[k] = p[k - 1] + 0.5 * (v[k] + v[k - 1]) * dt
    return p, v, C


def pose_at(d, conv, t):
    """Truth position, velocity (linear interpolation) and attitude (slerp) at times t."""
    from scipy.spatial.transform import Slerp

    tp = d["t_pose"]
    p = np.column_stack([np.interp(t, tp, d["p_e"][:, i]) for i in range(3)])
    v = np.column_stack([np.interp(t, tp, d["v_e"][:, i]) for i in range(3)])
    R = Rotation.from_matrix(rot(d["q"], conv))
    C = Slerp(tp, R)(np.clip(t, tp[0], tp[-1])).as_matrix()
    return p, v, C


def free_inertial(d: dict, conv: str, offset: float = 0.0, gyro=None, accel=None, t=None):
    """Free-inertial errors (position, velocity, attitude) of the IMU against the pose.

    Default IMU: the real phone's Android-calibrated gyro (``gyro_uncalibrated - gyro_bias``)
    and raw accelerometer. Starts at the first IMU sample inside the pose span, on the truth.
    """
    if t is None:
        t = d["t_imu"] - offset
        gyro = d["gyro_uncal"] - d["gyro_bias"]
        accel = d["accel"]
    sel = (t >= d["t_pose"][0]) & (t <= d["t_pose"][-1])
    t, gyro, accel = t[sel], gyro[sel], accel[sel]
    p_t, v_t, C_t = pose_at(d, conv, t)
    p, v, C = mechanize(t, gyro, accel, p_t[0], v_t[0], C_t[0])
    lat, lon, _ = ecef_to_geodetic(p_t[:1])
    Cne = C_en(lat, lon)[0]
    dp = (p - p_t) @ Cne.T
    dv = (v - v_t) @ Cne.T
    dth = Rotation.from_matrix(np.einsum("kji,kjl->kil", C_t, C)).as_rotvec()  # body-frame
    return {"t": t - t[0], "dp_n": dp, "dv_n": dv, "dth_b": dth}


# --- batched free inertial for Monte Carlo ----------------------------------------------------
def _rodrigues(phi):
    """Rotation matrices (S, 3, 3) of rotation vectors (S, 3)."""
    th = np.linalg.norm(phi, axis=-1)[:, None, None]
    K = np.zeros((*phi.shape[:-1], 3, 3))
    K[:, 0, 1], K[:, 0, 2] = -phi[:, 2], phi[:, 1]
    K[:, 1, 0], K[:, 1, 2] = phi[:, 2], -phi[:, 0]
    K[:, 2, 0], K[:, 2, 1] = -phi[:, 1], phi[:, 0]
    small = th < 1e-12
    a = np.where(small, 1.0, np.sin(th) / np.where(small, 1.0, th))
    b = np.where(small, 0.5, (1 - np.cos(th)) / np.where(small, 1.0, th * th))
    return np.eye(3) + a * K + b * (K @ K)


def mechanize_batch(t, gyro, accel, p0, v0, C0):
    """:func:`mechanize` for S IMUs at once: gyro, accel (S, K, 3); returns p, v (S, K, 3) and
    the final C (S, 3, 3)."""
    S, K, _ = gyro.shape
    W = np.array([0.0, 0.0, OMEGA_IE])
    Wx = np.array([[0, -OMEGA_IE, 0], [OMEGA_IE, 0, 0], [0, 0, 0]])
    p = np.zeros((S, K, 3))
    v = np.zeros((S, K, 3))
    p[:, 0], v[:, 0] = p0, v0
    C = np.broadcast_to(C0, (S, 3, 3)).copy()
    for k in range(1, K):
        dt = t[k] - t[k - 1]
        w = 0.5 * (gyro[:, k] + gyro[:, k - 1])
        f = 0.5 * (accel[:, k] + accel[:, k - 1])
        Cmid = C @ _rodrigues(w * dt / 2)
        dE = Rotation.from_rotvec(-W * dt).as_matrix()
        C = dE @ C @ _rodrigues(w * dt)
        g = gravity_e(p[:, k - 1])
        a = np.einsum("sij,sj->si", Cmid, f) + g - (v[:, k - 1] @ Wx.T) * 2
        v[:, k] = v[:, k - 1] + a * dt
        p[:, k] = p[:, k - 1] + 0.5 * (v[:, k] + v[:, k - 1]) * dt
    return p, v, C


def truth_imu(d: dict, conv: str, t):
    """Pose-implied IMU interpolated to times t (linear), for simulated IMUs on this truth."""
    tc, f_b, w_ib = implied_imu(d, conv)
    f = np.column_stack([np.interp(t, tc, f_b[:, i]) for i in range(3)])
    w = np.column_stack([np.interp(t, tc, w_ib[:, i]) for i in range(3)])
    return f, w
