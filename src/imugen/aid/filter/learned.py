"""A learner's measurements: the IMU's velocity in body axes with its covariance (TLIO,
RINS-W style), at the epochs where it is given.

``z = C^T v + e``, ``e ~ N(0, R)`` (``R`` the learner's 3x3 covariance, body axes): with
``dx`` estimate minus truth, ``z_pred - z = C^T dv + C^T [v x] psi + ...``. The three
components are correlated through ``R``; they are whitened by ``W = L^-1`` (``R = L L^T``,
given per epoch as ``Inputs.lvW``): three scalar updates of unit variance with rows
``W [C^T, C^T [v x]]`` and residuals ``W (C^T v - z)``, gated by ``Options.gate_sigma``.
A NaN first component means no measurement at that epoch.

The adaptive NHC noise of AI-IMU (learned lateral and vertical variances per epoch) replaces
the slip's in :mod:`imugen.aid.filter.nhc` (``Inputs.nvar``).
"""

from __future__ import annotations

import math

from imugen.aid.filter.geometry import skew
from imugen.aid.filter.kalman import F_REJECT, clear, put, scalar_update
from imugen.core.jit import njit_borrowing

F_LEARNED = 256
"""Epoch flag: a learned measurement was used."""


@njit_borrowing(cache=True)
def update(e, md, inp, wk, x, tn, win):
    """The learned body-frame velocity at epoch ``e`` when given; returns the flag bits."""
    if inp.lv.shape[1] == 0 or not math.isfinite(inp.lv[e.s, e.j, 0]):
        return 0
    s, j, iv, ie, C, Xm = e.s, e.j, md.ix.v, md.ie, wk.C, wk.Xm
    vx, vy, vz = x[iv], x[iv + 1], x[iv + 2]
    skew(vx, vy, vz, Xm)
    r0 = C[0, 0] * vx + C[1, 0] * vy + C[2, 0] * vz - inp.lv[s, j, 0]
    r1 = C[0, 1] * vx + C[1, 1] * vy + C[2, 1] * vz - inp.lv[s, j, 1]
    r2 = C[0, 2] * vx + C[1, 2] * vy + C[2, 2] * vz - inp.lv[s, j, 2]
    flag = F_LEARNED
    for row in range(3):
        w0, w1, w2 = inp.lvW[s, j, row, 0], inp.lvW[s, j, row, 1], inp.lvW[s, j, row, 2]
        m = clear(wk)
        for a in range(3):  # W C^T on the velocity: sum_c W[row, c] C[a, c]
            m = put(wk, m, ie.v + a, w0 * C[a, 0] + w1 * C[a, 1] + w2 * C[a, 2])
        for a in range(3):  # W C^T [v x] on the attitude
            acc = 0.0
            for c in range(3):
                wc = w0 if c == 0 else (w1 if c == 1 else w2)
                acc += wc * (C[0, c] * Xm[0, a] + C[1, c] * Xm[1, a] + C[2, c] * Xm[2, a])
            m = put(wk, m, ie.att + a, acc)
        r = w0 * r0 + w1 * r1 + w2 * r2
        if not scalar_update(wk, m, r, 1.0, md.opt.gate):
            flag |= F_REJECT
    return flag
