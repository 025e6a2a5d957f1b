"""The vertical channel of the strapdown: free, or damped by a reference height (issue #27).

Free channel. Above a rotating Earth gravity weakens with height, so a height error ``dh``
feeds itself: ``dh'' = Gamma dh + da``, ``Gamma = -d|g|/dh`` (the normal free-air gradient,
3.086e-6 s^-2 at 45 deg, h = 0). Linearized,

    ``dh(t) = dh0 cosh(t/tau) + tau dv0 sinh(t/tau) + tau^2 da (cosh(t/tau) - 1)``,

``tau = 1/sqrt(Gamma)`` = 569-570 s (:func:`growth_time_s`): any seed (float64 rounding, the
discretization of the first minutes, a 1 ug bias) grows as ``exp(t / 570 s)``, x10 over
``3 tau`` and x1e14 over 5 h; through Coriolis the Schuler loop answers with a horizontal error
``(4/3) Omega tau cos(lat) dh`` (0.038 dh at 46 deg). Over hours the free solution leaves the
planet: a real INS never runs it (a barometer or another height source damps it). In ``flat``
gravity is constant and the free channel neutral (``Gamma = 0``).

Damped channel. The classic height-aided loop (Widnall & Sinha, J. Guidance & Control 3(2),
1980; the baro-inertial loop of navigation-grade INS), with ``dh = h - h_ref`` and ``u`` the local
geodetic up at the vehicle:

    ``dp/dt = v - k1 dh u``,  ``dv/dt = C_nb f + G (+ Coriolis) - (k2 dh + b) u``,
    ``db/dt = k3 dh``.

Error dynamics ``s^3 + k1 s^2 + (k2 - Gamma) s + k3 = 0``; the gains place every pole at
``-1/tau_v`` (:func:`loop_gains`): third order ``k1 = 3/tau_v``, ``k2 = 3/tau_v^2 + Gamma``,
``k3 = 1/tau_v^3`` (a steady accelerometer bias is absorbed by ``b``; no steady height error),
second order ``k1 = 2/tau_v``, ``k2 = 1/tau_v^2 + Gamma``, ``k3 = 0`` (steady error
``da tau_v^2``). Default: third order, ``tau_v = 100 s`` (0.03 1/s, 3.03e-4 1/s^2, 1e-6 1/s^3).
The kernel (:func:`imugen.navigate._kernel.kernel`) applies the loop as impulses at every
gravitation node (``T = m dt``, 0.2 s; every step in ``flat``), from the reference height of
that sample; attitude is untouched.

Rule (``auto``): damped when the route's duration exceeds :data:`AUTO_FACTOR` growth times
(``3 x 570 s = 1,710 s``, where ``cosh(3) = 10``) on a rotating Earth; free otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imugen.core import earth
from imugen.core.earth import OriginFrame

MODES = ("auto", "free", "damped")
REFERENCES = ("truth",)
"""Reference height sources: ``truth`` (the true height of the vehicle: an ideal height
sensor; the vertical error then isolates the loop, the horizontal the IMU)."""
AUTO_FACTOR = 3.0
"""``auto`` damps routes longer than this many growth times (module docstring)."""
TIME_CONSTANT_S = 100.0
"""Default time constant of the damped loop (every pole at -1/100 s)."""
ORDER = 3
"""Default loop order."""
SCHULER_RATIO = 4.0 / 3.0
"""Horizontal/vertical error ratio of the free channel, ``(4/3) Omega tau cos(lat)``."""


def gravity_gradient_up(lat_rad: float, h_m: float) -> float:
    """``Gamma = -d|g|/dh`` [1/s^2] of WGS-84 normal gravity (central difference over +-1 m)."""
    g = earth.normal_gravity(np.array([lat_rad, lat_rad]), np.array([h_m - 1.0, h_m + 1.0]))
    return float((g[0] - g[1]) / 2.0)


def growth_time_s(lat_rad: float, h_m: float) -> float:
    """Growth time of the free vertical channel ``1/sqrt(Gamma)`` [s] (569-570 s near ground)."""
    return 1.0 / math.sqrt(gravity_gradient_up(lat_rad, h_m))


def loop_gains(tau_s: float, order: int = ORDER, gamma_up: float = 0.0) -> np.ndarray:
    """Gains ``(k1 [1/s], k2 [1/s^2], k3 [1/s^3])`` placing every pole of the damped channel
    at ``s = -1/tau_s``: ``s^3 + k1 s^2 + (k2 - gamma_up) s + k3 = (s + 1/tau_s)^3`` (order 3),
    ``s^2 + k1 s + (k2 - gamma_up) = (s + 1/tau_s)^2`` (order 2, ``k3 = 0``)."""
    if not tau_s > 0:
        raise ValueError(f"the loop's time constant must be > 0 s, got {tau_s}")
    w = 1.0 / float(tau_s)
    if order == 3:
        return np.array([3.0 * w, 3.0 * w * w + gamma_up, w**3])
    if order == 2:
        return np.array([2.0 * w, w * w + gamma_up, 0.0])
    raise ValueError(f"the loop's order must be 2 or 3, got {order}")


@dataclass(frozen=True)
class VerticalChannel:
    """The vertical channel a navigation run uses (:func:`resolve`), and why.

    Attributes
    ----------
    mode : {"free", "damped"}
    requested : {"auto", "free", "damped"}
    order : int
    time_constant_s : float
    gains : tuple of float
        ``(k1, k2, k3)``; zeros when free.
    reference : str
        Source of the reference height of the damped loop (unused when free).
    growth_time_s : float
        Growth time of the free channel at the scene (inf in ``flat``).
    duration_s : float
    """

    mode: str
    requested: str
    order: int
    time_constant_s: float
    gains: tuple
    reference: str
    growth_time_s: float
    duration_s: float

    @property
    def damped(self) -> bool:
        return self.mode == "damped"

    @property
    def growth_factor(self) -> float:
        """``cosh(D / tau)`` of the free channel over the route (inf when it overflows)."""
        x = self.duration_s / self.growth_time_s
        return math.cosh(x) if x < 700 else math.inf

    def kernel_gains(self) -> np.ndarray:
        return np.array(self.gains if self.damped else (0.0, 0.0, 0.0), dtype=float)

    def meta(self) -> dict:
        """JSON-ready record for the tables' metadata (``vertical_channel``; inf -> None)."""
        return _finite(
            {
                "mode": self.mode,
                "requested": self.requested,
                "order": self.order if self.damped else None,
                "time_constant_s": self.time_constant_s if self.damped else None,
                "gains": list(self.gains) if self.damped else None,
                "reference": self.reference,
                "growth_time_s": self.growth_time_s,
                "growth_factor": self.growth_factor,
                "duration_s": self.duration_s,
                "rule": self.why(),
            }
        )

    def why(self) -> str:
        """The rule and how it decided for this scene (one line, for the metadata)."""
        rule = f"auto: damped when duration > {AUTO_FACTOR:g} x growth time on a rotating Earth"
        D = self.duration_s
        if not math.isfinite(self.growth_time_s):
            case = "flat Earth: constant gravity, the free channel is neutral, not unstable"
        else:
            lim = AUTO_FACTOR * self.growth_time_s
            cmp = ">" if D > lim else "<="
            case = (
                f"{D:,.0f} s {cmp} {lim:,.0f} s = {AUTO_FACTOR:g} x {self.growth_time_s:.0f} s; "
                f"free, a height error grows x{self.growth_factor:.3g} over the route"
            )
        if self.requested != "auto":
            return f"{self.requested}, as requested ({rule}; here {case})"
        return f"{rule}: {self.mode} ({case})"


