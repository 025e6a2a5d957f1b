"""GNSS receiver model: truth arrays -> position and velocity fixes at the antenna, per sequence.

Epochs
------
A receiver at ``rate_hz`` (1-10 Hz) delivers epoch ``j`` at IMU sample ``k_j = j * step``
(``step = imu_rate / rate_hz``, an integer), i.e. at ``time_s = t_{k_j}``. The fix describes the
antenna at the *time of validity* ``t_j - latency`` (the fix is late by the latency; epochs whose
time of validity precedes the first truth sample carry no fix). Truth at the time of validity:
position by cubic Hermite interpolation of ``(p_n, v_n)``, velocity and rate linearly,
attitude of the preceding sample rotated by the interpolated rate.

Antenna (lever arm ``l_b`` in the body frame, metres)
    ``p_ant = p_n + C_nb l_b``, ``v_ant = v_n + C_nb (omega_eb_b x l_b)`` with
    ``omega_eb_b = omega_ib_b - C_nb^T omega_ie_n`` (Earth rate 0 in ``flat``).

Errors (per axis of the local level at the antenna; East and North use the horizontal
figures, Up the vertical ones)
    ``p_meas = p_ant + b_j + w_j``: white ``w ~ N(0, s_w^2)`` plus a first-order Gauss-Markov
    bias with exact discretization ``b_{j+1} = phi b_j + s_b sqrt(1 - phi^2) xi``,
    ``phi = exp(-T / tau)``, started from its stationary law ``b_0 ~ N(0, s_b^2)``;
    ``v_meas = v_ant + u_j``, ``u ~ N(0, s_v^2)``. The receiver reports the 1-sigma per axis
    ``sqrt(s_w^2 + s_b^2)`` (horizontal, vertical) and ``s_v`` (velocity), and the GGA fix
    quality of its preset (0 where no fix). In ``flat`` and ``wgs84`` the local level is taken
    as the origin's ENU axes (n itself, within the Earth budget's tilt); in ``geodetic`` (n =
    ECEF) the errors are drawn along East, North, Up at the true antenna position and rotated
    to n, ``e_n = C_ln^T e_l``, so the reported sigmas stay per local-level axis (what the
    aided filter rotates back, :mod:`imugen.aid.filter.gnss`).

Randomness
----------
Sequence ``j`` of a shard draws from ``SeedSequence(seed, spawn_key=(GNSS_KEY, receiver_id,
shard, j, stream))`` (:func:`imugen.core.seeding.gnss_rng`): its parameters and, separately, each noise. So the
GNSS of a sequence does not depend on the IMU grade, on the number of shards or on the other
sequences, and the same seed gives every grade the same GNSS errors (common random numbers
when grades are compared). Parameters: each figure log-uniform in its preset range (one
uniform per figure, shared by the axes), the lever arm ``l_b = nominal + N(0, s_l^2)`` per axis.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from importlib import resources
from types import MappingProxyType

import numpy as np
import pandas as pd
import yaml
from scipy.signal import lfilter

from imugen.core.errors import InputError
from imugen.core.seeding import gnss_rng

PRESET_FILE = "gnss.yaml"
FIX_NONE = 0
"""GGA quality of an epoch without a fix."""
FIGURES = (
    "position_white_h_m",
    "position_white_v_m",
    "position_bias_h_m",
    "position_bias_v_m",
    "position_bias_tau_s",
    "velocity_white_h_mps",
    "velocity_white_v_mps",
    "latency_s",
)
"""Figures of a receiver preset (SI units in the names), in draw order."""


@dataclass(frozen=True)
class Figure:
    """Nominal value and optional draw range ``[lo, hi]`` of one receiver figure (SI)."""

    value: float
    lo: float | None = None
    hi: float | None = None

    def draw(self, u: float, nominal: bool) -> float:
        """Nominal, or log-uniform in the range from the uniform ``u`` (uniform if ``lo == 0``)."""
        if nominal or self.lo is None:
            return self.value
        if self.lo == 0.0:
            return self.hi * u
        return self.lo * (self.hi / self.lo) ** u


@dataclass(frozen=True)
class Receiver:
    """A receiver preset (see ``imugen/data/gnss.yaml``)."""

    name: str
    id: int
    description: str
    source: str
    fix_quality: int
    rate_hz: float
    figures: MappingProxyType


def parse_figure(entry, where) -> Figure:
    """A preset figure: a number, or ``{value: x, range: [lo, hi]}`` (``where`` names it in
    errors); receivers and companion sensors share the form."""
    if isinstance(entry, int | float) and not isinstance(entry, bool):
        entry = {"value": entry}
    if not isinstance(entry, dict) or "value" not in entry:
        raise InputError(where, "expected a number or {value: x, range: [lo, hi]}")
    try:
        v = float(entry["value"])
        rng = entry.get("range")
        lo, hi = (None, None) if rng is None else (float(rng[0]), float(rng[1]))
    except (TypeError, ValueError, IndexError, KeyError):
        raise InputError(where, "value and range must be numbers") from None
    if not (math.isfinite(v) and v >= 0.0):
        raise InputError(where, f"value must be finite and >= 0, got {v}")
    if lo is not None and not (0.0 <= lo <= hi and math.isfinite(hi)):
        raise InputError(where, f"range must be 0 <= lo <= hi, got [{lo}, {hi}]")
    return Figure(v, lo, hi)


def receiver_from_config(name: str, cfg: dict, origin: str = "<config>") -> Receiver:
    """Build a :class:`Receiver` from a mapping of the preset file's layout."""
    where = f"{origin}: receiver {name!r}"
    if not isinstance(cfg, dict):
        raise InputError(where, "expected a mapping")
    miss = [k for k in ("id", *FIGURES) if k not in cfg]
    if miss:
        raise InputError(where, f"missing {', '.join(miss)}")
    figs = {k: parse_figure(cfg[k], f"{where}.{k}") for k in FIGURES}
    if figs["position_bias_tau_s"].value <= 0 or (figs["position_bias_tau_s"].lo or 1) <= 0:
        raise InputError(where, "position_bias_tau_s must be > 0")
    rate = float(cfg.get("rate_hz", 10.0))
    if not (0.0 < rate <= 100.0):
        raise InputError(where, f"rate_hz must be in (0, 100], got {rate}")
    return Receiver(
        name,
        int(cfg["id"]),
        str(cfg.get("description", "")),
        str(cfg.get("source", "")),
        int(cfg.get("fix_quality", 1)),
        rate,
        MappingProxyType(figs),
    )


