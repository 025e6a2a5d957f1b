"""Small compiled helpers of the filter: 3x3 products, the DCM of a quaternion, the skew
matrix, and the local level (East, North, Up) of an ECEF point.

Inlined scalar code on preallocated arrays (no allocation per step); quaternions scalar first.
"""

from __future__ import annotations

import math

from imugen.core import earth
from imugen.core.jit import njit_borrowing


@njit_borrowing(cache=True)
def local_level_nb(x, y, z, L):
    """``L = C_le`` (ECEF -> East, North, Up at the ECEF point ``(x, y, z)``); returns ``h``."""
    sl, cl, co, so, hgt = earth.geodetic_parts_nb(x, y, z)
    L[0, 0] = -so
    L[0, 1] = co
    L[0, 2] = 0.0
    L[1, 0] = -sl * co
    L[1, 1] = -sl * so
    L[1, 2] = cl
    L[2, 0] = cl * co
    L[2, 1] = cl * so
    L[2, 2] = sl
    return hgt


@njit_borrowing(cache=True)
def local_sd(P, L, i0, out, o0):
    """``out[o0 + a] = sqrt(L_a P_blk L_a^T)``: 1-sigma along the rows of ``L`` of the 3x3
    block of ``P`` starting at ``i0``."""
    for a in range(3):
        acc = 0.0
        for b in range(3):
            for c in range(3):
                acc += L[a, b] * P[i0 + b, i0 + c] * L[a, c]
        out[o0 + a] = math.sqrt(max(acc, 0.0))


@njit_borrowing(cache=True, inline="always")
def mv(m, o, x, y, z):
    """``M (x, y, z)`` with ``M`` the 3x3 matrix stored row-major at ``m[o : o + 9]``."""
    return (
        m[o] * x + m[o + 1] * y + m[o + 2] * z,
        m[o + 3] * x + m[o + 4] * y + m[o + 5] * z,
        m[o + 6] * x + m[o + 7] * y + m[o + 8] * z,
    )


@njit_borrowing(cache=True, inline="always")
def dcm(q0, q1, q2, q3, C):
    """``C`` (3, 3) <- the rotation matrix of the unit quaternion ``q`` (scalar first)."""
    C[0, 0] = 1.0 - 2.0 * (q2 * q2 + q3 * q3)
    C[0, 1] = 2.0 * (q1 * q2 - q0 * q3)
    C[0, 2] = 2.0 * (q1 * q3 + q0 * q2)
    C[1, 0] = 2.0 * (q1 * q2 + q0 * q3)
    C[1, 1] = 1.0 - 2.0 * (q1 * q1 + q3 * q3)
    C[1, 2] = 2.0 * (q2 * q3 - q0 * q1)
    C[2, 0] = 2.0 * (q1 * q3 - q0 * q2)
    C[2, 1] = 2.0 * (q2 * q3 + q0 * q1)
    C[2, 2] = 1.0 - 2.0 * (q1 * q1 + q2 * q2)


@njit_borrowing(cache=True, inline="always")
def skew(x, y, z, M):
    """``M`` (3, 3) <- ``[(x, y, z) x]``, the cross-product matrix."""
    M[0, 0] = 0.0
    M[0, 1] = -z
    M[0, 2] = y
    M[1, 0] = z
    M[1, 1] = 0.0
    M[1, 2] = -x
    M[2, 0] = -y
    M[2, 1] = x
    M[2, 2] = 0.0
