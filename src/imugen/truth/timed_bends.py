"""Bends of a timed ground route within the vehicle's least turning radius.

The timed fit (:func:`imugen.truth.fit.fit_timed`) smooths the fixes in time. Where a
vehicle slows through a tight bend between sparse fixes (a switchback logged every 5 s),
the smoothed curve slows at the apex and turns tighter than the vehicle can
(``max_curvature_1pm``), so its heading, rate-limited by the distance travelled
(:class:`imugen.truth.attitude.GroundAttitude`), cannot follow the velocity: the body slides
sideways (the mountain-pass drive 3.3 m/s). Smoothing harder in time does not help (it slows
the apex further).

:func:`bound_timed_bends` takes the geometry instead: around each place where the fit turns
tighter than the limit while moving, the fitted curve's stretch (:data:`REACH_RADII` turning
radii each side, never into a stop) keeps its timing (the distance travelled over time) while
its heading is turned by a smooth ``delta(s)`` and its distance stretched by ``1 + eps(s)``
(quintic B-splines every :data:`BASIS_M` over the middle, zero with two derivatives at the
ends held, :data:`HOLD_SHARE` of the stretch each; free at the route's end): the least such
(sum of squared coefficients, SLSQP) that turns within :data:`imugen.truth.fit.CURVATURE_MARGIN`
x the limit, keeps the acceleration within :data:`ACCEL_SHARE` x ``max_accel_mps2`` and closes
on the fit at the stretch's end; the bound is tightened from the fit's own tightest bend in
steps of :data:`HOMOTOPY_FACTOR`, each started from the last (a U-turn whose fixes' legs lie
closer than the turning diameter becomes a loop). The new stretch, the fit plus the integrated
displacement, is sampled every :data:`SAMPLE_S` by a quintic spline with the fit's velocity and
acceleration at its ends (:class:`SplicedSpline`). It is kept only where it holds the bound and
leaves no fix of the stretch farther from the curve than ``cap_m``; otherwise the input itself
turns tighter than the vehicle and the gate refuses its slip.

:func:`slow_turns` finds the places where the route turns round while creeping (a turn at rest
stands in for them).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline
from scipy.optimize import minimize

from imugen.truth.fit import CURVATURE_MARGIN
from imugen.truth.vehicles import VehicleParams

REACH_RADII = 6.0
"""Half-width of the stretch refitted around a bend too tight, in least turning radii
(``1 / max_curvature_1pm``; at least :data:`REACH_MIN_M`), beyond the bend's own extent."""

REACH_MIN_M = 5.0
"""Least half-width of that stretch [m]."""

HOLD_SHARE = 0.15
"""Share of the stretch's distance held (unchanged) at each end in its refit."""

ACCEL_SHARE = 0.8
"""Share of the class's ``max_accel_mps2`` a refitted stretch's acceleration may reach."""

HOMOTOPY_FACTOR = 1.2
"""Factor by which the curvature bound tightens per step of a stretch's refit."""

GRID_M = 0.25
"""Distance step [m] of a stretch's heading, curvature and closure."""

BASIS_M = 2.0
"""Spacing [m] of the smooth corrections' B-splines (4 to 20 of each)."""

SAMPLE_S = 0.05
"""Time step [s] of the samples of a refitted stretch (its quintic's knots)."""


def _curvature(d1, d2):
    vh2 = d1[:, 0] ** 2 + d1[:, 1] ** 2
    return np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(vh2, 1e-30) ** 1.5, vh2


def _tight(spline, tq, vp: VehicleParams, share: float):
    """Mask of the times ``tq`` where the curve turns tighter than ``share`` x the limit while
    faster than twice ``stop_speed_mps`` (a stop's direction is undefined)."""
    k, vh2 = _curvature(spline(tq, 1), spline(tq, 2))
    return (k > share * vp.max_curvature_1pm) & (vh2 > (2.0 * vp.stop_speed_mps) ** 2)


