"""Plausibility report of a truth: is it a motion the vehicle makes?

Figures from the truth table itself (so any truth, old or new, can be checked) and the input
points: largest |pitch|, |roll| (relative to the local level), yaw rate (the body's turn rate
about the local vertical, :func:`turn_rate`), |acceleration| and |jerk| (finite differences of
the velocity), the yaw rate beyond ``horizontal speed x max curvature`` (turning on the spot),
rate-versus-increment consistency (``dtheta_k`` against a
4th-order integral of the gyro columns, beyond that rule's own error estimate), attitude
steps beyond what the rates allow (``(max |w| + |dw|) dt`` per interval), truth
length against the input path length, fit residuals, the time stopped, moving and
airborne, and the body-frame velocity on the ground (sideslip and vertical slip angles while
moving, largest and RMS lateral and vertical body speeds, the fraction of the moving time slipping
beyond 0.1 deg; on a suspension also the vertical speed of the vehicle under the body's pitch on
it, the path's own vertical slip without the dive and squat). A warning names every vehicle limit exceeded.
"""

from __future__ import annotations

import math

import numpy as np

from imugen.core import earth as ea
from imugen.core import rotations as rot
from imugen.tables import truth as col
from imugen.truth.vehicles import has_suspension

# tolerances of the consistency checks (numerical, not vehicle limits)
RATE_INCREMENT_TOL_RADPS = 1e-3
STEP_TOL_RAD = 1e-3
YAW_EXCESS_TOL_RADPS = 1e-3
ROLL_ZERO_TOL_RAD = 1e-6
INVENTED_TOL = 0.01
SLIP_TOL_RAD = math.radians(0.1)  # slip counted in ``slip_fraction`` beyond this angle


def _integral(w, dt):
    """Integrals of the sampled rates over each interval, each (K-1, 3): the 4th-order rule
    ``dt (-w[k-1] + 13 w[k] + 13 w[k+1] - w[k+2]) / 24`` (trapezoid at the ends) and the
    trapezoid (their difference estimates the quadrature error)."""
    trap = 0.5 * (w[1:] + w[:-1]) * dt[:, None]
    out = trap.copy()
    if len(w) >= 4:
        inner = (-w[:-3] + 13.0 * w[1:-2] + 13.0 * w[2:-1] - w[3:]) / 24.0
        out[1:-1] = inner * dt[1:-1, None]
    return out, trap


def _invented(t, p, v, t_in):
    """Truth length beyond a circular arc over each interval between input times [m].

    Over an interval whose chord is ``c`` and whose tangent turns by ``alpha``, a vehicle
    driving no more than needed covers the arc ``c (alpha/2) / sin(alpha/2)``; sparse fixes
    on a winding road make the truth longer than the input polyline by exactly that, which
    is not invented. Wandering between fixes (bridged gaps) is.
    """
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    cum = np.r_[0.0, np.cumsum(seg)]
    ti = t_in[(t_in >= t[0]) & (t_in <= t[-1])]
    if len(ti) < 2:
        return 0.0
    L = np.diff(np.interp(ti, t, cum))
    k = np.clip(np.searchsorted(t, ti), 0, len(t) - 1)
    c = np.linalg.norm(np.diff(p[k], axis=0), axis=1)
    u = v[k] / np.maximum(np.linalg.norm(v[k], axis=1), 1e-9)[:, None]
    alpha = np.arccos(np.clip(np.einsum("ij,ij->i", u[1:], u[:-1]), -1.0, 1.0))
    h = 0.5 * alpha
    arc = c * np.where(h > 1e-6, h / np.maximum(np.sin(h), 1e-12), 1.0)
    return float(np.sum(np.maximum(L - arc, 0.0)))


def local_velocity(p_n, v_n, frame):
    """Velocity in the local level at the vehicle (ENU there), (K, 3) [m/s]."""
    return np.einsum("kij,kj->ki", frame.C_ln(p_n), v_n)


