"""Sensor grades: shipped presets and custom grades from configuration, validated and immutable.

A grade describes one kind of IMU (gyro triad + accelerometer triad) by datasheet figures with
explicit units (:mod:`imugen.core.units`), each optionally with a Monte-Carlo range and a source.
Presets live in ``imugen/data/grades.yaml``; a user's file has the same layout::

    grades:
      my_imu:
        id: 1001                      # stable integer id (seeds use it; never list order)
        description: ...
        gyro:
          turn_on_bias:     {value: 5,    range: [2, 10],  unit: deg_per_h, kind: one_sigma}
          bias_instability: {value: 3,    unit: deg_per_h, kind: allan_floor,
                             model: gauss_markov,
                             correlation_time: {value: 600, range: [300, 3600], unit: s}}
          white_noise:      {value: 0.2,  unit: deg_per_sqrt_h}
          ...
        accel: {...}

Terms (per sensor; all optional; an absent term is off)
-------------------------------------------------------
``turn_on_bias``       1-sigma per axis of the constant (run-to-run) bias (kind ``one_sigma``).
``bias_instability``   in-run bias: ``kind: allan_floor`` (the Allan-deviation minimum a
                       datasheet quotes as "bias instability"/"in-run stability") or
                       ``kind: gm_sigma`` (the standard deviation of a Gauss-Markov process);
                       ``model: gauss_markov`` (one first-order GM, ``correlation_time``) or
                       ``model: flicker`` (a sum of ``components`` GM processes with
                       log-spaced correlation times in ``flicker_band`` approximating 1/f noise,
                       ``allan_floor`` only); ``start: zero`` (the in-run wander, starting
                       at 0 around the turn-on value; the default beside a ``turn_on_bias``)
                       or ``start: stationary`` (one process that is the whole slow bias,
                       started from its stationary law; the default without a
                       ``turn_on_bias``, and refused beside one: it would count the initial
                       bias twice).
``white_noise``        density (ARW / VRW).
``rate_random_walk``   density of the bias derivative (RRW).
``scale_factor``       1-sigma per axis (dimensionless).
``cross_coupling``     1-sigma of each off-diagonal element of the 3x3 misalignment /
                       cross-coupling matrix (angle or dimensionless).
``g_sensitivity``      gyro only: 1-sigma of each element of the 3x3 g-sensitivity matrix.
``quantization``       LSB of the rate output (increments use LSB * dt), fixed; ``mode: carry``
                       (default: the residual is carried to the next sample, so integrated
                       outputs do not accumulate it) or ``mode: round`` (each sample rounded
                       on its own, as a rate register is: white ``LSB^2 / 12`` per sample).
``range``              full-scale of the rate output (saturation), fixed.
``temperature_bias``   1-sigma per axis of the bias temperature coefficient.
``temperature_scale_factor``  1-sigma per axis of the scale-factor temperature coefficient.
``slow_bias``          a second, slower first-order Gauss-Markov bias process beside the
                       ``bias_instability`` (environment-driven wander, e.g. a lab's temperature
                       cycling: the hump past the floor a real log shows at 100-1000 s):
                       ``kind: allan_floor`` (its Allan-deviation peak, at tau = 1.89 T) or
                       ``kind: gm_sigma``, ``correlation_time`` and ``start`` as a
                       ``gauss_markov`` ``bias_instability``. Absent: no draw is made for it, so
                       a grade without it gives the numbers it gave before the term existed.

Besides the terms, a sensor may give its output ``bandwidth`` (not an error term: the part's
internal sample rate and digital low-pass, :func:`imugen.sensors.bandwidth.spec_from_config`):
the whole sensed signal -- motion, vibration and noise -- goes through it before
quantization, and ``white_noise`` is then the sensor's own (passband) density. Without it the
output is ideal: white noise ``N / sqrt(dt)`` per sample (a bandwidth of half the rate).

Grade keys besides the sensors: ``variant`` (``uncalibrated``, default: the part's turn-on
figures; or ``calibrated``: residuals after a calibration, which ``calibration`` names with its
source) and ``calibrated_at_rest`` (calibrated grades: the bias was measured at rest and level,
so it also removed the static error on gravity: the gyro g-sensitivity's ``G (0, 0, g0)``
and the accelerometer scale factor and cross-coupling's ``E (0, 0, g0)``; ``true`` for both
sensors, or a list of the sensors whose bias was so calibrated, e.g. ``[gyro]`` for a phone
whose OS estimates the gyro bias at rest and leaves the accelerometer alone).

Every entry: ``value`` (scalar or three per-axis values), optional ``range: [lo, hi]`` (same
unit; sequences draw a level log-uniformly inside it, see :mod:`imugen.simulate.stage`), ``unit``,
``kind`` where required, ``source``. Values are converted to SI once, here.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import math
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import yaml

from imugen.core import units
from imugen.core.earth import GradeFigures
from imugen.core.errors import InputError
from imugen.sensors.bandwidth import BandwidthSpec, spec_from_config

SENSORS = ("gyro", "accel")

# term -> (dimension per sensor {gyro, accel} (tuple = several allowed), allowed kinds,
#          default kind or None = required, random level allowed)
_TERMS: dict[str, tuple[dict[str, tuple[str, ...]], tuple[str, ...], str | None]] = {
    "turn_on_bias": (
        {"gyro": ("angular_rate",), "accel": ("acceleration",)},
        ("one_sigma",),
        None,
    ),
    "bias_instability": (
        {"gyro": ("angular_rate",), "accel": ("acceleration",)},
        ("allan_floor", "gm_sigma"),
        None,
    ),
    "white_noise": (
        {"gyro": ("angular_rate_density",), "accel": ("acceleration_density",)},
        ("density",),
        "density",
    ),
    "rate_random_walk": (
        {"gyro": ("angular_rate_rw",), "accel": ("acceleration_rw",)},
        ("density",),
        "density",
    ),
    "scale_factor": (
        {"gyro": ("dimensionless",), "accel": ("dimensionless",)},
        ("one_sigma",),
        "one_sigma",
    ),
    "cross_coupling": (
        {"gyro": ("angle", "dimensionless"), "accel": ("angle", "dimensionless")},
        ("one_sigma",),
        "one_sigma",
    ),
    "g_sensitivity": ({"gyro": ("g_sensitivity",)}, ("one_sigma",), "one_sigma"),
    "quantization": (
        {"gyro": ("angular_rate",), "accel": ("acceleration",)},
        ("lsb",),
        "lsb",
    ),
    "range": (
        {"gyro": ("angular_rate",), "accel": ("acceleration",)},
        ("full_scale",),
        "full_scale",
    ),
    "temperature_bias": (
        {"gyro": ("angular_rate_per_K",), "accel": ("acceleration_per_K",)},
        ("one_sigma",),
        "one_sigma",
    ),
    "temperature_scale_factor": (
        {"gyro": ("dimensionless_per_K",), "accel": ("dimensionless_per_K",)},
        ("one_sigma",),
        "one_sigma",
    ),
    "slow_bias": (
        {"gyro": ("angular_rate",), "accel": ("acceleration",)},
        ("allan_floor", "gm_sigma"),
        None,
    ),
}
TERMS = tuple(_TERMS)
"""Names of the error terms, in a fixed order (also the order of parameter draws)."""

FIXED_TERMS = ("quantization", "range")
"""Terms that are device constants (no Monte-Carlo range)."""

_ENTRY_KEYS = {"value", "range", "unit", "kind", "source", "note"}
QUANTIZATION_MODES = ("carry", "round")
"""How the rate output is quantized (``quantization.mode``)."""
_BI_KEYS = _ENTRY_KEYS | {"model", "correlation_time", "flicker_band", "components", "start"}
_SLOW_KEYS = _ENTRY_KEYS | {"correlation_time", "start"}
_GRADE_KEYS = {
    "id",
    "description",
    "source",
    "notes",
    "reading",
    "variant",
    "calibration",
    "calibrated_at_rest",
    "gyro",
    "accel",
}
VARIANTS = ("uncalibrated", "calibrated")
"""What a grade's bias figures describe: the part as it turns on, or the residual after a
factory or field calibration (``calibration`` then says which, with its source)."""
STARTS = ("stationary", "zero")
"""Initial law of the in-run bias process (``bias_instability.start``)."""
_NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")
PRESET_FILE = "grades.yaml"


def _yaml(text: str):
    """``yaml.safe_load`` with libyaml's C loader when available (same documents, ~10x
    faster: the shipped presets parse in a few ms at every job's start)."""
    return yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


