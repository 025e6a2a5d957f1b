"""Speed profile of an untimed path: time-optimal under speed, acceleration and lateral limits,
jerk-bounded by moving-average filtering; the path motion ``G(s(t))``."""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import BSpline, PPoly
from scipy.ndimage import minimum_filter1d

from imugen.core.errors import InputError
from imugen.core.jit import njit


class PathMotion:
    """Position ``G(s(t))``: geometry G(s) (arc length) and speed profile s(t) (PPoly);
    ``profile``: the road profile ``(H, report)`` whose vertical ``G`` has
    (:func:`imugen.truth.road.path_on_road`), or None."""

    kind = "untimed"

    def __init__(self, G: BSpline, s_of_t: PPoly, length: float, profile=None):
        self.profile = profile
        self.G = [G] + [G.derivative(nu) for nu in (1, 2, 3)]
        self.S = [s_of_t] + [s_of_t.derivative(nu) for nu in (1, 2, 3)]
        self.length = length
        self.t0 = float(s_of_t.x[0])
        self.t1 = float(s_of_t.x[-1])

    def _s(self, t):
        return np.clip(self.S[0](t), 0.0, self.length)

    def position(self, t):
        return self.G[0](self._s(t))

    def velocity(self, t):
        return self.G[1](self._s(t)) * self.S[1](t)[:, None]

    def eval(self, t):
        s = self._s(t)
        sd, sdd, sddd = (self.S[i](t)[:, None] for i in (1, 2, 3))
        g1, g2, g3 = (self.G[i](s) for i in (1, 2, 3))
        p = self.G[0](s)
        v = g1 * sd
        a = g2 * sd**2 + g1 * sdd
        j = g3 * sd**3 + 3.0 * g2 * sd * sdd + g1 * sddd
        return p, v, a, j


def curvature(G: BSpline, s):
    d1 = G.derivative(1)(s)
    d2 = G.derivative(2)(s)
    n1 = np.linalg.norm(d1, axis=1)
    return np.linalg.norm(np.cross(d1, d2), axis=1) / np.maximum(n1, 1e-12) ** 3


def _moving_average(x, m):
    """Causal moving average over m samples with zero history: y_i = mean(x[i-m+1..i])."""
    c = np.cumsum(np.r_[np.zeros(m), x])
    return (c[m:] - c[:-m]) / m


@njit(cache=True)
def _prefix_sums(x, start):
    """``start + cumsum(x)``, each sum correctly rounded from the exact one (Neumaier's
    compensated summation): the error of a prefix does not grow with its length."""
    out = np.empty(len(x) + 1)
    s = start
    comp = 0.0
    out[0] = start
    for i in range(len(x)):
        t = s + x[i]
        if abs(s) >= abs(x[i]):
            comp += (s - t) + x[i]
        else:
            comp += (x[i] - t) + s
        s = t
        out[i + 1] = s + comp
    return out


def continuous(pp: PPoly) -> PPoly:
    """``pp`` with each piece's constant term the compensated sum of the first piece's and the
    increments of the pieces before it (each piece's value at its end less its constant).

    A speed profile has a piece every 0.02 s: the constants that
    :meth:`PPoly.antiderivative` chains piece by piece round at every joint, with one sign
    along a steady run (the same increment added to a slowly growing distance), so the
    distance stepped away from the integral of the speed by 1.3e-7 m per 200 s at 145 km
    (an 84-minute Schuler oscillation of 1e-6 m in a closure); compensated, the steps stay
    within an ulp and do not add up.
    """
    c = np.array(pp.c, dtype=float)
    h = np.diff(pp.x)
    k = c.shape[0] - 1
    inc = np.zeros(c.shape[1])
    for i in range(k):  # Horner without the constant: sum_i c_i h^(k-i)
        inc = (inc + c[i]) * h
    c[-1] = _prefix_sums(inc, float(c[-1, 0]))[:-1]
    return PPoly(c, pp.x)


