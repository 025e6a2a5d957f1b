"""Explicit corners of untimed ground paths: fillets of arcs and clothoids (issue 27).

A ground vehicle takes a bend no tighter than its least turning radius. Where the smoothed
polyline of an untimed ground path (:func:`imugen.truth.fit.fit_path`) turns tighter than
that, the bend is built here, tangent to the legs either side of it, from pieces of linear
curvature in arc length: clothoids (Euler spirals) from the straight to the arc and back, and
arcs of radius :func:`fillet_radius_m` (``1 / (CORNER_MARGIN max_curvature)``). The curvature
is continuous (the heading's rate and the yaw acceleration stay finite) and at most
``1 / R`` everywhere.

* A corner of deflection ``delta`` < :data:`HAIRPIN_TURN_RAD` (its legs' lines meet ahead):
  clothoid - arc - clothoid at the legs' intersection ``V``, each clothoid ``Ls = R`` long
  (it turns ``Ls / 2R``; below 1 rad two clothoids peaking at the radius ``R / delta``, which
  stands for ``R`` below). Its points lie within
  ``E = (R + p) / cos(delta / 2) - R`` of ``V`` and within
  ``(R + p) - R cos(delta / 2)`` of the legs (the arc's middle), ``p`` the clothoid's shift
  (``p ~ Ls^2 / 24 R``, :func:`fillet_offsets`).
* A hairpin (deflection >= :data:`HAIRPIN_TURN_RAD`, the legs run back side by side): two half
  fillets joined by a straight across the gap where the legs are at least the fillets' width
  apart, else one fillet of the whole turn at a radius widened to the gap (up to
  :data:`WIDE_RADII` ``R``), else (legs closer than that fillet's width at ``R``) a bulb (keyhole) that first swings out by ``beta`` and then turns
  ``delta + 2 beta`` back onto the exit leg, every piece at radius ``R``; the turn reaches as
  far as the drawn hairpin's apex.

:func:`corner_zones` finds the bends that need it (a vertex group where the plain fit is too
tight) and returns their pieces; a bend the construction cannot place within
``CURVATURE_RESIDUAL_RADII`` radii of the polyline is left to the fit's curvature bound.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

#: Share of the class's ``max_curvature_1pm`` that a constructed corner reaches (below the
#: fit's own bound, :data:`imugen.truth.fit.CURVATURE_MARGIN`: the spline through the corner's
#: samples stays within it).
CORNER_MARGIN = 0.8

#: Length of each clothoid of a fillet, in radii (at most the deflection times the radius:
#: then the fillet is two clothoids without an arc).
SPIRAL_RADII = 1.0

#: Largest radius of a hairpin taken as one fillet, in radii ``R`` (legs closer than two half
#: fillets' width, farther than one fillet's at ``R``: the fillet's radius widened to fit).
WIDE_RADII = 2.0

#: Deflection (rad) from which a bend is built as a hairpin (the legs' lines meet far behind or
#: not at all).
HAIRPIN_TURN_RAD = math.radians(150.0)

#: Least deflection (rad) of a bend built here (a flatter one is a jog the fit's bound takes).
MIN_TURN_RAD = math.radians(10.0)

#: Spacing of the corner's samples, in radii.
SAMPLE_RADII = 0.1

#: A corner built for a group of vertexes turns as the group does within this (rad): one
#: that leaves a part of the group's turn to the straight legs is no corner of the group.
GROUP_TURN_TOL_RAD = math.radians(15.0)

#: A corner's ends lie within this many radii of the polyline (they join it without a kink).
JOIN_RADII = 0.02


def fillet_radius_m(max_curvature_1pm: float) -> float:
    """Radius [m] of a constructed corner: ``1 / (CORNER_MARGIN max_curvature_1pm)``."""
    return 1.0 / (CORNER_MARGIN * max_curvature_1pm)


def _spiral(a, R):
    """Clothoid length [m] of a fillet turning ``a`` (rad, > 0) at radius ``R`` and the radius
    it reaches: ``SPIRAL_RADII R`` and ``R``; a turn below ``SPIRAL_RADII`` rad is two
    clothoids of that length peaking at the radius ``SPIRAL_RADII R / a`` (the curvature
    changes no faster than ``1 / (SPIRAL_RADII R^2)`` in any fillet)."""
    ls = SPIRAL_RADII * R
    return ls, (R if a >= SPIRAL_RADII else ls / a)


def _pieces(turns, R, straight_after=None):
    """Pieces (length m, curvature at start, at end 1/m) of consecutive fillets turning
    ``turns`` (signed rad) at radius ``R``, each clothoid - arc - clothoid, with a straight
    ``straight_after[i]`` after fillet i."""
    out = []
    for i, d in enumerate(turns):
        a = abs(d)
        if a > 0.0:
            ls, re = _spiral(a, R)
            k = math.copysign(1.0 / re, d)
            out += [(ls, 0.0, k), (a * re - ls, k, k), (ls, k, 0.0)]
        if straight_after is not None and straight_after[i] > 0.0:
            out.append((straight_after[i], 0.0, 0.0))
    return [p for p in out if p[0] > 0.0]


def integrate(pieces, ds):
    """Points (M, 2), headings (M,) [rad] and curvatures (M,) [1/m] of the curve of the
    pieces (linear curvature in arc length) from the origin heading along +x, ``ds`` [m]
    apart at most (every piece's ends are samples); heading exact, positions by Simpson's
    rule on each interval."""
    s_parts, k_parts = [np.zeros(1)], [np.zeros(1)]
    s0 = 0.0
    for length, k0, k1 in pieces:
        n = max(1, math.ceil(length / ds))
        f = np.arange(1, n + 1) / n
        s_parts.append(s0 + f * length)
        k_parts.append(k0 + f * (k1 - k0))
        s0 += length
    s = np.concatenate(s_parts)
    k = np.concatenate(k_parts)
    if len(pieces):
        k[0] = pieces[0][1]
    h = np.diff(s)
    th = np.r_[0.0, np.cumsum(0.5 * h * (k[1:] + k[:-1]))]  # exact: k linear on each step
    # heading at each step's middle (exact for linear curvature): Simpson on cos/sin
    thm = th[:-1] + 0.5 * h * (0.75 * k[:-1] + 0.25 * k[1:])
    c = (np.cos(th[:-1]) + 4.0 * np.cos(thm) + np.cos(th[1:])) * h / 6.0
    sn = (np.sin(th[:-1]) + 4.0 * np.sin(thm) + np.sin(th[1:])) * h / 6.0
    P = np.column_stack([np.r_[0.0, np.cumsum(c)], np.r_[0.0, np.cumsum(sn)]])
    return P, th, k


def fillet_offsets(delta, R):
    """Closed-form figures of a fillet turning ``delta`` (rad, 0 < |delta| < pi) at radius
    ``R``: (tangent length ``T`` from the vertex to each end [m], shift ``p`` [m], apex
    distance ``E`` from the vertex [m], largest distance from the legs [m]), from the
    integrated clothoid (:func:`integrate`)."""
    a = abs(delta)
    ls, R = _spiral(a, R)
    P, th, _ = integrate([(ls, 0.0, 1.0 / R)], R * 1e-3)
    x, y, ts = P[-1, 0], P[-1, 1], th[-1]
    p = y - R * (1.0 - math.cos(ts))
    k = x - R * math.sin(ts)
    T = (R + p) * math.tan(0.5 * a) + k
    E = (R + p) / math.cos(0.5 * a) - R
    return T, p, E, (R + p) - R * math.cos(0.5 * a)


@dataclass
class Corner:
    """A constructed bend: its samples (M, 2) in the path's ENU, their curvature (M,), the
    polyline's vertex range it replaces, its kind and radius."""

    points: np.ndarray
    curvature: np.ndarray
    first: int
    last: int
    kind: str
    radius_m: float
    turn_rad: float
    u_in: float = 0.0
    u_out: float = 0.0


def _cross(a, b):
    """z of the cross product of two plane vectors."""
    return float(a[0] * b[1] - a[1] * b[0])


def _rot(th):
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s], [s, c]])


