"""The sensor error model as a batched PyTorch function, on CPU or CUDA (the ``torch`` extra).

The same model as :mod:`imugen.sensors.model` (its docstring states the equations), applied to
a batch of ``S`` windows of ideal signals at once, each window with its own drawn parameters
(:class:`imugen.sensors.model.SensorParams`, e.g. from :func:`imugen.sensors.model.draw_sensor`
or the stream): turn-on bias, Gauss-Markov bias instability (one component, or several for
flicker), rate random walk, scale factor and cross-coupling (misalignment), g-sensitivity
(gyro), white noise, saturation and quantization with residual carry. Not here: temperature
terms, a sensor's output bandwidth and rounding quantization (``bandwidth``,
``quantization.mode: round`` of a grade: the measured presets ``adis16405``, ``phone``; use the
NumPy path, :class:`imugen.sensors.model.SensorModel`, for them).

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
    """

    def __init__(self, params: SensorParams, dt: float, device=None, dtype=torch.float32):
        if getattr(params, "q_round", False):
            raise ValueError("rounding quantization is not on the torch path (use the NumPy one)")
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
        w = self._randn((S, L, 3), generator) * self.white[:, None, :] if self.use_w else None
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
            if w is not None:
                y = y + (w / math.sqrt(dt) if kind == "rate" else w * math.sqrt(dt))
            c = torch.clamp(y, -fs, fs) if math.isfinite(fs) else y
            if f"err_{kind}" in outputs:
                out[f"err_{kind}"] = (e + (c - y)).to(self.dtype)
            if kind in outputs:
                if q > 0:
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