def _finite(d: dict) -> dict:
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}


def resolve(
    mode: str,
    frame: OriginFrame,
    duration_s: float,
    *,
    order: int = ORDER,
    time_constant_s: float = TIME_CONSTANT_S,
    reference: str = "truth",
) -> VerticalChannel:
    """The vertical channel for a scene: ``auto`` -> damped when ``duration_s`` exceeds
    :data:`AUTO_FACTOR` growth times on a rotating Earth (``wgs84``, ``geodetic``), else free.

    Parameters
    ----------
    mode : {"auto", "free", "damped"}
    frame : OriginFrame
        The scene's origin (growth time at its latitude and height) and Earth model.
    duration_s : float
        Duration of the navigated span [s].
    order, time_constant_s, reference
        The damped loop's (:func:`loop_gains`, :data:`REFERENCES`).
    """
    if mode not in MODES:
        raise ValueError(f"vertical channel must be one of {MODES}, got {mode!r}")
    if reference not in REFERENCES:
        raise ValueError(f"reference height must be one of {REFERENCES}, got {reference!r}")
    flat = frame.model == "flat"
    gamma = 0.0 if flat else gravity_gradient_up(frame.lat0_rad, frame.h0_m)
    tau = math.inf if flat else 1.0 / math.sqrt(gamma)
    if mode == "auto":
        damped = (not flat) and duration_s > AUTO_FACTOR * tau
    else:
        damped = mode == "damped"
    gains = tuple(float(x) for x in loop_gains(time_constant_s, order, gamma))
    return VerticalChannel(
        mode="damped" if damped else "free",
        requested=mode,
        order=int(order),
        time_constant_s=float(time_constant_s),
        gains=gains,
        reference=reference,
        growth_time_s=tau,
        duration_s=float(duration_s),
    )


