"""Sensor error model: ideal rates/increments -> what a gyro or accelerometer triad outputs.

One model, applied consistently to instantaneous rate samples and to increments (``dtheta``,
``dv``). For one sensor triad (``u`` the true rate -- ``omega_ib_b`` or ``f_b`` --, ``du`` its
increment over the interval ``[t_{k-1}, t_k]``, ``a``/``da`` the specific force and its
increment for the gyro g-sensitivity, ``dT`` the temperature offset):

slow bias (state at sample ``t_k``)
    ``s_k = b_on + sum_c x_c(t_k) + r(t_k) + k_b dT(t_k)``
    * ``b_on`` turn-on bias, constant over the run;
    * ``x_c`` first-order Gauss-Markov (bias instability), exact discretization
      ``x_k = phi x_{k-1} + sigma sqrt(1 - phi^2) xi``, ``phi = exp(-dt/T)``, started from
      its stationary law ``x_0 ~ N(0, sigma^2)`` when it is the whole slow bias, or from
      ``x_0 = 0`` when it is the in-run wander beside a turn-on bias (grade key ``start``);
      a sum of several (log-spaced ``T``)
      approximates flicker (1/f) noise; a grade's ``slow_bias`` is one more component, the
      last (its own ``T`` and start; its normals from the streams ``gyro_slow`` /
      ``accel_slow``, so the other components draw what they drew without it);
    * ``r`` rate random walk, ``r_k = r_{k-1} + K sqrt(dt) xi``, ``r_0 = 0`` (the turn-on bias
      is the initial value);
    * ``k_b dT`` temperature-driven bias.
rate output (sample at ``t_k``)
    ``y_k = u_k + E_k u_k + G a_k + s_k + (N / sqrt(dt)) w_k``
    with ``E_k = diag(s_f + k_s dT_k) + C`` (scale-factor errors and the off-diagonal
    misalignment / cross-coupling ``C``), ``G`` the g-sensitivity matrix (gyro only) and ``N``
    the white-noise density (ARW/VRW). The white term is the mean of white noise of density
    ``N`` over one sample interval (variance ``N^2 / dt``), i.e. the averaged-rate output of a
    real sensor; the same normal ``w_k`` drives the increment below, so ``increment / dt`` and
    the rate output carry the same white noise.
increment output (interval ending at ``t_k``, ``k >= 1``; row 0 is zero as in the truth)
    ``dy_k = du_k + E_bar du_k + G da_k + dt (s_{k-1} + s_k) / 2 + N sqrt(dt) w_k``
    * white noise of density ``N`` integrated over ``dt`` has standard deviation
      ``N sqrt(dt)`` (exact);
    * a constant bias contributes ``b dt`` (exact);
    * GM and random-walk biases contribute their integral over the interval, taken as the
      trapezoid of the end states. This is the conditional mean of the integral given both
      ends (exact for the random walk's Brownian bridge, to ``O(dt/T)`` for GM); the omitted
      conditional variance ``q dt^3 / 12`` (``q = K^2`` or ``2 sigma^2 / T``) is white and
      below ``dt sqrt(dt / (6T))`` of the bias itself, e.g. 4e-3 at 100 Hz, ``T = 100 s``;
    * ``E_bar`` uses the mean temperature of the interval; scale factor and cross-coupling are
      linear, so applying them to the exact increment is exact for constant ``E``;
    * g-sensitivity uses the true ``dv`` (``int G f dt`` up to the body rotation within
      the interval, an ``O(|omega| dt)`` relative effect on an already small term).
saturation and quantization (last)
    The output is clipped to ``+-range`` (increments: ``+-range dt``), then quantized to the
    LSB ``q`` (increments: ``q dt``) with residual carry (``r += y; out = q round(r / q);
    r -= out``), so the quantization error does not accumulate in integrated outputs.
effective error (optional output)
    Everything above except the white term and quantization: ``E u + G a + s`` (rates) or
    ``E_bar du + G da + dt (s_{k-1} + s_k) / 2`` (increments), plus the saturation excess
    (clipped minus unclipped output), so that ``output = true + effective error + white +
    quantization error`` holds exactly.

Everything is vectorized over a batch of sequences (leading axis ``S``) in a numba kernel
that resumes from a state array, so time can be processed in chunks (increments alone, without
series or temperature: a one-pass kernel giving the same bits as the general one). The random
normals are drawn outside (NumPy ``Generator``) so reproducibility is NumPy's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imugen.core import units
from imugen.sensors._kernel import kernel, kernel_increments, quantize_series
from imugen.sensors.bandwidth import Stream
from imugen.sensors.grades import TERMS, SensorSpec

# Layout of one sequence's parameter draw for one sensor (always drawn in full, whatever is
# configured or enabled, so that each term's draw never depends on another term).
N_UNIFORM = TERMS.index("slow_bias") + 1
"""One level per term up to ``temperature_scale_factor`` + the GM correlation time (fixed: a
``slow_bias`` draws its two uniforms after the layout, and only where the grade has one)."""
N_NORMAL = (
    3 + 3 + 6 + 9 + 3 + 3
)  # turn-on, scale factor, cross-coupling, g-sens, temp bias, temp SF
N_SLOW_UNIFORM = 2
"""Uniforms of a ``slow_bias`` (its level, its correlation time), drawn after the layout."""
_OFFDIAG = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
AXES = "xyz"


@dataclass
class SensorParams:
    """Drawn error parameters of one sensor triad for a batch of ``S`` sequences (SI).

    Attributes
    ----------
    b_on : (S, 3)      turn-on bias [rad/s | m/s^2] (for a grade calibrated at rest, minus the
                       static error on gravity the calibration removed: ``G (0, 0, g0)`` for
                       a gyro, ``E (0, 0, g0)`` for an accelerometer)
    bi_level : (S, 3)  drawn bias-instability level in the configured kind (Allan floor or
                       GM sigma) [rad/s | m/s^2]
    bi_floor : (S, 3)  Allan-deviation floor (peak for one GM) of the in-run bias
    bi_sigma : (S, 3, C) GM sigma of each component
    bi_tau : (S, C)    GM correlation times [s]
    white : (S, 3)     white-noise density [rad/s/sqrt(Hz) | m/s^2/sqrt(Hz)]
    rrw : (S, 3)       rate-random-walk density [rad/s/sqrt(s) | m/s^2/sqrt(s)]
    sf : (S, 3)        scale-factor error (dimensionless)
    cc : (S, 3, 3)     cross-coupling (zero diagonal)
    gs : (S, 3, 3)     g-sensitivity [rad/s per m/s^2] (zeros for accelerometers)
    tb : (S, 3)        bias temperature coefficient [.../K]
    ts : (S, 3)        scale-factor temperature coefficient [1/K]
    lsb : float        quantization step of the rate output (0: off)
    full_scale : float measurement range (inf: off)
    bi_x0 : (S, 3, C)  standard deviation of each GM component's initial state: ``bi_sigma``
                       (start from the stationary law) or 0 (in-run wander from the turn-on
                       value); None means ``bi_sigma``
    n_slow : int       0, or 1 when the last of the ``C`` components is the grade's
                       ``slow_bias`` (a second, slower GM process)
    slow_level : (S, 3) drawn ``slow_bias`` level in its configured kind (zeros without one)
    """

    b_on: np.ndarray
    bi_level: np.ndarray
    bi_floor: np.ndarray
    bi_sigma: np.ndarray
    bi_tau: np.ndarray
    white: np.ndarray
    rrw: np.ndarray
    sf: np.ndarray
    cc: np.ndarray
    gs: np.ndarray
    tb: np.ndarray
    ts: np.ndarray
    lsb: float
    full_scale: float
    bi_x0: np.ndarray | None = None
    q_round: bool = False
    """Quantize each rate sample on its own (``quantization.mode: round``) instead of
    carrying the residual."""
    n_slow: int = 0
    slow_level: np.ndarray | None = None

    def __post_init__(self):
        if self.bi_x0 is None:
            self.bi_x0 = self.bi_sigma
        if self.slow_level is None:
            self.slow_level = np.zeros_like(self.b_on)

    @property
    def components(self) -> int:
        """GM components the kernel runs (the bias instability's, then the slow bias)."""
        return self.bi_sigma.shape[2]

    @property
    def fast_components(self) -> int:
        """Components of the bias instability (stream ``*_bi``), without the slow bias."""
        return self.components - self.n_slow

    ARRAYS = ("b_on", "bi_level", "bi_floor", "bi_sigma", "bi_tau", "white", "rrw", "sf", "cc",
              "gs", "tb", "ts", "bi_x0", "slow_level")  # fmt: skip
    """The per-sequence fields (leading axis ``S``)."""

    @staticmethod
    def stack(items: list[SensorParams]) -> SensorParams:
        """Concatenate per-sequence parameter sets along the sequence axis."""
        f = items[0]
        kw = {name: np.concatenate([getattr(p, name) for p in items]) for name in f.ARRAYS}
        return SensorParams(**kw, lsb=f.lsb, full_scale=f.full_scale, q_round=f.q_round,
                            n_slow=f.n_slow)  # fmt: skip

    def rows(self, i: int) -> SensorParams:
        """Sequence ``i`` alone (``S = 1``; views of this set's arrays)."""
        kw = {name: getattr(self, name)[i : i + 1] for name in self.ARRAYS}
        return SensorParams(**kw, lsb=self.lsb, full_scale=self.full_scale, q_round=self.q_round,
                            n_slow=self.n_slow)  # fmt: skip

    def labels(self, prefix: str, unit: str) -> dict[str, np.ndarray]:
        """Flat label columns ``{name: (S,) array}`` with the SI unit in each name."""
        out = {}
        rate = unit  # "radps" or "mps2"
        for i, a in enumerate(AXES):
            out[f"{prefix}_turn_on_bias_{a}_{rate}"] = self.b_on[:, i]
        for i, a in enumerate(AXES):
            out[f"{prefix}_bias_instability_level_{a}_{rate}"] = self.bi_level[:, i]
            out[f"{prefix}_bias_instability_floor_{a}_{rate}"] = self.bi_floor[:, i]
            for c in range(self.fast_components):
                out[f"{prefix}_bias_instability_sigma{c}_{a}_{rate}"] = self.bi_sigma[:, i, c]
        for c in range(self.fast_components):
            out[f"{prefix}_bias_instability_tau{c}_s"] = self.bi_tau[:, c]
        if self.n_slow:  # the second, slow GM process (grade term slow_bias)
            for i, a in enumerate(AXES):
                out[f"{prefix}_slow_bias_level_{a}_{rate}"] = self.slow_level[:, i]
                out[f"{prefix}_slow_bias_sigma_{a}_{rate}"] = self.bi_sigma[:, i, -1]
            out[f"{prefix}_slow_bias_tau_s"] = self.bi_tau[:, -1]
        dens = "rad_per_sqrt_s" if unit == "radps" else "m_per_s_per_sqrt_s"
        rw = "radps_per_sqrt_s" if unit == "radps" else "mps2_per_sqrt_s"
        for i, a in enumerate(AXES):
            out[f"{prefix}_white_noise_{a}_{dens}"] = self.white[:, i]
        for i, a in enumerate(AXES):
            out[f"{prefix}_rate_random_walk_{a}_{rw}"] = self.rrw[:, i]
        for i, a in enumerate(AXES):
            out[f"{prefix}_scale_factor_{a}"] = self.sf[:, i]
        for i, j in _OFFDIAG:
            out[f"{prefix}_cross_coupling_{AXES[i]}{AXES[j]}"] = self.cc[:, i, j]
        if prefix == "gyro":
            for i in range(3):
                for j in range(3):
                    out[f"gyro_g_sensitivity_{AXES[i]}{AXES[j]}_radps_per_mps2"] = self.gs[:, i, j]
        for i, a in enumerate(AXES):
            out[f"{prefix}_temperature_bias_{a}_{rate}_per_K"] = self.tb[:, i]
        for i, a in enumerate(AXES):
            out[f"{prefix}_temperature_scale_factor_{a}_per_K"] = self.ts[:, i]
        n = len(self.b_on)
        out[f"{prefix}_quantization_{rate}"] = np.full(n, self.lsb)
        out[f"{prefix}_range_{rate}"] = np.full(n, self.full_scale)
        return out


def _level(p, u: np.ndarray, nominal: bool) -> np.ndarray:
    """Per-axis levels ``(S, 3)`` of ``S`` sequences: nominal, or log-uniform in [lo, hi] with
    one uniform ``u[s]`` shared by the axes."""
    v = np.asarray(p.value, float)
    if nominal or p.lo is None:
        return np.tile(v, (len(u), 1))
    lo = np.asarray(p.lo)
    hi = np.asarray(p.hi)
    return lo * (hi / lo) ** u[:, None]


def draw_sensor(
    spec: SensorSpec, rng: np.random.Generator, enabled: frozenset, nominal: bool = False
) -> SensorParams:
    """Draw one sequence's parameters for one sensor triad.

    Distributions: each configured level (1-sigma, density, Allan floor, correlation time) is
    log-uniform in its ``range`` (one uniform per term shared by the three axes; the nominal
    value when there is no range or ``nominal``); realizations are Gaussian with that level:
    turn-on bias, scale factor, temperature coefficients ``N(0, level^2)`` per axis,
    cross-coupling and g-sensitivity ``N(0, level^2)`` per matrix element. The draw consumes a
    fixed number of variates (:data:`N_UNIFORM` uniforms, :data:`N_NORMAL` normals) whatever is
    configured or ``enabled``, so a term's draw never depends on the others. A grade with a
    ``slow_bias`` draws two more uniforms after that layout (its level, its correlation
    time), whether the term is enabled or not; grades without one draw nothing more. The
    slow process is appended as the last GM component (:attr:`SensorParams.n_slow`).

    Parameters
    ----------
    spec : SensorSpec
    rng : numpy.random.Generator
        The sequence's parameter stream.
    enabled : frozenset of str
        Term names to apply (others are zero in the result).
    nominal : bool
        Use nominal levels instead of drawing them in the ranges.
    """
    u = rng.random(N_UNIFORM)
    z = rng.standard_normal(N_NORMAL)
    us = None if spec.slow_bias is None else rng.random(N_SLOW_UNIFORM)[None]
    return draw_sensors(spec, u[None], z[None], enabled, nominal, us)


def draw_sensors(
    spec: SensorSpec,
    u: np.ndarray,
    z: np.ndarray,
    enabled: frozenset,
    nominal: bool = False,
    us: np.ndarray | None = None,
) -> SensorParams:
    """:func:`draw_sensor` of ``S`` sequences at once from their variates: ``u`` ``(S,
    N_UNIFORM)``, ``z`` ``(S, N_NORMAL)`` and, for a grade with a ``slow_bias``, ``us`` ``(S,
    N_SLOW_UNIFORM)``, each row drawn from its sequence's stream as :func:`draw_sensor` draws
    it. Element-wise the same operations, hence the same numbers."""
    S = len(u)
    ti = {t: i for i, t in enumerate(TERMS)}

    def lvl(term):
        p = getattr(spec, term)
        if p is None or term not in enabled:
            return None
        if term == "bias_instability":
            p = p.level
        return _level(p, u[:, ti[term]], nominal)

    zero3 = np.zeros((S, 3))
    b = lvl("turn_on_bias")
    b_on = zero3 if b is None else b * z[:, 0:3]
    bi = spec.bias_instability
    C = 1 if bi is None else bi.components
    bi_level = np.zeros((S, 3))
    bi_floor = np.zeros((S, 3))
    bi_sigma = np.zeros((S, 3, C))
    bi_x0 = bi_sigma
    bi_tau = np.ones((S, C))
    lv = lvl("bias_instability")
    if lv is not None:
        bi_level = lv
        if bi.model == "gauss_markov":
            bi_tau = _level(bi.correlation_time, u[:, -1], nominal)[:, :1]
        else:
            from imugen.sensors.grades import flicker_taus

            bi_tau = np.tile(np.asarray(flicker_taus(bi.flicker_band, C), float), (S, 1))
        bi_sigma = np.repeat(np.asarray(bi.sigma_from_level(lv), float)[:, :, None], C, axis=2)
        bi_x0 = bi_sigma if bi.start == "stationary" else np.zeros_like(bi_sigma)
        bi_floor = np.asarray(bi.allan_floor_from_level(lv), float)
    w = lvl("white_noise")
    r = lvl("rate_random_walk")
    s = lvl("scale_factor")
    sf = zero3 if s is None else s * z[:, 3:6]
    c = lvl("cross_coupling")
    cc = np.zeros((S, 3, 3))
    if c is not None:
        for k, (i, j) in enumerate(_OFFDIAG):
            cc[:, i, j] = c[:, i] * z[:, 6 + k]
    g = lvl("g_sensitivity")
    gs = np.zeros((S, 3, 3)) if g is None else g[:, :, None] * z[:, 12:21].reshape(S, 3, 3)
    if spec.static_g_removed:
        # calibrated at rest and level: the bias estimate absorbed the static error on gravity,
        # (E + G) (0, 0, g0) with E = diag(sf) + cross-coupling, G the g-sensitivity
        diag = np.zeros((S, 3, 3))
        diag[:, (0, 1, 2), (0, 1, 2)] = sf
        E = cc + diag
        if spec.sensor == "accel":
            b_on = b_on - E[:, :, 2] * units.G0
        b_on = b_on - gs[:, :, 2] * units.G0
    tbl = lvl("temperature_bias")
    tb = zero3 if tbl is None else tbl * z[:, 21:24]
    tsl = lvl("temperature_scale_factor")
    ts = zero3 if tsl is None else tsl * z[:, 24:27]
    slow_level, n_slow = zero3, 0
    sb = spec.slow_bias
    if sb is not None and "slow_bias" in enabled:
        n_slow = 1
        slow_level = _level(sb.level, us[:, 0], nominal)
        sig = np.asarray(sb.sigma_from_level(slow_level), float)[:, :, None]
        bi_sigma = np.concatenate([bi_sigma, sig], axis=2)
        bi_x0 = np.concatenate([bi_x0, sig if sb.start == "stationary" else 0.0 * sig], 2)
        T = _level(sb.correlation_time, us[:, 1], nominal)[:, :1]
        bi_tau = np.concatenate([np.asarray(bi_tau, float), T], axis=1)
    q = spec.quantization
    lsb = q.value[0] if q is not None and "quantization" in enabled else 0.0
    fr = spec.range
    full_scale = fr.value[0] if fr is not None and "range" in enabled else math.inf
    return SensorParams(
        b_on=b_on,
        bi_level=bi_level,
        bi_floor=bi_floor,
        bi_sigma=bi_sigma,
        bi_tau=np.asarray(bi_tau, float),
        white=zero3 if w is None else w,
        rrw=zero3 if r is None else r,
        sf=sf,
        cc=cc,
        gs=gs,
        tb=tb,
        ts=ts,
        lsb=float(lsb),
        full_scale=float(full_scale),
        bi_x0=bi_x0,
        q_round=spec.quantization_mode == "round",
        n_slow=n_slow,
        slow_level=slow_level,
    )


class SensorState:
    """Resumable state of one sensor triad for ``S`` sequences (time-chunked processing).

    Attributes
    ----------
    x : (S, 3, C)  Gauss-Markov states
    r : (S, 3)     rate-random-walk state
    s_prev : (S, 3) slow bias at the previous sample (trapezoid of increments)
    q_rate, q_inc : (S, 3) quantization residuals of the rate and increment outputs
    """

    def __init__(self, S: int, C: int):
        self.x = np.zeros((S, 3, C))
        self.r = np.zeros((S, 3))
        self.s_prev = np.zeros((S, 3))
        self.q_rate = np.zeros((S, 3))
        self.q_inc = np.zeros((S, 3))


_EMPTY3 = np.zeros((0, 0, 3))
_EMPTY2 = np.zeros((0, 3))
_EMPTY1 = np.zeros(1)


class SensorModel:
    """Apply one sensor triad's errors to time chunks of truth, for ``S`` sequences.

    Parameters
    ----------
    params : SensorParams
        Drawn parameters (leading axis ``S``).
    dt : float
        Sample interval [s].
    band : OutputFilter, optional
        The sensor's output bandwidth read at ``1 / dt`` (:mod:`imugen.sensors.bandwidth`):
        the whole sensed signal goes through it before quantization, and the white noise is
        generated at its internal rate from ``band_rngs`` instead of ``zw``.
    band_rngs : list of numpy.random.Generator
        One stream per sequence (with ``band``).
    """

    def __init__(self, params: SensorParams, dt: float, band=None, band_rngs=None):
        self.p = params
        self.dt = float(dt)
        phi = np.exp(-self.dt / params.bi_tau)  # (S, C)
        self.phi = phi
        self.drv = params.bi_sigma * np.sqrt(-np.expm1(-2.0 * self.dt / params.bi_tau))[:, None, :]
        self.use_w = bool(np.any(params.white > 0))
        self.use_r = bool(np.any(params.rrw > 0))
        self.use_b = bool(np.any(params.bi_sigma > 0))
        Cf = params.fast_components
        self.use_bf = bool(np.any(params.bi_sigma[:, :, :Cf] > 0))
        """The bias instability draws normals (stream ``*_bi``, ``3 Cf`` per sample)."""
        self.use_s = bool(np.any(params.bi_sigma[:, :, Cf:] > 0))
        """The slow bias draws normals (stream ``*_slow``, 3 per sample)."""
        self._zk = np.empty(0)  # the kernel's joined GM normals (with a slow bias), reused
        self.use_g = bool(np.any(params.gs != 0))
        self.use_t = bool(np.any(params.tb != 0) or np.any(params.ts != 0))
        self.state = SensorState(len(params.b_on), params.components)
        self._slow = np.empty((0, 3))  # scratch of the kernel's slow-bias pass, reused
        self.stream = None
        if band is not None:
            if band_rngs is None or len(band_rngs) != len(params.b_on):
                raise ValueError("a bandwidth needs one noise stream per sequence")
            self.stream = Stream(band, params.white, band_rngs)
            self.use_w = False  # the stream generates the white noise at the internal rate

    @property
    def normals_per_sample(self) -> int:
        """Gaussian variates this sensor consumes per sample and sequence."""
        return (
            3 * (self.use_w + self.use_r)
            + (3 * self.p.fast_components if self.use_bf else 0)
            + (3 if self.use_s else 0)
        )

    def _join(self, zb, zs):
        """The kernel's GM normals ``(S, L, 3 C)`` (axis-major) from the bias instability's
        ``zb`` ``(S, L, 3 Cf)`` and the slow bias's ``zs`` ``(S, L, 3)`` (either None: zeros)."""
        if zb is None and zs is None:
            return None
        ref = zb if zb is not None else zs
        S, L = ref.shape[0], ref.shape[1]
        C, Cf = self.p.components, self.p.fast_components
        if self._zk.size < S * L * 3 * C:
            self._zk = np.empty(S * L * 3 * C)
        zk = self._zk[: S * L * 3 * C].reshape(S, L, 3, C)
        if zb is not None:
            zk[..., :Cf] = zb.reshape(S, L, 3, Cf)
        else:
            zk[..., :Cf] = 0.0
        if zs is not None:
            zk[..., Cf:] = zs.reshape(S, L, 3, 1)
        else:
            zk[..., Cf:] = 0.0
        return zk.reshape(S, L, 3 * C)

    def step(
        self,
        k0,
        u,
        du,
        a,
        da,
        dT,
        zw,
        zr,
        zb,
        out_rate=None,
        out_inc=None,
        out_bias=None,
        out_sf=None,
        out_err_rate=None,
        out_err_inc=None,
        zs=None,
    ):
        """Process samples ``k0 .. k0 + L - 1`` (call with consecutive chunks).

        Parameters
        ----------
        k0 : int
            Global index of the first sample of the chunk (0 starts the processes).
        u, du : ndarray, shape (L, 3)
            True rate at each sample and true increment of the interval ending at it.
        a, da : ndarray, shape (L, 3) or None
            Specific force and its increment (gyro g-sensitivity only).
        dT : ndarray, shape (L + 1,) or None
            Temperature offset [K] at the sample before the chunk and at each sample.
        zw, zr : ndarray, shape (S, L, 3) or None
            Standard normals of the white noise and of the rate random walk.
        zb : ndarray, shape (S, L, 3 Cf) or None
            Standard normals of the bias instability's Gauss-Markov components (axis-major,
            component minor; ``Cf`` = :attr:`SensorParams.fast_components`).
        out_rate, out_inc, out_bias, out_sf : ndarray, shape (S, L, 3) or None
            Outputs: rate samples, increments, slow bias and scale-factor error labels.
        out_err_rate, out_err_inc : ndarray, shape (S, L, 3) or None
            Effective error of the rate and increment outputs: everything added except
            white noise and quantization (slow bias, scale factor, cross-coupling,
            g-sensitivity, temperature, saturation excess), so that output = true + error +
            white noise + quantization error.
        zs : ndarray, shape (S, L, 3) or None
            Standard normals of the grade's ``slow_bias`` (stream ``*_slow``; with one only).
        """
        if self.p.n_slow:
            zb = self._join(zb, zs)
        if self.stream is not None or self.p.q_round:
            self._step_post(k0, u, du, a, da, dT, zw, zr, zb, out_rate, out_inc, out_bias,
                            out_sf, out_err_rate, out_err_inc)  # fmt: skip
            return
        self._step(k0, u, du, a, da, dT, zw, zr, zb, out_rate, out_inc, out_bias, out_sf,
                   out_err_rate, out_err_inc, self.p.lsb)  # fmt: skip

    def _step_post(self, k0, u, du, a, da, dT, zw, zr, zb, out_rate, out_inc, out_bias, out_sf,
                   out_err_rate, out_err_inc):  # fmt: skip
        """Bandwidth and/or rounding quantization: the kernel without quantization (and,
        with a bandwidth, without white noise) into float64 scratch, then the output filter
        with its internal-rate noise, saturation, and quantization here."""
        p, dt, L = self.p, self.dt, len(u)
        S = len(p.b_on)
        band = self.stream
        r64 = np.empty((S, L, 3)) if out_rate is not None else None
        i64 = np.empty((S, L, 3)) if out_inc is not None else None
        er = np.empty((S, L, 3)) if out_err_rate is not None and band is None else None
        ei = np.empty((S, L, 3)) if out_err_inc is not None and band is None else None
        self._step(k0, u, du, a, da, dT, zw, zr, zb, r64, i64, out_bias, out_sf, er, ei, 0.0)
        noise = band.noise(k0, L) if band is not None else None
        st = self.state
        if r64 is not None:
            if band is not None:
                r64 = band.motion("rate", k0, r64)
                if out_err_rate is not None:
                    out_err_rate[...] = r64 - u[None]
                np.clip(r64 + noise, -p.full_scale, p.full_scale, out=r64)
            elif er is not None:
                out_err_rate[...] = er
            quantize_series(r64, p.lsb, p.q_round, st.q_rate)
            out_rate[...] = r64
        if i64 is not None:
            if band is not None:
                if k0 == 0 and L > 1:  # sample 0 has no interval: start the filter at sample 1
                    i64[:, 0] = i64[:, 1]
                i64 = band.motion("increments", k0, i64 / dt) * dt
                if k0 == 0:
                    i64[:, 0] = 0.0
                if out_err_inc is not None:
                    out_err_inc[...] = i64 - du[None]
                    if k0 == 0:
                        out_err_inc[:, 0] = 0.0
                fs = p.full_scale * dt
                np.clip(i64 + noise * dt, -fs, fs, out=i64)
                if k0 == 0:
                    i64[:, 0] = 0.0
            elif ei is not None:
                out_err_inc[...] = ei
            quantize_series(i64, p.lsb * dt, p.q_round, st.q_inc)
            out_inc[...] = i64

    def _step(self, k0, u, du, a, da, dT, zw, zr, zb, out_rate, out_inc, out_bias, out_sf,
              out_err_rate, out_err_inc, lsb):  # fmt: skip
        p = self.p
        st = self.state
        if len(self._slow) < len(u):
            self._slow = np.empty((len(u), 3))
        use_g = self.use_g and a is not None and da is not None
        use_t = self.use_t and dT is not None
        if (
            out_inc is not None
            and out_rate is None
            and out_bias is None
            and out_sf is None
            and out_err_inc is None
            and not use_t
            and (p.components == 1 or not (self.use_b and zb is not None))
        ):
            kernel_increments(int(k0), self.dt, du, da if use_g else _EMPTY2,
                              _EMPTY3 if zw is None else zw, _EMPTY3 if zr is None else zr,
                              _EMPTY3 if zb is None else zb, self.use_w and zw is not None,
                              self.use_r and zr is not None, self.use_b and zb is not None, p.b_on,
                              p.bi_x0, self.phi, self.drv, p.white, p.rrw, p.sf, p.cc, p.gs, use_g,
                              p.ts, lsb, p.full_scale, st.x, st.r, st.s_prev, st.q_inc,
                              out_inc)  # fmt: skip
            return
        kernel(
            int(k0),
            self.dt,
            u,
            du,
            a if use_g else _EMPTY2,
            da if use_g else _EMPTY2,
            dT if use_t else _EMPTY1,
            use_t,
            _EMPTY3 if zw is None else zw,
            _EMPTY3 if zr is None else zr,
            _EMPTY3 if zb is None else zb,
            self.use_w and zw is not None,
            self.use_r and zr is not None,
            self.use_b and zb is not None,
            p.b_on,
            p.bi_x0,
            self.phi,
            self.drv,
            p.white,
            p.rrw,
            p.sf,
            p.cc,
            p.gs,
            use_g,
            p.tb,
            p.ts,
            lsb,
            p.full_scale,
            st.x,
            st.r,
            st.s_prev,
            st.q_rate,
            st.q_inc,
            self._slow,
            _EMPTY3 if out_rate is None else out_rate,
            _EMPTY3 if out_inc is None else out_inc,
            _EMPTY3 if out_bias is None else out_bias,
            _EMPTY3 if out_sf is None else out_sf,
            _EMPTY3 if out_err_rate is None else out_err_rate,
            _EMPTY3 if out_err_inc is None else out_err_inc,
        )


# --- analytic Allan variances of the terms (used by the verification and the Allan report) -----
def avar_white(tau, N):
    """Allan variance of white rate noise of density ``N``: ``N^2 / tau``."""
    return N**2 / np.asarray(tau, float)


def avar_rrw(tau, K):
    """Allan variance of a rate random walk of density ``K``: ``K^2 tau / 3``."""
    return K**2 * np.asarray(tau, float) / 3.0


def avar_quantization(tau, lsb, dt):
    """Allan variance of rate quantization with residual carry (angle LSB ``q = lsb dt``).

    ``3 q^2 / tau^2`` (IEEE Std 952-1997 C.1, quantization noise ``Q = q / sqrt(12)``).
    """
    q = lsb * dt
    return 3.0 * (q / math.sqrt(12.0)) ** 2 / np.asarray(tau, float) ** 2


def avar_bias_instability(tau, sigma, taus):
    """Allan variance of a sum of GM components with sigmas ``sigma`` (C,) and ``taus`` (C,)."""
    from imugen.sensors.grades import gm_avar

    tau = np.asarray(tau, float)
    out = np.zeros_like(tau)
    for sg, T in zip(np.atleast_1d(sigma), np.atleast_1d(taus), strict=True):
        out += gm_avar(tau, sg, T)
    return out
