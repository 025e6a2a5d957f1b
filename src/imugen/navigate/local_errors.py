"""Navigation errors in the local level at the TRUE position, plus along- and cross-track.

The error ``p_nav - p_true`` (resolved in the navigation frame ``n`` of the truth) is rotated
into East-North-Up at the true position, ``d_l = C_ln(p_true) d_n`` (:meth:`OriginFrame.C_ln`):

- ``flat``: ``C_ln = I`` (the local level is ``n``), so the errors equal the ``n`` errors;
- ``wgs84``: ``n`` is ENU at the origin; ``C_ln = C_le(p_true) C_en^T`` turns them by the
  angle between the two verticals (the route's angular extent, ``d / R``);
- ``geodetic``: ``n`` is ECEF; ``C_ln = C_le(p_true)``.

Only the true position enters the rotation, so an absurd navigated position (a free-inertial
solution gone 1e9 m away) still gives finite errors with the norm of ``d_n``.

Along-track is the horizontal error along the true horizontal velocity, cross-track across it,
positive to the left of the track. Below ``min_speed_mps`` the track direction is undefined;
there the direction of the nearest moving epoch is used (the last one before, else the first
one after: a parked car keeps the heading it stopped with). A route that never moves has NaN
along/cross errors.
"""

from __future__ import annotations

import numpy as np

from imugen.core.earth import OriginFrame
from imugen.core.jit import njit

MIN_SPEED_MPS = 0.1
"""Below this true horizontal speed the track direction is taken from the nearest moving epoch."""


def track_direction(v_l: np.ndarray, min_speed_mps: float = MIN_SPEED_MPS) -> np.ndarray:
    """Unit horizontal track direction (East, North) of a time-ordered velocity series.

    Parameters
    ----------
    v_l : ndarray, shape (J, 3)
        True velocity in the local level (ENU) at successive epochs [m/s].
    min_speed_mps : float
        Epochs slower than this take the direction of the nearest moving epoch (last before,
        else first after).

    Returns
    -------
    ndarray, shape (J, 2)
        ``(t_e, t_n)``; NaN everywhere when no epoch moves.
    """
    v_l = np.asarray(v_l, dtype=float)
    sp = np.hypot(v_l[:, 0], v_l[:, 1])
    ok = sp >= min_speed_mps
    out = np.full((len(v_l), 2), np.nan)
    if not ok.any():
        return out
    moving = np.flatnonzero(ok)
    # index of the last moving epoch at or before each epoch; before the first, the first one
    last = np.maximum.accumulate(np.where(ok, np.arange(len(ok)), -1))
    src = np.where(last >= 0, last, moving[0])
    out[:] = v_l[src, :2] / sp[src, None]
    return out


def local_errors(
    frame: OriginFrame,
    p_true_n: np.ndarray,
    v_true_n: np.ndarray,
    err_n: np.ndarray,
    min_speed_mps: float = MIN_SPEED_MPS,
) -> np.ndarray:
    """Position errors East, North, Up at the true position, along- and cross-track.

    Parameters
    ----------
    frame : OriginFrame
        Navigation frame and Earth model of the truth.
    p_true_n, v_true_n : ndarray, shape (J, 3)
        True position and velocity in ``n`` at the ``J`` time-ordered epochs [m, m/s].
    err_n : ndarray, shape (..., J, 3)
        Navigated minus true position in ``n`` [m] (any leading sequence axes).
    min_speed_mps : float
        See :func:`track_direction`.

    Returns
    -------
    ndarray, shape (..., J, 5)
        ``east, north, up, along, cross`` [m].
    """
    C = rotation_ln(frame, p_true_n)
    t = track_direction(
        np.einsum("jik,jk->ji", C, np.asarray(v_true_n, dtype=float)), min_speed_mps
    )
    return apply(C, t, err_n)


def apply(C_ln: np.ndarray, track: np.ndarray, err_n: np.ndarray) -> np.ndarray:
    """:func:`local_errors` with the rotation and track direction already computed.

    Parameters
    ----------
    C_ln : ndarray, shape (J, 3, 3)
        :func:`rotation_ln` at the true positions.
    track : ndarray, shape (J, 2)
        :func:`track_direction` of the true local-level velocity.
    err_n : ndarray, shape (..., J, 3)

    Returns
    -------
    ndarray, shape (..., J, 5)
    """
    # one (J, 5, 3) operator: the three rows of C_ln, then along = t . C_ln d and
    # cross = (u x t) . C_ln d (left of the track), so the sequences are swept once
    te, tn = track[:, 0, None], track[:, 1, None]
    M = np.concatenate(
        [
            C_ln,
            (te * C_ln[:, 0] + tn * C_ln[:, 1])[:, None],
            (te * C_ln[:, 1] - tn * C_ln[:, 0])[:, None],
        ],
        axis=1,
    )
    return _rows(M, err_n)


def _rows(M: np.ndarray, x) -> np.ndarray:
    """``out[..., j, i] = sum_k M[j, i, k] x[..., j, k]``, (..., J, R), element by element (the
    same float operations whatever the number of sequences: batch-independent bits, which a
    BLAS-backed product does not give)."""
    x = np.asarray(x, dtype=float)
    J = M.shape[0]
    xs = np.ascontiguousarray(x.reshape(-1, J, 3))
    out = np.empty((xs.shape[0], J, M.shape[1]))
    _rows_nb(np.ascontiguousarray(M, dtype=float), xs, out)
    return out.reshape((*x.shape[:-1], M.shape[1]))


@njit(cache=True)
def _rows_nb(M, x, out):
    for s in range(x.shape[0]):
        for j in range(x.shape[1]):
            x0, x1, x2 = x[s, j, 0], x[s, j, 1], x[s, j, 2]
            for i in range(M.shape[1]):
                out[s, j, i] = M[j, i, 0] * x0 + M[j, i, 1] * x1 + M[j, i, 2] * x2


def rotation_ln(frame: OriginFrame, p_true_n: np.ndarray) -> np.ndarray:
    """``C_ln`` (n -> ENU at the true position), shape (J, 3, 3); the identity in ``flat``."""
    return frame.C_ln(np.asarray(p_true_n, dtype=float).reshape(-1, 3))


def local_sd(C_ln: np.ndarray, sd_n: np.ndarray) -> np.ndarray:
    """Per-axis 1-sigma rotated to the local level, correlations ignored.

    ``sd_l_i = sqrt(sum_k C_ik^2 sd_n_k^2)`` (exact for a diagonal covariance in ``n``).

    Parameters
    ----------
    C_ln : ndarray, shape (J, 3, 3)
    sd_n : ndarray, shape (..., J, 3)

    Returns
    -------
    ndarray, shape (..., J, 3)
    """
    return np.sqrt(_rows(np.asarray(C_ln, dtype=float) ** 2, np.asarray(sd_n, dtype=float) ** 2))
