"""Grades from the files users have (Kalibr/EuRoC, VINS, i2Nav/KF-GINS, datasheet figures),
and back to Kalibr.

Import (``imugen grade import FILE``) reads one of these and returns an imugen grade
configuration (datasheet units, every figure with its ``source``), validated by
:func:`imugen.sensors.grades.grade_from_config`:

=====================================  ===============================  ========================
file key                               imugen term                      conversion
=====================================  ===============================  ========================
Kalibr ``gyroscope_noise_density``     ``gyro.white_noise``             identical (rad/s/sqrt(Hz))
Kalibr ``gyroscope_random_walk``       ``gyro.rate_random_walk``        identical (rad/s^2/sqrt(Hz))
Kalibr ``accelerometer_noise_density``  ``accel.white_noise``           identical (m/s^2/sqrt(Hz))
Kalibr ``accelerometer_random_walk``   ``accel.rate_random_walk``       identical (m/s^3/sqrt(Hz))
VINS ``gyr_n``, ``gyr_w``, ``acc_n``, ``acc_w``  as the Kalibr keys     identical
i2Nav ``arw`` [deg/sqrt(h)], ``vrw`` [m/s/sqrt(h)]  ``white_noise``     unit names only
i2Nav ``gbstd`` [deg/h], ``abstd`` [mGal], ``corrtime`` [h]  ``bias_instability``
                                       (``kind: gm_sigma``, one Gauss-Markov state whose
                                       stationary law is also the turn-on value)
i2Nav ``gsstd``, ``asstd`` [ppm]       ``scale_factor`` (1-sigma)
datasheet ``<figure>_<unit>``          see :data:`DATASHEET_FIGURES`    the unit in the key name
=====================================  ===============================  ========================

Datasheet figures (a YAML file with a top-level ``datasheet:`` mapping; example in the README)::

    datasheet:
      part: InvenSense MPU-6050          # optional; the default grade name
      source: PS-MPU-6000A-00 rev 3.4    # optional
      rate_hz: 1000                      # optional: output data rate and -3 dB bandwidth;
      bandwidth_hz: 260                  #   together (bandwidth < rate/2) a bandwidth entry
                                         #   per sensor: Butterworth-2 at bandwidth_hz on a
                                         #   rate_hz internal grid
      filter: {filter: mpu6050_dlpf, setting: 3}   # optional instead: the part's own filter
                                         #   (a grade ``bandwidth`` entry, both sensors)
      density_sides: 2                   # optional: 1 if densities are one-sided ASDs
      spread: 1.5                        # optional: every drawn figure gets [v/1.5, v*1.5]
      gyro:
        noise_density_deg_per_s_per_sqrt_hz: 0.005    # or arw_deg_per_sqrt_h: 0.30
        bias_instability_deg_per_h: 4.6               # the Allan minimum
        bias_instability_correlation_time_s: 500      # optional (default 3600 s, warned)
        slow_bias_deg_per_h: 20                       # optional: a second, slow Gauss-Markov
        slow_bias_correlation_time_s: 150             #   (its Allan peak and its T, needed)
        turn_on_bias_deg_per_h: 200
        scale_factor_percent: {limit: 3}              # +-limit read as 3 sigma
        misalignment_mrad: 1.0
        g_sensitivity_deg_per_s_per_g: 0.1
        range_deg_per_s: 2000
      accel:
        noise_density_ug_per_sqrt_hz: 400              # or vrw_m_per_s_per_sqrt_h
        bias_instability_ug: 36
        ...

A figure key is a name of :data:`DATASHEET_FIGURES` followed by ``_`` and any unit name of
:mod:`imugen.core.units` of the right dimension (``deg_per_h``, ``mg``, ``ug_per_sqrt_hz``, ``ppm``,
``mrad``, ``g``...). A value is a number (a typical figure, read as 1 sigma), three per-axis
numbers, ``{typical: x}`` or ``{limit: x}`` (a +-x limit, read as 3 sigma, as the presets read
datasheet limits), each mapping with an optional ``source``. ``bias_instability`` is the
datasheet's Allan-deviation minimum (``kind: allan_floor``): :mod:`imugen.sensors.grades` models it as
one Gauss-Markov state of sigma ``floor / 0.618`` whose Allan peak (at ``tau = 1.89 T``) is the
floor (IEEE Std 952-1997 annex C), with ``bias_instability_correlation_time_<unit>``, or as a
flicker sum with ``bias_instability_flicker_band_<unit>: [min, max]``. ``slow_bias`` is a
second, slower Gauss-Markov process beside it (the grade's ``slow_bias``: the hump past the
floor that a real log shows, e.g. :func:`imugen.sensors.fit.fit_grade`'s), given by its Allan
peak (``kind: allan_floor``) with ``slow_bias_correlation_time_<unit>`` (required). (The IEEE 952 flicker
coefficient ``B`` is another quantity: a flat 1/f floor is ``0.664 B``; datasheets quote the
floor.)

Caveats (stated in every imported and exported file):

* Densities. Kalibr's ``*_noise_density`` is the continuous-time white-noise sigma
  ``sigma_c``: a sample at rate ``1/dt`` has ``sigma_d = sigma_c / sqrt(dt)``, and the bias
  walks by ``sigma_bc sqrt(dt)`` per sample. ``sigma_c^2`` is the *two-sided* PSD ``S2``
  (autocorrelation ``sigma_c^2 delta(t)``), and equals the IEEE 952 ``N^2`` (Allan deviation
  ``N`` at ``tau = 1 s``; ARW [deg/sqrt(h)] = 60 x ``N`` [deg/s/sqrt(Hz)]). A *one-sided* PSD is
  ``S1 = 2 S2``, so a one-sided amplitude density is ``sqrt(2)`` times Kalibr's number (a
  spectrum analyser or ``scipy.signal.welch`` reads ``sqrt(2) sigma_c``). imugen's densities are
  Kalibr's; datasheets that give ARW = 60 x density use the same number (the default,
  ``density_sides: 2``); a density measured as a one-sided ASD is divided by ``sqrt(2)``
  (``density_sides: 1``). ARW/VRW figures in deg/sqrt(h), m/s/sqrt(h) are Allan figures, ``N``
  itself, whatever the sides.
* ``sqrt(dt)``: the scaling assumes ideal anti-alias filtering at ``1/(2 dt)``; a part filtered
  below that has less per-sample noise than ``N / sqrt(dt)``.
* Kalibr has no turn-on bias, Gauss-Markov bias, scale factor, misalignment, g-sensitivity,
  temperature or quantization terms: importing it gives a grade with white noise and random
  walk only, and exporting a grade to Kalibr keeps only a projection (see :func:`to_kalibr`).
"""

