"""The sensor error model as a batched PyTorch function, on CPU or CUDA (the ``torch`` extra).

The same model as :mod:`imugen.sensors.model` (its docstring states the equations), applied to
a batch of ``S`` windows of ideal signals at once, each window with its own drawn parameters
(:class:`imugen.sensors.model.SensorParams`, e.g. from :func:`imugen.sensors.model.draw_sensor`
or the stream): turn-on bias, Gauss-Markov bias instability (one component, or several for
flicker; a grade's ``slow_bias`` is one more, the last), rate random walk, scale factor and cross-coupling (misalignment), g-sensitivity
(gyro), white noise, an output bandwidth (internal rate, low-pass, decimation:
:mod:`imugen.sensors.bandwidth`, e.g. the measured presets ``adis16405``, ``phone``),
saturation and quantization with residual carry or rounding (``quantization.mode: round``).
Not here: temperature terms (use the NumPy path, :class:`imugen.sensors.model.SensorModel`).

Output bandwidth (``band``, an :class:`~imugen.sensors.bandwidth.OutputFilter`): as the NumPy
path's :class:`~imugen.sensors.bandwidth.Stream`, the sensed signal is interpolated linearly to
the internal grid, filtered and read at ``floor(k D + phase)`` (``phase`` uniform per window
for an asynchronous read, 0 for a synchronous one); the white noise is generated at the
internal rate (``N sqrt(f_i)`` per internal sample), filtered and read at the same indices,
after a warm-up of the impulse response's length (steady state: exact law). The filter is
applied as a convolution with its impulse response (an IIR's truncated where its energy tail
is below 1e-13, rescaled to unit DC gain). The motion's filter starts in steady state on the window's first row: give a
window :func:`imugen.stream.windows.warmup_rows` rows early and drop them where the filter's
lag at the window's start matters (the stream's window mode does).

A window covers samples ``k0 .. k0 + L - 1`` of a sequence (``k0 >= 1``; row ``j``'s increment is
the interval ending at sample ``k0 + j``). As in the stream's window mode
(:mod:`imugen.stream.windows`), the slow states at sample ``k0 - 1`` are drawn from their exact
law there (GM ``N(0, x0^2 phi^(2m) + sigma^2 (1 - phi^(2m)))``, random walk
``N(0, K^2 m dt)``, ``m = k0 - 1``; quantization residuals uniform), so a batch of windows
has the law of windows cut from whole sequences. Statistically the same as the NumPy path (its
tests compare closed forms and Allan deviations), not bit for bit: the normals come from
``torch.randn`` and the recursions are evaluated as scans.

Recursions as scans: the GM state ``x_j = phi x_{j-1} + d xi_j`` is evaluated per block of
at most ``10 T_min / dt`` samples as ``phi^(j+1) x_start + phi^j cumsum(phi^-i d xi_i)`` (the
weights stay below ``e^10``), the random walk as a cumulative sum, and quantization with
residual carry exactly as the difference of the quantized cumulative sum
(``out_k = Q_k - Q_{k-1}``, ``Q_k = q floor((r0 + sum_{i<=k} y_i) / q + 1/2)``, which is what the
carry computes). Scans and sums run in float64; the outputs are ``dtype``.

torch is imported when this module is imported: import it only where torch is installed.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from imugen.sensors.model import SensorParams

_FIELDS = ("b_on", "bi_x0", "bi_sigma", "bi_tau", "white", "rrw", "sf", "cc", "gs")


class TorchSensor:
    """One sensor triad's drawn parameters for ``S`` windows, as tensors on a device.

    Parameters
    ----------
    params : SensorParams
        Leading axis ``S`` (:meth:`SensorParams.stack` of per-sequence draws).
    dt : float
        Sample interval [s].
    device : torch device, optional
    dtype : torch dtype
        Of the outputs (float32 default; scans in float64).
    band : OutputFilter, optional
        The sensor's output bandwidth read at ``1 / dt`` (module docstring).
    """

    def __init__(self, params: SensorParams, dt: float, device=None, dtype=torch.float32,
                 band=None):  # fmt: skip
        self.q_round = bool(getattr(params, "q_round", False))
        self.band = band
        self.dt = float(dt)
        self.device = torch.device(device) if device is not None else torch.device("cpu")
        self.dtype = dtype
        f64 = torch.float64
        for name in _FIELDS:
            setattr(self, name, torch.as_tensor(np.asarray(getattr(params, name)), dtype=f64,
                                                device=self.device))  # fmt: skip
        self.S = self.b_on.shape[0]
        self.lsb = float(params.lsb)
        self.full_scale = float(params.full_scale)
        self.phi = torch.exp(-self.dt / self.bi_tau)  # (S, C)
        self.drv = self.bi_sigma * torch.sqrt(-torch.expm1(-2.0 * self.dt / self.bi_tau))[:, None]
        self.use_b = bool((self.bi_sigma > 0).any())
        self.use_r = bool((self.rrw > 0).any())
        self.use_w = bool((self.white > 0).any())
        self.E = self.cc + torch.diag_embed(self.sf)  # (S, 3, 3)
        if band is not None:
            if abs(band.output_rate_hz * self.dt - 1.0) > 1e-9:
                raise ValueError(f"band read at {band.output_rate_hz} Hz, not 1 / dt")
            h = np.asarray(band.impulse())
            h = torch.as_tensor(h / h.sum(), dtype=f64, device=self.device)  # unit DC gain
            self._h = h.flip(0)[None, None]  # conv1d kernel (1, 1, n): correlation with flipped h

    def _reads(self, L: int, generator):
        """Internal read indices ``(S, L)`` of rows ``0 .. L - 1`` and the read phases
        ``(S, 1)`` (uniform if the read is asynchronous, else 0)."""
        f = self.band
        k = torch.arange(L, dtype=torch.float64, device=self.device)
        if f.synchronous:
            ph = torch.zeros((self.S, 1), dtype=torch.float64, device=self.device)
            return (k * round(f.ratio)).to(torch.int64).expand(self.S, L), ph
        ph = torch.rand((self.S, 1), generator=generator, device=self.device, dtype=torch.float64)
        return torch.floor(k * f.ratio + ph).to(torch.int64), ph

    def _filter(self, x):
        """Causal filter of internal samples ``(N, n)`` (zero before the first): ``(N, n)``."""
        n = self._h.shape[-1]
        return torch.nn.functional.conv1d(torch.nn.functional.pad(x[:, None], (n - 1, 0)),
                                          self._h)[:, 0]  # fmt: skip

    def _band_noise(self, j, generator):
        """Filtered internal white noise read at ``j`` ``(S, L)``: ``(S, L, 3)``."""
        S, L = j.shape
        warm = self._h.shape[-1]
        n = int(j.max()) + 1 + warm
        z = self._randn((S * 3, n), generator)
        y = self._filter(z).reshape(S, 3, n)
        idx = (j + warm)[:, None, :].expand(S, 3, L)
        scale = self.white * math.sqrt(self.band.internal_rate_hz)  # (S, 3)
        return torch.gather(y, 2, idx).transpose(1, 2) * scale[:, None, :]

    def _band_motion(self, y, j, phase):
        """The signal ``y`` ``(S, L, 3)`` (output rows) interpolated to the internal grid,
        filtered (steady state on its first row) and read at ``j``: ``(S, L, 3)``."""
        S, L, _ = y.shape
        warm = self._h.shape[-1]
        D = self.band.ratio
        i = torch.arange(-warm, int(j.max()) + 1, device=self.device, dtype=torch.float64)
        pos = torch.clamp((i[None] - phase) / D, 0.0, float(L - 1))  # (S, n)
        i0 = torch.clamp(torch.floor(pos).to(torch.int64), max=L - 1)
        i1 = torch.clamp(i0 + 1, max=L - 1)
        fr = (pos - i0)[..., None]
        g0 = torch.gather(y, 1, i0[..., None].expand(-1, -1, 3))
        g1 = torch.gather(y, 1, i1[..., None].expand(-1, -1, 3))
        x = (g0 * (1.0 - fr) + g1 * fr).transpose(1, 2).reshape(S * 3, -1)
        yf = self._filter(x).reshape(S, 3, -1)
        idx = (j + warm)[:, None, :].expand(S, 3, L)
        return torch.gather(yf, 2, idx).transpose(1, 2)

    def _randn(self, shape, gen):
        return torch.randn(shape, generator=gen, device=self.device, dtype=torch.float64)

    def slow(self, L: int, k0=1, generator=None) -> torch.Tensor:
        """Slow bias at samples ``k0 - 1 .. k0 + L - 1``: ``(S, L + 1, 3)`` float64."""
        S, dt = self.S, self.dt
        k0 = torch.as_tensor(k0, dtype=torch.float64, device=self.device).expand(S)
        m = (k0 - 1.0)[:, None, None]  # (S, 1, 1)
        s = self.b_on[:, None, :].expand(S, L + 1, 3).clone()
        if self.use_b:
            C = self.bi_sigma.shape[2]
            phi = self.phi[:, None, :]  # (S, 1, C)
            f2 = phi ** (2.0 * m)
            sd0 = torch.sqrt(self.bi_x0**2 * f2 + self.bi_sigma**2 * (1.0 - f2))  # (S, 3, C)
            x = sd0 * self._randn((S, 3, C), generator)
            xs = [x]
            z = self._randn((S, 3, C, L), generator) * self.drv[..., None]
            Tmin = float(self.bi_tau.min())
            Lb = max(1, min(L, int(10.0 * Tmin / dt)))
            for b0 in range(0, L, Lb):
                n = min(Lb, L - b0)
                i = torch.arange(n, dtype=torch.float64, device=self.device)
                lp = torch.log(self.phi)[:, None, :, None]  # (S, 1, C, 1)
                acc = torch.cumsum(torch.exp(-i * lp) * z[..., b0 : b0 + n], dim=-1)
                blk = torch.exp((i + 1) * lp) * x[..., None] + torch.exp(i * lp) * acc
                xs.append(blk)
                x = blk[..., -1]
            xa = torch.cat([xs[0][..., None], *xs[1:]], dim=-1)  # (S, 3, C, L + 1)
            s = s + xa.sum(dim=2).transpose(1, 2)
        if self.use_r:
            r0 = self.rrw[:, None, :] * torch.sqrt(dt * m) * self._randn((S, 1, 3), generator)
            steps = self.rrw[:, None, :] * math.sqrt(dt) * self._randn((S, L, 3), generator)
            r = torch.cat([r0, r0 + torch.cumsum(steps, dim=1)], dim=1)
            s = s + r
        return s

    def apply(self, u=None, du=None, a=None, da=None, *, k0=1, generator=None,
              outputs=("inc",)) -> dict:  # fmt: skip
        """Measured windows of ideal signals.

        Parameters
        ----------
        u, du : tensor (S, L, 3) or (L, 3), optional
            True rate at each sample and true increment of the interval ending at it (give
            ``u`` for rate outputs, ``du`` for increment outputs).
        a, da : tensor, optional
            Specific force and its increment (gyro g-sensitivity).
        k0 : int or (S,) tensor
            Sample index of each window's first row (``>= 1``).
        generator : torch.Generator, optional
            On the device.
        outputs : iterable of {"rate", "inc", "err_rate", "err_inc", "bias"}

        Returns
        -------
        dict name -> (S, L, 3) tensor of ``dtype``
        """
        outputs = set(outputs)
        ref = u if u is not None else du
        L = ref.shape[-2]
        dt, S = self.dt, self.S

        def f64(t):
            return None if t is None else t.to(self.device, torch.float64).expand(S, L, 3)

        u, du, a, da = f64(u), f64(du), f64(a), f64(da)
        s = self.slow(L, k0, generator)
        band = self.band is not None
        w = None
        if self.use_w and not band:
            w = self._randn((S, L, 3), generator) * self.white[:, None, :]
        if band:
            j, phase = self._reads(L, generator)
            nz = self._band_noise(j, generator) if self.use_w else None
        use_g = bool((self.gs != 0).any()) and a is not None
        out = {}
        if "bias" in outputs:
            out["bias"] = s[:, 1:].to(self.dtype)
        q_u = self._randn((S, 2, 3), generator) if self.lsb > 0 else None
        for kind, x, g, q, fs in (
            ("rate", u, a, self.lsb, self.full_scale),
            ("inc", du, da, self.lsb * dt, self.full_scale * dt),
        ):
            if kind not in outputs and f"err_{kind}" not in outputs:
                continue
            e = torch.einsum("sij,slj->sli", self.E, x)
            if use_g:
                e = e + torch.einsum("sij,slj->sli", self.gs, g)
            e = e + (s[:, 1:] if kind == "rate" else 0.5 * dt * (s[:, :-1] + s[:, 1:]))
            y = x + e
            if band:  # filter the sensed signal (increments as mean rates), then add its noise
                y = (self._band_motion(y / dt, j, phase) * dt if kind == "inc"
                     else self._band_motion(y, j, phase))  # fmt: skip
                e = y - x
                if nz is not None:
                    y = y + (nz if kind == "rate" else nz * dt)
            if w is not None:
                y = y + (w / math.sqrt(dt) if kind == "rate" else w * math.sqrt(dt))
            c = torch.clamp(y, -fs, fs) if math.isfinite(fs) else y
            if f"err_{kind}" in outputs:
                out[f"err_{kind}"] = (e + (c - y)).to(self.dtype)
            if kind in outputs:
                if q > 0 and self.q_round:
                    c = q * torch.floor(c / q + 0.5)
                elif q > 0:
                    z = q_u[:, 0 if kind == "rate" else 1][:, None, :]
                    r0 = (0.5 * torch.erfc(-z / math.sqrt(2.0)) - 0.5) * q
                    Q = q * torch.floor((r0 + torch.cumsum(c, dim=1)) / q + 0.5)
                    c = torch.diff(Q, dim=1, prepend=torch.zeros_like(Q[:, :1]))
                out[kind] = c.to(self.dtype)
        return out


def imu(gyro: TorchSensor, accel: TorchSensor, dtheta, dv, omega=None, f=None, *, k0=1,
        generator=None, outputs=("inc",)) -> dict:  # fmt: skip
    """Both triads on ideal IMU windows: ``{name: (S, L, 6)}`` (gyro columns, then accel).

    ``dtheta, dv`` (and ``omega, f`` for rate outputs) are ``(S, L, 3)`` or ``(L, 3)``.
    """
    og = gyro.apply(omega, dtheta, f, dv, k0=k0, generator=generator, outputs=outputs)
    oa = accel.apply(f, dv, k0=k0, generator=generator, outputs=outputs)
    return {n: torch.cat([og[n], oa[n]], dim=-1) for n in og}