# --- Gauss-Markov Allan deviation (used to convert an Allan floor to a GM sigma) ---------------
def gm_avar(tau, sigma, T):
    """Allan variance of a first-order Gauss-Markov process.

    ``AVAR = (2 sigma^2 T / tau) [1 - T/(2 tau) (3 - 4 e^{-tau/T} + e^{-2 tau/T})]``
    (IEEE Std 952-1997 C.2 form; tends to ``(2 sigma^2 / T) tau / 3`` (RRW) for tau << T and
    to ``2 sigma^2 T / tau`` (white) for tau >> T).

    Parameters
    ----------
    tau : array_like
        Averaging times [s].
    sigma : float
        Process standard deviation (any unit).
    T : float
        Correlation time [s].
    """
    x = np.asarray(tau, dtype=float) / T
    small = x < 1e-3
    xs = np.where(small, 1.0, x)
    # 3 - 4 e^-x + e^-2x written with expm1 (exact cancellation of the constants)
    br = 1.0 - (-4.0 * np.expm1(-xs) + np.expm1(-2.0 * xs)) / (2.0 * xs)
    br = np.where(small, x * x / 3.0 - x**3 / 4.0, br)
    return 2.0 * sigma**2 * br / np.where(x > 0, x, np.inf)


GM_PEAK, GM_PEAK_X = 0.6173642831444415, 1.8926178169666992
"""Peak Allan deviation of a unit-sigma GM process and where it is (tau = 1.8926 T): the
maximum of :func:`gm_avar` (constants, so that loading the module does not import
scipy.optimize; ``tests/sensors/test_grades.py`` recomputes them)."""


