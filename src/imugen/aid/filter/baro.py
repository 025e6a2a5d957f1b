"""Barometric height update.

The barometer reads the height above the origin's plus a first-order Gauss-Markov drift (the
labelled model, :mod:`imugen.aid.companions`; a state of the filter), white noise ``s_w^2``
(the measurement's variance). Predicted height: ``p_u`` in ``flat``; ``p_u + (p_e^2 +
p_n^2) / 2R`` in ``wgs84`` (the local level's drop); the ellipsoidal height of the ECEF
position minus the origin's in ``geodetic`` (``dh = u^T dp``, ``u`` the local Up).
"""

from __future__ import annotations

import math

from imugen.aid.companions import C_BARO, C_BARO_VAR
from imugen.aid.filter.geometry import local_level_nb
from imugen.aid.filter.kalman import F_REJECT, clear, put, scalar_update
from imugen.core import earth
from imugen.core.jit import njit

F_BARO = 128
"""Epoch flag: barometer update applied."""


@njit(cache=True)
def height_row(md, x, wk, z):
    """The row of the height ``z`` [m]: fills ``wk.h``; returns ``(m, r)``."""
    ie, ix = md.ie, md.ix
    px, py, pz = x[ix.p], x[ix.p + 1], x[ix.p + 2]
    b_hat = x[ix.baro_bias]
    m = clear(wk)
    if md.geo:
        Lm = wk.Lm
        hgt = local_level_nb(px, py, pz, Lm)
        for c in range(3):
            m = put(wk, m, ie.p + c, Lm[2, c])
        m = put(wk, m, ie.baro_bias, 1.0)
        return m, hgt - md.h0 + b_hat - z
    pred = pz + b_hat
    m = put(wk, m, ie.p + 2, 1.0)
    if md.wgs:
        pred += (px * px + py * py) / (2.0 * earth.R_MEAN)
        m = put(wk, m, ie.p, px / earth.R_MEAN)
        m = put(wk, m, ie.p + 1, py / earth.R_MEAN)
    m = put(wk, m, ie.baro_bias, 1.0)
    return m, pred - z


@njit(cache=True)
def update(e, md, inp, wk, x, tn, win):
    """Barometer update at epoch ``e`` when switched on and measured; returns the flag bits."""
    if not md.opt.baro:
        return 0
    z = inp.cz[e.s, e.j, C_BARO]
    if not math.isfinite(z):
        return 0
    m, r = height_row(md, x, wk, z)
    return (
        F_BARO if scalar_update(wk, m, r, inp.cz[e.s, e.j, C_BARO_VAR], md.opt.gate) else F_REJECT
    )