from __future__ import annotations

import copy
import math
import sys
import warnings
from pathlib import Path

import numpy as np
import yaml

from imugen.core import units
from imugen.core.errors import InputError, printable
from imugen.sensors.bandwidth import spec_from_config
from imugen.sensors.grades import FIXED_TERMS, SENSORS, Grade, get_grade, grade_from_config
from imugen.sensors.options import GradeExportOptions, GradeImportOptions

KALIBR_KEYS = (
    "gyroscope_noise_density",
    "gyroscope_random_walk",
    "accelerometer_noise_density",
    "accelerometer_random_walk",
)
VINS_KEYS = {
    "gyr_n": KALIBR_KEYS[0],
    "gyr_w": KALIBR_KEYS[1],
    "acc_n": KALIBR_KEYS[2],
    "acc_w": KALIBR_KEYS[3],
}
I2NAV_KEYS = ("arw", "vrw", "gbstd", "abstd", "gsstd", "asstd", "corrtime")
CAVEAT = (
    "densities of the continuous-time model (two-sided; a one-sided ASD is sqrt(2) x these): "
    "rate-sample noise sigma = N / sqrt(dt), bias walk per sample = K sqrt(dt) (assumes ideal "
    "anti-alias filtering)"
)
_DATASHEET_COMMON = {
    "noise_density": "white_noise",
    "bias_instability": "bias_instability",
    "in_run_bias_stability": "bias_instability",
    "turn_on_bias": "turn_on_bias",
    "bias_repeatability": "turn_on_bias",
    "rate_random_walk": "rate_random_walk",
    "scale_factor": "scale_factor",
    "misalignment": "cross_coupling",
    "cross_axis": "cross_coupling",
    "quantization": "quantization",
    "range": "range",
    "temperature_bias": "temperature_bias",
    "temperature_scale_factor": "temperature_scale_factor",
    "slow_bias": "slow_bias",
}
DATASHEET_FIGURES: dict[str, dict[str, str]] = {
    "gyro": {"arw": "white_noise", **_DATASHEET_COMMON, "g_sensitivity": "g_sensitivity"},
    "accel": {"vrw": "white_noise", **_DATASHEET_COMMON},
}
"""Datasheet figure names per sensor -> imugen term (a key is ``<figure>_<unit name>``)."""
DATASHEET_KEYS = {
    "part",
    "source",
    "rate_hz",
    "bandwidth_hz",
    "filter",
    "density_sides",
    "spread",
}
_ONE_SIGMA_TERMS = (
    "turn_on_bias",
    "scale_factor",
    "cross_coupling",
    "g_sensitivity",
    "temperature_bias",
    "temperature_scale_factor",
)
DEFAULT_CORRELATION_TIME_S = 3600.0
"""Gauss-Markov correlation time of a datasheet bias instability given without one (the
presets' NavToolkit figure for the STIM300, HG1700 and HG9900)."""