def flicker_taus(band: tuple[float, float], components: int):
    """Log-spaced correlation times of the GM components approximating flicker noise."""
    lo, hi = band
    if components == 1:
        return np.array([math.sqrt(lo * hi)])
    return np.geomspace(lo, hi, components)


def _flicker_level(Ts) -> float:
    # mean Allan deviation (unit-sigma components) over the plateau [5 T_min, T_max / 2]
    grid = np.geomspace(5.0 * Ts[0], Ts[-1] / 2.0, 64)
    return float(np.mean(np.sqrt(sum(gm_avar(grid, 1.0, T) for T in Ts))))


def flicker_unit_avar(tau, band, components):
    """Allan variance of the flicker approximation with unit Allan floor.

    Equal-variance GM components at :func:`flicker_taus`; the variance is normalized so that
    the Allan deviation averaged (in log tau) over the plateau ``[5 T_min, T_max / 2]`` is 1
    (ripple within a few per cent for two components per decade).
    """
    Ts = flicker_taus(band, components)
    level = _flicker_level(Ts)
    tau = np.asarray(tau, dtype=float)
    return sum(gm_avar(tau, 1.0, T) for T in Ts) / level**2


def flicker_component_sigma(floor: float, band, components) -> float:
    """Standard deviation of each GM component giving the Allan floor ``floor``."""
    Ts = flicker_taus(band, components)
    level = _flicker_level(Ts)
    return floor / level


# --- immutable containers ------------------------------------------------------------------
@dataclass(frozen=True)
class Param:
    """One configured figure, in SI.

    Attributes
    ----------
    value : tuple of 3 float
        Nominal per-axis value [SI].
    lo, hi : tuple of 3 float or None
        Monte-Carlo range [SI] (None: every sequence uses ``value``).
    unit : str
        Datasheet unit the figure was given in.
    kind : str
        What the figure is (``one_sigma``, ``allan_floor``, ``gm_sigma``, ``density``, ``lsb``,
        ``full_scale``).
    source : str
        Where the number comes from.
    datasheet : tuple of 3 float
        Nominal value in ``unit``.
    """

    value: tuple[float, float, float]
    lo: tuple[float, float, float] | None
    hi: tuple[float, float, float] | None
    unit: str
    kind: str
    source: str
    datasheet: tuple[float, float, float]

    @property
    def randomized(self) -> bool:
        return self.lo is not None


