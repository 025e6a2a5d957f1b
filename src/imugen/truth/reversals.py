"""Untimed paths that double back: a stop and a turn at each reversal (issue 27).

A reversal is where an untimed path turns back on itself within less than the vehicle's
turning diameter (a rail line drawn out and back as one KML path): the directions of the
polyline :func:`window_m` before and after a vertex make an angle of at least
:data:`REVERSAL_ANGLE_DEG`. No vehicle drives through it at speed, and one smooth geometry
through it has a cusp whose speed profile either creeps or U-turns at full speed. The path
is cut there into legs; each leg is fitted and timed alone (:func:`imugen.truth.fit.fit_path`,
:func:`imugen.truth.profile.speed_profile`: from rest to rest, a jerk-limited profile within
the class's ``accel_mps2`` and ``jerk_mps3``), its ends moved onto the input points they stand
for (the legs meet at the reversal's vertex), the legs joined by a stop of
:data:`REVERSAL_STOP_S`, and the whole sampled every :data:`LEG_STEP_S` and joined by the
quintic spline through the samples, constant over the stops (:func:`legs_motion`): a timed
motion that is the legs' own (no smoothing, no stop detection that could move the stop into
the ramps), whose stops hold the position while the vehicle turns round at rest (the
timing report's ``turns_at_rest_s``, each stop's middle but :data:`TURN_REST_S` at either
end; :class:`imugen.truth.attitude.GroundAttitude`), so that it pulls away facing its
velocity, with no slide sideways.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from imugen.truth.fit import K_SPLINE, PenalizedSpline, TimedMotion, fit_path, noise_estimate
from imugen.truth.profile import speed_profile
from imugen.truth.vehicles import VehicleParams

#: Direction change (deg) within :func:`window_m` of a vertex that makes it a reversal.
REVERSAL_ANGLE_DEG = 150.0
#: Stop (s) at a reversal between the legs.
REVERSAL_STOP_S = 10.0
#: Rest (s) at each end of a reversal's stop around its turn at rest (the heading turns over
#: the stop's middle, ``REVERSAL_STOP_S - 2 TURN_REST_S``).
TURN_REST_S = 1.0
#: Spacing (s) of the samples of the timed legs that the timed fit joins.
LEG_STEP_S = 0.5
#: Penalty (normalized time) of the spline through the legs' samples: negligible (the
#: samples are exact), only keeping the system well conditioned.
JOIN_LAMBDA = 1e-6
#: A leg's end is moved onto its input point over this many times the offset (at least the
#: turning diameter): the added acceleration ``offset x 5.8 / D^2 x v^2`` stays small.
PIN_PER_OFFSET = 50.0


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


def _pin(d, length_m):
    """Weight (shape of ``d``) of an end correction at distance ``d`` [m] from the end: 1 at
    the end, 0 beyond ``length_m``, a quintic smoothstep between (zero slope and curvature at
    both ends)."""
    x = np.clip(np.asarray(d, float) / length_m, 0.0, 1.0)
    return 1.0 - x**3 * (10.0 - 15.0 * x + 6.0 * x * x)


def pin_length_m(offset_m: float, length_m: float, vp: VehicleParams) -> float:
    """Distance [m] over which a leg's end is moved by ``offset_m`` onto its input point:
    :data:`PIN_PER_OFFSET` offsets and at least :func:`window_m`, at most half the leg."""
    return min(0.5 * length_m, max(window_m(vp), PIN_PER_OFFSET * offset_m))


def _exact_spline(t, y, ties):
    """Quintic spline through the samples ``y`` (n, 3) at ``t`` (n,) (a penalized spline
    with a negligible penalty: the samples are exact), constant on the sample ranges
    ``ties`` (the stops)."""
    ps = PenalizedSpline(t, [(i0, i1 + K_SPLINE - 1) for i0, i1 in ties])
    coef = np.column_stack([ps.solve(JOIN_LAMBDA, y[:, i]) for i in range(3)])
    return ps.bspline(coef)


def legs_motion(y: np.ndarray, cuts: list[int], vp: VehicleParams, corner_m, prof: dict):
    """Time an untimed path with reversals at the vertexes ``cuts``: (TimedMotion, fit
    report, timing report); ``prof`` are :func:`speed_profile`'s limits. The timing report's
    ``vertex_times_s`` (n,) are the times the motion passes the input points (for the checks
    of timed routes against their input; not metadata).

    Each leg is the path fit of its vertexes (:func:`fit_path`) with its ends moved onto the
    input points they stand for (:func:`pin_length_m`: the legs meet at the reversal's vertex
    exactly), timed by :func:`speed_profile` from rest to rest: a jerk-limited profile
    (acceleration within ``accel_mps2``, jerk within ``jerk_mps3``, the class's comfortable
    figures, far within the gate's limits). The legs and the stops between them are sampled
    every :data:`LEG_STEP_S` and joined by the quintic spline through the samples, constant over
    each stop (no smoothing, no stop detection: the motion is the legs' own)."""
    t_parts, p_parts, legs, vertex_t, ties = [], [], [], [], []
    t_off, n_done = 0.0, 0
    for a, b in itertools.pairwise([0, *cuts, len(y) - 1]):
        G, L, _, s_v = fit_path(y[a : b + 1], vp, corner_m, vertices=True)
        s_pp, _rep = speed_profile(G, L, **prof)
        t_a, t_b = float(s_pp.x[0]), float(s_pp.x[-1])
        n = max(4, math.ceil((t_b - t_a) / LEG_STEP_S))
        tt = np.linspace(t_a, t_b, n + 1)
        s_tt = np.maximum.accumulate(np.clip(s_pp(tt), 0.0, L))
        d_a, d_b = y[a] - G(0.0), y[b] - G(L)
        p = (
            G(s_tt)
            + np.outer(_pin(s_tt, pin_length_m(float(np.linalg.norm(d_a)), L, vp)), d_a)
            + np.outer(_pin(L - s_tt, pin_length_m(float(np.linalg.norm(d_b)), L, vp)), d_b)
        )
        if p_parts:  # the stop: the previous leg's last position held, then this leg
            hold = t_off + LEG_STEP_S * np.arange(1, round(REVERSAL_STOP_S / LEG_STEP_S))
            t_parts.append(hold)
            p_parts.append(np.repeat(p_parts[-1][-1:], len(hold), axis=0))
            ties.append((n_done - 1, n_done + len(hold)))
            n_done += len(hold)
            t_off += REVERSAL_STOP_S
        t_parts.append(t_off + tt - t_a)
        tv = t_off + np.interp(s_v, s_tt, tt - t_a)
        vertex_t.append(tv if not vertex_t else tv[1:])  # the reversal's vertex: its arrival
        p_parts.append(p)
        n_done += len(tt)
        legs.append({"from_vertex": int(a), "to_vertex": int(b), "length_m": float(L),
                     "duration_s": t_b - t_a,
                     "end_moved_m": [float(np.linalg.norm(d_a)), float(np.linalg.norm(d_b))]})  # fmt: skip
        t_off += t_b - t_a
    t = np.concatenate(t_parts)
    samples = np.concatenate(p_parts)
    spline = _exact_spline(t, samples, ties)
    motion = TimedMotion(spline, float(t[0]), float(t[-1]))
    tv = np.concatenate(vertex_t)
    dist = np.linalg.norm(motion.position(tv) - y, axis=1)
    fit = {
        "method": "legs between reversals, each fitted as a path and timed alone (from rest to "
        f"rest), joined by stops of {REVERSAL_STOP_S:g} s: the quintic spline through the legs' "
        f"samples every {LEG_STEP_S:g} s, constant over each stop",
        "noise_estimate_m": noise_estimate(t, samples).tolist(),
        "rms_distance_m": float(np.sqrt(np.mean(dist**2))),
        "max_distance_m": float(dist.max()),
        "join_max_distance_m": float(np.max(np.linalg.norm(spline(t) - samples, axis=1))),
        "stops": [[float(t[i0]), float(t[i1])] for i0, i1 in ties],
        "limited": None,
        "legs": legs,
    }
    timing = {
        "timed": False,
        "source": f"speed profile of each leg between {len(cuts)} reversals, a "
        f"{REVERSAL_STOP_S:g} s stop and a turn at each",
        "reversals": len(cuts),
        "duration_s": float(t[-1]),
        "vertex_times_s": tv,
        "turns_at_rest_s": [
            [float(t[i0]) + TURN_REST_S, float(t[i1]) - TURN_REST_S] for i0, i1 in ties
        ],
    }
    return motion, fit, timing
