"""Zero-error closure: route file -> ingest -> truth -> mechanization of the ideal increments.

The truth generator's exact increments integrated by :mod:`imugen.navigate.mechanize` must give back the
truth trajectory; the residual measures the consistency of the two (and float64 rounding).
The mechanization runs in time chunks and compares each chunk with the truth as it goes, so
long runs (1 kHz for an hour) need no full-length navigation arrays.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imugen.core.options import Command, argument, option, same_as
from imugen.ingest.options import IngestOptions
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


def closure_of_truth(df, meta, *, chunk: int = CHUNK) -> dict:
    """Mechanize a truth table's increments and compare with its trajectory.

    Parameters
    ----------
    df : DataFrame
        Truth table (:data:`imugen.tables.truth.COLUMNS`).
    meta : dict
        Its metadata (``origin``, ``earth``).
    chunk : int
        Samples per mechanization call.

    Returns
    -------
    dict
        ``final_position_error_m``, ``max_position_error_m``, ``final_attitude_error_rad``,
        ``max_attitude_error_rad``, ``max_velocity_error_mps``, ``samples``,
        ``mechanization_seconds``.
    """
    from imugen.navigate.mechanize import Mechanizer
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
    if K < 2:
        return {
            "final_position_error_m": 0.0,
            "max_position_error_m": 0.0,
            "final_attitude_error_rad": 0.0,
            "max_attitude_error_rad": 0.0,
            "max_velocity_error_mps": 0.0,
            "samples": K,
            "mechanization_seconds": 0.0,
        }
    # the truth's own step (t[1] - t[0] carries the rounding of t[0]: 2e-12 s at t0 = 9,000 s,
    # a gravity bias of 4e-10 m/s^2 over the run)
    rate = meta.get("rate_hz")
    dt = 1.0 / float(rate) if rate else float((t[-1] - t[0]) / (K - 1))
    mech = Mechanizer(frame, dt, P[0], V[0], Q[0])
    chunk = max(int(chunk), 2)  # the first chunk needs two steps (look-ahead start)
    out_p = np.empty((1, chunk, 3))
    out_v = np.empty((1, chunk, 3))
    out_q = np.empty((1, chunk, 4))
    max_p = max_v = max_a = 0.0
    ep = ea = 0.0
    # increments of the interval ending at row k sit on row k: sample j = 1..K-1
    for a in range(1, K, chunk):
        b = min(K, a + chunk)
        n = b - a
        mech.run(dth[None, a:b], dv[None, a:b], out_p=out_p, out_v=out_v, out_q=out_q, out_start=a)
        e_p = np.linalg.norm(out_p[0, :n] - P[a:b], axis=1)
        e_v = np.max(np.abs(out_v[0, :n] - V[a:b]))
        e_a = attitude_angle(Q[a:b], out_q[0, :n])
        max_p = max(max_p, float(e_p.max()))
        max_v = max(max_v, float(e_v))
        max_a = max(max_a, float(e_a.max()))
        ep = float(e_p[-1])
        ea = float(e_a[-1])
    if not all(np.isfinite([max_p, max_v, max_a])):
        raise FloatingPointError("mechanization produced non-finite values")
    return {
        "final_position_error_m": ep,
        "max_position_error_m": max_p,
        "final_attitude_error_rad": ea,
        "max_attitude_error_rad": max_a,
        "max_velocity_error_mps": max_v,
        "samples": K,
        "mechanization_seconds": time.perf_counter() - t0,
    }


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
    **truth_options
        Passed to :func:`imugen.truth.build_truth` (e.g. ``cruise_mps``, ``fit_tol_m``).

    Returns
    -------
    dict
        JSON-ready: ``final_position_error_m``, ``max_position_error_m``,
        ``final_attitude_error_rad``, ``max_attitude_error_rad``, ``max_velocity_error_mps``,
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
    res = closure_of_truth(df, meta)
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
        dt=o.dt, grade=o.grade,
    )  # fmt: skip
    print(json.dumps(result))