def fillet(v, th_in, delta, R, ds):
    """Samples (M, 2) and curvatures of the fillet tangent to the line through ``v`` at
    heading ``th_in`` and the one through ``v`` at ``th_in + delta``."""
    P, _, k = integrate(_pieces([delta], R), ds)
    # the vertex in the fillet's own frame: where its end's tangent meets the x axis
    q, te = P[-1], delta
    xv = q[0] - q[1] * math.cos(te) / math.sin(te)
    return v + (P - [xv, 0.0]) @ _rot(th_in).T, k


def hairpin(a, th_in, b, th_out, delta, apex, R, ds):
    """Samples and curvatures of a hairpin from the entry line (point ``a``, heading
    ``th_in``) onto the exit line (``b``, ``th_out``), turning ``delta`` (signed, |delta| >=
    :data:`HAIRPIN_TURN_RAD`), reaching ``apex`` [m] along the direction into the bend; None
    when no placement joins the lines.

    Two half fillets joined by a straight ``c >= 0`` across the gap, or, where the legs are
    closer than that allows, a bulb: out by ``beta``, back by ``delta + 2 beta``, out by
    ``beta`` (each at radius ``R``). The start on the entry line is chosen so that the turn's
    farthest point along ``m`` (the bisector into the bend) is ``apex``; ``c`` or ``beta`` so
    that the end lies on the exit line."""
    d_in = np.array([math.cos(th_in), math.sin(th_in)])
    d_out = np.array([math.cos(th_out), math.sin(th_out)])
    m = d_in - d_out
    m = m / np.linalg.norm(m)
    dm = float(d_in @ m)
    if dm <= 1e-6:
        return None
    Rot = _rot(th_in)

    def place(pieces):
        P, _, k = integrate(pieces, ds)
        W = P @ Rot.T
        # start = a + x0 d_in, reaching the apex but not starting beyond a
        x0 = min((apex - float(np.max(W @ m)) - float(a @ m)) / dm, 0.0)
        W = W + a + x0 * d_in
        f = _cross(d_out, W[-1] - b)  # signed distance of the end to the exit line
        return W, k, f

    def straight(c):
        return place(_pieces([0.5 * delta, 0.5 * delta], R, [c, 0.0]))

    def bulb(beta):
        sgn = math.copysign(1.0, delta)
        return place(_pieces([-sgn * beta, delta + 2.0 * sgn * beta, -sgn * beta], R))

    f0 = straight(0.0)[2]
    span = 20.0 * R + float(np.linalg.norm(b - a))
    f1 = straight(span)[2]
    if f0 * f1 <= 0.0:
        c = brentq(lambda c: straight(c)[2], 0.0, span, xtol=1e-6 * R)
        W, k, _ = straight(c)
        return W, k

    # legs a little closer: one fillet of the whole turn at a radius between R and the
    # half fillets' width (R at most WIDE_RADII times)
    def one(r):
        return place(_pieces([delta], r))

    fw = one(WIDE_RADII * R)[2]
    if f0 * fw > 0.0 and one(R)[2] * fw < 0.0:
        r = brentq(lambda r: one(r)[2], R, WIDE_RADII * R, xtol=1e-6 * R)
        W, k, _ = one(r)
        return W, k
    g0, g1 = bulb(1e-9)[2], bulb(0.5 * math.pi)[2]
    if g0 * g1 < 0.0:
        beta = brentq(lambda x: bulb(x)[2], 1e-9, 0.5 * math.pi, xtol=1e-9)
        W, k, _ = bulb(beta)
        return W, k
    return None


