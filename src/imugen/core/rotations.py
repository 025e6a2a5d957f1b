"""Vectorized SO(3) helpers: quaternions, direction cosine matrices, rotation vectors.

Shapes broadcast over leading axes: vectors ``(..., 3)``, quaternions ``(..., 4)`` scalar
first ``(w, x, y, z)``, matrices ``(..., 3, 3)``. A quaternion ``q_nb`` and the matrix
``C_nb = quat_to_dcm(q_nb)`` rotate vectors from ``b`` to ``n`` (``v_n = C_nb @ v_b``);
``quat_mul(q_ab, q_bc) = q_ac`` like ``C_ab @ C_bc``.

Rotation vectors: ``exp``/``log`` map between ``phi`` (axis times angle, rad) and rotations,
accurate to rounding near 0 and near pi (computed through the quaternion half-angle form,
never through ``arccos`` of the trace).

Euler angles (ENU navigation frame, FLU body: x forward, y left, z up)::

    C_nb = Rz(yaw) @ Ry(-pitch) @ Rx(roll)

* ``yaw``: rotation about up, measured from East toward North (0 faces East, +pi/2 faces
  North); it is *not* a compass heading (that is ``pi/2 - yaw``).
* ``pitch``: nose up positive (body x = ``(cos p cos y, cos p sin y, sin p)``). Because y
  points left, a nose-up pitch *rate* is a negative rotation about body y.
* ``roll``: right-handed about body x (forward): positive raises the left wing, i.e. right
  wing down.
"""

from __future__ import annotations

import math

import numpy as np