@dataclass(frozen=True)
class BiasInstability:
    """In-run bias instability configuration (SI).

    Attributes
    ----------
    level : Param
        The configured figure (Allan floor or GM sigma, per ``level.kind``).
    model : str
        ``"gauss_markov"`` or ``"flicker"``.
    correlation_time : Param or None
        GM correlation time [s] (``gauss_markov``).
    flicker_band : tuple of 2 float or None
        Smallest and largest correlation time [s] of the flicker components.
    components : int
        Number of GM components (1 for ``gauss_markov``).
    start : str
        ``"stationary"``: the process starts from its stationary law and is the whole slow
        bias (its sigma is the turn-on spread; no ``turn_on_bias`` may be configured beside
        it). ``"zero"``: it starts at 0 and is the in-run wander around the turn-on value.
    """

    level: Param
    model: str
    correlation_time: Param | None
    flicker_band: tuple[float, float] | None
    components: int
    start: str = "stationary"

    def sigma_from_level(self, level_si: float) -> float:
        """GM sigma of each component for a drawn level (Allan floor or GM sigma) [SI]."""
        if self.model == "flicker":
            return flicker_component_sigma(level_si, self.flicker_band, self.components)
        if self.level.kind == "allan_floor":
            return level_si / GM_PEAK
        return level_si

    def allan_floor_from_level(self, level_si: float) -> float:
        """Allan-deviation floor (peak for a single GM) of a drawn level [SI]."""
        if self.model == "gauss_markov" and self.level.kind == "gm_sigma":
            return level_si * GM_PEAK
        return level_si


@dataclass(frozen=True)
class SensorSpec:
    """Configured error terms of one sensor triad (``None`` = term off)."""

    sensor: str
    turn_on_bias: Param | None = None
    bias_instability: BiasInstability | None = None
    white_noise: Param | None = None
    rate_random_walk: Param | None = None
    scale_factor: Param | None = None
    cross_coupling: Param | None = None
    g_sensitivity: Param | None = None
    quantization: Param | None = None
    range: Param | None = None
    temperature_bias: Param | None = None
    temperature_scale_factor: Param | None = None
    slow_bias: BiasInstability | None = None
    """A second, slower Gauss-Markov bias process (``model`` ``gauss_markov``, one
    component) beside the ``bias_instability``."""
    bandwidth: BandwidthSpec | None = None
    """Output bandwidth (None: ideal, white noise ``N / sqrt(dt)`` per sample)."""
    quantization_mode: str = "carry"
    """``"carry"`` or ``"round"`` (see ``quantization``)."""
    static_g_removed: bool = False
    """Sensor of a grade calibrated at rest and level: the bias estimate also absorbed the
    static error on gravity -- ``G (0, 0, g0)`` for a gyro's g-sensitivity, ``E (0, 0, g0)``
    for an accelerometer's scale factor and cross-coupling ``E`` -- so only the errors on
    ``f - (0, 0, g0)`` act."""

    def configured(self) -> tuple[str, ...]:
        """Names of the configured terms."""
        return tuple(t for t in TERMS if getattr(self, t) is not None)


