"""Untimed paths that double back: a stop and a turn at each reversal (issue 27).

A reversal is where an untimed path turns back on itself within less than the vehicle's
turning diameter (a rail line drawn out and back as one KML path): the directions of the
polyline :func:`window_m` before and after a vertex make an angle of at least
:data:`REVERSAL_ANGLE_DEG`. No vehicle drives through it at speed, and one smooth geometry
through it has a cusp whose speed profile either creeps or U-turns at full speed. The path
is cut there into legs; each leg is fitted and timed alone (:func:`imugen.truth.fit.fit_path`,
:func:`imugen.truth.profile.speed_profile`: from rest to rest), the legs joined by a stop of
:data:`REVERSAL_STOP_S`, and the whole sampled every :data:`LEG_STEP_S` and fitted as a timed
route (:func:`imugen.truth.fit.fit_timed`), whose stops hold the attitude and whose ground
attitude turns the vehicle round as it pulls away (as a timed route that reverses through a
stop does).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from imugen.truth.fit import fit_path, fit_timed
from imugen.truth.profile import speed_profile
from imugen.truth.vehicles import VehicleParams

#: Direction change (deg) within :func:`window_m` of a vertex that makes it a reversal.
REVERSAL_ANGLE_DEG = 150.0
#: Stop (s) at a reversal between the legs.
REVERSAL_STOP_S = 10.0
#: Spacing (s) of the samples of the timed legs that the timed fit joins.
LEG_STEP_S = 0.5


def window_m(vp: VehicleParams) -> float:
    """Half-window (m) of the reversal test: the vehicle's turning diameter."""
    return 2.0 / vp.max_curvature_1pm


def find_reversals(y: np.ndarray, vp: VehicleParams) -> list[int]:
    """Vertex indexes (into ``y``, shape (n, 2 or 3), m) where the path reverses; one per
    cluster (the sharpest), none within a window of either end."""
    y = np.asarray(y, float)[:, :2]
    seg = np.linalg.norm(np.diff(y, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    w = window_m(vp)
    inner = np.flatnonzero((s > w) & (s < s[-1] - w) & np.r_[True, seg > 1e-9])
    if not len(inner):
        return []
    si = s[inner]
    pa = np.column_stack([np.interp(si - w, s, y[:, k]) for k in range(2)])
    pb = np.column_stack([np.interp(si + w, s, y[:, k]) for k in range(2)])
    u, v = y[inner] - pa, pb - y[inner]
    nu, nv = np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1)
    ok = (nu > 1e-9) & (nv > 1e-9)
    cos = np.einsum("ij,ij->i", u, v) / np.where(ok, nu * nv, 1.0)
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    hits = np.flatnonzero(ok & (ang >= REVERSAL_ANGLE_DEG))
    out: list[tuple[int, float, float]] = []
    for j in hits:
        if out and si[j] - out[-1][1] < w:
            if ang[j] > out[-1][2]:
                out[-1] = (int(inner[j]), float(si[j]), float(ang[j]))
        else:
            out.append((int(inner[j]), float(si[j]), float(ang[j])))
    return [i for i, _, _ in out]


def legs_motion(y: np.ndarray, cuts: list[int], vp: VehicleParams, corner_m, prof: dict):
    """Time an untimed path with reversals at the vertexes ``cuts``: (TimedMotion, fit
    report, timing report); ``prof`` are :func:`speed_profile`'s limits. The timing report's
    ``vertex_times_s`` (n,) are the times the motion passes the input points (for the checks
    of timed routes against their input; not metadata)."""
    t_parts, p_parts, legs, vertex_t = [], [], [], []
    t_off = 0.0
    for a, b in itertools.pairwise([0, *cuts, len(y) - 1]):
        G, L, _, s_v = fit_path(y[a : b + 1], vp, corner_m, vertices=True)
        s_pp, _rep = speed_profile(G, L, **prof)
        t_a, t_b = float(s_pp.x[0]), float(s_pp.x[-1])
        n = max(4, math.ceil((t_b - t_a) / LEG_STEP_S))
        tt = np.linspace(t_a, t_b, n + 1)
        p = G(np.clip(s_pp(tt), 0.0, L))
        if p_parts:  # the stop: the previous leg's last position held, then this leg
            hold = t_off + LEG_STEP_S * np.arange(1, round(REVERSAL_STOP_S / LEG_STEP_S))
            t_parts.append(hold)
            p_parts.append(np.repeat(p_parts[-1][-1:], len(hold), axis=0))
            t_off += REVERSAL_STOP_S
            p = p + (p_parts[-1][-1] - p[0]) * np.exp(-(tt - t_a))[:, None]  # joined exactly
        t_parts.append(t_off + tt - t_a)
        s_tt = np.maximum.accumulate(np.clip(s_pp(tt), 0.0, L))
        tv = t_off + np.interp(s_v, s_tt, tt - t_a)
        vertex_t.append(tv if not vertex_t else tv[1:])  # the reversal's vertex: its arrival
        p_parts.append(p)
        legs.append({"from_vertex": int(a), "to_vertex": int(b), "length_m": float(L),
                     "duration_s": t_b - t_a})  # fmt: skip
        t_off += t_b - t_a
    t = np.concatenate(t_parts)
    keep = np.r_[True, np.diff(t) > 1e-9]
    motion, fit = fit_timed(t[keep], np.concatenate(p_parts)[keep], vp)
    fit = {**fit, "method": "legs between reversals, each fitted and timed alone, joined by "
           f"stops, then fitted as a timed route ({fit['method']})", "legs": legs}  # fmt: skip
    timing = {
        "timed": False,
        "source": f"speed profile of each leg between {len(cuts)} reversals, a "
        f"{REVERSAL_STOP_S:g} s stop and a turn at each",
        "reversals": len(cuts),
        "duration_s": float(t[-1]),
        "vertex_times_s": np.concatenate(vertex_t),
    }
    return motion, fit, timing