def speed_profile(
    G: BSpline,
    L: float,
    *,
    cruise_mps,
    accel_mps2,
    lat_accel_mps2,
    jerk_mps3,
    vmax_mps=None,
    max_iter=30,
    lat_tol=0.01,
):
    """Speed profile s(t) along the geometry; returns (PPoly s(t), report).

    The profile starts and ends at rest; see the module docstring for the construction.
    ``vmax_mps`` (callable of the arc length [m], optional) caps the speed along the path
    (the phases of a flight, :mod:`imugen.truth.flight`).
    """
    for name, val in (
        ("cruise speed", cruise_mps),
        ("acceleration", accel_mps2),
        ("lateral acceleration", lat_accel_mps2),
        ("jerk", jerk_mps3),
    ):
        if not (val > 0 and math.isfinite(val)):
            raise InputError(None, f"{name} limit must be a positive number, got {val}")
    ns = int(min(400_000, max(200, math.ceil(L / 0.25))))
    s = np.linspace(0.0, L, ns + 1)
    ds = s[1] - s[0]
    kappa = curvature(G, s)
    A = accel_mps2
    scale_lim = np.ones_like(s)
    cap2 = np.full_like(s, cruise_mps**2) if vmax_mps is None else np.asarray(vmax_mps(s)) ** 2
    cap2 = np.minimum(cap2, cruise_mps**2)
    for it in range(max_iter):  # noqa: B007 (reported below)
        vlim2 = np.minimum(cap2, lat_accel_mps2 / np.maximum(kappa, 1e-12)) * scale_lim
        vlim2[0] = vlim2[-1] = 0.0
        fwd = 2 * A * s + np.minimum.accumulate(vlim2 - 2 * A * s)
        bwd = -2 * A * s + np.minimum.accumulate((vlim2 + 2 * A * s)[::-1])[::-1]
        v = np.sqrt(np.maximum(np.minimum(np.minimum(fwd, bwd), vlim2), 0.0))
        vm = v[:-1] + v[1:]
        if not np.all(vm > 0):
            raise InputError(None, "speed profile stalls (zero speed limit inside the path)")
        dtj = 2.0 * ds / vm
        tj = np.r_[0.0, np.cumsum(dtj)]
        acc = (v[1:] - v[:-1]) / dtj  # uniform acceleration within each s-segment
        T = tj[-1]
        h = min(0.02, T / 200.0)
        ti = np.arange(0.0, T + h, h)
        j = np.clip(np.searchsorted(tj, ti, side="right") - 1, 0, ns - 1)
        V = np.clip(v[j] + acc[j] * (ti - tj[j]), 0.0, None)
        V[-1] = 0.0
        a_raw = np.diff(V) / h
        Tf = max(float(a_raw.max() - a_raw.min()) / jerk_mps3, 2 * h)
        m = math.ceil(Tf / h)
        a_pad = np.r_[a_raw, np.zeros(2 * m + 2)]
        c = np.r_[0.0, 0.0, _moving_average(_moving_average(a_pad, m), m)]
        # accel = sum c_i B2(t/h - i): uniform quadratic B-splines, support [i h, (i+3) h];
        # the two leading zeros put the whole motion inside the base interval [2h, len(c) h]
        acc_sp = BSpline(h * np.arange(len(c) + 3.0), c, 2)
        pp = PPoly.from_spline(acc_sp)  # also holds extrapolated pieces: keep the base interval
        pp = PPoly(pp.c[:, 2 : len(c)], pp.x[2 : len(c) + 1])
        s_pp = continuous(pp.antiderivative(2))
        t_end = float(s_pp.x[-1])
        total = float(s_pp(t_end))
        s_pp = PPoly(s_pp.c * (L / total), s_pp.x - s_pp.x[0])  # steps of an ulp, not summed
        # check the lateral acceleration on a fine grid
        tt = np.linspace(0.0, s_pp.x[-1], max(2000, int(s_pp.x[-1] / h) + 1))
        sv = np.clip(s_pp(tt), 0.0, L)
        vv = s_pp.derivative(1)(tt)
        ratio = curvature(G, sv) * vv**2 / lat_accel_mps2
        worst = float(ratio.max())
        if worst <= 1.0 + lat_tol:
            break
        # lower the limit where exceeded, spread over the distance the filter reaches
        bad = ratio > 1.0
        fac = np.ones_like(s)
        idx = np.clip(np.searchsorted(s, sv[bad]), 0, ns)
        np.minimum.at(fac, idx, 1.0 / ratio[bad])
        reach = max(1, math.ceil(2.0 * Tf * float(vv[bad].max()) / ds))
        fac = minimum_filter1d(fac, 2 * reach + 1)
        scale_lim *= np.where(fac < 1.0, 0.98 * fac, 1.0)
    report = {
        "cruise_mps": cruise_mps,
        "accel_mps2": accel_mps2,
        "lat_accel_mps2": lat_accel_mps2,
        "jerk_mps3": jerk_mps3,
        "filter_width_s": Tf,
        "duration_s": float(s_pp.x[-1]),
        "max_lateral_ratio": worst,
        "iterations": it + 1,
        "distance_scale": L / total,
    }
    return s_pp, report
