"""Companion sensors of vehicle navigation: odometer (wheel speed) and barometric altitude.

Odometer (preset in ``imugen/data/companions.yaml``, rate ``f_o``, epoch ``m`` at IMU sample
``k_m = m * step``, interval ``T_o = 1 / f_o``)
    The vehicle reference point sits at ``l_b`` (body frame, metres; default the truth's own
    point) and moves forward at ``u = e_x^T (C_nb^T v_n + omega_eb_b x l_b)`` (vehicle frame =
    body frame of the truth). Its true distance ``s(t)`` is the trapezoid integral of ``u`` on
    the IMU grid. The wheel counts ``N_m = floor(D_m / c)`` ticks of ``c = circumference_m /
    ticks_per_rev``, with ``D_m = (1 + k) s(t_m) + sum_{i <= m} s_w T_o xi_i + phi c``: scale
    factor ``k ~ N(0, s_k^2)`` per sequence (tyre radius), white speed noise ``s_w`` on every
    interval in which the vehicle moves (a wheel at rest emits no ticks), initial tick phase
    ``phi ~ U(0, 1)``. Epoch ``m >= 1`` outputs ``ticks = N_m - N_{m-1}`` (signed: a
    direction-aware sensor; negative only when reversing or crawling below the noise)
    and ``speed = ticks c / T_o``; its true value is the mean forward speed over the interval,
    ``(s(t_m) - s(t_{m-1})) / T_o``.

Barometer (rate ``f_b``)
    ``altitude = h + b_m + w_m``: ``h`` the true ellipsoidal height (``alt0 + p_u`` in ``flat``;
    geoid and weather ignored), ``b`` a first-order Gauss-Markov drift (stationary sigma
    ``s_b``, correlation time ``tau``, exact discretization, started from its stationary law),
    ``w ~ N(0, s_w^2)`` white.

Randomness
----------
Sequence ``j`` draws from ``SeedSequence(seed, spawn_key=(COMPANION_KEY, kind, sensor_id,
shard, j, stream))`` (:data:`KINDS`, :func:`imugen.core.seeding.companion_rng`); the aid stage passes ``seed = [root
seed, route id, index of the sequence in the route]`` and ``shard = j = 0``, as for the GNSS
receiver. So a draw depends on neither the grade (common random numbers across grades), nor
the shard size, nor the other sequences, nor the other companion sensor. Parameters: each
figure log-uniform in its preset range (one uniform per figure), then the scale factor's normal
and the tick phase's uniform.
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

from imugen.aid.gnss import epoch_step, parse_figure
from imugen.core.errors import InputError
from imugen.core.rotations import quat_to_dcm
from imugen.core.seeding import companion_rng

PRESET_FILE = "companions.yaml"
KINDS = {"odometer": 1, "barometer": 2}
"""Sensor kinds and their codes (spawn keys, the ``sensor`` column of the table)."""
ODO_FIGURES = ("scale_factor_sd", "white_mps")
BARO_FIGURES = ("white_m", "bias_sd_m", "bias_tau_s")


@dataclass(frozen=True)
class Sensor:
    """A companion preset (see ``imugen/data/companions.yaml``); ``ticks_per_rev`` and
    ``circumference_m`` are the odometer's (0 for a barometer)."""

    kind: str
    name: str
    id: int
    description: str
    source: str
    rate_hz: float
    figures: MappingProxyType
    ticks_per_rev: int = 0
    circumference_m: float = 0.0

    @property
    def tick_m(self) -> float:
        """Distance of one odometer tick [m]."""
        return self.circumference_m / self.ticks_per_rev


