"""Frame, attitude and clock conversions for the export formats, written once.

imugen: navigation ``n`` = ENU, body ``b`` = FLU (x forward, y left, z up), quaternions scalar
first, times in seconds from the route start. The formats want:

* NED navigation and FRD body (KF-GINS, i2Nav): ``v_ned = T v_enu`` with ``T`` swapping E/N and
  negating Up; ``v_frd = D v_flu`` with ``D = diag(1, -1, -1)``; ``C_ned_frd = T C_enu_flu D``.
  Euler angles of ``C_ned_frd`` (roll, pitch, heading; ZYX, heading from North towards East).
* scalar-last quaternions (TUM ``qx qy qz qw``, TLIO ``qxyzw``).
* integer clocks: nanoseconds (EuRoC, ROS) and microseconds (TLIO) from a start epoch.
"""

from __future__ import annotations

import numpy as np

from imugen.core import rotations as rot

T_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
"""``v_ned = T_NED_ENU @ v_enu`` (its own inverse)."""
D_FRD_FLU = np.diag([1.0, -1.0, -1.0])
"""``v_frd = D_FRD_FLU @ v_flu`` (its own inverse)."""


def enu_to_ned(v):
    """(..., 3) ENU vectors -> NED."""
    v = np.asarray(v, float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def flu_to_frd(v):
    """(..., 3) FLU body vectors -> FRD."""
    v = np.asarray(v, float)
    return np.stack([v[..., 0], -v[..., 1], -v[..., 2]], axis=-1)


def dcm_ned_frd(C_nb):
    """(..., 3, 3) ``C_enu_flu`` -> ``C_ned_frd = T C D``."""
    return T_NED_ENU @ np.asarray(C_nb, float) @ D_FRD_FLU


def euler_ned_frd(C_ned_frd):
    """Roll, pitch, heading [rad] (ZYX) of ``C_ned_frd``; heading in [0, 2 pi)."""
    C = np.asarray(C_ned_frd, float)
    roll = np.arctan2(C[..., 2, 1], C[..., 2, 2])
    pitch = -np.arcsin(np.clip(C[..., 2, 0], -1.0, 1.0))
    yaw = np.mod(np.arctan2(C[..., 1, 0], C[..., 0, 0]), 2.0 * np.pi)
    return np.stack([roll, pitch, yaw], axis=-1)


def quat_scalar_last(q_wxyz):
    """(..., 4) scalar-first quaternions -> scalar-last ``(x, y, z, w)``."""
    q = np.asarray(q_wxyz, float)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def rotate(q_nb, v_b):
    """``C(q_nb) v_b`` for (K, 4) quaternions and (K, 3) vectors."""
    return np.einsum("kij,kj->ki", rot.quat_to_dcm(q_nb), np.asarray(v_b, float))


def clock(time_s, unit: float, start: int = 0) -> np.ndarray:
    """Integer clock ``start + round(time_s / unit)`` (int64), e.g. ``unit=1e-9`` for ns."""
    return start + np.rint(np.asarray(time_s, float) / unit).astype(np.int64)