def _smoothstep9(x):
    """0 to 1 over [0, 1], its first four derivatives zero at both ends."""
    x = np.clip(x, 0.0, 1.0)
    return x**5 * (126.0 + x * (-420.0 + x * (540.0 + x * (-315.0 + 70.0 * x))))


class SplicedSpline:
    """A vector curve ``base(t)`` with stretches ``[ta, tb]`` replaced by other curves (each
    equal to the base at its ends to the third derivative); ``derivative(nu)`` and
    ``(t, nu)`` calls as a :class:`scipy.interpolate.BSpline`."""

    def __init__(self, base, pieces):
        self.base, self.pieces = base, list(pieces)

    def __call__(self, t, nu=0):
        t = np.asarray(t, float)
        out = np.array(self.base(t, nu) if nu else self.base(t))
        for ta, tb, f in self.pieces:
            m = (t >= ta) & (t <= tb)
            if m.any():
                out[m] = f(t[m], nu) if nu else f(t[m])
        return out

    def derivative(self, nu=1):
        return SplicedSpline(
            self.base.derivative(nu), [(a, b, f.derivative(nu)) for a, b, f in self.pieces]
        )


def _stretches(spline, t, vp, stops):
    """Time intervals to refit: each run of tight samples grown by the reach (in distance),
    clipped at the route's ends and at stops, merged where they overlap."""
    per = 8
    f = np.linspace(0.0, 1.0, per, endpoint=False)
    tq = np.r_[(t[:-1, None] + f * np.diff(t)[:, None]).ravel(), t[-1]]
    bad = _tight(spline, tq, vp, 1.0)
    if not bad.any():
        return []
    d1 = spline(tq, 1)
    vh = np.hypot(d1[:, 0], d1[:, 1])
    s = np.r_[0.0, np.cumsum(0.5 * (vh[1:] + vh[:-1]) * np.diff(tq))]
    reach = max(REACH_RADII / vp.max_curvature_1pm, REACH_MIN_M)
    out = []
    for i in np.flatnonzero(bad):
        sa, sb = s[i] - reach, s[i] + reach
        ta = float(np.interp(sa, s, tq)) if sa > 0 else float(t[0])
        tb = float(np.interp(sb, s, tq)) if sb < s[-1] else float(t[-1])
        for a, b in stops:  # never into a stop (it stays exactly still)
            if a <= tq[i] <= b:
                ta = tb = tq[i]
            elif b < tq[i]:
                ta = max(ta, b)
            elif a > tq[i]:
                tb = min(tb, a)
        if tb - ta <= 0.0:
            continue
        if out and ta <= out[-1][1]:
            out[-1][1] = max(out[-1][1], tb)
        else:
            out.append([ta, tb])
    return [(a, b) for a, b in out]


def _basis(x, a, b, nb, free_b=False):
    """Quintic B-splines on ``[a, b]`` at ``x`` (m, nb) with their values and first two
    derivatives zero at both ends (the outer three of each end dropped), and their
    derivatives (m, nb)."""
    inner = np.linspace(a, b, nb + 2)  # nb + 6 basis functions in all, 6 dropped
    knots = np.r_[[a] * 5, inner, [b] * 5]
    full = BSpline.design_matrix(np.clip(x, a, b), knots, 5).toarray()
    eye = np.eye(full.shape[1])
    d = np.column_stack(
        [BSpline(knots, eye[j], 5).derivative(1)(np.clip(x, a, b)) for j in range(full.shape[1])]
    )
    keep = slice(3, full.shape[1] - (0 if free_b else 3))
    out, dout = full[:, keep], d[:, keep]
    off = (x < a) | (x > b)
    out[off] = 0.0
    dout[off] = 0.0
    return out, dout