def sensor_from_config(kind: str, name: str, cfg: dict, origin: str = "<config>") -> Sensor:
    """Build a :class:`Sensor` of ``kind`` (odometer, barometer) from a preset-file mapping."""
    where = f"{origin}: {kind} {name!r}"
    if not isinstance(cfg, dict):
        raise InputError(where, "expected a mapping")
    figs = ODO_FIGURES if kind == "odometer" else BARO_FIGURES
    extra = ("ticks_per_rev", "circumference_m") if kind == "odometer" else ()
    miss = [k for k in ("id", "rate_hz", *figs, *extra) if k not in cfg]
    if miss:
        raise InputError(where, f"missing {', '.join(miss)}")
    f = {k: parse_figure(cfg[k], f"{where}.{k}") for k in figs}
    rate = float(cfg["rate_hz"])
    if not (0.0 < rate <= 1000.0):
        raise InputError(where, f"rate_hz must be in (0, 1000], got {rate}")
    tpr, circ = 0, 0.0
    if kind == "odometer":
        tpr, circ = int(cfg["ticks_per_rev"]), float(cfg["circumference_m"])
        if tpr < 1 or not circ > 0:
            raise InputError(where, "ticks_per_rev must be >= 1 and circumference_m > 0")
    elif f["bias_tau_s"].value <= 0 or (f["bias_tau_s"].lo or 1) <= 0:
        raise InputError(where, "bias_tau_s must be > 0")
    return Sensor(
        kind, name, int(cfg["id"]), str(cfg.get("description", "")),
        str(cfg.get("source", "")), rate, MappingProxyType(f), tpr, circ,
    )  # fmt: skip


@functools.lru_cache(maxsize=1)
def _presets() -> MappingProxyType:
    text = (resources.files("imugen") / "data" / PRESET_FILE).read_text(encoding="utf-8")
    doc = yaml.safe_load(text)
    origin = f"imugen/data/{PRESET_FILE}"
    out = {}
    for kind, block in (("odometer", "odometers"), ("barometer", "barometers")):
        out[kind] = MappingProxyType(
            {n: sensor_from_config(kind, n, c, origin) for n, c in doc[block].items()}
        )
    return MappingProxyType(out)


def presets(kind: str) -> MappingProxyType:
    """The shipped presets of ``kind`` by name (odometer: ``abs``, ``encoder``; barometer:
    ``bmp388``, ``ms5611``)."""
    return _presets()[kind]


def get_sensor(kind: str, spec) -> Sensor:
    """A :class:`Sensor` of ``kind`` from a preset name or a Sensor."""
    if isinstance(spec, Sensor):
        if spec.kind != kind:
            raise InputError(f"companions.{kind}", f"{spec.name!r} is a {spec.kind}")
        return spec
    p = presets(kind)
    if spec not in p:
        raise InputError(f"companions.{kind}", f"unknown preset {spec!r}; presets: {', '.join(p)}")
    return p[spec]


def _rng(seed, sensor: Sensor, shard, j, stream):
    return companion_rng(seed, KINDS[sensor.kind], sensor.id, shard, j, stream)


def draw_params(sensor: Sensor, seed, shard, ids, *, nominal=False) -> dict[str, np.ndarray]:
    """Drawn parameters of sequences ``ids`` (indices within the shard), ``{name: (M,)}``.

    Odometer: ``scale_factor`` (0 if nominal), ``scale_factor_sd``, ``white_mps``, ``tick_m``,
    ``phase`` (initial tick phase in ticks); barometer: ``white_m``, ``bias_sd_m``,
    ``bias_tau_s``. Every sequence consumes the same numbers of its ``params`` stream whatever
    is nominal.
    """
    names = ODO_FIGURES if sensor.kind == "odometer" else BARO_FIGURES
    out = {k: [] for k in names}
    if sensor.kind == "odometer":
        out.update(scale_factor=[], tick_m=[], phase=[])
    for j in ids:
        rng = _rng(seed, sensor, shard, int(j), "params")
        u = rng.random(len(names))
        z = rng.standard_normal()
        ph = rng.random()
        for i, k in enumerate(names):
            out[k].append(sensor.figures[k].draw(u[i], nominal))
        if sensor.kind == "odometer":
            out["scale_factor"].append(0.0 if nominal else out["scale_factor_sd"][-1] * z)
            out["tick_m"].append(sensor.tick_m)
            out["phase"].append(ph)
    return {k: np.asarray(v, float) for k, v in out.items()}


@dataclass
class CompanionData:
    """Epochs of one companion sensor for ``M`` sequences (``J`` epochs).

    Attributes
    ----------
    sensor : Sensor
    time_s, index : (J,)      epoch times [s] (IMU sample times) and IMU sample indices
    value : (M, J)            odometer speed [m/s] or barometric altitude [m] (measured)
    true : (M, J)             mean forward speed over the interval [m/s] / true height [m]
    ticks : (M, J) int64      odometer ticks in the interval (zeros for a barometer)
    count : (M, J) int64      odometer cumulative ticks ``N_m`` (zeros for a barometer)
    bias : (M, J)             barometer drift ``b`` [m] (zeros for an odometer)
    params : dict             drawn parameters, ``{name: (M,)}`` (:func:`draw_params`)
    labels : DataFrame        one row per sequence: ``sequence`` and the drawn parameters
    """

    sensor: Sensor
    time_s: np.ndarray
    index: np.ndarray
    value: np.ndarray
    true: np.ndarray
    ticks: np.ndarray
    count: np.ndarray
    bias: np.ndarray
    params: dict
    labels: pd.DataFrame

    @property
    def error(self) -> np.ndarray:
        """(M, J) true measurement error, measured minus true."""
        return self.value - self.true