def _number(doc: dict, key: str, origin) -> float:
    v = doc[key]
    if isinstance(v, list | tuple):  # i2Nav gives per-axis triples sometimes
        if len(v) != 3:
            raise InputError(origin, f"{key}: expected a number or three numbers, got {v!r}")
        v = float(np.mean([float(x) for x in v]))
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise InputError(origin, f"{key}: expected a number, got {v!r}") from None
    if not math.isfinite(x) or x < 0:
        raise InputError(origin, f"{key}: must be a finite number >= 0, got {v!r}")
    return x


def _find_block(doc, keys) -> dict | None:
    """The mapping (``doc`` or one nested level down) that holds any of ``keys``."""
    if not isinstance(doc, dict):
        return None
    if any(k in doc for k in keys):
        return doc
    for v in doc.values():
        if isinstance(v, dict) and any(k in v for k in keys):
            return v
    return None


def detect_format(doc) -> str:
    """``"kalibr"``, ``"vins"``, ``"i2nav"``, ``"datasheet"`` or ``"imugen"`` for a document."""
    if isinstance(doc, dict) and isinstance(doc.get("grades"), dict):
        return "imugen"
    if isinstance(doc, dict) and isinstance(doc.get("datasheet"), dict):
        return "datasheet"
    if _find_block(doc, KALIBR_KEYS) is not None:
        return "kalibr"
    if _find_block(doc, tuple(VINS_KEYS)) is not None:
        return "vins"
    if _find_block(doc, I2NAV_KEYS) is not None:
        return "i2nav"
    raise InputError(
        None,
        "not a known IMU description: expected Kalibr/EuRoC keys (gyroscope_noise_density, ...), "
        "VINS keys (gyr_n, acc_n, ...), an i2Nav imunoise block (arw, vrw, gbstd, ...), a "
        "'datasheet:' mapping of figures or an imugen grades document",
    )


def _kalibr_config(block: dict, origin, fmt: str) -> dict:
    src = f"{fmt} file {Path(str(origin)).name}"
    keys = KALIBR_KEYS if fmt == "kalibr" else tuple(VINS_KEYS)
    names = dict(zip(keys, KALIBR_KEYS, strict=True))
    vals = {names[k]: _number(block, k, origin) for k in keys if k in block}
    missing = [k for k in keys if k not in block]
    if len(missing) == len(keys):
        raise InputError(origin, f"no {fmt} noise keys found")
    cfg: dict = {"gyro": {}, "accel": {}}
    units = {
        "gyroscope_noise_density": ("gyro", "white_noise", "rad_per_s_per_sqrt_hz"),
        "gyroscope_random_walk": ("gyro", "rate_random_walk", "rad_per_s_per_sqrt_s"),
        "accelerometer_noise_density": ("accel", "white_noise", "m_per_s2_per_sqrt_hz"),
        "accelerometer_random_walk": ("accel", "rate_random_walk", "m_per_s2_per_sqrt_s"),
    }
    for key, v in vals.items():
        sensor, term, unit = units[key]
        if v > 0:
            cfg[sensor][term] = {"value": v, "unit": unit, "source": f"{src}: {key}; {CAVEAT}"}
    if "update_rate" in block or "rate_hz" in block:
        cfg["notes"] = f"update_rate {block.get('update_rate', block.get('rate_hz'))} Hz in {src}"
    return cfg