@dataclass(frozen=True)
class Grade:
    """An immutable sensor grade.

    Attributes
    ----------
    name : str
    id : int
        Stable id (part of every seed's spawn key).
    description, source, reading : str
        Free text; ``reading`` documents how ambiguous figures were interpreted.
    gyro, accel : SensorSpec
    origin : str
        Where the grade was loaded from (preset file or user file).
    config_json : str
        The grade's configuration as given (datasheet units), JSON.
    variant : str
        ``"uncalibrated"`` (turn-on figures of the part) or ``"calibrated"`` (residuals).
    calibration : str
        For a calibrated grade: the calibration its residuals assume, and the source.
    """

    name: str
    id: int
    description: str
    source: str
    reading: str
    gyro: SensorSpec
    accel: SensorSpec
    origin: str
    config_json: str = field(repr=False)
    variant: str = "uncalibrated"
    calibration: str = ""

    @property
    def config(self) -> dict:
        """A fresh copy of the configuration as given (datasheet units)."""
        return json.loads(self.config_json)

    def sensor(self, name: str) -> SensorSpec:
        return self.gyro if name == "gyro" else self.accel


# --- parsing ---------------------------------------------------------------------------------
def _err(origin, where, msg):
    return InputError(origin, f"{where}: {msg}")


def _triple(v, origin, where) -> tuple[float, float, float]:
    if isinstance(v, bool):
        raise _err(origin, where, f"expected a number or three numbers, got {v!r}")
    if isinstance(v, int | float):
        v = [v, v, v]
    if not isinstance(v, list | tuple) or len(v) != 3:
        raise _err(origin, where, f"expected a number or three numbers, got {v!r}")
    out = []
    for x in v:
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
            raise _err(origin, where, f"expected finite numbers, got {v!r}")
        if x < 0:
            raise _err(origin, where, f"must be >= 0 (a magnitude or 1-sigma), got {x!r}")
        out.append(float(x))
    return tuple(out)


def _param(entry, dims, kinds, default_kind, origin, where, fixed=False) -> Param:
    if not isinstance(entry, dict):
        raise _err(origin, where, f"expected a mapping with value/unit, got {entry!r}")
    extra = set(entry) - _ENTRY_KEYS
    if extra:
        raise _err(origin, where, f"unknown key(s) {sorted(extra)}; allowed {sorted(_ENTRY_KEYS)}")
    if "value" not in entry or "unit" not in entry:
        raise _err(origin, where, "needs 'value' and 'unit'")
    uname = entry["unit"]
    u = units.UNITS.get(uname) if isinstance(uname, str) else None
    if u is None or u.dimension not in dims:
        allowed = [n for d in dims for n in units.units_of(d)]
        got = f"{uname!r} ({u.dimension})" if u else repr(uname)
        raise _err(origin, where, f"unit {got} not allowed here; use one of {', '.join(allowed)}")
    kind = entry.get("kind", default_kind)
    if kind is None:
        raise _err(
            origin, where, f"needs 'kind' (one of {', '.join(kinds)}): say what the figure is"
        )
    if kind not in kinds:
        raise _err(origin, where, f"kind {kind!r} not allowed; use one of {', '.join(kinds)}")
    ds = _triple(entry["value"], origin, where + ".value")
    val = tuple(x * u.factor for x in ds)
    lo = hi = None
    if entry.get("range") is not None:
        if fixed:
            raise _err(origin, where, "this term is a device constant and takes no range")
        r = entry["range"]
        if not isinstance(r, list | tuple) or len(r) != 2:
            raise _err(origin, where, f"range must be [lo, hi], got {r!r}")
        lo_ds = _triple(r[0], origin, where + ".range")
        hi_ds = _triple(r[1], origin, where + ".range")
        for a, v, b in zip(lo_ds, ds, hi_ds, strict=True):
            if not (0 < a <= v <= b):
                raise _err(
                    origin, where, f"need 0 < lo <= value <= hi, got lo={a}, value={v}, hi={b}"
                )
        lo = tuple(x * u.factor for x in lo_ds)
        hi = tuple(x * u.factor for x in hi_ds)
    src = entry.get("source", "")
    if not isinstance(src, str):
        raise _err(origin, where, "source must be text")
    return Param(val, lo, hi, uname, kind, src, ds)