def _grid(time_s, rate_hz):
    t = np.asarray(time_s, float)
    K = len(t)
    if K < 2:
        raise InputError("companions", "truth needs at least 2 samples")
    imu_rate = (K - 1) / (t[-1] - t[0])
    step = epoch_step(imu_rate, rate_hz)
    return t, step, np.arange(0, K, step), step / imu_rate


def _labels(sensor, par, M, first, rate):
    lab = {"sequence": (first + np.arange(M)).astype(np.int64)}
    p = "odo" if sensor.kind == "odometer" else "baro"
    lab[f"{p}_preset_id"] = np.full(M, sensor.id, np.int32)
    lab[f"{p}_rate_hz"] = np.full(M, float(rate))
    for k, v in par.items():
        lab[f"{p}_{k}"] = v
    return pd.DataFrame(lab)


def forward_distance(time_s, v_n, q_nb, omega_eb_b=None, lever_arm_b_m=(0.0, 0.0, 0.0)):
    """True forward speed ``u`` (K,) [m/s] of the point at ``lever_arm_b_m`` and its trapezoid
    distance ``s`` (K,) [m] from the first sample."""
    C = quat_to_dcm(np.asarray(q_nb, float))
    u = np.einsum("ki,ki->k", C[:, :, 0], np.asarray(v_n, float))
    lb = np.asarray(lever_arm_b_m, float).reshape(3)
    if omega_eb_b is not None and np.any(lb):
        u = u + np.cross(np.asarray(omega_eb_b, float), lb)[:, 0]
    t = np.asarray(time_s, float)
    s = np.concatenate([[0.0], np.cumsum(0.5 * np.diff(t) * (u[1:] + u[:-1]))])
    return u, s


def simulate_odometer(
    time_s, v_n, q_nb, omega_eb_b=None, sensor="abs", sequences=1, seed=0, shard=0, *,
    rate_hz=None, draw="ranges", lever_arm_b_m=(0.0, 0.0, 0.0), first=None,
) -> CompanionData:  # fmt: skip
    """Odometer epochs of ``sequences`` sequences sharing one truth (see the module doc).

    ``time_s`` (K,), ``v_n`` (K, 3) [m/s], ``q_nb`` (K, 4), ``omega_eb_b`` (K, 3) [rad/s]
    (only needed with a lever arm); ``sensor`` a preset name or Sensor; ``rate_hz`` default
    the preset's; ``draw`` ``ranges`` or ``nominal``; ``first`` the global id of the first
    sequence (labels).
    """
    sen = get_sensor("odometer", sensor)
    if draw not in ("ranges", "nominal"):
        raise InputError("companions.draw", f"must be ranges or nominal, got {draw!r}")
    rate = float(rate_hz or sen.rate_hz)
    t, _, idx, T = _grid(time_s, rate)
    _, s = forward_distance(t, v_n, q_nb, omega_eb_b, lever_arm_b_m)
    M = int(sequences)
    par = draw_params(sen, seed, shard, range(M), nominal=draw == "nominal")
    S = s[idx]
    J = len(idx)
    count = np.zeros((M, J), np.int64)
    moving = np.abs(np.diff(S)) > 1e-9  # a wheel at rest emits no ticks
    for j in range(M):
        xi = _rng(seed, sen, shard, j, "white").standard_normal(J)
        xi[0] = 0.0
        xi[1:] *= moving
        c = par["tick_m"][j]
        D = (1.0 + par["scale_factor"][j]) * S + np.cumsum(par["white_mps"][j] * T * xi)
        count[j] = np.floor(D / c + par["phase"][j]).astype(np.int64)
    ticks = np.diff(count, axis=1)
    tick = par["tick_m"][:, None]
    first = shard * M if first is None else int(first)
    return CompanionData(
        sen, t[idx[1:]], idx[1:], ticks * tick / T, np.broadcast_to(np.diff(S) / T, (M, J - 1)),
        ticks, count[:, 1:], np.zeros((M, J - 1)), par, _labels(sen, par, M, first, rate),
    )  # fmt: skip