def _i2nav_config(block: dict, origin) -> dict:
    src = f"i2Nav imunoise block of {Path(str(origin)).name}"
    v = {k: _number(block, k, origin) for k in I2NAV_KEYS if k in block}
    cfg: dict = {"gyro": {}, "accel": {}}
    if "arw" in v:
        cfg["gyro"]["white_noise"] = {
            "value": v["arw"],
            "unit": "deg_per_sqrt_h",
            "source": f"{src}: arw",
        }
    if "vrw" in v:
        cfg["accel"]["white_noise"] = {
            "value": v["vrw"],
            "unit": "m_per_s_per_sqrt_h",
            "source": f"{src}: vrw",
        }
    if ("gbstd" in v or "abstd" in v) and not v.get("corrtime"):
        raise InputError(origin, "gbstd/abstd need corrtime (hours) for the Gauss-Markov bias")
    for key, sensor, unit in (("gbstd", "gyro", "deg_per_h"), ("abstd", "accel", "mgal")):
        if v.get(key):
            cfg[sensor]["bias_instability"] = {
                "value": v[key],
                "unit": unit,
                "kind": "gm_sigma",
                "model": "gauss_markov",
                "correlation_time": {"value": v["corrtime"], "unit": "h"},
                "source": f"{src}: {key}, corrtime (one GM state; its stationary law is the "
                "turn-on value, so no separate turn-on bias)",
            }
    for key, sensor in (("gsstd", "gyro"), ("asstd", "accel")):
        if v.get(key):
            cfg[sensor]["scale_factor"] = {
                "value": v[key],
                "unit": "ppm",
                "source": f"{src}: {key}",
            }
    return cfg


def _ds_value(v, origin, where, one_sigma: bool):
    """A datasheet value -> (value in the key's unit (float or 3 floats), how it was read)."""
    reading = "typical, read as 1 sigma" if one_sigma else "typical"
    src = ""
    if isinstance(v, dict):
        extra = set(v) - {"typical", "limit", "source"}
        if extra or len(set(v) & {"typical", "limit"}) != 1:
            raise InputError(origin, f"{where}: give a number, {{typical: x}} or {{limit: x}}")
        src = v.get("source", "")
        if not isinstance(src, str):
            raise InputError(origin, f"{where}.source: must be text")
        if "limit" in v:
            if not one_sigma:
                raise InputError(
                    origin,
                    f"{where}: a limit is read as 3 sigma only for biases, scale "
                    "factors, misalignments and sensitivities; give the typical value",
                )
            v, reading = v["limit"], "+-limit read as 3 sigma"
        else:
            v = v["typical"]
    vals = v if isinstance(v, list | tuple) else [v]
    if len(vals) not in (1, 3):
        raise InputError(origin, f"{where}: expected a number or three numbers, got {v!r}")
    out = []
    for x in vals:
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x) or x < 0:
            raise InputError(origin, f"{where}: must be finite numbers >= 0, got {v!r}")
        out.append(float(x) / (3.0 if reading.startswith("+-") else 1.0))
    return (out[0] if len(out) == 1 else out), reading + (f"; {src}" if src else "")


def _ds_split(key: str, figures: dict[str, str]):
    """``"<figure>_<unit>"`` -> (figure, unit), or None."""
    for fig in sorted(figures, key=len, reverse=True):
        if key.startswith(fig + "_") and key[len(fig) + 1 :] in units.UNITS:
            return fig, key[len(fig) + 1 :]
    return None