def in_intervals(t, intervals) -> np.ndarray:
    """Whether each time ``t`` (K,) [s] lies in one of ``intervals`` ((t0, t1) pairs [s])."""
    out = np.zeros(len(t), bool)
    for t0, t1 in intervals:
        out |= (t >= t0) & (t <= t1)
    return out


def turn_rate(p_n, w_ib_b, C_nb, frame=None):
    """Turn rate of the body: its rate relative to the Earth about the local vertical,
    ``u_n . (C_nb omega_ib_b - Omega_n)``, shape (K,) [rad/s].

    The yaw rate relative to a level that does not turn about the vertical (wander azimuth):
    defined at the poles, where the yaw from geographic North turns by 180 deg as the
    vehicle passes. ``p_n`` (K, 3), ``w_ib_b`` (K, 3) [rad/s], ``C_nb`` (K, 3, 3);
    ``frame`` None or ``flat``: n's Up and no Earth rate.
    """
    w_n = np.einsum("kij,kj->ki", C_nb, w_ib_b)
    if frame is None or frame.model == "flat":
        return w_n[:, 2]
    up_n = frame.C_ln(p_n)[:, 2, :]  # the local Up resolved in n
    return np.einsum("ki,ki->k", up_n, w_n - ea.earth_rate_n(frame))


def yaw_axis_turn_rate(p_n, w_ib_b, C_nb, frame=None):
    """The part of :func:`turn_rate` about the body's own z axis, ``(u_b)_z (omega_eb_b)_z``,
    shape (K,) [rad/s]: the turn of a body that rolls and pitches on a suspension, whose roll
    and pitch rates project onto the vertical on a grade or in a lean without turning it."""
    up_n = np.array([0.0, 0.0, 1.0]) if frame is None or frame.model == "flat" else None
    if up_n is None:
        up = frame.C_ln(p_n)[:, 2, :]
        w_eb = w_ib_b - np.einsum("kji,j->ki", C_nb, ea.earth_rate_n(frame))
    else:
        up = np.broadcast_to(up_n, (len(C_nb), 3))
        w_eb = w_ib_b
    up_bz = np.einsum("ki,ki->k", C_nb[:, :, 2], up)
    return up_bz * w_eb[:, 2]


def _rms(x, dts, mask):
    w = dts * mask
    return float(np.sqrt(np.sum(w * x * x) / np.sum(w))) if np.sum(w) > 0 else 0.0


def _path_length(p):
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))) if len(p) > 1 else 0.0


