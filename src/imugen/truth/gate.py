"""The truth's pre-write gate: a truth is a motion its vehicle makes, or it is not written.

:func:`findings` checks every sample of a built truth against its vehicle class's limits
(:class:`imugen.truth.vehicles.VehicleParams`) and finds, per limit, the worst place that
exceeds it: speed (3-D), |acceleration| and |jerk| (finite differences of the velocity;
the jerk limit is the class's own, :data:`imugen.truth.vehicles.JERK_SOURCES`),
on the ground the pitch (beyond the road's grade limit, on a suspension, by
:func:`imugen.truth.report.suspension_pitch_margin_rad`), the roll (zero, or a leaning
vehicle's lean, or on a suspension the body roll, bounded by ``max_roll_rad``), the turn rate beyond
``horizontal speed x max curvature`` (turning on the spot); in flight the pitch, the bank and the turn rate; everywhere an attitude step beyond
what the rates allow; and the height against the input's: never below the lowest input
height, and for ground vehicles never above the highest, by more than
:data:`HEIGHT_TOL_M` (a flight fitted underground, a road profile overshooting a hill).

The truth stage (:func:`imugen.truth.stage.run`) refuses a truth with findings in one line
(:func:`refusal`: the file, the time, the place and the limit; exit status 2, nothing
written). Cleaning happens before: ingestion cleans the input (heights interpolated, spikes
removed), the fit smooths locally where it exceeds the vehicle's curvature or acceleration limit,
within the input's noise (:mod:`imugen.truth.fit`). On the ground the body's lateral speed
(a sideways slide at a bend tighter than the vehicle turns) is gated on untimed paths
(``slip``: the geometry is the project's own, its bends widened to the vehicle's least
turning radius and the speed profile slowed for them, :func:`imugen.truth.fit.fit_path`)
against ``max_slip_mps``; on timed routes it is reported (:mod:`imugen.truth.report`), not
gated: real timed tracks still slip up to 3 m/s at a few bends after the fit's local
smoothing (the mountain-pass drive 3.3 m/s, a bicycle computer's track 2.9 m/s).
"""

from __future__ import annotations

import math

import numpy as np

from imugen.core import rotations as rot
from imugen.tables import truth as col
from imugen.truth.report import (
    STEP_TOL_RAD,
    YAW_EXCESS_TOL_RADPS,
    in_intervals,
    local_velocity,
    suspension_pitch_margin_rad,
    turn_rate,
    yaw_axis_turn_rate,
)
from imugen.truth.vehicles import has_suspension

HEIGHT_TOL_M = 30.0
"""Largest height of a truth below the lowest input height (and, on the ground, above the
highest) [m]: a road profile's residual against noisy GNSS heights stays well within it."""

ANGLE_TOL_RAD = 1e-6
"""Tolerance on the bounded angles (pitch, roll, bank) [rad]: they are soft-bounded."""


def _worst(name, x, limit, unit, mask=None):
    """(name, value, limit, unit, index) of the largest ``x`` beyond ``limit`` (within
    ``mask``), or None."""
    x = np.where(np.ones(len(x), bool) if mask is None else mask, x, -np.inf)
    if not x.size:
        return None
    k = int(np.argmax(x))
    if not x[k] > limit:
        return None
    return {"limit": name, "value": float(x[k]), "bound": float(limit), "unit": unit, "index": k}


