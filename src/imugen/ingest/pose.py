"""Pose trajectories in ingestion: the file's world put on the Earth, the attitude cleaned.

A pose reader (:mod:`imugen.ingest.readers.pose`) gives positions and attitudes in the file's
own world frame ``w``. ``--pose-world`` says what that world is:

``enu``, ``ned``
    Local axes East-North-Up or North-East-Down, origin at ``--origin`` (the geodetic position
    of the world's origin, not of the first pose).
``flu``
    z up, x at ``--pose-world-yaw-deg`` from East towards North (a motion-capture room).
``ecef``
    Earth-centred Earth-fixed (WGS-84) positions and attitudes.

The ingested table stores each pose's attitude relative to the local ENU at its own point
(columns ``q_w .. q_z`` of :mod:`imugen.tables.enu`); attitude rows that are not finite or
whose quaternion norm is far from 1 are dropped, the others normalized.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from imugen.core import earth as ea
from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.ingest.route import RoutePath

WORLDS = ("enu", "ned", "flu", "ecef")
"""World frames of a pose file (``--pose-world``)."""
_C_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
ECEF_RADIUS_M = (6_356_752.0 - 11_000.0, 6_378_137.0 + 100_000.0)
"""Distances from the Earth's centre of ECEF poses accepted (the heights ingestion accepts)."""
MAX_NORM_ERROR = 0.1
"""Quaternions whose norm differs from 1 by more than this are not attitudes (dropped)."""


def C_nw(world: str, yaw_deg: float = 0.0) -> np.ndarray:
    """Rotation of a local world's axes into ENU (``v_n = C_nw v_w``), shape (3, 3)."""
    if world == "enu":
        return np.eye(3)
    if world == "ned":
        return _C_NED.copy()
    if world == "flu":
        c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    raise InputError("--pose-world", f"{world!r} is not one of {', '.join(WORLDS)}")


def _keep(p: RoutePath, keep: np.ndarray) -> RoutePath:
    def cut(a):
        return None if a is None or len(a) == 0 else a[keep]

    return replace(
        p,
        enu_m=cut(p.enu_m),
        lat_deg=p.lat_deg if p.enu_m is not None else p.lat_deg[keep],
        lon_deg=p.lon_deg if p.enu_m is not None else p.lon_deg[keep],
        alt_m=p.alt_m if p.enu_m is not None else p.alt_m[keep],
        time_unix_s=cut(p.time_unix_s),
        alt_missing=cut(p.alt_missing),
        attitude=cut(p.attitude),
    )


def clean_attitude(p: RoutePath, source, warnings: list[str]) -> tuple[RoutePath, dict]:
    """Drop poses without a usable attitude, normalize the others; returns the path and the
    report (``dropped_invalid``, ``max_quat_norm_error`` of the kept ones)."""
    q = np.asarray(p.attitude, float)
    if q.ndim != 2 or q.shape[1] != 4 or len(q) != p.n_points:
        raise InputError(source, "pose attitudes do not match the positions")
    norm = np.linalg.norm(np.where(np.isfinite(q), q, 0.0), axis=1)
    ok = np.all(np.isfinite(q), axis=1) & (np.abs(norm - 1.0) <= MAX_NORM_ERROR)
    rep = {"dropped_invalid": int((~ok).sum())}
    if not ok.all():
        warnings.append(
            f"dropped {int((~ok).sum())} poses whose quaternion is not finite or not of unit norm"
        )
        p = _keep(p, ok)
        norm = norm[ok]
    rep["max_quat_norm_error"] = float(np.max(np.abs(norm - 1.0))) if len(norm) else 0.0
    return replace(p, attitude=p.attitude / norm[:, None]), rep


def on_the_earth(p: RoutePath, world: str, yaw_deg: float, source) -> RoutePath:
    """The path of a pose file in navigation terms: ENU rows of the origin (local worlds;
    attitude relative to the origin's ENU axes, ``attitude_frame = "origin"``) or geodetic
    points (``ecef``; attitude relative to the local ENU at each point, ``"level"``)."""
    if p.attitude_frame != "world":
        return p
    if world == "ecef":
        r = p.enu_m
        radius = np.linalg.norm(r, axis=1)
        far = ~((radius > ECEF_RADIUS_M[0]) & (radius < ECEF_RADIUS_M[1]))
        if far.any():
            i = int(np.flatnonzero(far)[0])
            raise InputError(
                source,
                f"pose {i + 1} lies {radius[i]:.6g} m from the Earth's centre: not an ECEF "
                "position near the Earth (--pose-world=ecef takes ECEF metres)",
            )
        lat, lon, h = ea.geodetic_from_ecef(r)
        C_le = ea.C_en_from_geodetic(lat, lon)
        q = rot.quat_mul(rot.dcm_to_quat(C_le), p.attitude)
        return replace(
            p, enu_m=None, lat_deg=np.degrees(lat), lon_deg=np.degrees(lon), alt_m=h,
            attitude=q, attitude_frame="level",
        )  # fmt: skip
    C = C_nw(world, yaw_deg)
    q = rot.quat_mul(rot.dcm_to_quat(C)[None, :], p.attitude)
    return replace(p, enu_m=p.enu_m @ C.T, attitude=q, attitude_frame="origin")


def level_attitude(q: np.ndarray, frame: str, origin, enu: np.ndarray) -> np.ndarray:
    """Attitudes relative to the local ENU at each point, (N, 4): ``q`` as they are
    (``"level"``) or, relative to the origin's ENU axes (``"origin"``), turned by ``C_ln``
    at the points ``enu`` (N, 3) [m] of the origin's ENU."""
    if frame == "level":
        return q
    o = ea.OriginFrame.from_deg(origin.lat_deg, origin.lon_deg, origin.alt_m, "wgs84")
    return rot.quat_continuous(rot.quat_mul(rot.dcm_to_quat(o.C_ln(enu)), q))


def report(p: RoutePath, world: str, yaw_deg: float, cleaning: dict) -> dict:
    """Metadata ``pose`` of the ingested table."""
    return {
        "attitude": "q_w..q_z: pose body -> local ENU at the point (scalar first)",
        "world": world if p.kind == "pose" else "geodetic (carried)",
        "world_yaw_deg": yaw_deg if world == "flu" else None,
        **cleaning,
    }