def _refit(spline, ta, tb, vp, end=False):
    """The stretch ``[ta, tb]`` of ``spline`` with its heading turned by ``delta(s)`` and its
    distance stretched by ``1 + eps(s)`` over the middle (both smooth, zero with two
    derivatives at the held ends), the least such that it turns within the bound and closes
    on the fit at the stretch's end; sampled by a quintic; or None."""
    n = max(40, math.ceil((tb - ta) / SAMPLE_S) + 1)
    tw = np.linspace(ta, tb, n)
    P, V, A = spline(tw), spline(tw, 1), spline(tw, 2)
    vh = np.hypot(V[:, 0], V[:, 1])
    s = np.r_[0.0, np.cumsum(0.5 * (vh[1:] + vh[:-1]) * np.diff(tw))]
    S = float(s[-1])
    if S < 1.0:
        return None
    m = max(16, math.ceil(S / GRID_M))
    sg = np.linspace(0.0, S, m + 1)
    h = sg[1] - sg[0]
    tg = np.interp(sg, s, tw)
    Vg, Ag = spline(tg, 1), spline(tg, 2)
    vg2 = np.maximum(Vg[:, 0] ** 2 + Vg[:, 1] ** 2, 1e-12)
    theta = np.unwrap(np.arctan2(Vg[:, 1], Vg[:, 0]))
    kap = (Vg[:, 0] * Ag[:, 1] - Vg[:, 1] * Ag[:, 0]) / vg2**1.5  # signed, 1/m
    a_t = (Vg[:, 0] * Ag[:, 0] + Vg[:, 1] * Ag[:, 1]) / np.sqrt(vg2)  # along the path
    a, b = HOLD_SHARE * S, (S if end else (1.0 - HOLD_SHARE) * S)
    nb = int(np.clip(round((b - a) / BASIS_M), 4, 20))
    nb_in = nb
    Bf, dBf = _basis(sg, a, b, nb, end)
    nb = Bf.shape[1]
    kmax = CURVATURE_MARGIN * vp.max_curvature_1pm
    w = np.full(m + 1, h)
    w[[0, -1]] *= 0.5

    def parts(z):
        dl, ep = Bf @ z[:nb], Bf @ z[nb:]
        return dl, ep, dBf @ z[:nb]

    def closure(z):
        dl, ep, _ = parts(z)
        c = (1.0 + ep) * np.cos(theta + dl) - np.cos(theta)
        d = (1.0 + ep) * np.sin(theta + dl) - np.sin(theta)
        return np.array([w @ c, w @ d])

    def bound(z, kb):  # kb (1 + eps) - |kappa + delta'| >= 0, and |a| within the limit
        _, ep, dd = parts(z)
        k = kap + dd
        a_lon = (dBf @ z[nb:]) * vg2 + (1.0 + ep) * a_t
        a_lat = (1.0 + ep) * vg2 * k
        a2 = (ACCEL_SHARE * vp.max_accel_mps2) ** 2 - a_lon**2 - a_lat**2
        return np.r_[kb * (1.0 + ep) - k, kb * (1.0 + ep) + k, a2 / vp.max_accel_mps2**2]

    # from the fit's own tightest bend down to the bound, each step started from the last
    z = np.zeros(2 * nb)
    k_fit = float(np.max(np.abs(kap)))
    steps = max(1, math.ceil(math.log(max(k_fit / kmax, 1.0)) / math.log(HOMOTOPY_FACTOR)))
    for kb in kmax * (k_fit / kmax) ** (np.arange(steps - 1, -1, -1) / steps):
        res = minimize(
            lambda z: float(z @ z),
            z,
            jac=lambda z: 2.0 * z,
            method="SLSQP",
            constraints=[
                *([] if end else [{"type": "eq", "fun": closure}]),
                {"type": "ineq", "fun": bound, "args": (max(kb, kmax),)},
            ],
            bounds=[(-math.pi, math.pi)] * nb + [(-0.5, 1.0)] * nb,
            options={"maxiter": 100, "ftol": 1e-10},
        )
        if res.status != 0:
            return None  # the input turns tighter than the vehicle there
        z = res.x
    if (not end and np.max(np.abs(closure(z))) > 1e-3) or bound(z, kmax).min() < -1e-3 * kmax:
        return None
    # the shift at the samples' own distances, integrated there (a quintic through the
    # grid's values rang about the held ends, 1e-6 m at 0.05 s: 2e-3 m/s^2, a kink in the
    # gyro); exactly constant where the heading and stretch are held
    Bw = _basis(np.clip(s, 0.0, S), a, b, nb_in, end)[0]
    dl, ep = Bw @ z[:nb], Bw @ z[nb:]
    theta_w = np.arctan2(V[:, 1], V[:, 0])
    c = (1.0 + ep) * np.cos(theta_w + dl) - np.cos(theta_w)
    d = (1.0 + ep) * np.sin(theta_w + dl) - np.sin(theta_w)
    hs = np.diff(s)
    D = np.column_stack(
        [
            np.r_[0.0, np.cumsum(0.5 * (c[1:] + c[:-1]) * hs)],
            np.r_[0.0, np.cumsum(0.5 * (d[1:] + d[:-1]) * hs)],
        ]
    )
    if not end:  # the closure's residual (< 1 mm), spread
        D -= _smoothstep9(s / S)[:, None] * D[-1]
    Dt = np.zeros_like(P)
    Dt[:, :2] = D
    if end:  # the route's end: still there (third and fourth derivatives zero)
        z3 = np.zeros(3)
        bc = ([(1, V[0]), (2, A[0])], [(3, z3), (4, z3)])
        return make_interp_spline(tw, P + Dt, k=5, bc_type=bc)
    # the fit plus the shift, a septic whose first three derivatives are zero at both held
    # ends as the shift's own: the fit's jerk continues across the joins (a quintic through
    # the shifted samples matched only velocity and acceleration there, and its jerk step
    # kinked the gyro: 1.2e-3 rad/s in an interval on a walk)
    z3 = [(nu, np.zeros(3)) for nu in (1, 2, 3)]
    return _Shifted(spline, make_interp_spline(tw, Dt, k=7, bc_type=(z3, z3)))


