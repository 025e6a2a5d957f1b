"""The filter's start: the initial alignment of every sequence from its first seconds
(:func:`align`, vectorized NumPy), an explicit start (:func:`initial_state`) and the
block-diagonal priors of the error state (:func:`initial_covariance`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imugen.aid.filter.options import Options
from imugen.aid.filter.state import CC_PAIRS, NOMINAL, NX
from imugen.aid.filter.tuning import T_BB_SD, T_GB_SD, T_GW, T_OSF_SD, Tuning
from imugen.core import earth
from imugen.core.earth import OriginFrame
from imugen.core.rotations import dcm_to_quat, euler_to_dcm

LEVEL_SD_RAD = math.radians(1.0)
"""Roll/pitch 1-sigma of a moving-start alignment (land vehicle assumed level)."""
HEADING_SD_RAD = math.radians(0.5)
"""Heading-along-velocity 1-sigma margin of a moving-start alignment."""


@dataclass
class Initial:
    """Filter start: sample index ``k0`` (S,), nominal state ``x0`` (S, NX), covariance ``P0``."""

    k0: np.ndarray
    x0: np.ndarray
    P0: np.ndarray


def initial_state(k0, p_n, v_n, q_nb, P0, gyro_bias=None, accel_bias=None) -> Initial:
    """An :class:`Initial` from explicit values (S rows each; biases default 0).

    ``k0`` (S,) or scalar start sample; ``p_n`` [m], ``v_n`` [m/s] (S, 3); ``q_nb`` (S, 4)
    (normalized here); ``P0`` (S, n, n) or (n, n); ``gyro_bias`` [rad/s], ``accel_bias``
    [m/s^2] (S, 3).
    """
    p = np.atleast_2d(np.asarray(p_n, float))
    v = np.atleast_2d(np.asarray(v_n, float))
    q = np.atleast_2d(np.asarray(q_nb, float))
    P0 = np.asarray(P0, float)
    S = max(len(p), len(v), len(q), len(P0) if P0.ndim == 3 else 1)
    x0 = np.zeros((S, NX))
    x0[:, NOMINAL.slice("p")] = p
    x0[:, NOMINAL.slice("v")] = v
    x0[:, NOMINAL.slice("att")] = q / np.linalg.norm(q, axis=1, keepdims=True)
    if gyro_bias is not None:
        x0[:, NOMINAL.slice("bg")] = gyro_bias
    if accel_bias is not None:
        x0[:, NOMINAL.slice("ba")] = accel_bias
    k = np.broadcast_to(np.asarray(k0, np.int64), (S,)).copy()
    return Initial(k, x0, np.ascontiguousarray(np.broadcast_to(P0, (S, *np.shape(P0)[-2:]))))


def initial_covariance(
    tun: Tuning, opts: Options, sd_p, sd_v, sd_att, gnss_bias_sd=None, odo_sf_sd=0.0,
    baro_sd_m=0.0,
) -> np.ndarray:  # fmt: skip
    """Block-diagonal initial covariance (S, n, n) of the error state of ``opts``.

    ``sd_p`` [m], ``sd_v`` [m/s], ``sd_att`` [rad]: per-axis sigmas in n, broadcast to (S, 3);
    biases, scale factors, cross-coupling from ``tun``; the mounting and lever arm from
    ``opts``. With GNSS bias states (``gnss_bias_sd`` [m], (S, 3)), a position taken from a
    fix has error ``b + w``: its covariance with the bias error ``-b`` is ``-sigma_b^2``.
    ``odo_sf_sd``, ``baro_sd_m`` [m] (scalars or (S,)): priors of the companion states (when
    in ``opts``). The odometer's tick residuals start at zero (set at each mark).
    """
    sd_p, sd_v, sd_att = (np.atleast_2d(np.asarray(a, float)) for a in (sd_p, sd_v, sd_att))
    S = max(len(sd_p), len(sd_v), len(sd_att))
    lay = opts.layout
    P = np.zeros((S, lay.n, lay.n))
    ix = np.arange(3)

    def d(key):  # the first three indices of a block
        return lay.offset(key) + ix

    P[:, d("p"), d("p")] = np.broadcast_to(sd_p, (S, 3)) ** 2
    P[:, d("v"), d("v")] = np.broadcast_to(sd_v, (S, 3)) ** 2
    P[:, d("att"), d("att")] = np.broadcast_to(sd_att, (S, 3)) ** 2
    P[:, d("bg"), d("bg")] = tun.gyro_bias_sd**2
    P[:, d("ba"), d("ba")] = tun.accel_bias_sd**2
    if lay.has("sa"):  # the scale-factor state carries its error on gravity
        P[:, d("ba"), d("ba")] -= tun.accel_static_sf_sd**2
    if lay.has("cc"):  # the cross-coupling states carry the body-fixed tilt
        P[:, d("ba"), d("ba")] -= tun.accel_tilt_cc_sd**2
    if lay.has("ca"):  # the accelerometer's cross-coupling states carry its error on gravity
        P[:, d("ba"), d("ba")] -= tun.accel_static_cc_sd**2
    if lay.has("gnss_bias"):
        gb = np.broadcast_to(
            np.atleast_2d(gnss_bias_sd if gnss_bias_sd is not None else 0.0), (S, 3)
        )
        P[:, d("gnss_bias"), d("gnss_bias")] = gb**2
        P[:, d("p"), d("gnss_bias")] = -(gb**2)
        P[:, d("gnss_bias"), d("p")] = -(gb**2)
    if lay.has("sg"):
        P[:, d("sg"), d("sg")] = tun.gyro_sf_sd**2
        P[:, d("sa"), d("sa")] = tun.accel_sf_sd**2
    if lay.has("odo_sf"):
        i = lay.offset("odo_sf")
        P[:, i, i] = np.broadcast_to(np.asarray(odo_sf_sd, float), (S,)) ** 2
    if lay.has("baro_bias"):
        i = lay.offset("baro_bias")
        P[:, i, i] = np.broadcast_to(np.asarray(baro_sd_m, float), (S,)) ** 2
    if lay.has("mount"):
        i = lay.offset("mount")
        P[:, i, i], P[:, i + 1, i + 1] = np.square(opts.nhc_misalignment_sd_rad)
    if lay.has("lever"):
        # body axes: C_bv l = l + [l x] theta to first order, theta the misalignment (pitch,
        # yaw; roll not modelled)
        lx = np.cross(np.asarray(opts.nhc_lever_arm_m, float), np.eye(3))  # [l x] = lx.T
        sth = np.diag([0.0, *np.square(opts.nhc_misalignment_sd_rad)])
        blk = lay.slice("lever")
        P[:, blk, blk] = np.diag(np.square(opts.nhc_lever_arm_sd_m)) + lx.T @ sth @ lx
    if lay.has("cc"):
        i = lay.offset("cc")
        for m, (r, _) in enumerate(CC_PAIRS):
            P[:, i + m, i + m] = tun.gyro_cc_sd[r] ** 2
    if lay.has("ca"):
        i = lay.offset("ca")
        for m, (r, _) in enumerate(CC_PAIRS):
            P[:, i + m, i + m] = tun.accel_cc_sd[r] ** 2
    return P


def align(
    dtheta_b,
    dv_b,
    dt,
    gnss,
    tun: Tuning,
    opts: Options,
    frame: OriginFrame,
    *,
    speed_mps=5.0,
    static_s=10.0,
    level_sd_rad=LEVEL_SD_RAD,
    heading_sd_rad=HEADING_SD_RAD,
    tuning_T=None,
) -> Initial:
    """Initial alignment of every sequence from its first seconds.

    * Static start (every sample of the first ``static_s`` seconds still by the ZUPT
      thresholds) in ``wgs84`` or ``geodetic`` with gyros good enough to gyrocompass (heading sigma
      ``sqrt(sigma_bg^2 + N_g^2 / T) / (Omega cos lat) < 5 deg`` over the window ``T``): coarse
      alignment -- roll and pitch from the mean specific force (sigma ``sqrt(sigma_ba^2 +
      N_a^2 / T) / g``), yaw from the levelled mean angular rate -- at the end of the window.
    * Otherwise (moving start, flat Earth or MEMS gyros), at the first GNSS epoch whose
      horizontal speed reaches ``speed_mps``: yaw along the GNSS velocity, pitch its climb
      angle, roll 0 (a land vehicle), sigmas ``level_sd_rad`` and ``hypot(sigma_v / speed,
      heading_sd_rad)``.
    Angles are relative to the local level at the fix (in ``geodetic``, ``C_nb = C_ln^T C_lb``
    and the initial covariance of position, velocity and attitude is rotated likewise).
    Position and velocity come from the fix at that epoch (lever arm removed, position carried
    forward over the latency).

    Sequences that never qualify start at sample K (no output).
    """
    dth = np.asarray(dtheta_b, float)
    dvb = np.asarray(dv_b, float)
    S, K = dth.shape[:2]
    g0 = frame.g0
    idx = np.asarray(gnss.index)
    valid = np.asarray(gnss.valid)
    v_l = np.asarray(gnss.v_n, float)
    if frame.model == "geodetic":  # horizontal speed in the local level at each fix
        p_ok = np.where(valid[..., None], gnss.p_n, [earth.A_WGS84, 0.0, 0.0])
        v_l = np.einsum("sjik,sjk->sji", frame.C_ln(p_ok), v_l)
    vh = np.hypot(v_l[..., 0], v_l[..., 1])
    moving = valid & (np.nan_to_num(vh) >= speed_mps)
    k0 = np.full(S, K, np.int64)
    rpy = np.zeros((S, 3))
    sd_att = np.zeros((S, 3))
    p0 = np.zeros((S, 3))
    v0 = np.zeros((S, 3))
    sd_p = np.ones((S, 3))
    sd_v = np.ones((S, 3))
    ns = round(static_s / dt)
    Om = earth.OMEGA_IE * math.cos(frame.lat0_rad)
    # coarse alignment errors: bias plus the white noise averaged over the window
    Tw = max(ns, 1) * dt
    gyro_sd = math.sqrt(
        float(np.max(tun.gyro_bias_sd)) ** 2 + float(np.max(tun.gyro_white)) ** 2 / Tw
    )
    acc_sd = np.sqrt(tun.accel_bias_sd**2 + tun.accel_white**2 / Tw)
    can_compass = frame.model != "flat" and gyro_sd < math.radians(5.0) * Om
    geo = frame.model == "geodetic"
    C_ln = np.broadcast_to(np.eye(3), (S, 3, 3)).copy()  # n -> local level at the start fix
    for s in range(S):
        done = False
        if geo:
            jv = np.flatnonzero(valid[s])
            if len(jv):
                C_ln[s] = frame.C_ln(gnss.p_n[s, jv[0]])
        if can_compass and 1 <= ns < K:
            w = dth[s, 1 : ns + 1] / dt
            f = dvb[s, 1 : ns + 1] / dt
            still = np.all(np.linalg.norm(w, axis=1) < opts.zupt_gyro_radps) and np.all(
                np.abs(np.linalg.norm(f, axis=1) - g0) < opts.zupt_accel_mps2
            )
            je = np.searchsorted(idx, ns)
            if geo and je < len(idx) and valid[s, je]:
                C_ln[s] = frame.C_ln(gnss.p_n[s, je])
            if still and je < len(idx) and valid[s, je]:
                fm, wm = f.mean(0), w.mean(0)
                roll = math.atan2(fm[1], fm[2])
                pitch = math.atan2(fm[0], math.hypot(fm[1], fm[2]))
                Cl = euler_to_dcm(roll, pitch, 0.0)  # body -> level (yaw 0)
                wl = Cl @ wm
                yaw = math.atan2(wl[0], wl[1])  # w_level = Rz(-yaw) (0, Om, .)
                rpy[s] = roll, pitch, yaw
                sd_att[s] = acc_sd[1] / g0, acc_sd[0] / g0, gyro_sd / Om
                k0[s] = idx[je]
                j0 = je
                done = True
        if not done:
            js = np.flatnonzero(moving[s])
            if len(js) == 0:
                continue
            j0 = js[0]
            if geo:
                C_ln[s] = frame.C_ln(gnss.p_n[s, j0])
            v = C_ln[s] @ gnss.v_n[s, j0]  # heading from the velocity in the local level
            sp = math.hypot(v[0], v[1])
            rpy[s] = 0.0, math.atan2(v[2], sp), math.atan2(v[1], v[0])
            svh = float(gnss.sigma_v_n[s, j0, 0])
            sd_att[s] = (
                level_sd_rad,
                math.hypot(level_sd_rad, svh / sp),
                math.hypot(svh / sp, heading_sd_rad),
            )
            k0[s] = idx[j0]
        C = C_ln[s].T @ euler_to_dcm(*rpy[s])
        lb = gnss.params.lever_arm_b_m[s]
        v0[s] = gnss.v_n[s, j0]
        # the fix is late by the latency: carry it forward to the epoch
        lat = float(gnss.params.latency_s[s]) if opts.latency else 0.0
        p0[s] = gnss.p_n[s, j0] - C @ lb + lat * v0[s]
        if done:
            v0[s] = 0.0
        sd_p[s] = gnss.sigma_p_n[s, j0]
        sd_v[s] = gnss.sigma_v_n[s, j0]
    C0 = euler_to_dcm(rpy[:, 0], rpy[:, 1], rpy[:, 2])
    q0 = dcm_to_quat(np.swapaxes(C_ln, 1, 2) @ C0 if geo else C0)
    gb = None
    if opts.gnss_bias and tuning_T is not None:
        gb = tuning_T[:, T_GB_SD : T_GB_SD + 3]
        sd_p = np.sqrt(gb**2 + tuning_T[:, T_GW : T_GW + 3] ** 2)
    osd, bsd = (0.0, 0.0) if tuning_T is None else (tuning_T[:, T_OSF_SD], tuning_T[:, T_BB_SD])
    P0 = initial_covariance(tun, opts, sd_p, sd_v, sd_att, gb, osd, bsd)
    if geo:  # the sigmas are along the local axes: P_n = T P_l T^T, T = C_nl on p, v, psi
        n = opts.n
        Tr = np.broadcast_to(np.eye(n), (S, n, n)).copy()
        for key in ("p", "v", "att"):
            blk = opts.layout.slice(key)
            Tr[:, blk, blk] = np.swapaxes(C_ln, 1, 2)
        P0 = Tr @ P0 @ np.swapaxes(Tr, 1, 2)
    return initial_state(k0, p0, v0, q0, P0)