def _ds_sensor(block, sensor, top, origin) -> tuple[dict, list[str]]:
    """One sensor's datasheet figures -> (grade sensor configuration, warnings)."""
    figures = DATASHEET_FIGURES[sensor]
    if not isinstance(block, dict):
        raise InputError(origin, f"datasheet.{sensor}: expected a mapping of figures")
    cfg: dict = {}
    ct = band = slow_ct = None
    warn = []
    for key, v in block.items():
        where = f"datasheet.{sensor}.{key}"
        for extra in ("correlation_time", "flicker_band", "slow_correlation_time"):
            pre = (
                "slow_bias_correlation_time_"
                if extra == "slow_correlation_time"
                else f"bias_instability_{extra}_"
            )
            if isinstance(key, str) and key.startswith(pre):
                unit = key[len(pre) :]
                if units.UNITS.get(unit) is None or units.UNITS[unit].dimension != "time":
                    raise InputError(origin, f"{where}: unit {unit!r} is not a time unit")
                if extra == "slow_correlation_time":
                    slow_ct = {"value": _number(block, key, origin), "unit": unit}
                elif extra == "correlation_time":
                    ct = {"value": _number(block, key, origin), "unit": unit}
                elif not isinstance(v, list | tuple) or len(v) != 2:
                    raise InputError(origin, f"{where}: expected [min, max]")
                else:
                    band = {"min": v[0], "max": v[1], "unit": unit}
                break
        else:
            split = _ds_split(key, figures) if isinstance(key, str) else None
            if split is None:
                raise InputError(
                    origin,
                    f"{where}: not a datasheet figure; keys are <figure>_<unit> with figure one "
                    f"of {', '.join(figures)} and a unit of imugen.core.units (e.g. "
                    f"{'arw_deg_per_sqrt_h' if sensor == 'gyro' else 'vrw_m_per_s_per_sqrt_h'})",
                )
            fig, unit = split
            term = figures[fig]
            if term in cfg:
                raise InputError(origin, f"{where}: {term} given twice")
            val, reading = _ds_value(v, origin, where, term in _ONE_SIGMA_TERMS)
            if max(val if isinstance(val, list) else [val]) == 0:
                continue  # a zero figure is an absent term
            note = f"{Path(str(origin)).name}: {key} ({reading})"
            if term == "white_noise" and unit.endswith("_per_sqrt_hz") and top["sides"] == 1:
                r2 = math.sqrt(2.0)
                val = [x / r2 for x in val] if isinstance(val, list) else val / r2
                note += "; one-sided ASD / sqrt(2) (density_sides: 1)"
            entry = {"value": val, "unit": unit}
            if term == "turn_on_bias":
                entry["kind"] = "one_sigma"
            if term == "bias_instability":
                entry["kind"] = "allan_floor"
                note += "; the Allan minimum"
            if term == "slow_bias":
                entry["kind"] = "allan_floor"
                note += "; the Allan peak of a second, slow Gauss-Markov"
            spread = top["spread"]
            if spread and term not in FIXED_TERMS:
                vv = val if isinstance(val, list) else [val]
                if min(vv) > 0:
                    lo = [float(f"{x / spread:.6g}") for x in vv]
                    hi = [float(f"{x * spread:.6g}") for x in vv]
                    entry["range"] = [lo if len(lo) == 3 else lo[0], hi if len(hi) == 3 else hi[0]]
            entry["source"] = note
            cfg[term] = entry
    sb = cfg.get("slow_bias")
    if (sb is None) != (slow_ct is None):
        raise InputError(
            origin,
            f"datasheet.{sensor}: slow_bias_<unit> and slow_bias_correlation_time_<unit> go "
            "together (a second Gauss-Markov: its Allan peak and its correlation time)",
        )
    if sb is not None:
        sb["correlation_time"] = slow_ct
    bi = cfg.get("bias_instability")
    if (ct or band) and bi is None:
        raise InputError(
            origin,
            f"datasheet.{sensor}: a correlation time or flicker band needs "
            "a bias_instability figure",
        )
    if ct and band:
        raise InputError(
            origin,
            f"datasheet.{sensor}: give a correlation time (Gauss-Markov) or "
            "a flicker band, not both",
        )
    if bi is not None:
        if band:
            bi.update(model="flicker", flicker_band=band)
        else:
            if ct is None:
                ct = {"value": DEFAULT_CORRELATION_TIME_S, "unit": "s"}
                warn.append(
                    f"{sensor} bias instability without a correlation time: one Gauss-Markov "
                    f"state with T = {DEFAULT_CORRELATION_TIME_S:g} s assumed (give "
                    "bias_instability_correlation_time_s)"
                )
            bi.update(model="gauss_markov", correlation_time=ct)
    return cfg, warn