@functools.lru_cache(maxsize=1)
def _presets() -> MappingProxyType:
    text = (resources.files("imugen") / "data" / PRESET_FILE).read_text(encoding="utf-8")
    doc = yaml.safe_load(text)
    origin = f"imugen/data/{PRESET_FILE}"
    return MappingProxyType(
        {n: receiver_from_config(n, c, origin) for n, c in doc["receivers"].items()}
    )


def presets() -> MappingProxyType:
    """The shipped receiver presets by name (``phone``, ``standalone``, ``sbas``, ``rtk``)."""
    return _presets()


def get_receiver(spec) -> Receiver:
    """A :class:`Receiver` from a preset name or a Receiver."""
    if isinstance(spec, Receiver):
        return spec
    p = presets()
    if spec not in p:
        raise InputError("gnss.receiver", f"unknown receiver {spec!r}; presets: {', '.join(p)}")
    return p[spec]


# --- per-sequence parameters --------------------------------------------------------------------
@dataclass
class ReceiverParams:
    """Drawn receiver parameters of ``M`` sequences (SI; each field an array with leading M).

    ``lever_arm_b_m`` is (M, 3); every other field is (M,) and named like the preset figures.
    """

    position_white_h_m: np.ndarray
    position_white_v_m: np.ndarray
    position_bias_h_m: np.ndarray
    position_bias_v_m: np.ndarray
    position_bias_tau_s: np.ndarray
    velocity_white_h_mps: np.ndarray
    velocity_white_v_mps: np.ndarray
    latency_s: np.ndarray
    lever_arm_b_m: np.ndarray

    def axis(self, h: str, v: str) -> np.ndarray:
        """Per-axis (E, N, U) sigmas ``(M, 3)`` from a horizontal and a vertical field."""
        a, b = getattr(self, h), getattr(self, v)
        return np.stack([a, a, b], axis=-1)

    def labels(self) -> dict[str, np.ndarray]:
        """Label columns ``{gnss_<figure>: (M,)}`` plus ``gnss_lever_arm_{x,y,z}_m``."""
        out = {f"gnss_{k}": getattr(self, k) for k in FIGURES}
        for i, a in enumerate("xyz"):
            out[f"gnss_lever_arm_{a}_m"] = self.lever_arm_b_m[:, i]
        return out