def plausibility(
    df,
    vp,
    *,
    input_enu=None,
    input_time=None,
    fit=None,
    airborne=None,
    frame=None,
    turns_at_rest=(),
    suspension_pitch_rad=None,
) -> dict:
    """Plausibility figures and warnings of a truth table.

    Parameters
    ----------
    df : DataFrame
        Truth table (:data:`imugen.tables.truth.COLUMNS`).
    vp : imugen.truth.vehicles.VehicleParams
        The vehicle's limits.
    input_enu : ndarray, shape (N, 3), optional
        Input points (ENU) [m]: the path length the truth is compared with.
    input_time : ndarray, shape (N,), optional
        Their times [s] (timed routes): length invented between fixes.
    fit : dict, optional
        Fit report of the truth (``rms_distance_m``, ``max_distance_m``).
    airborne : ndarray of bool, shape (K,), optional
        Samples in flight (ground-vehicle limits do not apply there).
    frame : imugen.core.earth.OriginFrame, optional
        The truth's Earth model; in ``geodetic`` (ECEF) the horizontal speed is taken in the
        local level at the vehicle (default: n's East-North plane).
    turns_at_rest : sequence of (float, float)
        Intervals [s] of the declared turns at rest (a reversal's stop and turn): not
        counted as turning on the spot.
    suspension_pitch_rad : ndarray, shape (K,), optional
        The body's pitch on its suspension ``theta_s`` (:mod:`imugen.truth.suspension`):
        taken out of the body velocity for the vehicle's own vertical slip
        (``*_vehicle_vertical_speed_mps``; without it, the body's).

    Returns
    -------
    dict
        Figures (SI and degrees as named) and ``warnings`` (list of str).
    """
    t = df[col.TIME].to_numpy()
    K = len(t)
    dt = np.diff(t)
    v = df[list(col.VEL)].to_numpy()
    p = df[list(col.POS)].to_numpy()
    roll, pitch = (df[c].to_numpy() for c in col.EULER[:2])
    w = df[list(col.GYRO)].to_numpy()
    dth = df[list(col.DTHETA)].to_numpy()[1:]
    air = np.zeros(K, bool) if airborne is None else np.asarray(airborne, bool)
    gnd = ~air
    v_h = v if frame is None or frame.model != "geodetic" else local_velocity(p, v, frame)
    vh = np.hypot(v_h[:, 0], v_h[:, 1])
    speed = np.linalg.norm(v, axis=1)
    acc = np.diff(v, axis=0) / dt[:, None]
    jerk = np.diff(acc, axis=0) / (0.5 * (dt[1:] + dt[:-1]))[:, None] if K > 2 else acc[:0]
    C_nb = rot.quat_to_dcm(df[list(col.QUAT)].to_numpy())
    yaw_rate = turn_rate(p, w, C_nb, frame)
    # on a suspension the body's roll and pitch rates project onto the vertical on a grade:
    # the turn is judged by the body's yaw axis
    turn = yaw_axis_turn_rate(p, w, C_nb, frame) if has_suspension(vp) else yaw_rate
    yaw_excess = np.abs(turn) - vp.max_curvature_1pm * vh
    yaw_excess[in_intervals(t, turns_at_rest)] = 0.0  # a reversal's declared turn at rest
    wn = np.linalg.norm(w, axis=1)
    i4, itrap = _integral(w, dt)
    # beyond the quadrature's own error (4th-order rule against the trapezoid) ...
    rate_inc = (np.linalg.norm(dth - i4, axis=1) - 10.0 * np.linalg.norm(i4 - itrap, axis=1)) / dt
    # ... and beyond the angle the rates allow (peak between samples: |w_k+1 - w_k| dt)
    dw = np.linalg.norm(np.diff(w, axis=0), axis=1)
    step = np.linalg.norm(dth, axis=1) - (np.maximum(wn[1:], wn[:-1]) + dw) * dt

    def mx(x, mask=None):
        x = x if mask is None else x[mask]
        return float(np.max(np.abs(x))) if x.size else 0.0

    stopped = speed < vp.stop_speed_mps
    dts = np.r_[dt, 0.0] if K > 1 else np.zeros(1)
    # body-frame velocity on the ground: a car's (non-holonomic) has no y and z components
    v_b = np.einsum("kji,kj->ki", C_nb, v)
    # ... and of the vehicle under the body's pitch on its suspension (the dive and squat,
    # C_nb = C_nv Ry(-theta_s): v_v = Ry(-theta_s) v_b): the path's own vertical slip
    v_v = v_b
    if suspension_pitch_rad is not None:
        th = np.asarray(suspension_pitch_rad, float)
        v_v = np.einsum("kij,kj->ki", rot.euler_to_dcm(0.0 * th, th, 0.0 * th), v_b)
    mov = ~stopped & gnd
    slip = np.arctan2(np.abs(v_b[:, 1:]), np.maximum(np.abs(v_b[:, :1]), 1e-12))  # (K, 2)
    t_mov = float(np.sum(dts[mov]))
    L_truth = _path_length(p)
    L_in = None if input_enu is None else _path_length(np.asarray(input_enu, float))
    rep = {
        "max_abs_pitch_deg": math.degrees(mx(pitch, gnd)),
        "max_abs_roll_deg": math.degrees(mx(roll, gnd)),
        "max_abs_pitch_airborne_deg": math.degrees(mx(pitch, air)),
        "max_abs_roll_airborne_deg": math.degrees(mx(roll, air)),
        "max_yaw_rate_dps": math.degrees(mx(yaw_rate)),
        "max_yaw_rate_airborne_dps": math.degrees(mx(yaw_rate, air)),
        "max_yaw_rate_excess_dps": math.degrees(
            max(0.0, float(np.max(yaw_excess[gnd], initial=0)))
        ),
        "max_speed_mps": float(speed.max()),
        "max_accel_mps2": mx(np.linalg.norm(acc, axis=1)),
        "max_jerk_mps3": mx(np.linalg.norm(jerk, axis=1)),
        "max_rate_increment_radps": max(0.0, float(np.max(rate_inc, initial=0.0))),
        "max_attitude_step_excess_rad": max(0.0, float(np.max(step, initial=0.0))),
        "length_truth_m": L_truth,
        "length_input_m": L_in,
        "length_ratio": None if not L_in else L_truth / L_in,
        "invented_m": None if input_time is None else _invented(t, p, v, input_time),
        "fit_rms_m": None if fit is None else fit.get("rms_distance_m"),
        "fit_max_m": None if fit is None else fit.get("max_distance_m"),
        "time_stopped_s": float(np.sum(dts[stopped & gnd])),
        "time_moving_s": float(np.sum(dts[~stopped & gnd])),
        "time_airborne_s": float(np.sum(dts[air])),
        "max_sideslip_deg": math.degrees(mx(slip[:, 0], mov)),
        "max_vertical_slip_deg": math.degrees(mx(slip[:, 1], mov)),
        "max_body_lateral_speed_mps": mx(v_b[:, 1], gnd),
        "max_body_vertical_speed_mps": mx(v_b[:, 2], gnd),
        "rms_body_lateral_speed_mps": _rms(v_b[:, 1], dts, gnd),
        "rms_body_vertical_speed_mps": _rms(v_b[:, 2], dts, gnd),
        "max_vehicle_vertical_speed_mps": mx(v_v[:, 2], gnd),
        "rms_vehicle_vertical_speed_mps": _rms(v_v[:, 2], dts, gnd),
        "slip_fraction": (
            float(np.sum(dts[mov & (slip.max(axis=1) > SLIP_TOL_RAD)])) / t_mov if t_mov else 0.0
        ),
    }
    rep["invented_fraction"] = (
        None if rep["invented_m"] is None or not L_in else rep["invented_m"] / L_in
    )
    rep["warnings"] = _warnings(rep, vp)
    return rep