def _datasheet_config(ds: dict, origin) -> tuple[dict, list[str]]:
    """A ``datasheet:`` mapping -> (grade configuration without id, warnings)."""
    extra = set(ds) - DATASHEET_KEYS - set(SENSORS)
    if extra:
        raise InputError(
            origin,
            f"datasheet: unknown key(s) {sorted(map(str, extra))}; allowed "
            f"{sorted(DATASHEET_KEYS | set(SENSORS))}",
        )
    sides = ds.get("density_sides", 2)
    if sides not in (1, 2) or isinstance(sides, bool):
        raise InputError(origin, f"datasheet.density_sides: 1 or 2, got {sides!r}")
    spread = ds.get("spread")
    if spread is not None:
        spread = _number(ds, "spread", origin)
        if spread <= 1.0:
            raise InputError(origin, f"datasheet.spread: must be > 1, got {spread!r}")
    part = ds.get("part", "")
    if not isinstance(part, str) or not isinstance(ds.get("source", ""), str):
        raise InputError(origin, "datasheet: part and source must be text")
    src = f"{part or 'the part'}'s datasheet" + (f" ({ds['source']})" if ds.get("source") else "")
    top = {"sides": sides, "spread": spread}
    cfg: dict = {"source": f"{src}; figures in {Path(str(origin)).name}, imported by imugen"}
    if part:
        cfg["description"] = f"{part}: datasheet figures"
    warn: list[str] = []
    for sensor in SENSORS:
        if ds.get(sensor) is not None:
            cfg[sensor], w = _ds_sensor(ds[sensor], sensor, top, origin)
            warn += w
    if not any(cfg.get(s) for s in SENSORS):
        raise InputError(origin, "datasheet: no gyro or accel figures")
    rate = _number(ds, "rate_hz", origin) if "rate_hz" in ds else None
    bw = _number(ds, "bandwidth_hz", origin) if "bandwidth_hz" in ds else None
    band = None
    if ds.get("filter") is not None:
        band = dict(ds["filter"]) if isinstance(ds["filter"], dict) else ds["filter"]
        if isinstance(band, dict):
            band.setdefault("source", src)
        spec_from_config(band, origin, "datasheet.filter")
    elif rate and bw and bw < rate / 2:
        band = {
            "filter": "butterworth",
            "order": 2,
            "cutoff": {"value": bw, "unit": "hz"},
            "internal_rate": {"value": rate, "unit": "hz"},
            "source": f"{src}: output data rate {rate:g} Hz, bandwidth {bw:g} Hz; filter "
            "shape not given, read as a second-order Butterworth (imported by imugen)",
        }
        warn.append(
            f"bandwidth {bw:g} Hz < rate/2 = {rate / 2:g} Hz: read as a second-order "
            f"Butterworth at {bw:g} Hz on a {rate:g} Hz grid (the datasheet gives no shape)"
        )
    elif rate or bw:
        cfg["notes"] = (
            f"output rate {rate or '?'} Hz, bandwidth {bw or '?'} Hz ({src}); no filter "
            "below rate/2: white noise N / sqrt(dt) per sample"
        )
    if band is not None:
        for sensor in SENSORS:
            if cfg.get(sensor):
                cfg[sensor]["bandwidth"] = copy.deepcopy(band)
    return cfg, warn


def _slug(text: str) -> str:
    """A grade name (lower case letters, digits, underscores) from free text."""
    out = "".join(c if c.isascii() and c.isalnum() else "_" for c in text.lower())
    out = "_".join(p for p in out.split("_") if p) or "imu"
    return out if out[0].isalpha() else "imu_" + out