@dataclass(frozen=True)
class VerticalSpec:
    """What a user asked for (the ``navigate.vertical`` options), before the scene is known."""

    mode: str = "auto"
    order: int = ORDER
    time_constant_s: float = TIME_CONSTANT_S
    reference: str = "truth"

    @classmethod
    def of(cls, options) -> VerticalSpec:
        """From an options object with ``vertical``, ``vertical_order``,
        ``vertical_time_constant_s``, ``vertical_reference`` (the navigate command's)."""
        return cls(
            options.vertical,
            int(options.vertical_order),
            float(options.vertical_time_constant_s),
            options.vertical_reference,
        )

    def resolve(self, frame: OriginFrame, duration_s: float) -> VerticalChannel:
        """:func:`resolve` for a scene."""
        return resolve(
            self.mode,
            frame,
            duration_s,
            order=self.order,
            time_constant_s=self.time_constant_s,
            reference=self.reference,
        )


def free_growth(dh_m: float, dv_mps: float, t_from_s: float, t_to_s: float, tau_s: float) -> float:
    """Linearized free vertical error at ``t_to_s`` from the error ``dh_m`` and its rate
    ``dv_mps`` at ``t_from_s``: ``dh cosh(x) + tau dv sinh(x)``, ``x = (t_to - t_from) / tau``
    (no bias term: the error-free IMU of a closure). Magnitude [m]; inf beyond float range."""
    x = (t_to_s - t_from_s) / tau_s
    if x > 700:
        return math.inf
    return abs(dh_m * math.cosh(x) + tau_s * dv_mps * math.sinh(x))


def meaningless_reason(vc: dict | None) -> str:
    """Why free-inertial figures may be meaningless, from a ``vertical_channel`` record."""
    if not vc or vc.get("mode") != "free" or not vc.get("growth_time_s"):
        return ""
    tau = float(vc["growth_time_s"])
    D = float(vc.get("duration_s", 0.0))
    factor = vc.get("growth_factor") or math.inf
    lin = tau**2 * 9.80665e-6 * (factor - 1.0)
    return (
        f"the unaided vertical channel grows as cosh(t / {tau:.0f} s), x{factor:.3g} over this "
        f"{D:,.0f} s route (a 1 ug accelerometer bias alone: {lin:.3g} m, linearized); "
        f"navigate.vertical: damped (the default beyond {AUTO_FACTOR * tau:,.0f} s) bounds it"
    )