def suspension_pitch_margin_rad(vp) -> float:
    """Largest pitch of a body on its suspension beyond the road's grade [rad]: the pitch
    gradient x the largest plausible acceleration (the suspension's input is capped there,
    :mod:`imugen.truth.suspension`) with the step response's overshoot (x 1.3: the overshoot
    of a damping ratio of 0.4 is 1.25)."""
    return 1.3 * vp.pitch_gradient_radpmps2 * vp.max_accel_mps2


def _warnings(r, vp) -> list[str]:
    out = []
    susp = has_suspension(vp)
    pmax = math.degrees(vp.max_pitch_rad + (suspension_pitch_margin_rad(vp) if susp else 0.0))
    if r["max_abs_pitch_deg"] > pmax + 1e-6:
        out.append(
            f"|pitch| on the ground reaches {r['max_abs_pitch_deg']:.1f} deg (limit {pmax:.1f})"
        )
    rlim = math.degrees(vp.max_roll_rad if vp.lean or susp else ROLL_ZERO_TOL_RAD)
    if r["max_abs_roll_deg"] > rlim:
        out.append(
            f"|roll| on the ground reaches {r['max_abs_roll_deg']:.3g} deg (limit {rlim:.3g})"
        )
    if r["max_abs_roll_airborne_deg"] > math.degrees(vp.max_roll_rad) + 1e-6:
        out.append(f"bank reaches {r['max_abs_roll_airborne_deg']:.1f} deg")
    if r["max_abs_pitch_airborne_deg"] > math.degrees(vp.max_pitch_airborne_rad):
        out.append(
            f"|pitch| in flight reaches {r['max_abs_pitch_airborne_deg']:.1f} deg "
            f"(limit {math.degrees(vp.max_pitch_airborne_rad):.1f})"
        )
    if r["max_yaw_rate_airborne_dps"] > math.degrees(vp.max_yaw_rate_airborne_radps):
        out.append(
            f"turn rate in flight reaches {r['max_yaw_rate_airborne_dps']:.2f} deg/s "
            f"(limit {math.degrees(vp.max_yaw_rate_airborne_radps):.2f})"
        )
    if r["max_yaw_rate_excess_dps"] > math.degrees(YAW_EXCESS_TOL_RADPS):
        out.append(
            f"yaw rate exceeds speed x max curvature ({vp.max_curvature_1pm:g}/m) by "
            f"{r['max_yaw_rate_excess_dps']:.3g} deg/s (turning on the spot)"
        )
    if r["max_speed_mps"] > vp.max_speed_mps:
        out.append(f"speed reaches {r['max_speed_mps']:.1f} m/s (limit {vp.max_speed_mps:g})")
    if r["max_accel_mps2"] > vp.max_accel_mps2:
        out.append(
            f"|acceleration| reaches {r['max_accel_mps2']:.2f} m/s^2 (limit {vp.max_accel_mps2:g})"
        )
    if r["max_rate_increment_radps"] > RATE_INCREMENT_TOL_RADPS:
        out.append(
            f"dtheta and the gyro columns disagree by {r['max_rate_increment_radps']:.3g} rad/s"
        )
    if r["max_attitude_step_excess_rad"] > STEP_TOL_RAD:
        out.append(
            f"attitude steps {r['max_attitude_step_excess_rad']:.3g} rad beyond what the rates allow"
        )
    inv = r["invented_fraction"]
    if inv is not None and inv > INVENTED_TOL:
        out.append(
            f"{r['invented_m']:.0f} m of the truth ({100 * inv:.1f} % of the input path) lie "
            "beyond the arcs between fixes: motion the input does not show"
        )
    return out


