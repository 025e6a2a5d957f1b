"""Noise terms of one sensor axis: closed-form expected Allan variances and a pure-NumPy simulator.

The terms and how they are parameterised (SI; ``dt = 1 / rate``, ``tau = m dt``; every Allan
variance is the *expected overlapping* Allan variance of a record of ``K`` samples):

white (filtered)
    density ``N``, through a :class:`imugen.sensors.bandwidth.OutputFilter` (internal rate, low-pass,
    decimation): ``AVAR = N^2 A_f(m)`` from the filtered noise's autocovariance
    (:func:`bandwidth.avar_from_autocov`); ``A_f = 1 / tau`` for the ideal filter.
quantization
    LSB ``q``. ``mode="round"``: each rate sample rounded on its own (a rate register, as the
    ADIS16405 logs): white, ``AVAR = (q^2 / 12) / m`` (valid for a noise sigma above about
    0.3 LSB). ``mode="carry"``: residual carry (imugen's model, right for integrated
    outputs): ``AVAR = q^2 / (4 m^2)``.
narrowband line
    a second-order autoregressive process at the output rate (a resonance driven by white
    noise), centre ``f_c``, -3 dB full width ``B``, variance ``P``: poles ``rho e^{+-i theta}``,
    ``rho = exp(-pi B dt)``, ``theta = 2 pi f_c dt``; autocovariance
    ``P rho^l [cos(theta l) + c sin(theta l)]``, ``c = (1 - rho^2) / (1 + rho^2) cot(theta)``.
    A pure tone is the limit ``B -> 0``.
Gauss-Markov (one, or the sum approximating flicker)
    imugen's exact discretisation ``x_k = phi x_{k-1} + sigma sqrt(1 - phi^2) xi_k``,
    ``phi = exp(-dt / T)``, read as point samples. Stationary start: the continuous-time IEEE
    952 form (:func:`gm_avar`, imugen.grades.gm_avar) for ``m > 64``, exact sums of the
    sampled sequence's autocovariance below (at ``m = 1`` the sampled sequence has 3/2 of the
    averaged form's Allan variance). Zero start (``x_0 = 0``, imugen's
    ``start: zero``, the in-run wander beside a turn-on bias), expected over a record of ``K``
    samples: ``AVAR_stat - sigma^2 (1 - phi^m)^4 (1 - phi^{2n}) /
    ((1 - phi)^2 (1 - phi^2) n 2 m^2)``, ``n = K - 2m + 1`` (the process is the stationary one
    minus ``phi^k s_0``; the missing part's contribution averaged over the record).
flicker band (imugen.grades ``model: flicker``)
    ``C`` GM components of equal sigma at ``T_c = geomspace(T_min, T_max, C)`` (one
    component: ``sqrt(T_min T_max)``); default ``C = max(2, round(2 log10(T_max / T_min)) + 1)``;
    sigma of each = ``floor / level`` with ``level`` the mean (over 64 log-spaced tau in
    ``[5 T_min, T_max / 2]``) of the unit-sigma sum's Allan deviation. Same numbers as
    imugen.grades.flicker_taus / flicker_component_sigma.
rate random walk
    ``r_k = r_{k-1} + K sqrt(dt) xi_k``, ``r_0 = 0``: ``AVAR = K^2 dt (2 m^2 + 1) / (6 m)``
    (``K^2 tau / 3`` for large m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from imugen.sensors.bandwidth import OutputFilter, avar_from_autocov, ideal

GM_PEAK, GM_PEAK_X = 0.6173642831444415, 1.8926178169666992  # imugen.grades


# --- Gauss-Markov / flicker (imugen.grades formulas) ------------------------------------------
def gm_avar(tau, sigma, T):
    """Allan variance of a stationary first-order GM process (imugen.grades.gm_avar)."""
    x = np.asarray(tau, dtype=float) / T
    small = x < 1e-3
    xs = np.where(small, 1.0, x)
    br = 1.0 - (-4.0 * np.expm1(-xs) + np.expm1(-2.0 * xs)) / (2.0 * xs)
    br = np.where(small, x * x / 3.0 - x**3 / 4.0, br)
    return 2.0 * sigma**2 * br / np.where(x > 0, x, np.inf)


def gm_zero_start_correction(m, dt, sigma, T, K):
    """What a zero start removes from the expected overlapping AVAR (>= 0)."""
    m = np.asarray(m, float)
    n = np.maximum(K - 2 * m + 1, 1.0)
    a = -np.expm1(-m * dt / T)  # 1 - phi^m
    b = -np.expm1(-dt / T)  # 1 - phi
    c = -np.expm1(-2 * n * dt / T)  # 1 - phi^(2n)
    d = -np.expm1(-2 * dt / T)  # 1 - phi^2
    return sigma**2 * a**4 * c / (b * b * d * n) / (2 * m * m)


def gm_avar_sampled(m, dt, sigma, T):
    """AVAR of the point-sampled stationary GM sequence (what imugen's rate output holds):
    exact sums of ``sigma^2 phi^|l|`` for ``m <= 64``; beyond, the continuous form (they differ
    by ``1 / (2 m^2)`` relative)."""
    m = np.asarray(m, dtype=np.int64)
    out = gm_avar(m * dt, sigma, T)
    small = m <= 64
    if np.any(small):
        r = sigma**2 * np.exp(-np.arange(2 * 64 + 1) * dt / T)
        out = np.where(small, avar_from_autocov(r, np.where(small, m, 1)), out)
    return out


def gm_avar_record(m, dt, sigma, T, K=None, start="stationary"):
    """Expected overlapping AVAR of one GM component (stationary or zero start)."""
    out = gm_avar_sampled(m, dt, sigma, T)
    if start == "zero":
        out = out - gm_zero_start_correction(m, dt, sigma, T, K)
    return out


def flicker_components(lo: float, hi: float, components: int | None = None) -> int:
    """imugen's default component count for a flicker band."""
    if components is not None:
        return int(components)
    return max(2, round(2 * math.log10(hi / lo)) + 1)


def flicker_taus(lo, hi, C):
    if C == 1:
        return np.array([math.sqrt(lo * hi)])
    return np.geomspace(lo, hi, C)


def flicker_level(Ts) -> float:
    grid = np.geomspace(5.0 * Ts[0], Ts[-1] / 2.0, 64)
    return float(np.mean(np.sqrt(sum(gm_avar(grid, 1.0, T) for T in Ts))))


def flicker_sigma(floor: float, lo: float, hi: float, C: int) -> float:
    """GM sigma of each component giving the Allan floor ``floor``."""
    return floor / flicker_level(flicker_taus(lo, hi, C))


def flicker_avar_record(m, dt, floor, lo, hi, C, K=None, start="stationary"):
    Ts = flicker_taus(lo, hi, C)
    s = flicker_sigma(floor, lo, hi, C)
    return sum(gm_avar_record(m, dt, s, T, K, start) for T in Ts)


def gm_flat_decades(ratio: float = 1.25**2) -> float:
    """Widest tau range (decades) over which one GM's Allan deviation varies by less than
    ``ratio`` (highest / lowest): the band just around its peak."""
    x = np.geomspace(1e-3, 1e3, 6001)
    la = 0.5 * np.log(gm_avar(x, 1.0, 1.0))
    # the widest window is bounded by equal levels on both sides of the peak
    ip = int(np.argmax(la))
    best = 0.0
    for level in np.linspace(la[ip] - math.log(ratio), la[ip], 400):
        ok = np.nonzero(la >= level)[0]
        if la[ip] - level <= math.log(ratio):
            best = max(best, math.log10(x[ok[-1]] / x[ok[0]]))
    return best


def gm_width_decades(tol: float = 1.25) -> float:
    """Decades of tau over which one GM's Allan deviation stays within ``peak / tol``."""
    x = np.geomspace(1e-3, 1e3, 60001)
    a = np.sqrt(gm_avar(x, 1.0, 1.0))
    ok = x[a >= a.max() / tol]
    return float(math.log10(ok[-1] / ok[0]))


# --- narrowband line (AR(2)) ------------------------------------------------------------------
def ar2_coeffs(fc, width, dt):
    rho = math.exp(-math.pi * width * dt)
    theta = 2 * math.pi * fc * dt
    return rho, theta, (1.0, -2 * rho * math.cos(theta), rho * rho)


def ar2_autocov(fc, width, dt, power, nlags):
    """Autocovariance of the AR(2) line of variance ``power`` at lags ``0 .. nlags-1``."""
    rho, theta, _ = ar2_coeffs(fc, width, dt)
    lag = np.arange(nlags)
    s = math.sin(theta)
    c = (1 - rho * rho) / (1 + rho * rho) * (math.cos(theta) / s if abs(s) > 1e-15 else 0.0)
    return power * rho**lag * (np.cos(theta * lag) + c * np.sin(theta * lag))


def ar2_psd_shape(f, fc, width, dt):
    """One-sided PSD of the unit-variance AR(2) line at ``f`` [1/Hz]."""
    _, _, a = ar2_coeffs(fc, width, dt)
    w = 2 * np.pi * np.asarray(f, float) * dt
    A = a[0] + a[1] * np.exp(-1j * w) + a[2] * np.exp(-2j * w)
    s = 1.0 / np.abs(A) ** 2
    # normalise to unit variance: var = (1/fs) int_{-fs/2}^{fs/2} (g^2 / |A|^2) df
    ww = np.linspace(-np.pi, np.pi, 200001)
    AA = a[0] + a[1] * np.exp(-1j * ww) + a[2] * np.exp(-2j * ww)
    var = np.trapezoid(1.0 / np.abs(AA) ** 2, ww) / (2 * np.pi)
    return 2 * dt * s / var


def line_avar(m, fc, width, dt, power):
    m = np.asarray(m, dtype=np.int64)
    r = ar2_autocov(fc, width, dt, power, int(2 * m.max()) + 1)
    return avar_from_autocov(r, m)


# --- other closed forms ------------------------------------------------------------------------
def rrw_avar(m, dt, K):
    m = np.asarray(m, float)
    return K * K * dt * (2 * m * m + 1) / (6 * m)


def quant_avar(m, lsb, mode="round"):
    m = np.asarray(m, float)
    if lsb <= 0:
        return np.zeros_like(m)
    if mode == "round":
        return lsb * lsb / 12.0 / m
    return lsb * lsb / (4.0 * m * m)


# --- one axis's model ------------------------------------------------------------------------
@dataclass
class AxisModel:
    """Noise model of one axis (SI).

    Attributes
    ----------
    rate_hz : float
    white : float                 density N
    filt : OutputFilter           output bandwidth (ideal by default)
    lsb : float                   quantization step (0: off)
    quant_mode : str              "round" or "carry"
    lines : list of dict          {"fc": Hz, "width": Hz, "power": variance}
    bi_model : str or None        "flicker", "gauss_markov" or None
    bi_floor : float              Allan floor (flicker) / Allan peak (GM)
    bi_band : tuple               (T_min, T_max) for flicker
    bi_components : int
    bi_T : float                  GM correlation time
    bi_start : str                "zero" or "stationary"
    rrw : float                   K
    offset : float                static value added before quantization (bias, gravity)
    """

    rate_hz: float
    white: float = 0.0
    filt: OutputFilter | None = None
    lsb: float = 0.0
    quant_mode: str = "round"
    lines: list = field(default_factory=list)
    bi_model: str | None = None
    bi_floor: float = 0.0
    bi_band: tuple = (1.0, 100.0)
    bi_components: int = 5
    bi_T: float = 100.0
    bi_start: str = "zero"
    rrw: float = 0.0
    offset: float = 0.0
    slow_peak: float = 0.0  # a second GM (environmental / thermal bias wander): Allan peak
    slow_T: float = 300.0  # and correlation time

    def __post_init__(self):
        if self.filt is None:
            self.filt = ideal(self.rate_hz)

    @property
    def dt(self):
        return 1.0 / self.rate_hz

    def gm_parts(self):
        """(sigmas, taus) of the GM components of the in-run bias."""
        if self.bi_model is None or self.bi_floor <= 0:
            sg, Ts = np.zeros(0), np.zeros(0)
        elif self.bi_model == "flicker":
            lo, hi = self.bi_band
            C = self.bi_components
            Ts = flicker_taus(lo, hi, C)
            sg = np.full(C, flicker_sigma(self.bi_floor, lo, hi, C))
        else:
            sg, Ts = np.array([self.bi_floor / GM_PEAK]), np.array([self.bi_T])
        return sg, Ts

    def slow_parts(self):
        if self.slow_peak <= 0:
            return np.zeros(0), np.zeros(0)
        return np.array([self.slow_peak / GM_PEAK]), np.array([self.slow_T])

    def avar_terms(self, m, K) -> dict:
        """Expected overlapping AVAR of each term at ``tau = m dt`` for a record of ``K``."""
        m = np.asarray(m, dtype=np.int64)
        dt = self.dt
        out = {"white": self.filt.avar(m, self.white) if self.white > 0 else np.zeros(len(m))}
        out["quantization"] = quant_avar(m, self.lsb, self.quant_mode)
        for i, ln in enumerate(self.lines):
            out[f"line{i}"] = line_avar(m, ln["fc"], ln["width"], dt, ln["power"])
        sg, Ts = self.gm_parts()
        out["bias_instability"] = sum(
            (gm_avar_record(m, dt, s, T, K, self.bi_start) for s, T in zip(sg, Ts, strict=True)),
            np.zeros(len(m)),
        )
        sg, Ts = self.slow_parts()
        out["slow_gm"] = sum(
            (gm_avar_record(m, dt, s, T, K, self.bi_start) for s, T in zip(sg, Ts, strict=True)),
            np.zeros(len(m)),
        )
        out["rate_random_walk"] = rrw_avar(m, dt, self.rrw)
        return out

    def avar(self, m, K):
        return sum(self.avar_terms(m, K).values())

    # --- simulation ---------------------------------------------------------------------------
    def simulate(self, K: int, rng: np.random.Generator) -> np.ndarray:
        """One realisation of ``K`` output samples (float64)."""
        dt = self.dt
        y = np.full(K, float(self.offset))
        if self.white > 0:
            y += self.filt.white(self.white, K, rng)
        for ln in self.lines:
            y += simulate_ar2(ln["fc"], ln["width"], dt, ln["power"], K, rng)
        for sg, Ts in (self.gm_parts(), self.slow_parts()):
            for s, T in zip(sg, Ts, strict=True):
                y += simulate_gm(s, T, dt, K, rng, self.bi_start)
        if self.rrw > 0:
            z = rng.standard_normal(K)
            z[0] = 0.0
            y += np.cumsum(self.rrw * math.sqrt(dt) * z)
        if self.lsb > 0:
            y = quantize(y, self.lsb, self.quant_mode)
        return y


def simulate_gm(sigma, T, dt, K, rng, start="stationary"):
    """imugen's exact GM discretisation; ``x_0 ~ N(0, sigma^2)`` or 0."""
    phi = math.exp(-dt / T)
    drv = sigma * math.sqrt(-math.expm1(-2 * dt / T))
    x0 = sigma * rng.standard_normal() if start == "stationary" else 0.0
    z = rng.standard_normal(K - 1)
    rest = signal.lfilter([drv], [1.0, -phi], z, zi=[phi * x0])[0]
    return np.concatenate([[x0], rest])


def simulate_ar2(fc, width, dt, power, K, rng):
    """Stationary AR(2) line (initial pair drawn from its stationary law)."""
    _, _, a = ar2_coeffs(fc, width, dt)
    r = ar2_autocov(fc, width, dt, 1.0, 3)
    # innovation variance for unit process variance: gamma0 (1 - a1 rho1 - a2 rho2)
    a1, a2 = -a[1], -a[2]
    q = 1.0 - a1 * r[1] - a2 * r[2]
    L = np.linalg.cholesky(np.array([[1.0, r[1]], [r[1], 1.0]]))
    x_prev = L @ rng.standard_normal(2)  # (x_{-1}, x_{-2})
    zi = signal.lfiltic([1.0], a, y=x_prev)
    e = rng.standard_normal(K) * math.sqrt(max(q, 0.0))
    return math.sqrt(power) * signal.lfilter([1.0], a, e, zi=zi)[0]


def quantize(y, lsb, mode="round"):
    if mode == "round":
        return lsb * np.round(y / lsb)
    # residual carry: out_k = q round((y_k + res_{k-1}) / q); the integrated output error stays
    # within half an LSB (imugen's _quantize)
    c = np.cumsum(y)
    Q = lsb * np.floor(c / lsb + 0.5)
    return np.diff(np.concatenate([[0.0], Q]))
