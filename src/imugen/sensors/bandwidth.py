"""Output bandwidth of an inertial sensor: internal sampling, low-pass filter, decimation.

A grade gives it per sensor (``bandwidth``: :class:`BandwidthSpec`); the simulator streams the
whole sensed signal through it before quantization (:class:`Stream`).

Model (one axis; everything the sensor senses -- motion, vibration and noise -- goes through it,
before quantization):

1. internal samples ``x_j`` at ``f_i = internal_rate_hz``. White rate noise of (two-sided)
   density ``N`` enters as the mean of continuous white noise over one internal interval:
   independent, variance ``N^2 f_i`` (the convention imugen already uses at its output rate);
2. a causal digital low-pass ``H(z) = B(z) / A(z)`` on the internal grid, unit DC gain:
   ``ideal`` (none), ``moving_average`` (``L`` taps), ``bartlett`` (two cascaded moving
   averages of ``L`` taps each, a triangular FIR of ``2L - 1`` taps: the ADIS164xx
   ``SENS_AVG`` filter), ``butterworth`` (order ``n``, -3 dB cut-off ``f_c``, bilinear
   transform), ``mpu6050_dlpf`` (the register map's DLPF_CFG table, see :data:`MPU6050_DLPF`);
3. decimation to the output rate ``f_o``: the output is the filtered stream read every
   ``D = f_i / f_o`` internal samples. An integer ``D`` is a synchronous decimation; a
   non-integer ``D`` is a host polling the output register asynchronously (read index
   ``floor(k D + phi)``, ``phi`` uniform): successive reads are ``floor(D)`` or
   ``floor(D) + 1`` internal samples apart.

The density ``N`` is the sensor's own (passband) white density, what a datasheet's noise
density gives. The output's long-tau Allan white line is ``N sqrt(g)`` with the aliasing gain
``g = f_i sum_l c(l D) / f_o``: 1 when the read is synchronous behind a filter whose response
vanishes at the multiples of ``f_o`` (a moving average of ``D`` samples) and close to 1 behind
a good anti-alias filter; above 1 when noise from around ``k f_o`` folds to DC (1.115 for a
10-tap average at 819.2 Hz read at 100 Hz; 5.2 for the MPU-6050's 260 Hz DLPF read at
100 Hz: a part configured to alias really is that much noisier at long tau).

Closed forms (``h`` the impulse response on the internal grid, ``c(j) = sum_n h_n h_{n+j}``):

* output variance ``var y = N^2 f_i c(0)``;
* output autocovariance ``r_y(l) = N^2 f_i c(l D)`` (non-integer ``lD``: linear
  interpolation of ``c`` between its neighbours, the exact expectation over the read phase);
* two-sided output PSD (integer ``D``, per Hz, ``|f| <= f_o / 2``):
  ``S_y(f) = N^2 sum_k |H(e^{i 2 pi (f + k f_o) / f_i})|^2`` over the ``D`` aliases
  ``f + k f_o`` in ``(-f_i / 2, f_i / 2]`` (so ``S_y(0) = g N^2``);
* Allan variance of the output at ``tau = m / f_o`` (any stationary sequence):
  ``AVAR(m) = (4 V(m) - V(2m)) / (2 m^2)`` with ``V(m) = var(sum of m samples) =
  sum_{|l|<m} (m - |l|) r_y(l)``; beyond the filter's memory ``V(m) = m S - M1``
  (``S = sum_l r_y(l)``, ``M1 = 2 sum_{l>0} l r_y(l)``), so
  ``AVAR = S / m - 1.5 M1 / m^2``: the white line ``g N^2 / tau`` (``S = g N^2 f_o``)
  minus a ``1 / tau^2`` term. At ``tau = 1 / f_o``: ``AVAR = r_y(0) - r_y(1)``.
  An ideal sensor (no filter, ``f_i = f_o``) has ``AVAR = N^2 / tau`` at every tau.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from imugen.core import units
from imugen.core.errors import InputError


def _signal():
    """``scipy.signal``, imported when a filter is built or run: it imports ``scipy.linalg``,
    which a shard job without an output bandwidth never needs (tests/system/test_startup.py)."""
    from scipy import signal

    return signal


KINDS = ("ideal", "moving_average", "bartlett", "butterworth", "mpu6050_dlpf")

# InvenSense RM-MPU-6000A-00 rev 4.2, register 26 (CONFIG), DLPF_CFG: (accelerometer bandwidth
# Hz, delay ms, gyroscope bandwidth Hz, delay ms, gyroscope internal rate Hz); the
# accelerometer is sampled at 1 kHz in every setting. The filter's structure is not documented.
MPU6050_DLPF = {
    0: (260.0, 0.0, 256.0, 0.98, 8000.0),
    1: (184.0, 2.0, 188.0, 1.9, 1000.0),
    2: (94.0, 3.0, 98.0, 2.8, 1000.0),
    3: (44.0, 4.9, 42.0, 4.8, 1000.0),
    4: (21.0, 8.5, 20.0, 8.3, 1000.0),
    5: (10.0, 13.8, 10.0, 13.4, 1000.0),
    6: (5.0, 19.0, 5.0, 18.6, 1000.0),
}

# ADIS16400/16405: internal sample rate 1638.4 / (SMPL_PRD + 1) SPS (default SMPL_PRD = 1:
# 819.2 SPS), SENS_AVG[2:0] = N: Bartlett window of two cascaded 2^N-tap averages; the Linux
# IIO driver (drivers/iio/imu/adis16400.c) gives the -3 dB frequency as sps / divisor[N].
ADIS16400_BASE_RATE_HZ = 1638.4
ADIS16400_3DB_DIVISORS = {0: 2, 1: 6, 2: 12, 3: 25, 4: 50, 5: 100, 6: 200}


@dataclass(frozen=True)
class OutputFilter:
    """Internal rate, digital low-pass and output rate of one sensor axis.

    Attributes
    ----------
    internal_rate_hz, output_rate_hz : float
        ``f_i`` and ``f_o`` (``f_i >= f_o``).
    kind : str
        One of :data:`KINDS`.
    b, a : tuple of float
        Digital filter coefficients on the internal grid (unit DC gain).
    taps, order : int
        Moving-average / Bartlett stage length; Butterworth order (0 if not applicable).
    cutoff_hz : float
        Nominal -3 dB frequency (0 for ``ideal``).
    delay_s : float
        Extra pure delay (documented delay beyond the filter's own group delay), applied to
        motion; it does not change noise statistics.
    label : str
        What the filter stands for (part, setting, source).
    """

    internal_rate_hz: float
    output_rate_hz: float
    kind: str = "ideal"
    b: tuple = (1.0,)
    a: tuple = (1.0,)
    taps: int = 0
    order: int = 0
    cutoff_hz: float = 0.0
    delay_s: float = 0.0
    label: str = ""
    _cache: dict = field(default_factory=dict, compare=False, repr=False, hash=False)

    # --- construction -----------------------------------------------------------------------
    def __post_init__(self):
        if not (self.internal_rate_hz > 0 and self.output_rate_hz > 0):
            raise ValueError("rates must be > 0")
        if self.internal_rate_hz < self.output_rate_hz * (1 - 1e-12):
            raise ValueError(
                f"internal rate {self.internal_rate_hz} Hz below output rate "
                f"{self.output_rate_hz} Hz"
            )
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {self.kind!r}")
        dc = np.sum(self.b) / np.sum(self.a)
        if not math.isclose(dc, 1.0, rel_tol=1e-9):
            raise ValueError(f"filter DC gain {dc} != 1")

    @property
    def ratio(self) -> float:
        """Decimation ``D = f_i / f_o`` (non-integer: asynchronous read)."""
        return self.internal_rate_hz / self.output_rate_hz

    @property
    def synchronous(self) -> bool:
        return abs(self.ratio - round(self.ratio)) < 1e-9

    # --- impulse response and autocorrelation -------------------------------------------------
    def impulse(self, tol: float = 1e-13) -> np.ndarray:
        """Impulse response on the internal grid (IIR truncated where its energy tail < tol)."""
        if "h" in self._cache:
            return self._cache["h"]
        b, a = np.asarray(self.b, float), np.asarray(self.a, float)
        if len(a) == 1:
            h = b / a[0]
        else:
            n = 256
            while True:
                x = np.zeros(n)
                x[0] = 1.0
                h = _signal().lfilter(b, a, x)
                e = np.cumsum(h[::-1] ** 2)[::-1]
                if e[n // 2] < tol * e[0]:
                    h = h[: max(len(b), np.searchsorted(-e, -tol * e[0]) + 1)]
                    break
                n *= 2
        self._cache["h"] = h
        return h

    def internal_autocorr(self) -> np.ndarray:
        """``c(j) = sum_n h_n h_{n+j}``, ``j = 0 .. len(h) - 1``."""
        if "c" not in self._cache:
            h = self.impulse()
            self._cache["c"] = np.correlate(h, h, "full")[len(h) - 1 :]
        return self._cache["c"]

    def _c_at(self, nlags: int) -> np.ndarray:
        """``c`` at the read lags ``l D`` (interpolated), ``l = 0 .. nlags - 1``."""
        c = self.internal_autocorr()
        D = self.ratio
        j = np.arange(nlags) * D
        j0 = np.floor(j + 1e-9).astype(int)
        f = np.clip(j - j0, 0.0, 1.0)
        cc = np.concatenate([c, [0.0, 0.0]])
        j0 = np.minimum(j0, len(cc) - 2)
        return (1 - f) * cc[j0] + f * cc[j0 + 1]

    def alias_gain(self) -> float:
        """``g = f_i sum_l c(l D) / f_o``: the output's long-tau white level over the internal
        density's (1 for a synchronous read behind a filter whose response vanishes at the
        multiples of ``f_o``; above 1 where the read aliases noise from around them)."""
        if "g" not in self._cache:
            nl = math.ceil(len(self.internal_autocorr()) / self.ratio) + 2
            cl = self._c_at(nl)
            self._cache["g"] = float(
                self.internal_rate_hz * (cl[0] + 2 * cl[1:].sum()) / self.output_rate_hz
            )
        return self._cache["g"]

    def output_density(self, density: float) -> float:
        """The output's long-tau Allan white line for a sensor density ``density``:
        ``N sqrt(g)``."""
        return density * math.sqrt(self.alias_gain())

    def output_autocov(self, density: float, nlags: int | None = None) -> np.ndarray:
        """Autocovariance ``r_y(l)``, ``l = 0 .. nlags - 1``, of the output for a sensor white
        density ``density`` (default lags: the filter's memory + 2)."""
        if nlags is None:
            nlags = math.ceil(len(self.internal_autocorr()) / self.ratio) + 2
        return density**2 * self.internal_rate_hz * self._c_at(nlags)

    # --- closed forms ---------------------------------------------------------------------------
    def variance(self, density: float) -> float:
        """Variance of one output sample for a sensor white density ``density``:
        ``N^2 f_i c(0)``."""
        return float(density**2 * self.internal_rate_hz * self.internal_autocorr()[0])

    def response(self, f_hz) -> np.ndarray:
        """Complex frequency response ``H(e^{i 2 pi f / f_i})``."""
        w = 2 * np.pi * np.asarray(f_hz, float) / self.internal_rate_hz
        _, H = _signal().freqz(self.b, self.a, worN=w)
        return H

    def psd(self, f_hz, density: float) -> np.ndarray:
        """Two-sided PSD of the output (per Hz) at ``|f| <= f_o / 2`` (synchronous ``D``)."""
        if not self.synchronous:
            raise ValueError("closed-form PSD needs an integer decimation ratio")
        D = round(self.ratio)
        f = np.asarray(f_hz, float)
        out = np.zeros_like(f)
        fo, fi = self.output_rate_hz, self.internal_rate_hz
        for k in range(-D, D + 1):  # the D aliases f + k f_o inside (-f_i/2, f_i/2]
            g = f + k * fo
            ok = (g > -fi / 2 - 1e-12) & (g <= fi / 2 + 1e-12)
            out += np.where(ok, np.abs(self.response(np.where(ok, g, 0.0))) ** 2, 0.0)
        return density**2 * out

    def enbw_hz(self) -> float:
        """Equivalent noise bandwidth (one-sided, Hz): ``f_i c(0) / 2``."""
        return float(self.internal_rate_hz * self.internal_autocorr()[0] / 2)

    def cutoff_3db_hz(self) -> float:
        """-3 dB frequency of ``|H|`` (numerical; Nyquist of the internal grid if none)."""
        f = np.linspace(0, self.internal_rate_hz / 2, 20001)[1:]
        g = np.abs(self.response(f))
        below = np.nonzero(g < 1 / math.sqrt(2))[0]
        return float(f[below[0]]) if len(below) else self.internal_rate_hz / 2

    def group_delay_s(self) -> float:
        """DC group delay of the filter (centroid of ``h``) plus the extra pure delay."""
        h = self.impulse()
        return float(np.sum(np.arange(len(h)) * h) / np.sum(h) / self.internal_rate_hz) + (
            self.delay_s
        )

    def avar(self, m, density: float) -> np.ndarray:
        """Allan variance of the output (filtered white noise) at ``tau = m / f_o``."""
        return avar_from_autocov(self.output_autocov(density), m)

    def adev_ratio_tau0(self) -> float:
        """Allan deviation at ``tau = 1 / f_o`` over the sensor's white line
        ``N / sqrt(tau)``."""
        r = self.output_autocov(1.0, 2)
        return float(math.sqrt((r[0] - r[1]) / self.output_rate_hz))

    # --- applying it ----------------------------------------------------------------------------
    def internal_length(self, K: int) -> int:
        """Internal samples needed for ``K`` outputs (with the filter's warm-up)."""
        return math.ceil(K * self.ratio) + len(self.impulse()) + 2

    def apply(self, x_internal: np.ndarray, K: int, phase: float = 0.0) -> np.ndarray:
        """Filter internal samples ``x`` (..., n) and read ``K`` outputs.

        The first ``len(h)`` internal samples warm the filter up (the output starts in
        steady state); read ``k`` takes internal index ``warm + floor(k D + phase)``.
        """
        y = _signal().lfilter(self.b, self.a, x_internal, axis=-1)
        warm = len(self.impulse())
        idx = warm + np.floor(np.arange(K) * self.ratio + phase).astype(np.int64)
        if idx[-1] >= x_internal.shape[-1]:
            raise ValueError("x_internal too short; use internal_length(K)")
        return y[..., idx]

    def white(self, density: float, K: int, rng: np.random.Generator, shape=()) -> np.ndarray:
        """``K`` outputs of filtered white noise of sensor density ``density`` (random read
        phase)."""
        n = self.internal_length(K)
        x = rng.standard_normal((*shape, n)) * (density * math.sqrt(self.internal_rate_hz))
        phase = 0.0 if self.synchronous else float(rng.random())
        return self.apply(x, K, phase)

    def describe(self) -> dict:
        """Figures a user reads: rates, kind, -3 dB, ENBW, delay, tau0 ratio."""
        return {
            "kind": self.kind,
            "label": self.label,
            "internal_rate_hz": self.internal_rate_hz,
            "output_rate_hz": self.output_rate_hz,
            "taps": self.taps,
            "order": self.order,
            "cutoff_3db_hz": round(self.cutoff_3db_hz(), 4),
            "enbw_hz": round(self.enbw_hz(), 4),
            "group_delay_ms": round(1e3 * self.group_delay_s(), 4),
            "adev_ratio_tau0": round(self.adev_ratio_tau0(), 5),
            "alias_gain": round(self.alias_gain(), 5),
            "synchronous": self.synchronous,
        }


# --- constructors ---------------------------------------------------------------------------
def ideal(output_rate_hz: float) -> OutputFilter:
    """No filter, internal rate = output rate (imugen's current model)."""
    return OutputFilter(output_rate_hz, output_rate_hz, "ideal", label="ideal (N / sqrt(dt))")


def moving_average(taps: int, internal_rate_hz: float, output_rate_hz: float) -> OutputFilter:
    """Average of ``taps`` internal samples."""
    b = tuple(np.full(int(taps), 1.0 / int(taps)))
    return OutputFilter(
        internal_rate_hz,
        output_rate_hz,
        "moving_average",
        b=b,
        taps=int(taps),
        cutoff_hz=_ma_3db(int(taps), internal_rate_hz),
        label=f"moving average of {taps} samples at {internal_rate_hz:g} Hz",
    )


def bartlett(taps: int, internal_rate_hz: float, output_rate_hz: float) -> OutputFilter:
    """Two cascaded ``taps``-sample averages (triangular FIR of ``2 taps - 1``)."""
    L = int(taps)
    h = np.convolve(np.full(L, 1.0 / L), np.full(L, 1.0 / L))
    f = OutputFilter(
        internal_rate_hz,
        output_rate_hz,
        "bartlett",
        b=tuple(h),
        taps=L,
        label=f"Bartlett, 2 x {L}-tap average at {internal_rate_hz:g} Hz",
    )
    return _with_cutoff(f)


def butterworth(
    order: int, cutoff_hz: float, internal_rate_hz: float, output_rate_hz: float, delay_s=0.0
) -> OutputFilter:
    """Digital Butterworth low-pass (bilinear transform, -3 dB at ``cutoff_hz``)."""
    if not 0 < cutoff_hz < internal_rate_hz / 2:
        raise ValueError(f"cut-off {cutoff_hz} Hz outside (0, {internal_rate_hz / 2}) Hz")
    b, a = _signal().butter(int(order), cutoff_hz, fs=internal_rate_hz)
    g = np.sum(b) / np.sum(a)
    return OutputFilter(
        internal_rate_hz,
        output_rate_hz,
        "butterworth",
        b=tuple(b / g),
        a=tuple(a),
        order=int(order),
        cutoff_hz=float(cutoff_hz),
        delay_s=float(delay_s),
        label=f"Butterworth order {order}, {cutoff_hz:g} Hz at {internal_rate_hz:g} Hz",
    )


def mpu6050_dlpf(setting: int, sensor: str, output_rate_hz: float) -> OutputFilter:
    """MPU-6050 DLPF_CFG setting 0..6 for ``sensor`` ``"gyro"`` or ``"accel"``.

    The register map gives bandwidth and delay only. Modelled as a second-order Butterworth at
    the documented bandwidth on the internal grid (gyro 8 kHz for setting 0, else 1 kHz;
    accelerometer 1 kHz), plus a pure delay making up the documented delay where it exceeds
    the Butterworth's own DC group delay (``sqrt(2) / (2 pi f_c)``); settings 3-6 document
    less delay than that (5-6 less than any monotone causal low-pass of that bandwidth has:
    a first-order one already has ``1 / (2 pi f_c)`` = 31.8 ms at 5 Hz), so their delay is
    the filter's own.
    (Documented delays are honoured for settings 0-2; from setting 3 on the Butterworth's own
    delay already exceeds the documented one.) Second order because the datasheet's gyro figures (noise density 0.005 deg/s/sqrt(Hz),
    total RMS noise 0.05 deg/s at the 98 Hz setting) imply an equivalent noise bandwidth
    ``(0.05 / 0.005)^2 = 100`` Hz = 1.02 x the bandwidth (Butterworth-2: 1.11, first
    order: 1.57).
    """
    if setting not in MPU6050_DLPF:
        raise ValueError(f"DLPF_CFG must be 0..6, got {setting!r}")
    abw, adl, gbw, gdl, gfs = MPU6050_DLPF[setting]
    bw, dl, fs = (gbw, gdl, gfs) if sensor == "gyro" else (abw, adl, 1000.0)
    if fs < output_rate_hz:
        raise ValueError(f"output rate {output_rate_hz} Hz above the internal {fs} Hz")
    base = butterworth(2, min(bw, 0.45 * fs), fs, output_rate_hz)
    own = base.group_delay_s()
    f = butterworth(2, min(bw, 0.45 * fs), fs, output_rate_hz, delay_s=max(0.0, dl * 1e-3 - own))
    return OutputFilter(
        f.internal_rate_hz,
        f.output_rate_hz,
        "mpu6050_dlpf",
        b=f.b,
        a=f.a,
        order=2,
        cutoff_hz=bw,
        delay_s=f.delay_s,
        label=f"MPU-6050 DLPF_CFG={setting} {sensor}: {bw:g} Hz, documented delay {dl:g} ms",
    )


def adis16405(
    sens_avg_n: int = 2, smpl_prd: int = 1, output_rate_hz: float | None = None
) -> OutputFilter:
    """ADIS16400/16405 filter: Bartlett of ``2^N`` taps per stage at ``1638.4 / (smpl_prd + 1)``.

    ``output_rate_hz`` defaults to the internal rate (reading every sample); a host reading at
    another rate reads asynchronously.
    """
    fi = ADIS16400_BASE_RATE_HZ / (smpl_prd + 1)
    fo = fi if output_rate_hz is None else float(output_rate_hz)
    f = bartlett(2**sens_avg_n, fi, fo)
    return OutputFilter(
        fi,
        fo,
        "bartlett",
        b=f.b,
        taps=f.taps,
        cutoff_hz=f.cutoff_hz,
        label=f"ADIS16405 SENS_AVG N={sens_avg_n} ({2**sens_avg_n} taps x 2), {fi:g} SPS; "
        f"driver -3 dB {fi / ADIS16400_3DB_DIVISORS.get(sens_avg_n, 200):.3g} Hz",
    )


def _ma_3db(L: int, fs: float) -> float:
    if L <= 1:
        return fs / 2
    w = np.linspace(1e-9, np.pi, 200001)
    g = np.abs(np.sin(L * w / 2) / (L * np.sin(w / 2)))
    return float(w[np.nonzero(g < 1 / math.sqrt(2))[0][0]] / (2 * np.pi) * fs)


def _with_cutoff(f: OutputFilter) -> OutputFilter:
    return OutputFilter(
        f.internal_rate_hz,
        f.output_rate_hz,
        f.kind,
        b=f.b,
        a=f.a,
        taps=f.taps,
        order=f.order,
        cutoff_hz=f.cutoff_3db_hz(),
        delay_s=f.delay_s,
        label=f.label,
    )


# --- Allan variance of any stationary sequence from its autocovariance ------------------------
def variance_of_sums(r: np.ndarray, m) -> np.ndarray:
    """``V(m) = var(sum of m consecutive samples)`` from the autocovariance ``r[0..L-1]``
    (zero beyond)."""
    r = np.asarray(r, float)
    m = np.asarray(m, dtype=np.int64)
    L = len(r)
    lag = np.arange(L)
    c0 = np.concatenate([[0.0], np.cumsum(r[1:])])  # c0[n] = sum_{l=1}^{n} r(l)
    c1 = np.concatenate([[0.0], np.cumsum(lag[1:] * r[1:])])
    n = np.minimum(m - 1, L - 1)
    return m * (r[0] + 2 * c0[n]) - 2 * c1[n]


def avar_from_autocov(r: np.ndarray, m) -> np.ndarray:
    """Allan variance at ``tau = m dt`` of a stationary sequence with autocovariance ``r``:
    ``(4 V(m) - V(2m)) / (2 m^2)``."""
    m = np.asarray(m, dtype=np.int64)
    return (4 * variance_of_sums(r, m) - variance_of_sums(r, 2 * m)) / (2.0 * m * m)


# --- configuration (a grade's per-sensor ``bandwidth`` entry) ------------------------------
_SPEC_KEYS = {"filter", "internal_rate", "taps", "order", "cutoff", "setting", "source", "note"}
_NEEDS = {
    "ideal": (),
    "moving_average": ("internal_rate", "taps"),
    "bartlett": ("internal_rate", "taps"),
    "butterworth": ("internal_rate", "order", "cutoff"),
    "mpu6050_dlpf": ("setting",),
}


@dataclass(frozen=True)
class BandwidthSpec:
    """A sensor's output bandwidth as configured (``bandwidth`` in a grade), SI.

    ``filter`` is one of :data:`KINDS`; ``internal_rate_hz`` the part's internal sample rate
    (``mpu6050_dlpf``: the register map's, from ``setting``); ``taps`` (moving average; one
    Bartlett stage), ``order`` and ``cutoff_hz`` (Butterworth). The output rate is the run's.
    """

    filter: str
    internal_rate_hz: float | None = None
    taps: int = 0
    order: int = 0
    cutoff_hz: float = 0.0
    setting: int | None = None
    source: str = ""

    def output_filter(self, sensor: str, output_rate_hz: float) -> OutputFilter:
        """The filter read at ``output_rate_hz``.

        Raises
        ------
        InputError
            The output rate is above the part's internal rate.
        """
        fi = self.internal_rate_hz
        if self.filter == "mpu6050_dlpf":
            gfs = MPU6050_DLPF[self.setting][4]
            fi = gfs if sensor == "gyro" else 1000.0
        if fi is not None and output_rate_hz > fi * (1 + 1e-12):
            raise InputError(
                "--rate-hz",
                f"{output_rate_hz:g} Hz is above the {sensor}'s internal rate {fi:g} Hz "
                f"({self.filter} bandwidth of the grade): a part cannot output faster",
            )
        if self.filter == "ideal":
            return ideal(output_rate_hz)
        if self.filter == "moving_average":
            return moving_average(self.taps, fi, output_rate_hz)
        if self.filter == "bartlett":
            return bartlett(self.taps, fi, output_rate_hz)
        if self.filter == "butterworth":
            return butterworth(self.order, self.cutoff_hz, fi, output_rate_hz)
        return mpu6050_dlpf(self.setting, sensor, output_rate_hz)

    def config(self) -> dict:
        """The grade-document entry (datasheet units)."""
        out: dict = {"filter": self.filter}
        if self.internal_rate_hz is not None:
            out["internal_rate"] = {"value": self.internal_rate_hz, "unit": "hz"}
        if self.taps:
            out["taps"] = self.taps
        if self.order:
            out["order"] = self.order
        if self.cutoff_hz:
            out["cutoff"] = {"value": self.cutoff_hz, "unit": "hz"}
        if self.setting is not None:
            out["setting"] = self.setting
        if self.source:
            out["source"] = self.source
        return out


def _int(entry, key, lo, hi, origin, where) -> int:
    v = entry[key]
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise InputError(origin, f"{where}.{key}: an integer in {lo}..{hi}, got {v!r}")
    return v


def _hz(entry, key, origin, where) -> float:
    v = entry[key]
    if not isinstance(v, dict) or set(v) - {"value", "unit", "source"}:
        raise InputError(origin, f"{where}.{key}: expected {{value, unit}} (unit hz or khz)")
    try:
        x = units.to_si(v.get("value"), v.get("unit"), "frequency")
    except (KeyError, ValueError, TypeError) as exc:
        raise InputError(origin, f"{where}.{key}: {exc}") from None
    if isinstance(v.get("value"), bool) or not (math.isfinite(x) and x > 0):
        raise InputError(origin, f"{where}.{key}: must be a positive frequency, got {v!r}")
    return float(x)


def spec_from_config(entry, origin, where) -> BandwidthSpec:
    """Validate a grade's ``bandwidth`` entry.

    ``{filter: moving_average|bartlett, internal_rate: {value, unit: hz}, taps}``,
    ``{filter: butterworth, internal_rate, order, cutoff: {value, unit: hz}}``,
    ``{filter: mpu6050_dlpf, setting: 0..6}`` or ``{filter: ideal}``; optional ``source``.
    """
    if not isinstance(entry, dict):
        raise InputError(origin, f"{where}: expected a mapping with 'filter', got {entry!r}")
    extra = set(entry) - _SPEC_KEYS
    if extra:
        raise InputError(
            origin, f"{where}: unknown key(s) {sorted(extra)}; allowed {sorted(_SPEC_KEYS)}"
        )
    kind = entry.get("filter")
    if kind not in _NEEDS:
        raise InputError(origin, f"{where}.filter: one of {', '.join(KINDS)}, got {kind!r}")
    missing = [k for k in _NEEDS[kind] if k not in entry]
    if missing:
        raise InputError(origin, f"{where}: filter {kind} needs {', '.join(missing)}")
    unused = {"internal_rate", "taps", "order", "cutoff", "setting"} & set(entry)
    unused -= set(_NEEDS[kind])
    if unused:
        raise InputError(origin, f"{where}: filter {kind} takes no {', '.join(sorted(unused))}")
    src = entry.get("source", "")
    if not isinstance(src, str):
        raise InputError(origin, f"{where}.source: must be text")
    fi = _hz(entry, "internal_rate", origin, where) if "internal_rate" in entry else None
    taps = _int(entry, "taps", 1, 4096, origin, where) if "taps" in entry else 0
    order = _int(entry, "order", 1, 8, origin, where) if "order" in entry else 0
    setting = _int(entry, "setting", 0, 6, origin, where) if "setting" in entry else None
    fc = _hz(entry, "cutoff", origin, where) if "cutoff" in entry else 0.0
    if kind == "butterworth" and not fc < fi / 2:
        raise InputError(
            origin, f"{where}: cutoff {fc:g} Hz must be below half the internal rate {fi:g} Hz"
        )
    return BandwidthSpec(kind, fi, taps, order, fc, setting, src)


# --- streaming the simulator's chunks through it --------------------------------------------
class Stream:
    """One sensor's output bandwidth applied to ``S`` sequences, chunk by chunk.

    The sensed signal arrives at the output rate ``f_o``; it is interpolated linearly to the
    internal grid ``t_j = (j - phase) / f_i`` (exact for motion linear between output
    samples; content above ``f_o / 2`` is not in the truth, so aliasing of vibration above it
    is not modelled), filtered, and read at ``j_k = floor(k D + phase)``: the last internal
    sample at or before ``t_k``. The white noise is generated at the internal rate (density
    ``N``: ``N sqrt(f_i)`` per internal sample, from each sequence's own stream, a fixed
    number of variates per internal sample whatever the chunking), filtered and read at the
    same indices. Filters start in steady state (motion: at the first sample; noise: after a
    warm-up of the impulse response's length). ``phase`` is 0 for a synchronous read and
    uniform in [0, 1) (the stream's first variate) for an asynchronous one.

    Parameters
    ----------
    filt : OutputFilter
    density : ndarray, shape (S, 3)
        Sensor white-noise density per sequence and axis [SI].
    rngs : list of numpy.random.Generator
        One stream per sequence.
    """

    def __init__(self, filt: OutputFilter, density, rngs):
        self.f = filt
        self.D = filt.ratio
        self.Di = round(self.D) if filt.synchronous else 0
        self.rngs = list(rngs)
        self.phase = np.array([0.0 if self.Di else float(g.random()) for g in self.rngs])
        self.scale = np.asarray(density, float) * math.sqrt(filt.internal_rate_hz)
        self.b = np.asarray(filt.b, float)
        self.a = np.asarray(filt.a, float)
        self.n = max(len(self.a), len(self.b)) - 1
        self.zi0 = _signal().lfilter_zi(self.b, self.a) if self.n else np.zeros(0)
        self.state: dict[str, list] = {}

    def reads(self, s: int, k0: int, L: int) -> np.ndarray:
        """Internal indices ``j_k`` read for outputs ``k0 .. k0 + L - 1`` of sequence ``s``."""
        k = np.arange(k0, k0 + L, dtype=np.int64)
        if self.Di:
            return k * self.Di
        return np.floor(k * self.D + self.phase[s]).astype(np.int64)

    def _filter(self, x, zi):
        if not self.n:
            return x * (self.b[0] / self.a[0]), zi
        return _signal().lfilter(self.b, self.a, x, axis=0, zi=zi)

    def noise(self, k0: int, L: int) -> np.ndarray:
        """Filtered white noise read at outputs ``k0 .. k0 + L - 1``: ``(S, L, 3)``."""
        S = len(self.rngs)
        out = np.zeros((S, L, 3))
        if L == 0:
            return out
        st = self.state.setdefault("noise", [None] * S)
        for s, g in enumerate(self.rngs):
            j = self.reads(s, k0, L)
            if k0 == 0 or st[s] is None:
                warm = len(self.f.impulse()) if self.n else 0
                zi = np.zeros((self.n, 3))
                if warm:
                    _, zi = self._filter(g.standard_normal((warm, 3)) * self.scale[s], zi)
                st[s] = (int(j[0]), zi)
            jn, zi = st[s]
            z = g.standard_normal((int(j[-1]) - jn + 1, 3)) * self.scale[s]
            y, zi = self._filter(z, zi)
            out[s] = y[j - jn]
            st[s] = (int(j[-1]) + 1, zi)
        return out

    def motion(self, channel: str, k0: int, y) -> np.ndarray:
        """The signal ``y`` ``(S, L, 3)`` (outputs ``k0 ..``) filtered and read: ``(S, L, 3)``.

        ``channel`` names an independent filter state (the rate output, the increments)."""
        S, L, _ = y.shape
        out = np.empty((S, L, 3))
        if L == 0:
            return out
        st = self.state.setdefault(channel, [None] * S)
        for s in range(S):
            ys = y[s]
            j = self.reads(s, k0, L)
            if k0 == 0 or st[s] is None:
                zi = self.zi0[:, None] * ys[0][None, :] if self.n else np.zeros((0, 3))
                st[s] = (int(j[0]), zi, ys[0].copy())
            jn, zi, prev = st[s]
            idx = np.arange(jn, int(j[-1]) + 1)
            Y = np.concatenate([prev[None], ys])
            pos = np.clip((idx - self.phase[s]) / self.D - (k0 - 1), 0.0, float(L))
            i0 = np.minimum(np.floor(pos).astype(np.int64), L)
            i1 = np.minimum(i0 + 1, L)
            fr = (pos - i0)[:, None]
            x = Y[i0] * (1.0 - fr) + Y[i1] * fr
            yf, zi = self._filter(x, zi)
            out[s] = yf[j - jn]
            st[s] = (int(j[-1]) + 1, zi, ys[-1].copy())
        return out


# --- many independent windows at once (the stream's window mode) ----------------------------
def _coefs(f: OutputFilter) -> tuple:
    """``b, a`` normalized by ``a[0]`` (float64, contiguous) and the DF2T steady state."""
    b = np.ascontiguousarray(np.asarray(f.b, float) / f.a[0])
    a = np.ascontiguousarray(np.asarray(f.a, float) / f.a[0])
    order = max(len(a), len(b)) - 1
    zi = _signal().lfilter_zi(b, a) if len(a) > 1 else np.zeros(order)
    return b, a, np.ascontiguousarray(zi, dtype=float)


def _phase(f: OutputFilter, phase, B: int) -> np.ndarray:
    if f.synchronous:
        return np.zeros(B)
    return np.ascontiguousarray(np.broadcast_to(np.asarray(phase, float), (B,)))


def filter_windows(f: OutputFilter, y: np.ndarray, phase) -> np.ndarray:
    """Many windows' sensed signal through the output filter, as :class:`Stream` runs one
    sequence from its first sample (a compiled kernel over the windows:
    :func:`imugen.sensors._band_kernel.motion_reads`).

    Row ``i`` of window ``b`` is output ``k = i + 1``; it is interpolated linearly to the
    internal grid ``t_j = (j - phase_b) / f_i``, filtered from the filter's steady state on
    the first row, and read at ``j_k = k D`` (synchronous) or ``floor(k D + phase_b)``. An
    FIR filter is evaluated at the read indices only.

    Parameters
    ----------
    f : OutputFilter
    y : ndarray, shape (B, L, C)
        The signal at the output rate (any channels sharing the filter).
    phase : ndarray, shape (B,)
        Read phase of each window (ignored for a synchronous read).

    Returns
    -------
    ndarray, shape (B, L, C)
    """
    from imugen.sensors._band_kernel import motion_reads

    B, L, C = y.shape
    out = np.empty((B, L, C))
    if B == 0 or L == 0:
        return out
    b, a, zi = _coefs(f)
    Y = np.concatenate([y[:, :1], y], axis=1).astype(float)  # row 0: the first value
    Di = round(f.ratio) if f.synchronous else 0
    motion_reads(b, a, zi, Y, _phase(f, phase, B), float(f.ratio), Di, out)
    return out


def noise_windows(f: OutputFilter, z: np.ndarray, scale: np.ndarray, phase) -> np.ndarray:
    """Filtered internal-rate white noise of many windows, read at the output rate, drawn from
    its exact law (a compiled kernel over the windows:
    :func:`imugen.sensors._band_kernel.noise_law`).

    The reads ``j_k`` (``k D``, or ``floor(k D + phase)``) of stationary filtered white noise
    are jointly Gaussian with covariance ``N^2 f_i c(|j_k - j_l|)`` (``c``:
    :meth:`OutputFilter.internal_autocorr`; an IIR's from its impulse response truncated at
    1e-13 of its energy): one normal per output sample and axis instead of ``D`` at the
    internal rate, whatever the filter.

    Parameters
    ----------
    f : OutputFilter
    z : ndarray, shape (B, L, 3)
        Standard normals, one per output sample and axis.
    scale : ndarray, shape (B, 3)
        ``N sqrt(f_i)``: the internal samples' standard deviation.
    phase : ndarray, shape (B,)
        Read phase of each window (ignored for a synchronous read).

    Returns
    -------
    ndarray, shape (B, L, 3)
    """
    from imugen.sensors._band_kernel import noise_law

    B, L = z.shape[0], z.shape[1]
    out = np.empty((B, L, 3))
    if B == 0 or L == 0:
        return out
    Di = round(f.ratio) if f.synchronous else 0
    c = np.ascontiguousarray(f.internal_autocorr(), dtype=float)
    noise_law(c, np.ascontiguousarray(z, dtype=float), np.ascontiguousarray(scale, dtype=float),
              _phase(f, phase, B), float(f.ratio), Di, out)  # fmt: skip
    return out