class _Shifted:
    """``base(t) + shift(t)`` with ``(t, nu)`` calls and ``derivative(nu)``."""

    def __init__(self, base, shift):
        self.base, self.shift = base, shift

    def __call__(self, t, nu=0):
        return self.base(t, nu) + self.shift(t, nu)

    def derivative(self, nu=1):
        return _Shifted(self.base.derivative(nu), self.shift.derivative(nu))


def bound_timed_bends(spline, t, y, vp: VehicleParams, stops, cap_m):
    """The timed fit ``spline`` (of the input times ``t`` (N,), fixes ``y`` (N, 3)) with its
    bends tighter than the vehicle's least turning radius refitted (module docstring);
    ``stops`` the fit's still intervals [s], ``cap_m`` the largest distance of a fix from the
    curve. Returns the curve (the fit itself, or a :class:`SplicedSpline`) and a report (None
    when no bend was too tight)."""
    if vp.attitude != "ground":
        return spline, None
    t = np.asarray(t, float)
    stretches = _stretches(spline, t, vp, stops)
    if not stretches:
        return spline, None
    pieces, left = [], 0
    worst_before = worst_after = 0.0
    moved = 0.0
    kmax = vp.max_curvature_1pm
    for ta, tb in stretches:
        tq = np.linspace(ta, tb, max(40, math.ceil((tb - ta) / SAMPLE_S) + 1))
        k0, vh2 = _curvature(spline(tq, 1), spline(tq, 2))
        mov = vh2 > (2.0 * vp.stop_speed_mps) ** 2
        worst_before = max(worst_before, float(np.max(k0[mov] / kmax, initial=0.0)))
        f = _refit(spline, ta, tb, vp, end=tb >= t[-1])
        ok = f is not None
        if ok:
            k1, vh2n = _curvature(f(tq, 1), f(tq, 2))
            movn = vh2n > (2.0 * vp.stop_speed_mps) ** 2
            inside = (t >= ta) & (t <= tb)
            res = np.linalg.norm(f(t[inside]) - y[inside], axis=1) if inside.any() else [0.0]
            ok = not np.any(k1[movn] > kmax) and float(np.max(res)) <= cap_m
        if ok:
            pieces.append((ta, tb, f))
            worst_after = max(worst_after, float(np.max(k1[movn] / kmax, initial=0.0)))
            moved = max(moved, float(np.max(np.linalg.norm(f(tq) - spline(tq), axis=1))))
        else:
            left += 1
            worst_after = max(worst_after, float(np.max(k0[mov] / kmax, initial=0.0)))
    report = {
        "method": "bends tighter than the vehicle's least turning radius refitted as a path by "
        "distance with its curvature bounded, driven at the fit's distance over time",
        "curvature_margin": CURVATURE_MARGIN,
        "stretches": len(stretches),
        "refitted": len(pieces),
        "left": left,
        "max_curvature_ratio_before": worst_before,
        "max_curvature_ratio": worst_after,
        "max_moved_m": moved,
        "residual_cap_m": float(cap_m),
    }
    return (SplicedSpline(spline, pieces) if pieces else spline), report


