"""Zero-velocity update (ZUPT) at detected stops.

The interval since the previous epoch was still (every sample's corrected rate below
``Options.zupt_gyro_radps`` and specific-force magnitude within ``zupt_accel_mps2`` of gravity:
:func:`imugen.aid.filter.propagate.strapdown` tests it) and the speed (the GNSS velocity's
when the fix is usable, else the filter's plus ``zupt_speed_conf`` of its sigmas) is below
``zupt_speed_mps`` and the IMU has been still for ``zupt_min_still_s``: the velocity is zero,
one scalar update per axis with variance ``zupt_sd_mps^2 + zupt_crawl_mps^2 / 3`` (the crawl
the detector cannot exclude: at the end of a stop the truth still moves up to 0.18 m/s with
the IMU "still"), never gated. Without a fix the filter's own speed is no evidence of a stop
(a cruise is as still to the IMU); its sigma guards against false ZUPTs.
"""

from __future__ import annotations

import math

import numpy as np

from imugen.aid.filter.kalman import clear, put, scalar_update
from imugen.core.jit import njit, njit_borrowing

F_ZUPT = 4
"""Epoch flag: zero-velocity update applied."""


@njit_borrowing(cache=True)
def velocity_row(md, x, wk, a):
    """Row of axis ``a``: ``r = v_a``, ``h = e_{v,a}``; returns ``(m, r, var)``."""
    m = clear(wk)
    m = put(wk, m, md.ie.v + a, 1.0)
    return m, x[md.ix.v + a], md.opt.zupt_sd**2 + md.opt.zupt_crawl**2 / 3.0


@njit(cache=True)
def new_window():
    """``(still time [s], sample of the previous epoch)`` of one sequence."""
    return np.zeros(2)


@njit_borrowing(cache=True)
def start(w):
    """A sequence's start: not still."""
    w[0] = 0.0
    w[1] = -1.0


@njit_borrowing(cache=True)
def update(e, md, inp, wk, x, tn, win):
    """ZUPT at epoch ``e`` when switched on, still long enough and slow; returns the flag
    bits."""
    if not md.opt.zupt:
        return 0
    w = win.zupt
    w[0] = w[0] + (e.k - w[1]) * md.dt if (e.still and e.started) else 0.0
    w[1] = e.k
    if not (e.still and e.started and w[0] >= md.opt.zupt_min_still):
        return 0
    s, j, iv = e.s, e.j, md.ix.v
    if inp.ok[s, j]:
        spd = math.sqrt(inp.zv[s, j, 0] ** 2 + inp.zv[s, j, 1] ** 2 + inp.zv[s, j, 2] ** 2)
        ssd = 0.0
    else:
        spd = math.sqrt(x[iv] * x[iv] + x[iv + 1] * x[iv + 1] + x[iv + 2] * x[iv + 2])
        ie, P = md.ie.v, wk.P
        ssd = math.sqrt(max(P[ie, ie] + P[ie + 1, ie + 1] + P[ie + 2, ie + 2], 0.0) / 3.0)
    if not spd + md.opt.zupt_speed_conf * ssd < md.opt.zupt_speed:  # (NaN: no update)
        return 0
    for a in range(3):
        m, r, var = velocity_row(md, x, wk, a)
        scalar_update(wk, m, r, var, 0.0)
    return F_ZUPT