def true_height(p_n, frame) -> np.ndarray:
    """True ellipsoidal height [m] of ENU positions ``p_n`` (..., 3) of an OriginFrame."""
    p = np.asarray(p_n, float)
    if frame.model == "flat":
        return frame.h0_m + p[..., 2]
    return frame.geodetic_from_n(p)[2]


def simulate_barometer(
    time_s, p_n, frame, sensor="bmp388", sequences=1, seed=0, shard=0, *, rate_hz=None,
    draw="ranges", first=None,
) -> CompanionData:  # fmt: skip
    """Barometric altitude epochs of ``sequences`` sequences sharing one truth.

    ``p_n`` (K, 3) true position [m] in the ENU of ``frame`` (an OriginFrame).
    """
    sen = get_sensor("barometer", sensor)
    if draw not in ("ranges", "nominal"):
        raise InputError("companions.draw", f"must be ranges or nominal, got {draw!r}")
    rate = float(rate_hz or sen.rate_hz)
    t, _, idx, T = _grid(time_s, rate)
    h = true_height(np.asarray(p_n, float)[idx], frame)
    M = int(sequences)
    J = len(idx)
    par = draw_params(sen, seed, shard, range(M), nominal=draw == "nominal")
    bias = np.zeros((M, J))
    white = np.zeros((M, J))
    for j in range(M):
        phi = math.exp(-T / par["bias_tau_s"][j])
        zb = _rng(seed, sen, shard, j, "bias").standard_normal(J)
        x = par["bias_sd_m"][j] * math.sqrt(1.0 - phi * phi) * zb
        x[0] = par["bias_sd_m"][j] * zb[0]
        bias[j] = lfilter([1.0], [1.0, -phi], x)
        white[j] = par["white_m"][j] * _rng(seed, sen, shard, j, "white").standard_normal(J)
    first = shard * M if first is None else int(first)
    zeros = np.zeros((M, J), np.int64)
    return CompanionData(
        sen, t[idx], idx, h + bias + white, np.broadcast_to(h, (M, J)), zeros, zeros, bias,
        par, _labels(sen, par, M, first, rate),
    )  # fmt: skip


def _figure_value(f, level: str, tau: bool = False) -> float:
    if level == "law" and f.lo is not None:  # sigmas: the law's RMS; correlation times: its mean
        from imugen.aid.filter.tuning import law_mean, law_rms

        return float((law_mean if tau else law_rms)(f.lo, f.hi))
    return f.hi if (level == "upper" and f.hi is not None) else f.value


# --- companion measurements at the GNSS epochs (last axis of CompanionEpochs.z) ------------------
C_ODO, C_ODO_VAR, C_BARO, C_BARO_VAR = 0, 1, 2, 3


@dataclass
class CompanionEpochs:
    """Companion measurements on the aided filter's GNSS epoch grid (:func:`filter_input`;
    the filter, :mod:`imugen.aid.filter`, reads them).

    Attributes
    ----------
    z : (S, J, 4)       per epoch ``C_ODO`` odometer distance [m] over the window ending at the
                        epoch (from the previous marked epoch), ``C_ODO_VAR`` the variance of
                        its white part [m^2] (the tick quantization is modelled by states,
                        ``odo_tick_m``),
                        ``C_BARO`` barometric height above the origin's [m], ``C_BARO_VAR`` its
                        variance [m^2]; NaN where absent
    mark : (J,) int8    1 where the epoch is an odometer epoch (a window boundary)
    lever_b_m : (S, 3)  odometer point from the vehicle reference point, vehicle axes [m] (the
                        IMU's own lever arm, ``Options.nhc_lever_arm_m``, is taken off)
    odo_sf_sd : (S,)    prior 1-sigma of the odometer scale factor
    baro_sd_m, baro_tau_s : (S,)  barometer drift model (stationary sigma [m], tau [s])
    odo_tick_m : (S,)   odometer tick length ``c`` [m]: the count's residual at a window end is
                        a state of prior ``c^2 / 12`` (module docstring, "Measurements")
    """

    z: np.ndarray
    mark: np.ndarray
    lever_b_m: np.ndarray
    odo_sf_sd: np.ndarray
    baro_sd_m: np.ndarray
    baro_tau_s: np.ndarray
    odo_tick_m: np.ndarray | None = None


