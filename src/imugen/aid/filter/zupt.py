"""Zero-velocity update (ZUPT) at detected stops.

The interval since the previous epoch was still (every sample's corrected rate below
``Options.zupt_gyro_radps`` and specific-force magnitude within ``zupt_accel_mps2`` of gravity:
:func:`imugen.aid.filter.propagate.strapdown` tests it) and the speed (the GNSS velocity's
when the fix is usable, else the filter's) is below ``zupt_speed_mps``: the velocity is
zero, one scalar update per axis with variance ``zupt_sd_mps^2``, never gated.
"""

from __future__ import annotations

import math

from imugen.aid.filter.kalman import clear, put, scalar_update
from imugen.core.jit import njit

F_ZUPT = 4
"""Epoch flag: zero-velocity update applied."""


@njit(cache=True)
def velocity_row(md, x, wk, a):
    """Row of axis ``a``: ``r = v_a``, ``h = e_{v,a}``; returns ``(m, r, var)``."""
    m = clear(wk)
    m = put(wk, m, md.ie.v + a, 1.0)
    return m, x[md.ix.v + a], md.opt.zupt_sd**2


@njit(cache=True)
def update(e, md, inp, wk, x, tn, win):
    """ZUPT at epoch ``e`` when switched on, still and slow; returns the flag bits."""
    if not (md.opt.zupt and e.still and e.started):
        return 0
    s, j, iv = e.s, e.j, md.ix.v
    if inp.ok[s, j]:
        spd = math.sqrt(inp.zv[s, j, 0] ** 2 + inp.zv[s, j, 1] ** 2 + inp.zv[s, j, 2] ** 2)
    else:
        spd = math.sqrt(x[iv] * x[iv] + x[iv + 1] * x[iv + 1] + x[iv + 2] * x[iv + 2])
    if not spd < md.opt.zupt_speed:  # (NaN: no update)
        return 0
    for a in range(3):
        m, r, var = velocity_row(md, x, wk, a)
        scalar_update(wk, m, r, var, 0.0)
    return F_ZUPT
