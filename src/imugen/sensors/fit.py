"""Fit a sensor grade from a still IMU log (per axis, gyro and accelerometer).

``fit_grade(samples, rate_hz)`` returns the grade in imugen's grade-document format (datasheet
units, every figure with its source and uncertainty) plus per-axis details. Method, per sensor
(three axes share the filter, the bias-instability model and its band or correlation time, as
imugen's grade format requires; amplitudes are per axis):

1. static part removed: the per-axis mean (turn-on bias, gravity and Earth rate on a still
   unit); the gravity axis and its sign are found from the accelerometer means (a z axis
   reading -g points down: the figures are per axis and sign-free, the static means are
   reported in both frames);
2. quantization: the LSB read from the data (the smallest step between distinct values, when
   the values sit on that grid), applied as rounding of each rate sample (``mode: round``);
3. narrowband lines (vibration, interference, resonances): peaks of the Welch PSD above a
   running-median baseline, each an AR(2) line (centre, width), kept where it changes the
   Allan variance by more than 1 %;
4. the overlapping Allan variance on a dense tau grid (all ``m`` up to 8, then 12 per decade
   up to ``K / 5``), with the equivalent degrees of freedom of each point (Greenhall's
   algorithm, allantools.edf_greenhall, for the local noise type);
5. non-negative least squares of the relative AVAR residual, weights
   ``1 / (2 / edf + eps^2)`` (``eps = 1 %``: a model-error floor so that the huge edf of the
   shortest taus does not let a 1 % filter-shape mismatch decide everything), over amplitudes
   (white density^2, bias-instability floor^2, RRW^2, line powers) for every candidate of the
   nonlinear parameters: the output filter (moving average / Bartlett of L internal samples,
   Butterworth order 1 or 2 with its cut-off, or ideal) and the bias-instability shape
   (flicker band ``[T_min, T_max]``, or one Gauss-Markov ``T``, or none), by alternating grid
   searches;
6. flicker or Gauss-Markov: the width of the floor -- the widest tau range over which the bias
   part of the measured Allan deviation (measured AVAR minus the fitted white, quantization and
   line parts) varies by less than +-25 % -- against the widest a single GM makes
   (:func:`imugen.sensors.noise_terms.gm_flat_decades` = 1.58 decades): wider by more than ``WIDTH_MARGIN`` (0.3
   decades) -> flicker band, narrower by more -> one GM, in between the width cannot tell and the
   better weighted chi-square of the two decides; a second, slower GM (environment, e.g. lab
   temperature cycling: the grade's ``slow_bias``) is added beyond the floor only where it lowers
   chi-square by > 5 % (``slow_gm``); the reasons, with the chi-squares, are written into the
   grade's ``source`` and printed;
7. uncertainty of each figure from the record length: linear least-squares covariance of the
   amplitudes on the octave taus (nearly independent), each weighted by ``edf / 2``; a figure
   (a square root of an amplitude) gets half the relative standard error of its amplitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import allantools
import numpy as np
from scipy import signal
from scipy.optimize import nnls

from imugen.core.errors import InputError
from imugen.sensors import bandwidth as bw
from imugen.sensors.noise_terms import (
    GM_PEAK,
    AxisModel,
    flicker_avar_record,
    flicker_components,
    gm_avar_record,
    gm_flat_decades,
    line_avar,
    quant_avar,
    rrw_avar,
)
from imugen.sensors.options import GradeFitOptions

G0 = 9.80665
DEG = math.pi / 180
UNITS = {  # datasheet unit names of imugen.units and their SI factors
    "deg_per_sqrt_h": DEG / 60,
    "deg_per_h": DEG / 3600,
    "deg_per_h_per_sqrt_h": DEG / 3600 / 60,
    "deg_per_s": DEG,
    "m_per_s_per_sqrt_h": 1 / 60,
    "ug": 1e-6 * G0,
    "mg": 1e-3 * G0,
    "m_per_s2_per_sqrt_s": 1.0,
    "ug_per_sqrt_hz": 1e-6 * G0,
}
SENSOR_UNITS = {
    "gyro": {
        "white_noise": "deg_per_sqrt_h",
        "bias_instability": "deg_per_h",
        "rate_random_walk": "deg_per_h_per_sqrt_h",
        "quantization": "deg_per_s",
        "static": "deg_per_h",
        "line": "deg_per_h",
    },
    "accel": {
        "white_noise": "m_per_s_per_sqrt_h",
        "bias_instability": "ug",
        "rate_random_walk": "m_per_s2_per_sqrt_s",
        "quantization": "mg",
        "static": "mg",
        "line": "ug",
    },
}
EPS_MODEL = 0.01
WIDTH_MARGIN = 0.3  # decades around a single GM's width where the width cannot decide
FLAT_RATIO = 1.25**2  # +-25 %


# --- Allan variance and its degrees of freedom ------------------------------------------------
def oavar(y: np.ndarray, m) -> np.ndarray:
    """Overlapping Allan variance of rate samples at ``tau = m dt`` (cumulative sums, float64)."""
    y = np.asarray(y, np.float64)
    c = np.concatenate([[0.0], np.cumsum(y - y.mean())])
    out = np.empty(len(m))
    for i, mm in enumerate(np.asarray(m, dtype=np.int64)):
        d = c[2 * mm :] - 2 * c[mm:-mm] + c[: -2 * mm]
        out[i] = np.mean(d * d) / (2.0 * mm * mm)
    return out


def tau_grid(K: int, per_decade: int = 12, max_frac: float = 0.2) -> np.ndarray:
    """Averaging factors m: 1..8, then log-spaced up to ``max_frac K``."""
    top = max(9, int(K * max_frac))
    m = np.unique(np.round(np.geomspace(8, top, int(per_decade * math.log10(top / 8)) + 1)))
    return np.unique(np.concatenate([np.arange(1, 9), m])).astype(np.int64)


def octaves(K: int, max_frac: float = 0.25) -> np.ndarray:
    m = 2 ** np.arange(0, 40)
    return m[m <= K * max_frac].astype(np.int64)


def noise_alpha(m, avar) -> np.ndarray:
    """Power-law frequency-noise exponent per point from the local log-log slope mu of AVAR
    (``alpha = -mu - 1``, rounded, in [-2, 2])."""
    lm, la = np.log(np.asarray(m, float)), np.log(avar)
    mu = np.gradient(la, lm) if len(m) > 2 else np.full(len(m), -1.0)
    mu = np.convolve(np.pad(mu, 2, mode="edge"), np.ones(5) / 5, "valid")
    return np.clip(np.round(-mu - 1), -2, 2).astype(int)


def edf(m, K: int, alpha) -> np.ndarray:
    """Equivalent degrees of freedom of the overlapping AVAR (Greenhall; Riley's simple
    formulas where Greenhall is not implemented)."""
    out = np.empty(len(m))
    for i, (mm, a) in enumerate(zip(np.asarray(m), np.asarray(alpha), strict=True)):
        try:
            out[i] = allantools.edf_greenhall(
                alpha=int(a), d=2, m=int(mm), N=int(K), overlapping=True, modified=False
            )
        except (NotImplementedError, ValueError, ZeroDivisionError):
            out[i] = allantools.edf_simple(int(K), int(mm), int(a))
    return np.maximum(out, 1.0)


def adev_ci(adev, e, p=0.95):
    """Confidence interval of an Allan deviation estimate with ``e`` degrees of freedom."""
    from scipy.stats import chi2

    lo = adev * np.sqrt(e / chi2.ppf(0.5 + p / 2, e))
    hi = adev * np.sqrt(e / chi2.ppf(0.5 - p / 2, e))
    return lo, hi


# --- quantization and lines -------------------------------------------------------------------
def detect_lsb(y: np.ndarray, min_levels: int = 3) -> float:
    """LSB of quantized samples, or 0 when the data are not on a grid.

    The candidate is the smallest gap between distinct values (ignoring gaps below 1e-6 of the
    range: float32 conversion noise); accepted when 99.9 % of samples lie within 1 % of an
    LSB of the grid ``offset + k LSB``.
    """
    v = np.unique(np.asarray(y, np.float64))
    if len(v) < min_levels:
        return 0.0
    gaps = np.diff(v)
    span = v[-1] - v[0]
    gaps = gaps[gaps > 1e-6 * span]
    if len(gaps) == 0:
        return 0.0
    g0 = gaps.min()
    small = gaps[gaps < 1.5 * g0]
    q = float(np.median(small))
    k = (y - v[0]) / q
    ok = np.abs(k - np.round(k)) < 0.01
    return q if ok.mean() > 0.999 else 0.0


def find_lines(y, rate_hz, others_avar, m, K, max_lines=4, ratio=3.0):
    """Narrowband lines in the Welch PSD that matter to the Allan variance.

    Returns list of {"fc", "width", "power", "peak_ratio"} (SI), strongest first.
    """
    y = np.asarray(y, np.float64) - np.mean(y)
    nper = int(min(2**16, 2 ** math.floor(math.log2(max(256, K // 16)))))
    f, P = signal.welch(y, fs=rate_hz, nperseg=nper)
    df = f[1] - f[0]
    # running median baseline in log frequency (+-0.1 decade, >= 15 bins)
    base = np.empty_like(P)
    lf = np.log10(np.maximum(f, df))
    for i in range(len(f)):
        w = max(7, int(np.searchsorted(lf, lf[i] + 0.1) - i))
        a, b = max(1, i - w), min(len(f), i + w + 1)
        base[i] = np.median(P[a:b])
    base[0] = P[0]
    exc = P / base
    fmin = max(30 * df, 20.0 / (K / rate_hz))
    cand = (exc > ratio) & (f > fmin) & (f < rate_hz / 2 - 2 * df)
    lines = []
    idx = np.nonzero(cand)[0]
    # group contiguous candidate bins (allow one-bin gaps)
    groups = []
    for j in idx:
        if groups and j - groups[-1][-1] <= 2:
            groups[-1].append(j)
        else:
            groups.append([j])
    sm = np.convolve(exc, np.ones(9) / 9, "same")
    spans = []
    for g in groups:
        a, b = g[0], g[-1]
        # extend to where the (9-bin smoothed) excess falls back to 1.5x baseline
        while a > 1 and sm[a - 1] > 1.5:
            a -= 1
        while b < len(f) - 2 and sm[b + 1] > 1.5:
            b += 1
        if spans and a <= spans[-1][1] + 1:
            spans[-1] = (spans[-1][0], max(b, spans[-1][1]), max(spans[-1][2], exc[g].max()))
        else:
            spans.append((a, b, exc[g].max()))
    for a, b, peak in spans:
        sl = slice(a, b + 1)
        ex = np.maximum(P[sl] - base[sl], 0.0)
        power = float(np.sum(ex) * df)
        if power <= 0:
            continue
        fc = float(np.sum(f[sl] * ex) / np.sum(ex))
        # width: second moment of the excess (Gaussian-equivalent FWHM), at least 2 bins
        sd = math.sqrt(max(np.sum((f[sl] - fc) ** 2 * ex) / np.sum(ex), 0.0))
        width = max(2.355 * sd, 2 * df)
        # Welch's Hann window spreads a narrow line over ~2 bins: subtract it
        width = max(math.sqrt(max(width**2 - (2 * df) ** 2, 0.0)), 0.5 * df)
        lines.append({"fc": fc, "width": width, "power": power, "peak_ratio": float(peak)})
    # keep lines that change the Allan variance by > 1 %
    keep = []
    for ln in sorted(lines, key=lambda d: -d["power"]):
        a = line_avar(m, ln["fc"], ln["width"], 1 / rate_hz, ln["power"])
        share = np.max(a / np.maximum(others_avar, 1e-300))
        if share > 0.01:
            ln["max_avar_share"] = float(share)
            keep.append(ln)
        if len(keep) >= max_lines:
            break
    return keep


# --- candidate shapes -------------------------------------------------------------------------
def filter_candidates(rate_hz: float, internal_rate_hz: float | None):
    """Candidate output filters: ideal, moving averages, Bartletts, Butterworth 1/2."""
    fi = internal_rate_hz or rate_hz * 16
    D = fi / rate_hz
    out = [bw.ideal(rate_hz)]
    Lmax = math.ceil(4 * D)
    for L in range(1, Lmax + 1):
        out.append(bw.moving_average(L, fi, rate_hz))
    for L in range(2, math.ceil(2 * D) + 1):
        out.append(bw.bartlett(L, fi, rate_hz))
    for order in (1, 2):
        for fc in np.geomspace(rate_hz / 20, min(fi / 2.2, rate_hz * 4), 28):
            if fc < fi / 2:
                out.append(bw.butterworth(order, float(fc), fi, rate_hz))
    return out


def bi_candidates(dt: float, T_rec: float):
    out = [("none", None)]
    for T in np.geomspace(max(2 * dt, 0.05), 10 * T_rec, 45):
        out.append(("gauss_markov", float(T)))
    los = np.geomspace(max(10 * dt, 0.05), T_rec / 100, 12)
    for lo in los:
        for hi in np.geomspace(100 * lo, 30 * T_rec, 14):
            out.append(("flicker", (float(lo), float(hi))))
    return out


def bi_basis(kind, par, m, dt, K, start):
    """AVAR of the bias-instability term with unit floor (Allan floor / GM peak = 1)."""
    if kind == "none":
        return None
    if kind == "gauss_markov":
        return gm_avar_record(m, dt, 1.0 / GM_PEAK, par, K, start)
    lo, hi = par
    C = flicker_components(lo, hi)
    return flicker_avar_record(m, dt, 1.0, lo, hi, C, K, start)


# --- the fit ------------------------------------------------------------------------------------
@dataclass
class SensorFit:
    """Result for one sensor triad."""

    sensor: str
    rate_hz: float
    K: int
    m: np.ndarray
    avar: np.ndarray  # (3, n_tau) measured
    edf: np.ndarray  # (3, n_tau)
    models: list  # 3 AxisModel
    lsb: np.ndarray
    static_mean: np.ndarray
    filt: object
    bi_kind: str
    bi_par: object
    chi2: dict = field(default_factory=dict)
    choice: str = ""
    uncertainty: list = field(default_factory=list)  # per axis {figure: rel sigma}
    floor_width: np.ndarray | None = None
    filter_table: list = field(default_factory=list)
    slow_T: float | None = None
    slow_chi2: tuple | None = None  # weighted chi2 (without, with) the slow GM, when tried


def _solve(cols: list, target, w):
    """NNLS of relative residuals: minimise sum w ((A x - t) / t)^2."""
    A = np.column_stack(cols) / target[:, None]
    s = np.sqrt(w)
    x, _ = nnls(A * s[:, None], np.ones_like(target) * s)
    r = (A @ x - 1.0) * s
    return x, float(r @ r)


def _fit_sensor_grid(
    m, avar, wts, fixed, line_cols, filt_list, bi_list, dt, K, start, slow_gm=True
):
    """Alternating grid search of filter and bias-instability shape; returns best."""
    n_ax = avar.shape[0]
    rrw_col = rrw_avar(m, dt, 1.0)
    filt_cols = {}

    def fcol(f):
        key = id(f)
        if key not in filt_cols:
            filt_cols[key] = f.avar(m, 1.0)
        return filt_cols[key]

    bi_cols = {}

    def bcol(b):
        key = (b[0], b[1] if not isinstance(b[1], tuple) else tuple(b[1]))
        if key not in bi_cols:
            bi_cols[key] = bi_basis(b[0], b[1], m, dt, K, start)
        return bi_cols[key]

    def total(f, b, slow=None):
        chi, xs = 0.0, []
        for a in range(n_ax):
            cols = [fcol(f)]
            bc = bcol(b)
            if bc is not None:
                cols.append(bc)
            cols.append(rrw_col)
            cols.append(bcol(("gauss_markov", slow)) if slow else np.zeros(len(m)))
            cols += line_cols[a]
            tgt = avar[a] - fixed[a]
            tgt = np.maximum(tgt, 0.05 * avar[a])
            x, c = _solve(cols, tgt, wts[a])
            chi += c
            xs.append(x)
        return chi, xs

    slow_grid = list(np.geomspace(10.0, K * dt / 3, 16)) if slow_gm else []

    def slow_floor(b):
        # a second, slower GM (environment, e.g. lab temperature cycling) is allowed only
        # beyond the floor: correlation time above the bias-instability process's (flicker:
        # T_max / 2; GM: 2 T)
        if b[0] == "flicker":
            return b[1][1] / 2
        if b[0] == "gauss_markov":
            return 2 * b[1]
        return 10.0

    def with_slow(f, b):
        """(chi2, slow T or None) for filter f and bias-instability shape b; the slow GM
        only where it pays (weighted chi2 down by more than 5 %)."""
        c0 = total(f, b)[0]
        best = (c0, None)
        for T in slow_grid:
            if T >= slow_floor(b):
                c = total(f, b, T)[0]
                if c < 0.95 * c0 and c < best[0]:
                    best = (c, T)
        return best

    f_best = filt_list[0]
    b_best = ("none", None)
    s_best = None
    for _ in range(3):
        res = [(total(f, b_best, s_best)[0], i) for i, f in enumerate(filt_list)]
        f_best = filt_list[min(res)[1]]
        res = [(*with_slow(f_best, b), i) for i, b in enumerate(bi_list)]
        c, s_best, ib = min(res, key=lambda t: t[0])
        b_best = bi_list[ib]
    chi, xs = total(f_best, b_best, s_best)
    ftable = sorted(((total(f, b_best, s_best)[0], f) for f in filt_list), key=lambda t: t[0])
    best_by_kind = {}
    for c, f in ftable:
        best_by_kind.setdefault(f.kind, (c, f))
    bi_by_kind = {}
    for b in bi_list:
        c = with_slow(f_best, b)[0]
        if b[0] not in bi_by_kind or c < bi_by_kind[b[0]][0]:
            bi_by_kind[b[0]] = (c, b)
    return f_best, b_best, chi, xs, best_by_kind, bi_by_kind, s_best


def fit_sensor(
    Y: np.ndarray,
    rate_hz: float,
    sensor: str,
    internal_rate_hz: float | None = None,
    start: str = "zero",
    lines: bool = True,
    quant_mode: str = "round",
    bi_model: str | None = None,
    slow_gm: bool = True,
) -> SensorFit:
    """Fit one triad ``Y`` (K, 3) of still rate samples (SI)."""
    Y = np.asarray(Y, np.float64)
    K = Y.shape[0]
    dt = 1.0 / rate_hz
    m = tau_grid(K)
    mean = Y.mean(axis=0)
    lsb = np.array([detect_lsb(Y[:, a]) for a in range(3)])
    avar = np.array([oavar(Y[:, a], m) for a in range(3)])
    e = np.array([edf(m, K, noise_alpha(m, avar[a])) for a in range(3)])
    wts = 1.0 / (2.0 / e + EPS_MODEL**2)
    fixed = np.array([quant_avar(m, lsb[a], quant_mode) for a in range(3)])
    # first pass without lines to get the smooth model the line test compares with
    filt_list = filter_candidates(rate_hz, internal_rate_hz)
    bi_list = bi_candidates(dt, K * dt)
    if bi_model is not None:
        bi_list = [b for b in bi_list if b[0] == bi_model]
    no_lines = [[] for _ in range(3)]
    f0, _, _, xs0, _, _, _ = _fit_sensor_grid(
        m, avar, wts, fixed, no_lines, filt_list, bi_list, dt, K, start, False
    )
    found = [[] for _ in range(3)]
    if lines:
        for a in range(3):
            smooth = fixed[a] + xs0[a][0] * f0.avar(m, 1.0)
            found[a] = find_lines(Y[:, a], rate_hz, smooth, m, K)
    line_cols = [
        [line_avar(m, ln["fc"], ln["width"], dt, 1.0) for ln in found[a]] for a in range(3)
    ]
    f, b, _, xs, fby, bby, slow = _fit_sensor_grid(
        m, avar, wts, fixed, line_cols, filt_list, bi_list, dt, K, start, slow_gm
    )
    sf = SensorFit(sensor, rate_hz, K, m, avar, e, [], lsb, mean, f, b[0], b[1])
    sf.chi2 = {k: v[0] for k, v in bby.items()}
    sf.filter_table = [
        {"kind": k, "chi2": c, **fl.describe()} for k, (c, fl) in sorted(fby.items())
    ]
    # the choice: best flicker band vs best single GM, without the slow GM (can one GM make
    # this floor?), same filter and lines
    variants = {}
    for kind in ("flicker", "gauss_markov"):
        bl = [x for x in bi_list if x[0] == kind]
        if bl:
            variants[kind] = _fit_sensor_grid(
                m, avar, wts, fixed, line_cols, [f], bl, dt, K, start, False
            )
    widths = {}
    pick = b[0]
    if bi_model is None and len(variants) == 2:
        v = variants["flicker"]
        tmp = SensorFit(sensor, rate_hz, K, m, avar, e, [], lsb, mean, f, "", None)
        _build(tmp, v[0], v[1], v[3], found, start, quant_mode, None)
        widths["measured"] = [_flat_width(m, dt, K, avar[a], am) for a, am in enumerate(tmp.models)]
        wm = float(np.median([w[0] for w in widths["measured"]]))
        wg = gm_flat_decades(FLAT_RATIO)
        if wm > wg + WIDTH_MARGIN:
            pick = "flicker"
        elif wm < wg - WIDTH_MARGIN:
            pick = "gauss_markov"
        else:  # the width cannot tell: the better fit (weighted chi2, no slow GM) decides
            pick = min(("flicker", "gauss_markov"), key=lambda k: variants[k][2])
        widths["chi2_noslow"] = {k: v[2] for k, v in variants.items()}
        if bby.get("none", (np.inf,))[0] < min(v[2] for v in variants.values()):
            pick = "none"
    if pick != b[0]:
        bl = [x for x in bi_list if x[0] == pick]
        f, b, _, xs, _, _, slow = _fit_sensor_grid(
            m, avar, wts, fixed, line_cols, [f], bl, dt, K, start, slow_gm
        )
    _build(sf, f, b, xs, found, start, quant_mode, slow)
    if slow_gm:
        c_off = _fit_sensor_grid(m, avar, wts, fixed, line_cols, [f], [b], dt, K, start, False)[2]
        c_on = _fit_sensor_grid(m, avar, wts, fixed, line_cols, [f], [b], dt, K, start, True)[2]
        sf.slow_chi2 = (c_off, c_on)
    sf.floor_width = np.array([w[0] for w in widths.get("measured", [(0.0, None)] * 3)])
    sf.choice = _choice_text(sf, widths)
    sf.uncertainty = [_uncertainty(sf, am, a) for a, am in enumerate(sf.models)]
    return sf


def _flat_width(m, dt, K, avar, am: AxisModel):
    """Width (decades) of the floor: the widest tau range over which the bias part of the
    measured Allan deviation -- the measured AVAR minus the fitted white, quantization and line
    parts, smoothed over +-2 grid points in log tau -- varies by less than +-25 % (highest /
    lowest <= 1.25^2). Only taus where those removed parts are under 70 % of the AVAR and
    ``tau <= record / 5`` count. Returns (decades, (tau_start, tau_end))."""
    t = am.avar_terms(m, K)
    fast = t["white"] + t["quantization"] + sum(v for k, v in t.items() if k.startswith("line"))
    ok = (fast < 0.7 * avar) & (m <= K / 5)
    if ok.sum() < 2:
        return 0.0, (float("nan"), float("nan"))
    idx = np.nonzero(ok)[0]
    lb = 0.5 * np.log(np.maximum(avar - fast, 1e-300))
    lb = np.convolve(np.pad(lb, 2, mode="edge"), np.ones(5) / 5, "valid")
    best = (0.0, (float("nan"), float("nan")))
    lim = math.log(FLAT_RATIO)
    for i0 in range(len(idx)):
        lo = hi = lb[idx[i0]]
        for j in range(i0, len(idx)):
            if idx[j] != idx[i0] + (j - i0):  # contiguous only
                break
            lo, hi = min(lo, lb[idx[j]]), max(hi, lb[idx[j]])
            if hi - lo > lim:
                break
            w = math.log10(m[idx[j]] / m[idx[i0]])
            if w > best[0]:
                best = (w, (float(m[idx[i0]] * dt), float(m[idx[j]] * dt)))
    return best


def _build(sf, f, b, xs, found, start, quant_mode, slow=None):
    """Per-axis models from the amplitudes ``xs`` (white, [floor], rrw, lines...)."""
    models = []
    for a in range(3):
        x = list(xs[a])
        white = math.sqrt(x.pop(0))
        floor = math.sqrt(x.pop(0)) if b[0] != "none" else 0.0
        rrw = math.sqrt(x.pop(0))
        sp = x.pop(0)
        slow_peak = math.sqrt(sp) if slow else 0.0
        lns = [
            {**ln, "power": float(p), "power_psd": ln["power"]}
            for ln, p in zip(found[a], x, strict=True)
            if p > 0
        ]
        models.append(
            AxisModel(
                rate_hz=sf.rate_hz, white=white, filt=f, lsb=float(sf.lsb[a]),
                quant_mode=quant_mode, lines=lns,
                bi_model=None if b[0] == "none" else b[0], bi_floor=floor,
                bi_band=b[1] if b[0] == "flicker" else (1.0, 100.0),
                bi_components=flicker_components(*b[1]) if b[0] == "flicker" else 1,
                bi_T=b[1] if b[0] == "gauss_markov" else 100.0, bi_start=start, rrw=rrw,
                offset=float(sf.static_mean[a]), slow_peak=slow_peak,
                slow_T=float(slow) if slow else 300.0,
            )
        )  # fmt: skip
    sf.slow_T = slow
    sf.models, sf.bi_kind, sf.bi_par, sf.filt = models, b[0], b[1], f


def _choice_text(sf, widths):
    """Why flicker or Gauss-Markov, in words and numbers."""
    chi = ", ".join(f"{k} {v:.4g}" for k, v in sorted(sf.chi2.items()))
    if "measured" not in widths:
        return f"{sf.bi_kind} (as asked); weighted chi2 by model: {chi}; {slow_text(sf)}"
    ws = widths["measured"]
    per = ", ".join(
        f"{a} {w:.2f} dec ({r[0]:.3g}-{r[1]:.3g} s)" for a, (w, r) in zip("xyz", ws, strict=True)
    )
    wm = float(np.median([w[0] for w in ws]))
    wg = gm_flat_decades(FLAT_RATIO)
    c2 = widths.get("chi2_noslow", {})
    if wm > wg + WIDTH_MARGIN:
        why = f"wider than one GM can make ({wg:.2f} + {WIDTH_MARGIN} decades): flicker"
    elif wm < wg - WIDTH_MARGIN:
        why = f"narrower than {wg:.2f} - {WIDTH_MARGIN} decades, one GM makes it: gauss_markov"
    else:
        why = (
            f"within {WIDTH_MARGIN} decades of the {wg:.2f} decades one GM can make, so the width "
            f"cannot tell; the better fit decides (weighted chi2 without the slow GM: "
            + ", ".join(f"{k} {v:.4g}" for k, v in sorted(c2.items()))
            + ")"
        )
    return (
        f"{sf.bi_kind}: the bias part of the measured Allan deviation stays within +-25 % over "
        f"{wm:.2f} decades of tau (median of the axes; {per}), {why}; "
        f"weighted chi2 by model (final): {chi}; {slow_text(sf)}"
    )


def slow_text(sf) -> str:
    """Whether the second, slow GM (``slow_bias``) was kept, and why, in words and numbers."""
    if sf.slow_chi2 is None:
        return "no slow second Gauss-Markov tried"
    c0, c1 = sf.slow_chi2
    if sf.slow_T:
        return (
            f"slow_bias: a second Gauss-Markov at T {sf.slow_T:.3g} s beyond the floor lowers "
            f"the weighted chi2 from {c0:.4g} to {c1:.4g} (> 5 %): kept"
        )
    return "slow_bias: no second Gauss-Markov lowers the weighted chi2 by > 5 %: none"


def _uncertainty(sf: SensorFit, am: AxisModel, a: int) -> dict:
    """Relative 1-sigma of each figure from the record length.

    Fisher information of the relative amplitudes ``theta_j = amp_j^2 / fitted amp_j^2`` on
    the octave taus (nearly independent estimates), each AVAR point with relative variance
    ``2 / edf``: ``F = sum_i (edf_i / 2) s_i s_i^T`` with ``s_ij`` the share of term ``j`` in
    the model AVAR at tau_i; ``cov = F^-1``; a figure (square root of an amplitude) has half
    the relative standard error. A term fitted to zero gets a one-sided 95 % upper bound.
    """
    lo = np.log(sf.m)
    i_sel = np.unique([int(np.argmin(np.abs(lo - math.log(x)))) for x in octaves(sf.K, 0.2)])
    m = sf.m[i_sel]
    e = sf.edf[a][i_sel]
    terms = am.avar_terms(m, sf.K)
    model = sum(terms.values())
    dt = 1 / sf.rate_hz
    cols, names, ref = [], [], {}
    if am.white > 0:
        cols.append(terms["white"] / model)
        names.append("white_noise")
    if am.bi_model is not None:
        cols.append(terms["bias_instability"] / model)
        names.append("bias_instability")
    if am.rrw > 0:
        cols.append(terms["rate_random_walk"] / model)
        names.append("rate_random_walk")
    else:
        # reference amplitude: the RRW whose AVAR equals the model at the longest tau
        k2 = model[-1] / rrw_avar(m[-1:], dt, 1.0)[0]
        ref["rate_random_walk"] = math.sqrt(k2)
        cols.append(rrw_avar(m, dt, 1.0) * k2 / model)
        names.append("rate_random_walk")
    if am.slow_peak > 0:
        cols.append(terms["slow_gm"] / model)
        names.append("slow_gm")
    for j in range(len(am.lines)):
        cols.append(terms[f"line{j}"] / model)
        names.append(f"line{j}")
    S = np.column_stack(cols)
    Fm = S.T @ (S * (e / 2.0)[:, None])
    cov = np.linalg.pinv(Fm, rcond=1e-12)
    out = {}
    for j, n in enumerate(names):
        sd = math.sqrt(max(cov[j, j], 0.0))
        if n in ref:
            out[n + "_upper95_si"] = ref[n] * math.sqrt(1.645 * sd)
        else:
            out[n] = 0.5 * sd
    return out


# --- frames and the grade document ------------------------------------------------------------
def gravity_frame(accel_mean: np.ndarray) -> dict:
    """Which axis carries gravity and its sign; the rotation to imugen's body frame (z up)."""
    i = int(np.argmax(np.abs(accel_mean)))
    s = float(np.sign(accel_mean[i]))
    g = float(abs(accel_mean[i]))
    note = f"gravity on {'xyz'[i]} ({'+' if s > 0 else '-'}{g / G0:.4f} g)"
    R = np.eye(3)
    if i == 2 and s < 0:
        R = np.diag([1.0, -1.0, -1.0])
        note += (
            "; z points down: sensor axes map to imugen's body frame (x forward, y left, "
            "z up) by a 180 deg turn about x, (x, y, z) -> (x, -y, -z); per-axis noise figures "
            "are sign-free and keep their axis"
        )
    elif i != 2:
        note += "; the unit is not lying z-vertical: figures keep the sensor's axes"
    return {"axis": "xyz"[i], "sign": s, "g_measured": g, "R_body_sensor": R, "note": note}