def _bias_instability(entry, sensor, origin, where, has_turn_on, slow=False) -> BiasInstability:
    if not isinstance(entry, dict):
        raise _err(origin, where, f"expected a mapping, got {entry!r}")
    keys = _SLOW_KEYS if slow else _BI_KEYS
    extra = set(entry) - keys
    if extra:
        raise _err(origin, where, f"unknown key(s) {sorted(extra)}; allowed {sorted(keys)}")
    start = entry.get("start", "zero" if has_turn_on else "stationary")
    if start not in STARTS:
        raise _err(origin, where, f"start must be one of {', '.join(STARTS)}, got {start!r}")
    if start == "stationary" and has_turn_on:
        # one bias model per source: a process started from its stationary law already holds
        # the run-to-run spread, so a turn-on draw beside it counts the initial bias twice
        raise _err(
            origin,
            where,
            "start: stationary beside a turn_on_bias counts the initial bias twice; give "
            "either a turn_on_bias plus an in-run process (start: zero) or one process "
            "started from its stationary law (no turn_on_bias)",
        )
    dims, kinds, dk = _TERMS["bias_instability"]
    base = {k: v for k, v in entry.items() if k in _ENTRY_KEYS}
    level = _param(base, dims[sensor], kinds, dk, origin, where)
    model = entry.get("model", "gauss_markov")
    if model == "gauss_markov":
        if "correlation_time" not in entry:
            raise _err(origin, where, "model gauss_markov needs correlation_time")
        if "flicker_band" in entry or "components" in entry:
            raise _err(origin, where, "flicker_band/components only apply to model flicker")
        ct = _param(
            entry["correlation_time"],
            ("time",),
            ("one_sigma", "value"),
            "value",
            origin,
            where + ".correlation_time",
        )
        if min(ct.value) <= 0:
            raise _err(origin, where, "correlation_time must be > 0")
        return BiasInstability(level, model, ct, None, 1, start)
    if model == "flicker":
        if level.kind != "allan_floor":
            raise _err(origin, where, "model flicker takes kind allan_floor")
        if "correlation_time" in entry:
            raise _err(origin, where, "model flicker takes flicker_band, not correlation_time")
        fb = entry.get("flicker_band")
        if not isinstance(fb, dict) or set(fb) - {"min", "max", "unit", "source"}:
            raise _err(origin, where, "flicker_band must be {min, max, unit}")
        try:
            lo = units.to_si(fb["min"], fb["unit"], "time")
            hi = units.to_si(fb["max"], fb["unit"], "time")
        except (KeyError, ValueError, TypeError) as exc:
            raise _err(origin, where + ".flicker_band", str(exc)) from None
        if not (0 < lo and hi >= 100.0 * lo):
            raise _err(origin, where, "flicker_band needs 0 < min and max >= 100 min")
        n = entry.get("components", max(2, round(2 * math.log10(hi / lo)) + 1))
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 32:
            raise _err(origin, where, "components must be an integer in 1..32")
        return BiasInstability(level, model, None, (lo, hi), n, start)
    raise _err(origin, where, f"model must be gauss_markov or flicker, got {model!r}")


def _sensor(cfg, sensor, origin, where) -> SensorSpec:
    if cfg is None:
        return SensorSpec(sensor)
    if not isinstance(cfg, dict):
        raise _err(origin, where, f"expected a mapping of error terms, got {cfg!r}")
    known = [t for t in TERMS if sensor in _TERMS[t][0]] + ["bandwidth"]
    extra = set(cfg) - set(known)
    if extra:
        raise _err(origin, where, f"unknown term(s) {sorted(extra)}; known: {', '.join(known)}")
    kw = {}
    for t, entry in cfg.items():
        if entry is None:
            continue
        w = f"{where}.{t}"
        if t == "bandwidth":
            kw[t] = spec_from_config(entry, origin, w)
        elif t == "quantization" and isinstance(entry, dict) and "mode" in entry:
            mode = entry["mode"]
            if mode not in QUANTIZATION_MODES:
                raise _err(origin, w, f"mode: one of {', '.join(QUANTIZATION_MODES)}, got {mode!r}")
            dims, kinds, dk = _TERMS[t]
            rest = {k: v for k, v in entry.items() if k != "mode"}
            kw[t] = _param(rest, dims[sensor], kinds, dk, origin, w, fixed=True)
            kw["quantization_mode"] = mode
            if min(kw[t].value) <= 0:
                raise _err(origin, w, "must be > 0")
        elif t in ("bias_instability", "slow_bias"):
            kw[t] = _bias_instability(
                entry, sensor, origin, w, cfg.get("turn_on_bias") is not None, t == "slow_bias"
            )
        else:
            dims, kinds, dk = _TERMS[t]
            kw[t] = _param(entry, dims[sensor], kinds, dk, origin, w, fixed=t in FIXED_TERMS)
            if t in FIXED_TERMS and min(kw[t].value) <= 0:
                raise _err(origin, w, "must be > 0")
    return SensorSpec(sensor, **kw)