TURN_TOL_RAD = math.radians(30.0)
"""Lag of a heading turning at the least turning radius behind the velocity's direction, in a
slow stretch, that makes the stretch a turn at rest (:func:`slow_turns`)."""

TURN_RATE_RADPS = math.radians(22.5)
"""Mean rate of a turn at rest (8 s per half turn, as at an untimed reversal's stop): a
shorter slow stretch is widened to ``|turn| / rate``."""


def slow_turns(spline, t0, t1, vp: VehicleParams, stops, dt=0.1):
    """Intervals [s] where a timed ground route turns round while creeping: below twice
    ``max_slip_mps`` (not at a stop), a heading turning at the least turning radius with the
    distance would lag the velocity's direction by more than :data:`TURN_TOL_RAD` (a walker
    turning on the spot, a U-turn through a near stop that the fixes' jitter leaves in the
    fit).
    Declared turns at rest (:class:`imugen.truth.attitude.GroundAttitude`): the heading turns
    over the interval in time (at least ``|turn| /`` :data:`TURN_RATE_RADPS` long), standing
    in for a turn on the spot or a multi-point turn."""
    if vp.attitude != "ground":
        return []
    tq = np.arange(t0, t1 + 0.5 * dt, dt)
    v = spline(tq, 1)
    vh = np.hypot(v[:, 0], v[:, 1])
    still = np.zeros(len(tq), bool)
    for a, b in stops:
        still |= (tq >= a) & (tq <= b)
    slow = (vh < 2.0 * vp.max_slip_mps) & ~still
    if not slow.any():
        return []
    th = np.unwrap(np.arctan2(v[:, 1], v[:, 0]))
    step = vp.max_curvature_1pm * vh * dt  # the turn the distance allows per sample
    edges = np.flatnonzero(np.diff(np.r_[0, slow.astype(np.int8), 0]))
    out = []
    for i0, i1 in zip(edges[::2], edges[1::2] - 1, strict=True):
        if i1 <= i0 or (i0 == 0 and i1 == len(tq) - 1):
            continue  # a route that creeps all along turns with its distance
        lag, f = 0.0, th[i0]
        for j in range(i0 + 1, i1 + 1):  # the heading rate-limited by the distance
            f = min(max(th[j], f - step[j]), f + step[j])
            lag = max(lag, abs(th[j] - f))
        if lag <= TURN_TOL_RAD:
            continue
        c, half = 0.5 * (tq[i0] + tq[i1]), 0.5 * (tq[i1] - tq[i0])
        half = max(half, 0.5 * abs(th[i1] - th[i0]) / TURN_RATE_RADPS)
        a, b = max(c - half, t0), min(c + half, t1)
        a, b = max(min(a, b - 2.0 * half), t0), min(max(b, a + 2.0 * half), t1)  # at an end
        for sa, sb in stops:  # never into a stop
            if sb <= c:
                a = max(a, sb)
            elif sa >= c:
                b = min(b, sa)
        out.append([float(a), float(b)])
    return out