_SMALL = 1e-2  # below this angle (rad) the Jacobian coefficients use their Taylor series


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix: ``skew(a) @ b == cross(a, b)``; (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1] = -z
    out[..., 0, 2] = y
    out[..., 1, 0] = z
    out[..., 1, 2] = -x
    out[..., 2, 0] = -y
    out[..., 2, 1] = x
    return out


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p * q`` (scalar first); (..., 4), (..., 4) -> (..., 4)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate (inverse of a unit quaternion); (..., 4) -> (..., 4)."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Scale to unit norm; (..., 4) -> (..., 4)."""
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_continuous(q: np.ndarray, ref: np.ndarray | None = None) -> np.ndarray:
    """Flip signs along axis 0 so consecutive quaternions have a non-negative dot product.

    Parameters
    ----------
    q : ndarray, shape (K, 4)
    ref : ndarray, shape (4,), optional
        Quaternion preceding ``q[0]`` (continuity across chunks).
    """
    q = np.array(q, dtype=float)
    if len(q) == 0:
        return q
    d = np.einsum("ij,ij->i", q[1:], q[:-1])
    flips = np.concatenate([[0], np.cumsum(d < 0)])
    if ref is not None and np.dot(q[0], ref) < 0:
        flips += 1
    q[flips % 2 == 1] *= -1.0
    return q


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """Unit quaternion -> rotation matrix; (..., 4) -> (..., 3, 3)."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty((*q.shape[:-1], 3, 3))
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    out[..., 0, 0] = 1.0 - 2.0 * (yy + zz)
    out[..., 0, 1] = 2.0 * (xy - wz)
    out[..., 0, 2] = 2.0 * (xz + wy)
    out[..., 1, 0] = 2.0 * (xy + wz)
    out[..., 1, 1] = 1.0 - 2.0 * (xx + zz)
    out[..., 1, 2] = 2.0 * (yz - wx)
    out[..., 2, 0] = 2.0 * (xz - wy)
    out[..., 2, 1] = 2.0 * (yz + wx)
    out[..., 2, 2] = 1.0 - 2.0 * (xx + yy)
    return out


def dcm_to_quat(C: np.ndarray) -> np.ndarray:
    """Rotation matrix -> unit quaternion with ``w >= 0`` (Shepperd's method); (..., 3, 3) -> (..., 4)."""
    C = np.asarray(C, dtype=float)
    c00, c11, c22 = C[..., 0, 0], C[..., 1, 1], C[..., 2, 2]
    tr = c00 + c11 + c22
    # 4 * (w^2, x^2, y^2, z^2) candidates; pick the largest for stability
    cand = np.stack([1 + tr, 1 + 2 * c00 - tr, 1 + 2 * c11 - tr, 1 + 2 * c22 - tr], axis=-1)
    i = np.argmax(cand, axis=-1)
    d21 = C[..., 2, 1] - C[..., 1, 2]
    d02 = C[..., 0, 2] - C[..., 2, 0]
    d10 = C[..., 1, 0] - C[..., 0, 1]
    s01 = C[..., 0, 1] + C[..., 1, 0]
    s02 = C[..., 0, 2] + C[..., 2, 0]
    s12 = C[..., 1, 2] + C[..., 2, 1]
    big = np.sqrt(np.maximum(np.take_along_axis(cand, i[..., None], -1)[..., 0], 0.0))
    # rows: quaternion * (2 * big) for each choice of the largest component
    q = np.where(
        (i == 0)[..., None],
        np.stack([big * big, d21, d02, d10], -1),
        np.where(
            (i == 1)[..., None],
            np.stack([d21, big * big, s01, s02], -1),
            np.where(
                (i == 2)[..., None],
                np.stack([d02, s01, big * big, s12], -1),
                np.stack([d10, s02, s12, big * big], -1),
            ),
        ),
    )
    q = q / (2.0 * big)[..., None]
    q = np.where(q[..., :1] < 0, -q, q)
    return quat_normalize(q)


def exp_quat(phi: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) -> unit quaternion; (..., 3) -> (..., 4)."""
    phi = np.asarray(phi, dtype=float)
    theta = np.linalg.norm(phi, axis=-1)
    half = 0.5 * theta
    # sin(theta/2)/theta = 0.5 * sinc(theta / (2 pi)), exact at 0
    k = 0.5 * np.sinc(half / np.pi)
    return np.concatenate([np.cos(half)[..., None], k[..., None] * phi], axis=-1)


def log_quat(q: np.ndarray) -> np.ndarray:
    """Unit quaternion -> rotation vector with angle in [0, pi]; (..., 4) -> (..., 3)."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., :1] < 0, -q, q)
    w = q[..., 0]
    v = q[..., 1:]
    n = np.linalg.norm(v, axis=-1)
    safe = np.where(n > 0, n, 1.0)
    k = np.where(n > 0, 2.0 * np.arctan2(n, w) / safe, 2.0 / np.where(w > 0, w, 1.0))
    return k[..., None] * v


def exp_dcm(phi: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) -> rotation matrix (SO(3) exponential); (..., 3) -> (..., 3, 3)."""
    return quat_to_dcm(exp_quat(phi))


def log_dcm(C: np.ndarray) -> np.ndarray:
    """Rotation matrix -> rotation vector (SO(3) logarithm, angle in [0, pi]); (..., 3, 3) -> (..., 3)."""
    return log_quat(dcm_to_quat(C))


def right_jacobian(phi: np.ndarray) -> np.ndarray:
    """Right Jacobian of SO(3): ``d/dt Exp(phi) = Exp(phi) [J_r(phi) phi_dot]x``; (..., 3) -> (..., 3, 3)."""
    phi = np.asarray(phi, dtype=float)
    t = np.linalg.norm(phi, axis=-1)
    small = t < _SMALL
    ts = np.where(small, 1.0, t)
    t2 = t * t
    b = np.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - np.cos(ts)) / ts**2)
    c = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0, (ts - np.sin(ts)) / ts**3)
    S = skew(phi)
    return np.eye(3) - b[..., None, None] * S + c[..., None, None] * (S @ S)


def right_jacobian_inv(phi: np.ndarray) -> np.ndarray:
    """Inverse of :func:`right_jacobian` (singular at angle 2 pi); (..., 3) -> (..., 3, 3)."""
    phi = np.asarray(phi, dtype=float)
    t = np.linalg.norm(phi, axis=-1)
    small = t < _SMALL
    ts = np.where(small, 1.0, t)
    t2 = t * t
    d = np.where(
        small,
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0,
        1.0 / ts**2 - (1.0 + np.cos(ts)) / (2.0 * ts * np.sin(ts)),
    )
    S = skew(phi)
    return np.eye(3) + 0.5 * S + d[..., None, None] * (S @ S)


def euler_to_dcm(roll, pitch, yaw) -> np.ndarray:
    """Roll, pitch, yaw (rad, same shapes) -> ``C_nb = Rz(yaw) Ry(-pitch) Rx(roll)``, (..., 3, 3)."""
    r, p, y = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (roll, pitch, yaw)))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    out = np.empty((*r.shape, 3, 3))
    out[..., 0, 0] = cy * cp
    out[..., 0, 1] = -sy * cr - cy * sp * sr
    out[..., 0, 2] = sy * sr - cy * sp * cr
    out[..., 1, 0] = sy * cp
    out[..., 1, 1] = cy * cr - sy * sp * sr
    out[..., 1, 2] = -cy * sr - sy * sp * cr
    out[..., 2, 0] = sp
    out[..., 2, 1] = cp * sr
    out[..., 2, 2] = cp * cr
    return out


def dcm_to_euler(C: np.ndarray) -> np.ndarray:
    """``C_nb`` -> (roll, pitch, yaw) rad, (..., 3, 3) -> (..., 3); pitch in [-pi/2, pi/2].

    At pitch = +-90 deg only ``yaw - roll`` (nose up) is defined; the split returned there is
    whatever ``atan2`` gives, finite. Yaw and roll are wrapped to (-pi, pi].
    """
    C = np.asarray(C, dtype=float)
    roll = np.arctan2(C[..., 2, 1], C[..., 2, 2])
    pitch = np.arctan2(C[..., 2, 0], np.hypot(C[..., 2, 1], C[..., 2, 2]))
    yaw = np.arctan2(C[..., 1, 0], C[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def relative_rotation_vector(q_a, q_b, omega_n=None, dt: float = 0.0) -> np.ndarray:
    """``Log(q_a^-1 (x) Exp(Omega dt) (x) q_b)`` without cancellation, (N, 4) x2 -> (N, 3).

    The naive product of nearly equal unit quaternions leaves absolute rounding errors of
    ~1e-16 rad per interval; during a stop they repeat every step and integrate into a drift
    (1e-13 rad after a few seconds, a 1e-12 m/s^2 horizontal specific-force error). Here the
    relative rotation is formed from the difference ``d = q_b - q_a`` (exact when the two are
    close) and from ``Exp(Omega dt) - 1``, so the result is accurate to ~1e-16 *relative*.

    Parameters
    ----------
    q_a, q_b : ndarray, shape (N, 4)
        Unit quaternions (scalar first) at the start and end of each interval, same hemisphere.
    omega_n : ndarray, shape (3,), optional
        Earth rate in n (None or zeros: flat).
    dt : float
        Interval [s].
    """
    a = np.asarray(q_a, dtype=float)
    b = np.asarray(q_b, dtype=float)
    d = b - a
    aw, av = a[..., :1], a[..., 1:]
    dw, dv_ = d[..., :1], d[..., 1:]
    # a^* b = (a.b, aw b_v - bw a_v - a_v x b_v) with b = a + d
    vec = aw * dv_ - dw * av - np.cross(av, dv_)
    sm1 = np.sum(a * d, axis=-1, keepdims=True)  # a.b - 1 for unit a
    if omega_n is not None and np.any(np.asarray(omega_n) != 0.0):
        w = np.asarray(omega_n, dtype=float)
        wn = float(np.linalg.norm(w))
        th = wn * dt
        u = np.array([-2.0 * math.sin(th / 4.0) ** 2, *(math.sin(th / 2.0) * w / wn)])
        ua = quat_mul(np.broadcast_to(u, a.shape), b)  # (Exp - 1) b
        conj = a * np.array([1.0, -1.0, -1.0, -1.0])
        extra = quat_mul(conj, ua)
        sm1 = sm1 + extra[..., :1]
        vec = vec + extra[..., 1:]
    s = 1.0 + sm1
    n = np.sqrt(np.sum(vec * vec, axis=-1, keepdims=True))
    sign = np.where(s < 0.0, -1.0, 1.0)
    s = s * sign
    vec = vec * sign
    x = n / s
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(
            x < 1e-4,
            (1.0 - x * x / 3.0 + x**4 / 5.0) / s,
            np.arctan2(n, s) / np.where(n > 0, n, 1.0),
        )
    return 2.0 * ratio * vec
