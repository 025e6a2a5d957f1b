"""The filter's time loop (compiled): sequences outside, epochs inside; at each epoch
propagate -> updates -> feedback -> outputs. No allocation per step, no I/O.

* propagate: the strapdown from the previous epoch's sample to this one
  (:func:`~imugen.aid.filter.propagate.strapdown`) and the covariance
  (:func:`~imugen.aid.filter.error_model.propagate_covariance`);
* updates: every registered measurement model, in order
  (:func:`~imugen.aid.filter.measurements.update`);
* feedback: the error-state estimate into the nominal state (additive blocks by the layout's
  feedback table, the attitude as ``C <- Exp(-psi) C``), then reset to zero.
"""

from __future__ import annotations

import math

import numpy as np

from imugen.aid.filter import measurements
from imugen.aid.filter.context import Epoch
from imugen.aid.filter.error_model import propagate_covariance
from imugen.aid.filter.geometry import dcm, local_level_nb, local_sd
from imugen.aid.filter.kalman import symmetrize
from imugen.aid.filter.measurements import F_ALIGNED
from imugen.aid.filter.propagate import gravitation, rate_at, strapdown
from imugen.core import earth
from imugen.core.jit import njit_borrowing
from imugen.core.rotations_nb import qexpm1, qmul


@njit_borrowing(cache=True)
def feedback(md, wk, x):
    """``x <- x (-) dx``: subtract the additive blocks, rotate the attitude by ``-psi``."""
    dx, fb, ia, qa = wk.dx, md.feedback, md.ie.att, md.ix.att
    for b in range(fb.shape[0]):
        for a in range(fb[b, 2]):
            x[fb[b, 0] + a] -= dx[fb[b, 1] + a]
    e0, e1, e2, e3 = qexpm1(-dx[ia], -dx[ia + 1], -dx[ia + 2])
    q0, q1, q2, q3 = qmul(e0 + 1.0, e1, e2, e3, x[qa], x[qa + 1], x[qa + 2], x[qa + 3])
    nq = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    x[qa] = q0 * nq
    x[qa + 1] = q1 * nq
    x[qa + 2] = q2 * nq
    x[qa + 3] = q3 * nq


@njit_borrowing(cache=True)
def write_outputs(md, wk, x, out, s, j, flag):
    """Epoch ``j`` of sequence ``s``: nominal state, sigmas (along the local level in
    ``geodetic``), covariance (when stored), flags."""
    P, n, ie = wk.P, wk.P.shape[0], md.ie
    for i in range(x.shape[0]):
        out.x[s, j, i] = x[i]
    for i in range(n):
        out.sd[s, j, i] = math.sqrt(max(P[i, i], 0.0))
    if md.geo:  # position, velocity and attitude sigmas along the local E, N, U
        ip = md.ix.p
        local_level_nb(x[ip], x[ip + 1], x[ip + 2], wk.Lm)
        for i0 in (ie.p, ie.v, ie.att):
            local_sd(P, wk.Lm, i0, out.sd[s, j], i0)
    if out.P.shape[1] > 0:
        for i in range(n):
            for k in range(n):
                out.P[s, j, i, k] = P[i, k]
    out.flag[s, j] = flag


@njit_borrowing(cache=True)
def kernel(md, inp, out, wk, win, x):
    """Filter every sequence of the batch ``inp`` from its start sample ``inp.k0[s]`` through
    the epochs ``inp.ep_idx`` and write ``out`` (:mod:`imugen.aid.filter.context`); the state
    reached is written back into ``inp.x0``, ``inp.P0``, ``inp.k0``, ``inp.carry``. ``wk``
    (:func:`~imugen.aid.filter.context.new_work`, its transition pattern filled), ``win``
    (:func:`~imugen.aid.filter.measurements.new_windows`) and ``x`` (the nominal state's size)
    are scratch buffers allocated by the caller: the loop allocates nothing and counts no
    references (:func:`imugen.core.jit.njit_borrowing`)."""
    S, J, n = inp.dth.shape[0], inp.ep_idx.shape[0], inp.P0.shape[1]
    P, dx = wk.P, wk.dx
    ip = md.ix.p
    for s in range(S):
        for i in range(x.shape[0]):  # (loops: no broadcasting checks to compile)
            x[i] = inp.x0[s, i]
        for i in range(n):
            for k in range(n):
                P[i, k] = inp.P0[s, i, k]
        tn = inp.tun[s]
        k = inp.k0[s]
        wk.g_n[0], wk.g_n[1], wk.g_n[2] = gravitation(md, x)
        measurements.start(win)
        win.zupt[0], win.zupt[1] = inp.carry[s, 0], inp.carry[s, 1]
        for j in range(J):
            ke = inp.ep_idx[j]
            if ke < k:  # before the start
                for i in range(x.shape[0]):
                    out.x[s, j, i] = np.nan
                for i in range(n):
                    out.sd[s, j, i] = np.nan
                out.flag[s, j] = 0
                continue
            # --- propagate ---------------------------------------------------------------
            still = strapdown(md, inp, s, k, ke, x, wk, win, out.fc[s])
            if ke > k:
                propagate_covariance(md, tn, wk, x, ke - k)
            k = ke
            # --- updates -----------------------------------------------------------------
            for i in range(n):
                dx[i] = 0.0
            ia = md.ix.att
            dcm(x[ia], x[ia + 1], x[ia + 2], x[ia + 3], wk.C)
            e = Epoch(s, j, ke, ke > inp.k0[s], still, rate_at(md, inp, s, ke, x))
            flag = F_ALIGNED | measurements.update(e, md, inp, wk, x, tn, win)
            # --- feedback ----------------------------------------------------------------
            feedback(md, wk, x)
            measurements.after_feedback(win, md, wk, tn)
            if md.wgs and (dx[md.ie.p] != 0.0 or dx[md.ie.p + 1] != 0.0 or dx[md.ie.p + 2] != 0.0):
                wk.g_n[0], wk.g_n[1], wk.g_n[2] = earth.gravitation_nb(
                    md.prm, x[ip], x[ip + 1], x[ip + 2]
                )
            symmetrize(P)
            write_outputs(md, wk, x, out, s, j, flag)
        # where a later call over the following epochs resumes
        for i in range(x.shape[0]):
            inp.x0[s, i] = x[i]
        for i in range(n):
            for c in range(n):
                inp.P0[s, i, c] = P[i, c]
        inp.k0[s] = k
        inp.carry[s, 0], inp.carry[s, 1] = win.zupt[0], win.zupt[1]