def _fmt(x, sig=4):
    return float(f"{x:.{sig}g}")


def _vals(xs, unit):
    v = [_fmt(x / UNITS[unit]) for x in xs]
    return v[0] if len(set(v)) == 1 else v


def sensor_config(sf: SensorFit, source: str) -> dict:
    """imugen grade-document mapping of one sensor (datasheet units; every figure with its
    source and record-length uncertainty; lines and a slow hump go to the grade's notes,
    :func:`environment_note`)."""
    u = SENSOR_UNITS[sf.sensor]
    ms = sf.models
    unc = sf.uncertainty

    def pm(name):
        parts = []
        for a in range(3):
            if name in unc[a]:
                parts.append(f"{'xyz'[a]} +-{100 * unc[a][name]:.1f} %")
            elif name + "_upper95_si" in unc[a]:
                v = unc[a][name + "_upper95_si"] / UNITS[u[name]]
                parts.append(f"{'xyz'[a]} < {v:.3g} (95 %)")
        return ", ".join(parts)

    cfg = {
        "white_noise": {
            "value": _vals([x.white for x in ms], u["white_noise"]),
            "unit": u["white_noise"],
            "source": f"{source}: Allan fit, the sensor's white density before the output "
            f"filter and quantization (the output's long-tau white line is "
            f"{_vals([sf.filt.output_density(x.white) for x in ms], u['white_noise'])} "
            f"{u['white_noise']}, aliasing gain {sf.filt.alias_gain():.3f}); "
            f"1-sigma {pm('white_noise')}",
        }
    }
    if sf.bi_kind != "none":
        bi = {
            "value": _vals([x.bi_floor for x in ms], u["bias_instability"]),
            "unit": u["bias_instability"],
            "kind": "allan_floor",
            "model": sf.bi_kind,
            "start": ms[0].bi_start,
            "source": f"{source}: Allan floor; 1-sigma {pm('bias_instability')}; "
            f"model chosen: {sf.choice}",
        }
        if sf.bi_kind == "flicker":
            lo, hi = sf.bi_par
            lo_s, hi_s = _fmt(lo, 4), _fmt(hi, 4)
            hi_s = max(hi_s, 100.0 * lo_s)  # printed figures keep max >= 100 min
            bi["flicker_band"] = {"min": lo_s, "max": hi_s, "unit": "s"}
            bi["components"] = int(flicker_components(lo, hi))
        else:
            bi["correlation_time"] = {"value": _fmt(sf.bi_par, 3), "unit": "s"}
        cfg["bias_instability"] = bi
    if sf.slow_T:
        cfg["slow_bias"] = {
            "value": _vals([x.slow_peak for x in ms], u["bias_instability"]),
            "unit": u["bias_instability"],
            "kind": "allan_floor",
            "start": ms[0].bi_start,
            "correlation_time": {"value": _fmt(sf.slow_T, 3), "unit": "s"},
            "source": f"{source}: Allan fit, the peak of a second, slow Gauss-Markov beyond the "
            f"floor; 1-sigma {pm('slow_gm')}; {slow_text(sf)}",
        }
    if any(x.rrw > 0 for x in ms):
        cfg["rate_random_walk"] = {
            "value": _vals([x.rrw for x in ms], u["rate_random_walk"]),
            "unit": u["rate_random_walk"],
            "source": f"{source}: Allan fit; 1-sigma {pm('rate_random_walk')} (an axis at 0: "
            "not detected)",
        }
    if np.all(sf.lsb > 0):
        cfg["quantization"] = {
            "value": _vals(list(sf.lsb), u["quantization"]),
            "unit": u["quantization"],
            "mode": ms[0].quant_mode,
            "source": f"{source}: step between logged values (every sample on the grid)",
        }
    d = sf.filt.describe()
    band = {"filter": sf.filt.kind}
    if sf.filt.kind != "ideal":
        band["internal_rate"] = {"value": _fmt(sf.filt.internal_rate_hz, 6), "unit": "hz"}
    if sf.filt.kind in ("moving_average", "bartlett"):
        band["taps"] = int(sf.filt.taps)
    if sf.filt.kind == "butterworth":
        band["order"] = int(sf.filt.order)
        band["cutoff"] = {"value": _fmt(sf.filt.cutoff_hz, 4), "unit": "hz"}
    band["source"] = (
        f"{source}: short-tau Allan departure below the white line (an equivalent filter); "
        f"-3 dB {d['cutoff_3db_hz']:.3g} Hz, ENBW {d['enbw_hz']:.3g} Hz, delay "
        f"{d['group_delay_ms']:.3g} ms, ADEV(1/rate) = {d['adev_ratio_tau0']:.3f} x white line"
    )
    cfg["bandwidth"] = band
    return cfg