def _seg_dist(P, y):
    """Distance [m] of points P (M, 2) to the polyline y (N, 2)."""
    best = np.full(len(P), np.inf)
    for a, b in itertools.pairwise(y):
        d = b - a
        dd = float(d @ d)
        w = np.clip((P - a) @ d / dd, 0.0, 1.0) if dd > 0 else np.zeros(len(P))
        best = np.minimum(best, np.linalg.norm(P - (a + w[:, None] * d), axis=1))
    return best


def _line_meet(a, da, b, db):
    """Intersection of the lines a + t da and b + r db (None when parallel)."""
    den = _cross(da, db)
    if abs(den) < 1e-9:
        return None
    t = _cross(b - a, db) / den
    return a + t * da


def build_corner(y, i0, i1, R, cap_m):
    """The corner replacing the vertexes ``i0..i1`` (0 < i0 <= i1 < n - 1) of the polyline
    ``y`` (n, 2), tangent to the segment before ``i0`` and the one after ``i1``; None when it
    does not fit (its ends off the polyline by more than :data:`JOIN_RADII` radii, or a point
    farther than ``cap_m`` from it)."""
    d = np.diff(y, axis=0)
    th = np.arctan2(d[:, 1], d[:, 0])
    turn = (np.diff(th) + math.pi) % (2.0 * math.pi) - math.pi  # at vertexes 1..n-2
    delta = float(np.sum(turn[i0 - 1 : i1]))
    if abs(delta) < MIN_TURN_RAD:
        return None
    th_in, th_out = float(th[i0 - 1]), float(th[i1])
    ds = SAMPLE_RADII * R
    if abs(delta) < HAIRPIN_TURN_RAD:
        v = _line_meet(y[i0], d[i0 - 1], y[i1], d[i1])
        if v is None:
            return None
        P, k = fillet(v, th_in, delta, R, ds)
        kind = "fillet"
    else:
        m = np.array([math.cos(th_in), math.sin(th_in)]) - [math.cos(th_out), math.sin(th_out)]
        m /= np.linalg.norm(m)
        apex = float(np.max(y[i0 : i1 + 1] @ m))
        got = hairpin(y[i0], th_in, y[i1], th_out, delta, apex, R, ds)
        if got is None:
            return None
        P, k = got
        kind = "hairpin"
    lo, hi = max(0, i0 - 50), min(len(y), i1 + 52)
    if _seg_dist(P, y[lo:hi]).max() > cap_m:
        return None
    cum = np.r_[0.0, np.cumsum(np.linalg.norm(d, axis=1))]
    tol = JOIN_RADII * R
    # the ends lie on the legs either side of the group's middle, no farther along the
    # polyline from the group than the corner is long (not on another pass of a path that
    # comes back near)
    mid = (i0 + i1 + 1) // 2
    reach = float(np.sum(np.linalg.norm(np.diff(P, axis=0), axis=1)))
    j0 = max(lo, int(np.searchsorted(cum, cum[i0] - reach, side="right")) - 1)
    j1 = min(hi - 1, int(np.searchsorted(cum, cum[i1] + reach, side="left")) + 1)
    u_in = _chord_at(P[0], y, cum, j0, mid, tol)
    u_out = _chord_at(P[-1], y, cum, mid, j1, tol)
    if u_in is None or u_out is None or not u_in < u_out:
        return None
    if kind == "hairpin" and np.any(np.sign(k) == -np.sign(delta)):
        kind = "bulb"
    return Corner(P, k, i0, i1, kind, R, delta, u_in, u_out)