def grade_from_config(name: str, cfg: dict, origin: str = "<config>") -> Grade:
    """Build a validated, immutable :class:`Grade` from a configuration mapping.

    Parameters
    ----------
    name : str
        Grade name (lower case, digits, underscores).
    cfg : dict
        The grade's mapping (``id``, ``gyro``, ``accel``, ...), datasheet units.
    origin : str
        File or label for error messages and provenance.

    Raises
    ------
    InputError
        Anything invalid: unknown keys, wrong unit dimension, missing kind, bad ranges.
    """
    where = f"grade {name!r}"
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise _err(origin, where, "name must be lower case letters, digits and underscores")
    if not isinstance(cfg, dict):
        raise _err(origin, where, "expected a mapping")
    extra = set(cfg) - _GRADE_KEYS
    if extra:
        raise _err(origin, where, f"unknown key(s) {sorted(extra)}; allowed {sorted(_GRADE_KEYS)}")
    gid = cfg.get("id")
    if isinstance(gid, bool) or not isinstance(gid, int) or not 0 <= gid < 2**31:
        raise _err(origin, where, f"needs a stable integer 'id' in [0, 2^31), got {gid!r}")
    gyro = _sensor(cfg.get("gyro"), "gyro", origin, where + ": gyro")
    accel = _sensor(cfg.get("accel"), "accel", origin, where + ": accel")
    try:
        cj = json.dumps(cfg, sort_keys=True)
    except TypeError as exc:
        raise _err(origin, where, f"not serializable: {exc}") from None
    text = {k: cfg.get(k, "") for k in ("description", "source", "reading", "calibration")}
    for k, v in text.items():
        if not isinstance(v, str):
            raise _err(origin, where, f"{k} must be text")
    variant = cfg.get("variant", "uncalibrated")
    if variant not in VARIANTS:
        raise _err(origin, where, f"variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
    if variant == "calibrated" and not text["calibration"]:
        raise _err(
            origin, where, "a calibrated grade needs 'calibration': which one, and its source"
        )
    at_rest = cfg.get("calibrated_at_rest", False)
    if at_rest is True:
        at_rest = list(SENSORS)
    ok = at_rest is False or (
        isinstance(at_rest, list) and all(x in SENSORS for x in at_rest) and at_rest
    )
    if not ok or (at_rest and variant != "calibrated"):
        raise _err(
            origin,
            where,
            "calibrated_at_rest is true, false or a list of sensors (gyro, accel), and only "
            "for calibrated",
        )
    if at_rest and "gyro" in at_rest:
        gyro = dataclasses.replace(gyro, static_g_removed=True)
    if at_rest and "accel" in at_rest:
        accel = dataclasses.replace(accel, static_g_removed=True)
    return Grade(
        name,
        gid,
        text["description"],
        text["source"],
        text["reading"],
        gyro,
        accel,
        str(origin),
        cj,
        variant,
        text["calibration"],
    )


def grades_from_document(doc: Any, origin: str) -> dict[str, Grade]:
    """Parse a whole grades document ``{grades: {name: cfg}}``; ids must be unique."""
    if not isinstance(doc, dict) or not isinstance(doc.get("grades"), dict):
        raise InputError(origin, "expected a top-level mapping 'grades: {name: {...}}'")
    out: dict[str, Grade] = {}
    seen: dict[int, str] = {}
    for name, cfg in doc["grades"].items():
        g = grade_from_config(name, copy.deepcopy(cfg), origin)
        if g.id in seen:
            raise InputError(origin, f"grade {name!r}: id {g.id} already used by {seen[g.id]!r}")
        seen[g.id] = name
        out[name] = g
    return out


@functools.lru_cache(maxsize=1)
def _presets() -> MappingProxyType:
    ref = resources.files("imugen") / "data" / PRESET_FILE
    text = ref.read_text(encoding="utf-8")
    return MappingProxyType(grades_from_document(_yaml(text), f"imugen/data/{PRESET_FILE}"))


def presets() -> MappingProxyType:
    """The shipped presets by name (read-only mapping of immutable grades)."""
    return _presets()


def preset_text() -> str:
    """The shipped preset file's text (for provenance)."""
    return (resources.files("imugen") / "data" / PRESET_FILE).read_text(encoding="utf-8")


def load_grades(path) -> dict[str, Grade]:
    """Read custom grades from a YAML (or JSON) file; ids must not collide with presets."""
    path = Path(path)
    try:
        doc = _yaml(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        raise InputError(path, f"not valid YAML: {str(exc).splitlines()[0]}") from None
    except RecursionError:
        raise InputError(path, "is nested too deeply to be a grades file") from None
    out = grades_from_document(doc, str(path))
    pre = presets()
    pre_ids = {g.id: n for n, g in pre.items()}
    for name, g in out.items():
        if name in pre:
            raise InputError(path, f"grade {name!r}: name of a shipped preset; choose another")
        if g.id in pre_ids:
            raise InputError(path, f"grade {name!r}: id {g.id} is the preset {pre_ids[g.id]!r}'s")
    return out


def get_grade(spec, grades_file=None) -> Grade:
    """Resolve a grade: a :class:`Grade`, a preset name, or a name in ``grades_file``.

    ``spec`` may also be ``"path.yaml:name"``.
    """
    if isinstance(spec, Grade):
        return spec
    if not isinstance(spec, str):
        raise InputError("--grade", f"expected a grade name, got {spec!r}")
    if (
        grades_file is None
        and ":" in spec
        and spec.rsplit(":", 1)[0].endswith((".yaml", ".yml", ".json"))
    ):
        grades_file, spec = spec.rsplit(":", 1)
    if grades_file is not None:
        custom = load_grades(grades_file)
        if spec in custom:
            return custom[spec]
    pre = presets()
    if spec in pre:
        return pre[spec]
    known = sorted(pre) + (sorted(load_grades(grades_file)) if grades_file else [])
    raise InputError("--grade", f"unknown grade {spec!r}; known: {', '.join(known)}")


def budget_figures(grade: Grade | str) -> GradeFigures:
    """Nominal figures of a grade for the ``--earth auto`` budget (SI, axis means).

    Bias at the start of a run: the turn-on bias (1 sigma) and the in-run Allan floor in root
    sum square, or, for one process started from its stationary law, its stationary sigma
    (summed in variance over flicker components); a ``slow_bias`` adds its own in root sum
    square; scale factor and white-noise densities as
    configured; absent terms are 0.
    """
    g = get_grade(grade)

    def mean(p: Param | None) -> float:
        return 0.0 if p is None else float(np.mean(np.abs(p.value)))

    def process(bi: BiasInstability | None, on: float) -> float:
        if bi is None:
            return on
        lvl = mean(bi.level)
        if bi.start == "stationary":
            return float(bi.sigma_from_level(lvl) * math.sqrt(bi.components))
        return float(np.hypot(on, bi.allan_floor_from_level(lvl)))

    def bias(s: SensorSpec) -> float:
        b = process(s.bias_instability, mean(s.turn_on_bias))
        return b if s.slow_bias is None else float(np.hypot(b, process(s.slow_bias, 0.0)))

    return GradeFigures(
        name=g.name,
        gyro_bias_radps=bias(g.gyro),
        accel_bias_mps2=bias(g.accel),
        gyro_scale_factor=mean(g.gyro.scale_factor),
        arw_rad_per_sqrt_s=mean(g.gyro.white_noise),
        vrw_mps_per_sqrt_s=mean(g.accel.white_noise),
    )
