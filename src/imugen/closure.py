"""Zero-error closure: route file -> ingest -> truth -> mechanization of the ideal increments.

The truth generator's exact increments integrated by :mod:`imugen.navigate.mechanize` must give back the
truth trajectory; the residual measures the consistency of the two (and float64 rounding).
The mechanization runs in time chunks and compares each chunk with the truth as it goes, so
long runs (1 kHz for an hour) need no full-length navigation arrays.

The position error is split at the true position into its horizontal and vertical parts
(local level, geodetic up). The vertical channel follows :mod:`imugen.navigate.vertical`
(``auto``: damped by the truth's height beyond 3 growth times of the free channel, where a
free closure grows as ``exp(t / 570 s)`` and leaves the planet within hours). The ``free``
block states what the free channel would do: a free run over ``t1 = min(D, 3 tau)`` measures
its seed (the vertical error and rate at ``t1``: discretization and rounding of the first
minutes) and the linearized growth carries it to the route's end
(:func:`imugen.navigate.vertical.free_growth`; horizontal: ``(4/3) Omega tau cos(lat)`` times).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imugen.core.options import Command, argument, option, same_as
from imugen.ingest.options import IngestOptions
from imugen.navigate.options import NavigateOptions
from imugen.truth.options import TruthOptions

CHUNK = 1 << 16  # samples per mechanization chunk


@dataclass(frozen=True, kw_only=True)
class ClosureOptions:
    """Options of ``imugen closure``: the truth's and ingestion's that shape the scene."""

    rate_hz: float = same_as(TruthOptions, "rate_hz")
    earth: str = same_as(TruthOptions, "earth")
    vehicle: str = same_as(TruthOptions, "vehicle")
    path: str | int | None = same_as(IngestOptions, "path")
    origin: str | None = same_as(IngestOptions, "origin")
    dt: float | None = same_as(IngestOptions, "dt")
    grade: str | None = option(None, help="grade for the `--earth auto` budget", shown="consumer")
    vertical: str = same_as(NavigateOptions, "vertical")
    vertical_order: int = same_as(NavigateOptions, "vertical_order")
    vertical_time_constant_s: float = same_as(NavigateOptions, "vertical_time_constant_s")


COMMANDS = {
    "closure": Command(
        ClosureOptions,
        "imugen.closure:main",
        (argument("src", help="any route file ingestion reads"),),
    )
}


def attitude_angle(q_ref, q) -> np.ndarray:
    """Rotation angle between unit quaternions (rad), sign-insensitive; (..., 4) -> (...).

    ``2 asin |vec(q_ref^-1 q)|`` (accurate for small angles).
    """
    a = np.asarray(q_ref, dtype=float)
    b = np.asarray(q, dtype=float)
    aw, ax, ay, az = a[..., 0], -a[..., 1], -a[..., 2], -a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    s = np.sqrt(x * x + y * y + z * z)
    return 2.0 * np.arcsin(np.minimum(1.0, s))


def closure_of_truth(
    df,
    meta,
    *,
    chunk: int = CHUNK,
    vertical: str = "auto",
    vertical_order: int = 3,
    vertical_time_constant_s: float = 100.0,
) -> dict:
    """Mechanize a truth table's increments and compare with its trajectory.

    Parameters
    ----------
    df : DataFrame
        Truth table (:data:`imugen.tables.truth.COLUMNS`).
    meta : dict
        Its metadata (``origin``, ``earth``).
    chunk : int
        Samples per mechanization call.
    vertical, vertical_order, vertical_time_constant_s
        Vertical channel (:func:`imugen.navigate.vertical.resolve`; reference: the truth's
        height).

    Returns
    -------
    dict
        ``final_position_error_m``, ``max_position_error_m``, ``horizontal_final_m``,
        ``horizontal_max_m``, ``vertical_final_m``, ``vertical_max_m``,
        ``final_attitude_error_rad``, ``max_attitude_error_rad``, ``max_velocity_error_mps``,
        ``samples``, ``mechanization_seconds``, ``vertical_channel`` (the record of
        :meth:`~imugen.navigate.vertical.VerticalChannel.meta`) and ``free`` (the free
        channel's growth: module docstring).
    """
    from imugen.core import earth
    from imugen.navigate import vertical as vch
    from imugen.navigate.mechanize import reference_heights
    from imugen.tables import truth as col

    t0 = time.perf_counter()
    frame = col.origin_frame(meta)
    t = df[col.TIME].to_numpy()
    K = len(t)
    P = df[list(col.POS)].to_numpy()
    V = df[list(col.VEL)].to_numpy()
    Q = df[list(col.QUAT)].to_numpy()
    dth = df[list(col.DTHETA)].to_numpy()
    dv = df[list(col.DV)].to_numpy()
    D = float(t[-1] - t[0]) if K else 0.0
    vc = vch.resolve(
        vertical, frame, D, order=vertical_order, time_constant_s=vertical_time_constant_s
    )
    if K < 2:
        zero = dict.fromkeys(_ERROR_KEYS, 0.0)
        return {**zero, "samples": K, "mechanization_seconds": 0.0,
                "vertical_channel": vc.meta(), "free": None}  # fmt: skip
    # the truth's own step (t[1] - t[0] carries the rounding of t[0]: 2e-12 s at t0 = 9,000 s,
    # a gravity bias of 4e-10 m/s^2 over the run)
    rate = meta.get("rate_hz")
    dt = 1.0 / float(rate) if rate else float((t[-1] - t[0]) / (K - 1))
    h_ref, up = reference_heights(P, frame, with_up=True)
    res = _run(frame, dt, P, V, Q, dth, dv, up, h_ref, vc.kernel_gains(), K, chunk)
    if not all(np.isfinite([res["max_position_error_m"], res["max_velocity_error_mps"],
                            res["max_attitude_error_rad"]])):  # fmt: skip
        raise FloatingPointError("mechanization produced non-finite values")
    # the free channel: its seed over t1 = min(D, 3 tau), carried to D by the linear growth
    tau = vc.growth_time_s
    n1 = K if not np.isfinite(tau) else min(K, 1 + round(vch.AUTO_FACTOR * tau / dt))
    if vc.damped or n1 < K:
        seed = _run(frame, dt, P, V, Q, dth, dv, up, h_ref, np.zeros(3), n1, chunk)
    else:
        seed = res
    t1 = float(t[n1 - 1] - t[0])
    dh1, dv1 = seed["_dh"], seed["_dvu"]
    if np.isfinite(tau):
        exp_v = vch.free_growth(dh1, dv1, t1, D, tau)
        ratio = vch.SCHULER_RATIO * earth.OMEGA_IE * tau * math.cos(frame.lat0_rad)
    else:  # flat: constant gravity, the free channel is neutral (no growth)
        exp_v, ratio = abs(dh1), 0.0
    free = {
        "growth_time_s": tau if np.isfinite(tau) else None,
        "growth_factor": vc.growth_factor if np.isfinite(vc.growth_factor) else None,
        "seed_time_s": t1,
        "seed_vertical_m": dh1,
        "seed_vertical_rate_mps": dv1,
        "expected_vertical_m": exp_v if np.isfinite(exp_v) else None,
        "expected_horizontal_m": ratio * exp_v if np.isfinite(exp_v) else None,
        "linear": bool(np.isfinite(exp_v) and exp_v < 1e5),
    }
    if not vc.damped:
        free["vertical_final_m"] = res["vertical_final_m"]
        free["horizontal_final_m"] = res["horizontal_final_m"]
    out = {k: v for k, v in res.items() if not k.startswith("_")}
    out.update(
        {
            "samples": K,
            "mechanization_seconds": time.perf_counter() - t0,
            "vertical_channel": vc.meta(),
            "free": free,
        }
    )
    return out


_ERROR_KEYS = (
    "final_position_error_m",
    "max_position_error_m",
    "horizontal_final_m",
    "horizontal_max_m",
    "vertical_final_m",
    "vertical_max_m",
    "final_attitude_error_rad",
    "max_attitude_error_rad",
    "max_velocity_error_mps",
)


def _run(frame, dt, P, V, Q, dth, dv, up, h_ref, gains, K, chunk) -> dict:
    """Mechanize samples ``0 .. K-1`` of a truth in chunks and gather the errors (H/V split
    along ``up``, the local up at the true positions); ``_dh``, ``_dvu``: the signed vertical
    position and velocity errors at the last sample."""
    from imugen.navigate.mechanize import Mechanizer

    mech = Mechanizer(frame, dt, P[0], V[0], Q[0], gains=gains)
    chunk = max(int(chunk), 2)  # the first chunk needs two steps (look-ahead start)
    out_p = np.empty((1, chunk, 3))
    out_v = np.empty((1, chunk, 3))
    out_q = np.empty((1, chunk, 4))
    m = dict.fromkeys(_ERROR_KEYS, 0.0)
    dh = dvu = 0.0
    # increments of the interval ending at row k sit on row k: sample j = 1..K-1
    for a in range(1, K, chunk):
        b = min(K, a + chunk)
        n = b - a
        href = h_ref[None, a - 1 : b] if mech.damped else None
        mech.run(dth[None, a:b], dv[None, a:b], out_p=out_p, out_v=out_v, out_q=out_q,
                 out_start=a, href=href)  # fmt: skip
        e = out_p[0, :n] - P[a:b]
        u = up[a:b]
        ev = np.einsum("ij,ij->i", e, u)
        eh = np.linalg.norm(e - ev[:, None] * u, axis=1)
        e_p = np.linalg.norm(e, axis=1)
        e_vel = out_v[0, :n] - V[a:b]
        e_a = attitude_angle(Q[a:b], out_q[0, :n])
        m["max_position_error_m"] = max(m["max_position_error_m"], float(e_p.max()))
        m["horizontal_max_m"] = max(m["horizontal_max_m"], float(eh.max()))
        m["vertical_max_m"] = max(m["vertical_max_m"], float(np.abs(ev).max()))
        m["max_velocity_error_mps"] = max(m["max_velocity_error_mps"], float(np.abs(e_vel).max()))
        m["max_attitude_error_rad"] = max(m["max_attitude_error_rad"], float(e_a.max()))
        m["final_position_error_m"] = float(e_p[-1])
        m["horizontal_final_m"] = float(eh[-1])
        m["vertical_final_m"] = float(abs(ev[-1]))
        m["final_attitude_error_rad"] = float(e_a[-1])
        dh = float(ev[-1])
        dvu = float(e_vel[-1] @ u[-1])
    m["_dh"] = dh
    m["_dvu"] = dvu
    return m


def closure(
    src,
    *,
    rate_hz: float = 100.0,
    earth: str = "flat",
    path=None,
    origin=None,
    vehicle: str = "car",
    dt: float | None = None,
    grade: str | None = None,
    vertical: str = "auto",
    vertical_order: int = 3,
    vertical_time_constant_s: float = 100.0,
    **truth_options,
) -> dict:
    """Route file -> ingest -> truth -> strapdown of the ideal increments -> errors.

    Parameters
    ----------
    src : path-like
        Any route file ingestion reads.
    rate_hz : float
        IMU rate.
    earth : {"flat", "wgs84", "geodetic", "auto"}
        Earth model of truth and mechanization (``geodetic``: ECEF, routes of any length).
    path, origin, dt
        Ingestion options (path selection, ENU origin ``"LAT,LON,H"``, uniform time step of
        an untimed path).
    vehicle : {"car", "pedestrian", "aircraft"}
        Attitude model of the truth.
    grade : str, optional
        Grade for the ``auto`` Earth-model budget.
    vertical, vertical_order, vertical_time_constant_s
        Vertical channel of the mechanization (:func:`closure_of_truth`).
    **truth_options
        Passed to :func:`imugen.truth.build_truth` (e.g. ``cruise_mps``, ``fit_tol_m``).

    Returns
    -------
    dict
        JSON-ready: the fields of :func:`closure_of_truth` (``horizontal_final_m``,
        ``vertical_final_m``, ``vertical_channel``, ``free``, ...), ``final_attitude_error_rad``, ``max_attitude_error_rad``, ``max_velocity_error_mps``,
        ``samples`` (IMU samples), ``duration_s`` (scene), ``seconds`` (wall time of the whole
        run) with its parts ``truth_seconds`` and ``mechanization_seconds``, and ``earth``,
        ``rate_hz``, ``vehicle``, ``source``.

    Raises
    ------
    imugen.core.errors.InputError
        From ingestion or truth generation, for inputs they refuse.
    """
    from imugen.ingest.stage import ingest
    from imugen.tables import truth as col
    from imugen.truth.build import build_truth

    t0 = time.perf_counter()
    ing = ingest(src, path=path, origin=origin, dt=dt, vehicle=vehicle)
    t1 = time.perf_counter()
    df, meta = build_truth(
        ing.table,
        ing.meta,
        rate_hz=rate_hz,
        earth=earth,
        vehicle=vehicle,
        grade=grade,
        verbose=False,
        **truth_options,
    )
    t2 = time.perf_counter()
    res = closure_of_truth(
        df,
        meta,
        vertical=vertical,
        vertical_order=vertical_order,
        vertical_time_constant_s=vertical_time_constant_s,
    )
    res.update(
        {
            "duration_s": float(
                meta.get("duration_s", df[col.TIME].iloc[-1] - df[col.TIME].iloc[0])
            ),
            "seconds": time.perf_counter() - t0,
            "ingest_seconds": t1 - t0,
            "truth_seconds": t2 - t1,
            "earth": meta["earth"],
            "rate_hz": float(rate_hz),
            "vehicle": vehicle,
            "source": str(Path(src)),
        }
    )
    return res


def main(options: ClosureOptions, src) -> None:
    """``imugen closure``: the closure of ``src`` as one JSON line on stdout."""
    o = options
    result = closure(
        src, rate_hz=o.rate_hz, earth=o.earth, vehicle=o.vehicle, path=o.path, origin=o.origin,
        dt=o.dt, grade=o.grade, vertical=o.vertical, vertical_order=o.vertical_order,
        vertical_time_constant_s=o.vertical_time_constant_s,
    )  # fmt: skip
    print(json.dumps(result))