def draw_params(
    rec: Receiver, seed, shard, ids, *, nominal=False, lever_arm_b_m=(0.0, 0.0, 0.0), lever_sd_m=0.0
) -> ReceiverParams:
    """Draw the parameters of sequences ``ids`` (indices within the shard).

    Every sequence consumes ``len(FIGURES)`` uniforms then 3 normals of its ``params``
    stream, whatever is nominal, so each figure's draw never depends on the others.
    """
    vals = {k: [] for k in FIGURES}
    lever = []
    la = np.asarray(lever_arm_b_m, float).reshape(3)
    for j in ids:
        rng = gnss_rng(seed, rec.id, shard, int(j), "params")
        u = rng.random(len(FIGURES))
        z = rng.standard_normal(3)
        for i, k in enumerate(FIGURES):
            vals[k].append(rec.figures[k].draw(u[i], nominal))
        lever.append(la + float(lever_sd_m) * z)
    return ReceiverParams(
        **{k: np.asarray(v, float) for k, v in vals.items()},
        lever_arm_b_m=np.asarray(lever, float).reshape(-1, 3),
    )


# --- truth at the time of validity --------------------------------------------------------------
def _truth_at(time_s, p_n, v_n, q_nb, omega, t):
    """Interpolate truth at times ``t`` (inside the grid): p (Hermite), v, omega (linear), C."""
    from imugen.core.rotations import exp_dcm, quat_to_dcm

    dt = (time_s[-1] - time_s[0]) / (len(time_s) - 1)
    x = (t - time_s[0]) / dt
    i = np.clip(np.floor(x + 1e-9).astype(int), 0, len(time_s) - 2)
    s = np.clip(x - i, 0.0, 1.0)[:, None]
    p0, p1, v0, v1 = p_n[i], p_n[i + 1], v_n[i], v_n[i + 1]
    h00 = 2 * s**3 - 3 * s**2 + 1
    h10 = s**3 - 2 * s**2 + s
    h01 = -2 * s**3 + 3 * s**2
    h11 = s**3 - s**2
    p = h00 * p0 + h10 * dt * v0 + h01 * p1 + h11 * dt * v1
    v = (1 - s) * v0 + s * v1
    w = (1 - s) * omega[i] + s * omega[i + 1]
    C = quat_to_dcm(q_nb[i]) @ exp_dcm(0.5 * (omega[i] + w) * (s * dt))
    return p, v, w, C