def report_lines(rep: dict) -> list[str]:
    """Human-readable lines of a report (stderr)."""
    inv = rep["invented_fraction"]
    lines = [
        "truth plausibility: "
        f"|pitch| <= {rep['max_abs_pitch_deg']:.1f} deg, |roll| <= {rep['max_abs_roll_deg']:.1f} deg "
        f"(airborne {rep['max_abs_pitch_airborne_deg']:.1f}, {rep['max_abs_roll_airborne_deg']:.1f}), "
        f"yaw rate <= {rep['max_yaw_rate_dps']:.1f} deg/s, |a| <= {rep['max_accel_mps2']:.2f} m/s^2, "
        f"|jerk| <= {rep['max_jerk_mps3']:.2f} m/s^3",
        f"  dtheta vs gyro <= {rep['max_rate_increment_radps']:.2e} rad/s, attitude step excess "
        f"{rep['max_attitude_step_excess_rad']:.2e} rad; length {rep['length_truth_m']:.0f} m"
        + ("" if rep["length_input_m"] is None else f" vs input path {rep['length_input_m']:.0f} m")
        + ("" if inv is None else f", invented {rep['invented_m']:.0f} m ({100 * inv:.2f} %)"),
        f"  stopped {rep['time_stopped_s']:.0f} s, moving {rep['time_moving_s']:.0f} s, "
        f"airborne {rep['time_airborne_s']:.0f} s; body lateral / vertical speed RMS "
        f"{rep['rms_body_lateral_speed_mps']:.2g} / {rep['rms_body_vertical_speed_mps']:.2g} "
        f"m/s, slip <= {rep['max_sideslip_deg']:.2g} / {rep['max_vertical_slip_deg']:.2g} deg "
        f"(beyond 0.1 deg {100 * rep['slip_fraction']:.1f} % of the moving time)"
        + (
            ""
            if rep["fit_rms_m"] is None
            else f"; fit RMS {rep['fit_rms_m']:.2f} m, max {rep['fit_max_m']:.2f} m"
        ),
    ]
    return lines + [f"imugen: warning: truth: {w}" for w in rep["warnings"]]