def _chord_at(p, y, cum, j0, j1, tol):
    """Chord length [m] along ``y`` (its cumulative chord ``cum``) of the point ``p`` lying
    within ``tol`` [m] of one of the segments ``j0..j1 - 1``; None when it lies on none."""
    best, at = np.inf, None
    for j in range(j0, j1):
        a, b = y[j], y[j + 1]
        dd = b - a
        L2 = float(dd @ dd)
        if L2 <= 0.0:
            continue
        w = min(max(float((p - a) @ dd) / L2, 0.0), 1.0)
        dist = float(np.linalg.norm(p - a - w * dd))
        if dist < best:
            best, at = dist, cum[j] + w * (cum[j + 1] - cum[j])
    return at if best <= tol else None


def build_corners(y, groups, R, cap_m, grow=3):
    """Corners (:class:`Corner`, in path order, not overlapping) for the vertex groups
    ``groups`` ((i0, i1) pairs) of the polyline ``y`` (n, 2+): of the corners of the groups
    from one vertex narrower to ``grow`` vertexes wider either side, the one nearest the
    polyline (its largest distance) among those that turn as the group does (within
    :data:`GROUP_TURN_TOL_RAD`); a group none of which fits is left out."""
    y = np.asarray(y, float)[:, :2]
    out: list[Corner] = []
    n = len(y)
    d = np.diff(y, axis=0)
    th = np.arctan2(d[:, 1], d[:, 0])
    turn = (np.diff(th) + math.pi) % (2.0 * math.pi) - math.pi  # at vertexes 1..n-2
    for i0, i1 in groups:
        want = float(np.sum(turn[i0 - 1 : i1]))
        best, best_d = None, np.inf
        for a in range(max(1, i0 - grow), min(i0 + 1, i1) + 1):
            for b in range(max(a, i1 - 1), min(n - 2, i1 + grow) + 1):
                c = build_corner(y, a, b, R, cap_m)
                if (
                    c is None
                    or (out and c.u_in < out[-1].u_out)
                    or abs(c.turn_rad - want) > GROUP_TURN_TOL_RAD
                ):
                    continue
                lo, hi = max(0, a - 50), min(n, b + 52)
                dist = float(_seg_dist(c.points, y[lo:hi]).max())
                if dist < best_d:
                    best, best_d = c, dist
        if best is not None:
            out.append(best)
    return out