def environment_note(sf: SensorFit) -> str:
    """The fitted terms the grade format does not hold (narrowband lines): said in the grade's
    notes, not simulated (a slow second Gauss-Markov is the grade's ``slow_bias``)."""
    u = SENSOR_UNITS[sf.sensor]
    parts = []
    for a, am in enumerate(sf.models):
        for ln in am.lines:
            parts.append(
                f"{'xyz'[a]} line {ln['fc']:.3g} Hz (width {ln['width']:.2g} Hz, "
                f"{math.sqrt(ln['power']) / UNITS[u['line']]:.3g} {u['line']} rms)"
            )
    if not parts:
        return ""
    return (
        f"{sf.sensor}: fitted but not simulated (environment, not the part: lines a grade "
        "does not hold): " + "; ".join(parts)
    )


def fit_grade(
    samples,
    rate_hz: float,
    *,
    name: str = "fitted",
    grade_id: int = 1000,
    internal_rate_hz: float | None = None,
    start: str = "zero",
    source: str = "still log",
    lines: bool = True,
    bi_model: str | None = None,
    slow_gm: bool = True,
) -> dict:
    """Fit a grade from a still log.

    Parameters
    ----------
    samples : mapping or ndarray
        ``{"gyro": (K, 3) rad/s, "accel": (K, 3) m/s^2}`` or a (K, 6) array in that order, or
        a DataFrame with imugen's columns ``gyro_{x,y,z}_radps``, ``accel_{x,y,z}_mps2``.
    rate_hz : float
        Sample rate.
    internal_rate_hz : float, optional
        The part's internal sample rate when known (ADIS16405: 819.2); default 16 x rate
        (an internal grid fine enough to stand for continuous time).
    start : {"zero", "stationary"}
        Initial law of the in-run bias process (imugen's ``start``), and of the slow one.
    slow_gm : bool
        Try a second, slow Gauss-Markov beyond the floor (the grade's ``slow_bias``), kept
        where it lowers the weighted chi-square by more than 5 %.

    Returns
    -------
    dict
        ``{"document": {"grades": {name: cfg}}, "sensors": {"gyro": SensorFit, "accel": ...},
        "frame": gravity_frame(...), "static": {...}}``.
    """
    if hasattr(samples, "columns"):
        G = np.column_stack([samples[f"gyro_{a}_radps"].to_numpy(np.float64) for a in "xyz"])
        A = np.column_stack([samples[f"accel_{a}_mps2"].to_numpy(np.float64) for a in "xyz"])
    elif isinstance(samples, dict):
        G, A = np.asarray(samples["gyro"], np.float64), np.asarray(samples["accel"], np.float64)
    else:
        s = np.asarray(samples, np.float64)
        G, A = s[:, :3], s[:, 3:6]
    fits = {}
    for sensor, Y in (("gyro", G), ("accel", A)):
        fits[sensor] = fit_sensor(
            Y, rate_hz, sensor, internal_rate_hz, start, lines, bi_model=bi_model, slow_gm=slow_gm
        )
    frame = gravity_frame(fits["accel"].static_mean)
    R = frame["R_body_sensor"]
    static = {
        "gyro_mean_sensor_deg_per_h": (fits["gyro"].static_mean / UNITS["deg_per_h"]).tolist(),
        "accel_mean_sensor_mg": (fits["accel"].static_mean / UNITS["mg"]).tolist(),
        "gyro_mean_body_deg_per_h": (R @ fits["gyro"].static_mean / UNITS["deg_per_h"]).tolist(),
        "accel_mean_body_mg": (R @ fits["accel"].static_mean / UNITS["mg"]).tolist(),
    }
    cfg = {
        "id": int(grade_id),
        "description": f"fitted from {source} ({fits['gyro'].K} samples at {rate_hz:g} Hz, "
        f"{fits['gyro'].K / rate_hz / 3600:.2f} h)",
        "source": f"{source}; fitted by imugen grade fit",
        "notes": "; ".join(
            x for x in (frame["note"], *(environment_note(f) for f in fits.values())) if x
        ),
        "gyro": sensor_config(fits["gyro"], source),
        "accel": sensor_config(fits["accel"], source),
    }
    return {
        "document": {"grades": {name: cfg}},
        "sensors": fits,
        "frame": frame,
        "static": static,
    }