def import_grade(path, name: str | None = None, grade_id: int | None = None) -> tuple[str, dict]:
    """Read an IMU description and return ``(name, grade configuration)``, validated.

    Lossy or assumed readings (a default correlation time, a narrow bandwidth) are reported
    with :func:`warnings.warn` (the CLI prints them as ``imugen: warning:`` lines).

    Parameters
    ----------
    path : path
        Kalibr/EuRoC ``imu.yaml`` / ``sensor.yaml``, a VINS config, an i2Nav/KF-GINS config
        holding an ``imunoise`` block, a ``datasheet:`` file, or an imugen grades document
        (its first grade).
    name : str, optional
        Grade name (default: an imugen grade's own name, a datasheet's ``part``, else the file
        name, lower case).
    grade_id : int, optional
        Stable id of the new grade (>= 100; part of every seed). Default: an imugen grade's own
        id, else 1000.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(path, f"cannot read ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise InputError(path, "is not UTF-8 text") from None
    # Kalibr/EuRoC files begin with %YAML:1.0 (OpenCV), which PyYAML refuses
    text = "\n".join(ln for ln in text.splitlines() if not ln.startswith("%YAML"))
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise InputError(path, f"not valid YAML: {str(exc).splitlines()[0]}") from None
    except RecursionError:
        raise InputError(path, "is nested too deeply to be an IMU description") from None
    try:
        fmt = detect_format(doc)
    except InputError as exc:
        raise InputError(path, exc.message) from None
    if grade_id is not None and (
        isinstance(grade_id, bool) or not isinstance(grade_id, int) or not 100 <= grade_id < 2**31
    ):
        raise InputError("--id", f"custom grade ids are integers in [100, 2^31), got {grade_id!r}")
    notes: list[str] = []
    if fmt == "imugen":
        gname, cfg = next(iter(doc["grades"].items()), (None, None))
        if not isinstance(cfg, dict):
            raise InputError(path, "grades: expected at least one grade mapping")
        cfg = {**cfg, "id": cfg.get("id") if grade_id is None else grade_id}
        name = name or gname
        gid = cfg["id"]
        if isinstance(gid, bool) or not isinstance(gid, int) or not 100 <= gid < 2**31:
            raise InputError(
                path, f"grade {gname!r}: id {gid!r} is not a custom id in [100, 2^31); give --id"
            )
    else:
        if fmt == "datasheet":
            cfg, notes = _datasheet_config(doc["datasheet"], path)
            default = _slug(doc["datasheet"].get("part") or path.stem)
        else:
            default = _slug(path.stem)
            if fmt == "i2nav":
                cfg = _i2nav_config(_find_block(doc, I2NAV_KEYS), path)
            else:
                keys = KALIBR_KEYS if fmt == "kalibr" else tuple(VINS_KEYS)
                cfg = _kalibr_config(_find_block(doc, keys), path, fmt)
        name = name or default
        cfg = {
            "id": 1000 if grade_id is None else grade_id,
            "description": f"imported from {path.name} ({fmt})",
            "source": f"{path.name} ({fmt}); imported by imugen grade import",
            **cfg,
        }
    grade_from_config(name, cfg, str(path))  # raises InputError when invalid
    for note in notes:
        warnings.warn(note, stacklevel=2)
    return name, cfg


def grades_document(name: str, cfg: dict) -> str:
    """A grades YAML document (for ``--grades-file`` or a workflow config's ``grades:``)."""
    head = "# imugen grade (imported); semantics in src/imugen/sensors/grades.py and grade_io.py\n"
    return head + yaml.safe_dump({"grades": {name: cfg}}, sort_keys=False)


def kalibr_figures(grade: Grade | str, rate_hz: float | None = None) -> dict[str, float]:
    """The four Kalibr numbers that best represent a grade (SI, axis means).

    ``*_noise_density`` is the white-noise density; for a sensor with an output bandwidth
    read at ``rate_hz``, the density of the output's Allan white line ``N sqrt(g)``
    (:meth:`~imugen.sensors.bandwidth.OutputFilter.output_density`: what Kalibr's white-noise
    model, which assumes ideal sampling, sees at long times). ``*_random_walk`` is the rate random walk
    combined with the driving noise of the in-run Gauss-Markov bias: a GM state of sigma
    ``s`` and correlation time ``T`` walks like a random walk of density ``s sqrt(2 / T)``
    over times short against ``T`` (the regime a calibration filter's bias state sees), so
    ``K_kalibr = sqrt(K_rrw^2 + 2 s^2 / T)`` (a flicker bias sums its components). This is a
    heuristic: Kalibr's ``random_walk`` is a rate random walk (Allan slope +1/2), and a
    bias-instability floor is not one (kalibr #450, #622: no standard conversion exists; the
    other common reading, the +1/2 line touching the floor ``B`` at ``tau_B``,
    ``K = B sqrt(3 / tau_B)``, depends on an equally assumed time). With ``s = B / 0.618`` a
    datasheet floor ``B`` gives ``K = 2.29 B / sqrt(T)``. A ``slow_bias`` (a second
    Gauss-Markov) adds its own ``2 s^2 / T`` the same way. Turn-on bias, scale factor,
    misalignment, g-sensitivity, temperature and quantization have no Kalibr field and are
    dropped; per-axis values are averaged.
    """
    g = get_grade(grade)
    out = {}
    for sensor, prefix in ((g.gyro, "gyroscope"), (g.accel, "accelerometer")):
        w = 0.0 if sensor.white_noise is None else float(np.mean(sensor.white_noise.value))
        if sensor.bandwidth is not None and rate_hz is not None:
            w = sensor.bandwidth.output_filter(sensor.sensor, rate_hz).output_density(w)
        k2 = (
            0.0
            if sensor.rate_random_walk is None
            else float(np.mean(sensor.rate_random_walk.value)) ** 2
        )
        for bi in (sensor.bias_instability, sensor.slow_bias):
            if bi is None:
                continue
            sig = bi.sigma_from_level(float(np.mean(bi.level.value)))
            if bi.model == "gauss_markov":
                taus = [float(np.mean(bi.correlation_time.value))]
            else:
                from imugen.sensors.grades import flicker_taus

                taus = list(flicker_taus(bi.flicker_band, bi.components))
            k2 += sum(2.0 * sig**2 / T for T in taus)
        out[f"{prefix}_noise_density"] = w
        out[f"{prefix}_random_walk"] = math.sqrt(k2)
    return out


def to_kalibr(grade: Grade | str, rate_hz: float = 100.0, topic: str = "/imu0") -> str:
    """A Kalibr ``imu.yaml`` for a grade, labelled as a simplification of the full model."""
    g = get_grade(grade)
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise InputError("--rate-hz", f"must be a positive number, got {rate_hz!r}")
    fig = kalibr_figures(g, rate_hz)
    band = []
    for sp in (g.gyro, g.accel):
        if sp.bandwidth is not None:
            f = sp.bandwidth.output_filter(sp.sensor, rate_hz)
            band.append(
                f"# {sp.sensor} output bandwidth: {f.label}, -3 dB {f.cutoff_3db_hz():.4g} Hz, "
                f"read at {rate_hz:g} Hz; noise_density is the output's white line N sqrt(g), "
                f"g = {f.alias_gain():.4g} (sensor density "
                f"{float(np.mean(sp.white_noise.value)) if sp.white_noise else 0.0:.6e})."
            )
    dropped = [
        t
        for s in (g.gyro, g.accel)
        for t in s.configured()
        if t not in ("white_noise", "rate_random_walk", "bias_instability", "slow_bias")
    ]
    axes = sorted(
        {
            f"{s.sensor}.{t}"
            for s in (g.gyro, g.accel)
            for t in ("white_noise", "rate_random_walk")
            if getattr(s, t) is not None and len(set(getattr(s, t).value)) > 1
        }
    )
    lines = [
        f"# Kalibr IMU noise model of imugen grade {g.name!r} (id {g.id}).",
        "# A SIMPLIFICATION of the full model: white noise and random walk only.",
        "# random_walk = sqrt(RRW^2 + sum 2 sigma_GM^2 / T_GM) (in-run Gauss-Markov biases, the",
        "# slow_bias included, as a walk;",
        "# a heuristic: a bias-instability floor is not a rate random walk).",
        f"# Dropped terms (no Kalibr field): {', '.join(sorted(set(dropped))) or 'none'}.",
        *([f"# Per-axis values averaged: {', '.join(axes)}."] if axes else []),
        *band,
        f"# {CAVEAT}.",
    ]
    body = {
        **{k: float(f"{v:.6e}") for k, v in fig.items()},
        "rostopic": topic,
        "update_rate": float(rate_hz),
    }
    return "\n".join(lines) + "\n" + yaml.safe_dump(body, sort_keys=False)


def write_text(out, text: str) -> Path:
    """Write ``text`` atomically."""
    from imugen.core.io import atomic_output

    with atomic_output(out) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(out)


def main_import(options: GradeImportOptions, file, output) -> None:
    """``imugen grade import``: the grades document to ``output``, else to stdout; the
    reading's warnings as ``imugen: warning: FILE: ...`` lines."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        name, cfg = import_grade(file, name=options.name, grade_id=options.grade_id)
    for w in caught:
        print(printable(f"imugen: warning: {file}: {w.message}"), file=sys.stderr)
    text = grades_document(name, cfg)
    if output:
        write_text(output, text)
        print(f"{output}: grade {name!r} (id {cfg.get('id')})", file=sys.stderr)
    else:
        print(text, end="")


def main_export(options: GradeExportOptions, grade, output) -> None:
    """``imugen grade export``: the Kalibr file to ``output``, else to stdout."""
    g = get_grade(grade, options.grades_file)
    text = to_kalibr(g, rate_hz=options.rate_hz, topic=options.topic)
    if output:
        write_text(output, text)
    else:
        print(text, end="")