def findings(
    df, vp, *, frame, airborne=None, input_heights=None, slip=False, turns_at_rest=()
) -> list[dict]:
    """The vehicle limits a truth exceeds, each at its worst sample.

    Parameters
    ----------
    df : DataFrame
        Truth table (:data:`imugen.tables.truth.COLUMNS`).
    vp : imugen.truth.vehicles.VehicleParams
    frame : imugen.core.earth.OriginFrame
        The truth's Earth model (local level, heights, places).
    airborne : ndarray of bool, shape (K,), optional
        Samples in flight (the ground limits do not apply there).
    input_heights : ndarray, shape (N,), optional
        Heights of the input points [m] (ellipsoidal; n's Up in ``flat``).
    slip : bool
        Gate the body's lateral speed on the ground (ground classes, ``max_slip_mps``).
    turns_at_rest : sequence of (float, float)
        Intervals [s] of the declared turns at rest (a reversal's stop and turn,
        :mod:`imugen.truth.reversals`): not gated as turning on the spot.

    Returns
    -------
    list of dict
        ``limit`` (name), ``value``, ``bound``, ``unit``, ``t_s``, ``lat_deg``, ``lon_deg``,
        ``height_m``, ``distance_m`` (along the truth from its start), worst first by
        ``value / bound``.
    """
    t = df[col.TIME].to_numpy()
    K = len(t)
    if K < 3:
        return []
    p = df[list(col.POS)].to_numpy()
    v = df[list(col.VEL)].to_numpy()
    w = df[list(col.GYRO)].to_numpy()
    roll, pitch = (np.abs(df[c].to_numpy()) for c in col.EULER[:2])
    air = np.zeros(K, bool) if airborne is None else np.asarray(airborne, bool)
    gnd = ~air
    dt = np.diff(t)
    acc = np.diff(v, axis=0) / dt[:, None]
    jerk = np.diff(acc, axis=0) / (0.5 * (dt[1:] + dt[:-1]))[:, None]
    a_k = np.r_[0.0, np.linalg.norm(acc, axis=1)]  # on the sample ending the interval
    j_k = np.r_[0.0, np.linalg.norm(jerk, axis=1), 0.0]
    v_h = local_velocity(p, v, frame) if frame.model == "geodetic" else v
    vh = np.hypot(v_h[:, 0], v_h[:, 1])
    C_nb = rot.quat_to_dcm(df[list(col.QUAT)].to_numpy())
    susp = has_suspension(vp)
    # on a suspension the body's roll and pitch rates project onto the vertical on a grade
    # without turning it: the turn is judged by the yaw axis (as the report does)
    yaw = (yaw_axis_turn_rate if susp else turn_rate)(p, w, C_nb, frame)
    wn = np.linalg.norm(w, axis=1)
    dth = np.linalg.norm(df[list(col.DTHETA)].to_numpy()[1:], axis=1)
    step = np.r_[0.0, dth - (np.maximum(wn[1:], wn[:-1]) + np.abs(np.diff(wn))) * dt]
    lat, lon, h = frame.geodetic_from_n(p)
    checks = [
        _worst("speed", np.linalg.norm(v, axis=1), vp.max_speed_mps, "m/s"),
        _worst("acceleration", a_k, vp.max_accel_mps2, "m/s^2"),
        _worst("jerk", j_k, vp.max_jerk_mps3, "m/s^3"),
        _worst("attitude step beyond the rates", step, STEP_TOL_RAD, "rad"),
    ]
    if vp.attitude != "thrust":
        rlim = vp.max_roll_rad if vp.lean or susp else 0.0
        plim = vp.max_pitch_rad + (suspension_pitch_margin_rad(vp) if susp else 0.0)
        checks += [
            _worst("pitch on the ground", pitch, plim + ANGLE_TOL_RAD, "rad", gnd),
            _worst("roll on the ground", roll, rlim + ANGLE_TOL_RAD, "rad", gnd),
            _worst(
                "turn rate at speed (turning on the spot)",
                np.abs(yaw) - vp.max_curvature_1pm * vh,
                YAW_EXCESS_TOL_RADPS,
                "rad/s beyond speed x max curvature",
                gnd & ~in_intervals(t, turns_at_rest),
            ),
            _worst("pitch in flight", pitch, vp.max_pitch_airborne_rad + ANGLE_TOL_RAD, "rad", air),
            _worst("bank", roll, vp.max_roll_rad + ANGLE_TOL_RAD, "rad", air),
            _worst(
                "turn rate in flight", np.abs(yaw), vp.max_yaw_rate_airborne_radps, "rad/s", air
            ),
        ]
    if slip and vp.attitude == "ground":
        v_b = np.einsum("kji,kj->ki", C_nb, v)  # C_bn v
        checks.append(
            _worst(
                "slip (body lateral speed)",
                np.abs(v_b[:, 1]),
                vp.max_slip_mps,
                "m/s",
                gnd & ~in_intervals(t, turns_at_rest),
            )
        )
    if input_heights is not None and len(input_heights):
        lo, hi = float(np.min(input_heights)), float(np.max(input_heights))
        checks.append(
            _worst("height below the input's lowest", lo - h, HEIGHT_TOL_M, f"m below {lo:.0f} m")
        )
        if vp.attitude == "ground":
            checks.append(
                _worst(
                    "height above the input's highest", h - hi, HEIGHT_TOL_M, f"m above {hi:.0f} m"
                )
            )
    dist = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]
    out = []
    for c in checks:
        if c is None:
            continue
        k = c.pop("index")
        c.update(
            t_s=float(t[k]),
            lat_deg=math.degrees(float(lat[k])),
            lon_deg=math.degrees(float(lon[k])),
            height_m=float(h[k]),
            distance_m=float(dist[k]),
        )
        out.append(c)
    return sorted(out, key=lambda c: -c["value"] / max(c["bound"], 1e-12))


def _fmt(x, unit):
    if unit == "rad":
        return f"{math.degrees(x):.3g} deg"
    return f"{x:.3g} {unit}"


def refusal(found: list[dict], vehicle: str, written: bool = False) -> str:
    """One line refusing a truth with :func:`findings` ``found`` (worst first): where, what,
    the limit, and the other limits exceeded (``written``: the warning of a truth written
    anyway, ``--allow-implausible``)."""
    c = found[0]
    ns = "N" if c["lat_deg"] >= 0 else "S"
    ew = "E" if c["lon_deg"] >= 0 else "W"
    what = c["limit"]
    if what.startswith("height"):
        value = (
            f"{what} by {c['value']:.3g} m (limit {c['bound']:g} m, {c['unit'].split(' ', 1)[1]})"
        )
    else:
        value = f"{what} {_fmt(c['value'], c['unit'])} beyond the {vehicle} limit {_fmt(c['bound'], c['unit'])}"
    others = sorted({f["limit"] for f in found[1:]} - {what})
    more = f"; also {', '.join(others)}" if others else ""
    return (
        f"truth {'implausible' if written else 'refused'}, not a motion a {vehicle} makes: {value} at t = {c['t_s']:.1f} s "
        f"({abs(c['lat_deg']):.5f} {ns}, {abs(c['lon_deg']):.5f} {ew}, {c['height_m']:.0f} m; "
        f"{c['distance_m'] / 1e3:.3f} km along the route){more}"
        + ("; written anyway (--allow-implausible)" if written else "; nothing written")
    )