# --- the command ------------------------------------------------------------------------------
def plot_fit(result: dict, out, title: str = "", dpi: float = 150):
    """Measured (dots, 95 % band) and fitted (lines) Allan deviation per axis, gyro and
    accelerometer, written atomically (format from the extension)."""
    from pathlib import Path

    from imugen.core.plotting import figure, save, style

    out = Path(out)
    fmt = out.suffix.lstrip(".").lower() or "png"
    with style():
        fig = figure(figsize=(11, 4.8), layout="constrained")
        axes = fig.subplots(1, 2)
        for ax, (s, sf) in zip(axes, result["sensors"].items(), strict=True):
            unit = SENSOR_UNITS[s]["bias_instability"]
            f = UNITS[unit]
            tau = sf.m / sf.rate_hz
            for a, am in enumerate(sf.models):
                meas = np.sqrt(sf.avar[a])
                lo, hi = adev_ci(meas, sf.edf[a])
                (ln,) = ax.loglog(tau, meas / f, ".", ms=3, label=f"{'xyz'[a]} measured")
                ax.fill_between(tau, lo / f, hi / f, color=ln.get_color(), alpha=0.15, lw=0)
                ax.loglog(tau, np.sqrt(am.avar(sf.m, sf.K)) / f, "-", color=ln.get_color(),
                          lw=1, label=f"{'xyz'[a]} fitted")  # fmt: skip
            ax.set_xlabel("averaging time tau [s]")
            ax.set_ylabel(f"Allan deviation [{unit.replace('_per_', '/')}]")
            slow = f" + slow GM (T {sf.slow_T:.3g} s)" if sf.slow_T else ""
            ax.set_title(f"{s}: {sf.bi_kind}{slow}, filter {sf.filt.kind} {title}".strip())
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7, ncols=2)
        return save(fig, out.with_suffix(""), (fmt,), dpi)[0]