@dataclass
class GnssData:
    """GNSS epochs of ``M`` sequences (arrays; ``J`` epochs).

    Attributes
    ----------
    time_s : (J,)           arrival time of each epoch (an IMU sample time) [s]
    index : (J,)            IMU sample index of each epoch
    p_n, v_n : (M, J, 3)    measured antenna position [m] / velocity [m/s] in n (NaN: no fix)
    p_ant_n, v_ant_n : (M, J, 3)  true antenna position / velocity at the time of validity
    bias_n : (M, J, 3)      true Gauss-Markov position bias [m]
    offset_p_n, offset_v_n : (M, J, 3)  true total error ``measured - true`` at validity
    sigma_p_n : (M, J, 3)   reported 1-sigma of the position per local-level axis (E, N, U at
                            the antenna; the n axes in flat/wgs84) [m]
    sigma_v_n : (M, J, 3)   reported 1-sigma of the velocity, likewise [m/s]
    fix : (M, J) int8       GGA fix quality (0: no fix)
    params : ReceiverParams
    receiver : Receiver
    labels : DataFrame      one row per sequence (drawn parameters)
    """

    time_s: np.ndarray
    index: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    p_ant_n: np.ndarray
    v_ant_n: np.ndarray
    bias_n: np.ndarray
    offset_p_n: np.ndarray
    offset_v_n: np.ndarray
    sigma_p_n: np.ndarray
    sigma_v_n: np.ndarray
    fix: np.ndarray
    params: ReceiverParams
    receiver: Receiver
    labels: pd.DataFrame

    @property
    def valid(self) -> np.ndarray:
        """(M, J) bool: the epoch carries a fix."""
        return self.fix != FIX_NONE


def epoch_step(imu_rate_hz: float, rate_hz: float) -> int:
    """IMU samples per GNSS epoch; the IMU rate must be an integer multiple of the GNSS rate."""
    r = imu_rate_hz / rate_hz
    step = round(r)
    if step < 1 or abs(r - step) > 1e-6 * r:
        raise InputError(
            "gnss.rate_hz",
            f"the IMU rate {imu_rate_hz:g} Hz must be an integer multiple of {rate_hz:g} Hz",
        )
    return int(step)