def filter_input(
    gnss_index, sequences, odometer: CompanionData | None = None,
    barometer: CompanionData | None = None, *, h0_m=0.0, level="upper", oracle=False,
    lever_arm_b_m=(0.0, 0.0, 0.0),
):  # fmt: skip
    """Companion measurements on the GNSS epoch grid ``gnss_index`` (J,) for the aided filter.

    Odometer: the epochs that are also odometer epochs are marked; at a mark, the distance
    counted since the previous mark, ``(N(k_j) - N(k_prev)) c``, with the variance of its white
    part ``n (s_w T_o)^2`` (``n`` odometer epochs of white speed noise) and the tick length
    ``c``: the quantization of the two counts, residuals of ``c^2 / 12`` each shared by
    consecutive windows, is modelled by the filter's states (:mod:`imugen.aid.filter.odometer`).
    Barometer: the altitude minus ``h0_m`` (the origin's height) at the epochs that are
    barometer epochs, variance ``s_w^2``. The noise figures and the drift /
    scale-factor priors are the preset's top of range (``level="upper"``), nominal
    (``"nominal"``) or its law (``"law"``: the root mean square of each sigma's log-uniform
    law, the mean correlation time), or the drawn values of each sequence (``oracle=True``).

    Returns a :class:`CompanionEpochs`.
    """
    idx = np.asarray(gnss_index, np.int64)
    S, J = int(sequences), len(idx)
    z = np.full((S, J, 4), np.nan)
    mark = np.zeros(J, np.int8)
    osd, tick = np.zeros(S), np.zeros(S)
    bsd, btau = np.zeros(S), np.full(S, 3600.0)

    def fig(data, name):
        if oracle:
            return np.asarray(data.params[name], float)
        f = data.sensor.figures[name]
        return np.full(S, _figure_value(f, level, name.endswith("tau_s")))

    if odometer is not None:
        o = odometer
        oi = np.concatenate([[0], o.index])
        cnt = np.concatenate([np.zeros((S, 1), np.int64), o.count], axis=1)
        pos = np.searchsorted(oi, idx)
        hit = (pos < len(oi)) & (oi[np.minimum(pos, len(oi) - 1)] == idx)
        mark[hit] = 1
        js = np.flatnonzero(hit)
        step = int(oi[1] - oi[0]) if len(oi) > 1 else 1
        T = 1.0 / float(o.labels["odo_rate_hz"].iloc[0])
        c = o.params["tick_m"]
        sw = fig(o, "white_mps")
        a, b = js[:-1], js[1:]
        nep = (idx[b] - idx[a]) / step
        z[:, b, C_ODO] = (cnt[:, pos[b]] - cnt[:, pos[a]]) * c[:, None]
        z[:, b, C_ODO_VAR] = nep * ((sw * T) ** 2)[:, None]
        osd, tick = fig(o, "scale_factor_sd"), np.asarray(c, float)
    if barometer is not None:
        b = barometer
        pos = np.searchsorted(b.index, idx)
        hit = (pos < len(b.index)) & (b.index[np.minimum(pos, len(b.index) - 1)] == idx)
        z[:, hit, C_BARO] = b.value[:, pos[hit]] - float(h0_m)
        z[:, hit, C_BARO_VAR] = (fig(b, "white_m") ** 2)[:, None]
        bsd, btau = fig(b, "bias_sd_m"), fig(b, "bias_tau_s")
    lever = np.broadcast_to(np.asarray(lever_arm_b_m, float).reshape(-1, 3), (S, 3)).copy()
    return CompanionEpochs(z, mark, lever, osd, bsd, btau, tick)


def sensor_table() -> pd.DataFrame:
    """The presets as a table (nominal figures), for documentation."""
    rows = []
    for kind in KINDS:
        for s in presets(kind).values():
            row = {"kind": kind, "preset": s.name, "id": s.id, "rate_hz": s.rate_hz}
            if kind == "odometer":
                row["tick_m"] = s.tick_m
            row.update({k: f.value for k, f in s.figures.items()})
            rows.append(row)
    return pd.DataFrame(rows)


__all__ = [
    "CompanionData", "Sensor", "draw_params", "filter_input", "forward_distance", "get_sensor",
    "presets", "sensor_table", "simulate_barometer", "simulate_odometer", "true_height",
]  # fmt: skip