def run(log, out, options: GradeFitOptions) -> dict:
    """Read a still log, fit a grade, write it (YAML) and the Allan figure; return the result.

    Parameters
    ----------
    log : path
        A still IMU log (:func:`imugen.sensors.imu_log.read_log`).
    out : path
        The grade document to write (atomically).
    options : GradeFitOptions
    """
    from pathlib import Path

    import yaml

    from imugen.sensors.grade_io import write_text
    from imugen.sensors.grades import grades_from_document
    from imugen.sensors.imu_log import read_log

    if options.grade_id < 100:
        raise InputError(
            "--id", f"must be >= 100 (ids below are the presets'), got {options.grade_id}"
        )
    lg = read_log(log, options.rate_hz)
    r = fit_grade(
        {"gyro": lg.gyro, "accel": lg.accel},
        lg.rate_hz,
        name=options.name,
        grade_id=options.grade_id,
        internal_rate_hz=options.internal_rate_hz,
        source=Path(str(log)).name,
        bi_model=None if options.bias_model == "auto" else options.bias_model,
        slow_gm=options.slow_bias == "auto",
    )
    doc = r["document"]
    if lg.notes:
        cfg = doc["grades"][options.name]
        cfg["notes"] = "; ".join([cfg["notes"], *lg.notes])
    grades_from_document(doc, str(out))  # the document must load as it is written
    text = yaml.safe_dump(doc, sort_keys=False, allow_unicode=False)
    write_text(out, text)
    plot = options.plot or Path(out).with_suffix(".png")
    plot_fit(r, plot, title=f"({Path(str(log)).name})")
    r["plot"] = str(plot)
    return r


def main(options: GradeFitOptions, log, output) -> None:
    """``imugen grade fit LOG -o grade.yaml``: fit, write, and say what was chosen."""
    r = run(log, output, options)
    for s, sf in r["sensors"].items():
        print(f"{s}: {sf.choice}")
    print(f"wrote {output} and {r['plot']}")