def simulate_gnss(
    time_s,
    p_n,
    v_n,
    q_nb,
    omega_ib_b,
    receiver="standalone",
    sequences=1,
    seed=0,
    shard=0,
    *,
    rate_hz=None,
    draw="ranges",
    lever_arm_b_m=(0.0, 0.0, 0.0),
    lever_sd_m=0.0,
    omega_ie_n=(0.0, 0.0, 0.0),
    first=None,
    frame=None,
) -> GnssData:
    """GNSS fixes of ``sequences`` sequences sharing one truth.

    Parameters
    ----------
    time_s : ndarray, shape (K,)
        Uniform IMU time grid [s].
    p_n, v_n : ndarray, shape (K, 3)
        True position [m] and velocity [m/s] of the IMU in n (ENU of the route origin, or
        ECEF in ``geodetic``).
    q_nb : ndarray, shape (K, 4)
        True attitude (scalar first).
    omega_ib_b : ndarray, shape (K, 3)
        True angular rate [rad/s].
    receiver : str or Receiver
        Preset name (``phone``, ``standalone``, ``sbas``, ``rtk``) or a Receiver.
    sequences, seed, shard : int
        ``M`` sequences (indices ``0..M-1`` of the shard), root seed, shard.
    rate_hz : float, optional
        Epoch rate (default: the preset's).
    draw : {"ranges", "nominal"}
    lever_arm_b_m : (3,)
        Nominal antenna lever arm in the body frame [m]; ``lever_sd_m`` its per-axis spread.
    omega_ie_n : (3,)
        Earth rate in n (:func:`imugen.core.earth.earth_rate_n`; zeros in ``flat``).
    first : int, optional
        Global id of the first sequence (labels; default ``shard * sequences``).
    frame : OriginFrame, optional
        The truth's frame; in ``geodetic`` the errors are drawn in the local level at the
        antenna and rotated to n (otherwise, and by default, n is the local level).
    """
    rec = get_receiver(receiver)
    if draw not in ("ranges", "nominal"):
        raise InputError("gnss.draw", f"must be ranges or nominal, got {draw!r}")
    t = np.asarray(time_s, float)
    K = len(t)
    if K < 2:
        raise InputError("gnss", "truth needs at least 2 samples")
    imu_rate = (K - 1) / (t[-1] - t[0])
    rate = float(rate_hz or rec.rate_hz)
    if not (0.0 < rate <= 100.0):
        raise InputError("gnss.rate_hz", f"must be in (0, 100] Hz, got {rate}")
    step = epoch_step(imu_rate, rate)
    M = int(sequences)
    idx = np.arange(0, K, step)
    J = len(idx)
    par = draw_params(
        rec,
        seed,
        shard,
        range(M),
        nominal=draw == "nominal",
        lever_arm_b_m=lever_arm_b_m,
        lever_sd_m=lever_sd_m,
    )
    p_n, v_n = np.asarray(p_n, float), np.asarray(v_n, float)
    q_nb, omega = np.asarray(q_nb, float), np.asarray(omega_ib_b, float)
    Om = np.asarray(omega_ie_n, float).reshape(3)
    T = step / imu_rate
    geo = frame is not None and frame.model == "geodetic"
    shape = (M, J, 3)
    out = {k: np.full(shape, np.nan) for k in ("p", "v", "pa", "va", "b", "op", "ov")}
    sig_p = np.zeros(shape)
    sig_v = np.zeros(shape)
    fix = np.zeros((M, J), np.int8)
    for j in range(M):
        tv = t[idx] - par.latency_s[j]
        ok = tv >= t[0] - 1e-12
        pt, vt, wt, Ct = _truth_at(t, p_n, v_n, q_nb, omega, np.maximum(tv, t[0]))
        lb = par.lever_arm_b_m[j]
        w_eb = wt - np.einsum("jik,i->jk", Ct, Om)
        p_ant = pt + Ct @ lb
        v_ant = vt + np.einsum("jik,jk->ji", Ct, np.cross(w_eb, lb))
        s_w = par.axis("position_white_h_m", "position_white_v_m")[j]
        s_b = par.axis("position_bias_h_m", "position_bias_v_m")[j]
        s_u = par.axis("velocity_white_h_mps", "velocity_white_v_mps")[j]
        phi = math.exp(-T / par.position_bias_tau_s[j])
        zb = gnss_rng(seed, rec.id, shard, j, "position_bias").standard_normal((J, 3))
        x = s_b * math.sqrt(1.0 - phi * phi) * zb
        x[0] = s_b * zb[0]
        b = lfilter([1.0], [1.0, -phi], x, axis=0)
        w = s_w * gnss_rng(seed, rec.id, shard, j, "position_white").standard_normal((J, 3))
        u = s_u * gnss_rng(seed, rec.id, shard, j, "velocity_white").standard_normal((J, 3))
        if geo:  # drawn in the local level at the antenna: e_n = C_ln^T e_l
            C_ln = frame.C_ln(p_ant)
            b, w, u = (np.einsum("jki,jk->ji", C_ln, e) for e in (b, w, u))
        out["pa"][j], out["va"][j], out["b"][j] = p_ant, v_ant, b
        out["op"][j], out["ov"][j] = b + w, u
        out["p"][j] = np.where(ok[:, None], p_ant + b + w, np.nan)
        out["v"][j] = np.where(ok[:, None], v_ant + u, np.nan)
        sig_p[j] = np.sqrt(s_w**2 + s_b**2)
        sig_v[j] = s_u
        fix[j] = np.where(ok, rec.fix_quality, FIX_NONE)
    first = shard * M if first is None else int(first)
    lab = {
        "sequence": (first + np.arange(M)).astype(np.int64),
        "gnss_receiver_id": np.full(M, rec.id, np.int32),
        "gnss_rate_hz": np.full(M, rate),
        **par.labels(),
    }
    return GnssData(
        t[idx],
        idx,
        out["p"],
        out["v"],
        out["pa"],
        out["va"],
        out["b"],
        out["op"],
        out["ov"],
        sig_p,
        sig_v,
        fix,
        par,
        rec,
        pd.DataFrame(lab),
    )


def receiver_table() -> pd.DataFrame:
    """The presets as a table (nominal figures), for documentation."""
    rows = []
    for r in presets().values():
        row = {"receiver": r.name, "id": r.id, "rate_hz": r.rate_hz, "fix": r.fix_quality}
        row.update({k: r.figures[k].value for k in FIGURES})
        rows.append(row)
    return pd.DataFrame(rows)
