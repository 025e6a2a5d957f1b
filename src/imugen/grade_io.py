"""Grades from the files users have (Kalibr/EuRoC, VINS, i2Nav/KF-GINS), and back to Kalibr.

Import (``imugen grade import FILE``) reads one of these and returns an imugen grade
configuration (datasheet units, every figure with its ``source``), validated by
:func:`imugen.grades.grade_from_config`:

================================  =====================================  ======================
file key                          imugen term                            conversion
================================  =====================================  ======================
Kalibr ``gyroscope_noise_density``  ``gyro.white_noise``                 identical (rad/s/sqrt(Hz))
Kalibr ``gyroscope_random_walk``    ``gyro.rate_random_walk``            identical (rad/s^2/sqrt(Hz))
Kalibr ``accelerometer_noise_density`` ``accel.white_noise``             identical (m/s^2/sqrt(Hz))
Kalibr ``accelerometer_random_walk`` ``accel.rate_random_walk``          identical (m/s^3/sqrt(Hz))
VINS ``gyr_n``, ``gyr_w``, ``acc_n``, ``acc_w``  as the Kalibr keys above  identical
i2Nav ``arw`` [deg/sqrt(h)], ``vrw`` [m/s/sqrt(h)]  ``white_noise``      unit names only
i2Nav ``gbstd`` [deg/h], ``abstd`` [mGal], ``corrtime`` [h]  ``bias_instability``
                                  (``kind: gm_sigma``, one Gauss-Markov state whose stationary
                                  law is also the turn-on value: no separate turn-on bias)
i2Nav ``gsstd``, ``asstd`` [ppm]  ``scale_factor`` (1-sigma)
================================  =====================================  ======================

Caveats (stated in every imported and exported file):

* Kalibr's densities are those of the continuous-time model; a sample of a sensor at rate
  ``1/dt`` has white-noise standard deviation ``N / sqrt(dt)`` and its bias walks by
  ``K sqrt(dt)`` per sample. imugen uses exactly these relations, so the numbers are the same
  quantity. The ``sqrt(dt)`` scaling assumes ideal anti-alias filtering; datasheets that quote a
  noise density in deg/s/sqrt(Hz) mean the same amplitude density (ARW [deg/sqrt(h)] = density
  [deg/s/sqrt(Hz)] x 60). Figures fitted as "two-sided" PSDs must be converted by the user.
* Kalibr has no turn-on bias, Gauss-Markov bias, scale factor, misalignment, g-sensitivity,
  temperature or quantization terms: importing it gives a grade with white noise and random
  walk only, and exporting a grade to Kalibr keeps only a projection (see :func:`to_kalibr`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from imugen.errors import InputError
from imugen.grades import Grade, get_grade, grade_from_config

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
    "densities of the continuous-time model: rate-sample noise sigma = N / sqrt(dt), bias walk "
    "per sample = K sqrt(dt) (assumes ideal anti-alias filtering)"
)


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
    """``"kalibr"``, ``"vins"``, ``"i2nav"`` or ``"imugen"`` for a parsed document."""
    if isinstance(doc, dict) and isinstance(doc.get("grades"), dict):
        return "imugen"
    if _find_block(doc, KALIBR_KEYS) is not None:
        return "kalibr"
    if _find_block(doc, tuple(VINS_KEYS)) is not None:
        return "vins"
    if _find_block(doc, I2NAV_KEYS) is not None:
        return "i2nav"
    raise InputError(
        None,
        "not a known IMU description: expected Kalibr/EuRoC keys (gyroscope_noise_density, ...), "
        "VINS keys (gyr_n, acc_n, ...), an i2Nav imunoise block (arw, vrw, gbstd, ...) or an "
        "imugen grades document",
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


def import_grade(path, name: str | None = None, grade_id: int = 1000) -> tuple[str, dict]:
    """Read an IMU description and return ``(name, grade configuration)``, validated.

    Parameters
    ----------
    path : path
        Kalibr/EuRoC ``imu.yaml`` / ``sensor.yaml``, a VINS config, an i2Nav/KF-GINS config
        holding an ``imunoise`` block, or an imugen grades document (first grade taken).
    name : str, optional
        Grade name (default: from the file name, lower case).
    grade_id : int
        Stable id of the new grade (>= 100; part of every seed).
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
    try:
        fmt = detect_format(doc)
    except InputError as exc:
        raise InputError(path, exc.message) from None
    if isinstance(grade_id, bool) or not isinstance(grade_id, int) or not 100 <= grade_id < 2**31:
        raise InputError("--id", f"custom grade ids are integers in [100, 2^31), got {grade_id!r}")
    default = "".join(c if c.isalnum() else "_" for c in path.stem.lower()).strip("_") or "imu"
    if not default[0].isalpha():
        default = "imu_" + default
    name = name or default
    if fmt == "imugen":
        gname, cfg = next(iter(doc["grades"].items()))
        grade_from_config(gname, cfg, str(path))
        return name or gname, cfg
    if fmt == "i2nav":
        cfg = _i2nav_config(_find_block(doc, I2NAV_KEYS), path)
    else:
        keys = KALIBR_KEYS if fmt == "kalibr" else tuple(VINS_KEYS)
        cfg = _kalibr_config(_find_block(doc, keys), path, fmt)
    cfg = {
        "id": grade_id,
        "description": f"imported from {path.name} ({fmt})",
        "source": f"{path.name} ({fmt}); imported by imugen grade import",
        **cfg,
    }
    grade_from_config(name, cfg, str(path))  # raises InputError when invalid
    return name, cfg


def grades_document(name: str, cfg: dict) -> str:
    """A grades YAML document (for ``--grades-file`` or a workflow config's ``grades:``)."""
    head = "# imugen grade (imported); semantics in src/imugen/grades.py and grade_io.py\n"
    return head + yaml.safe_dump({"grades": {name: cfg}}, sort_keys=False)


def kalibr_figures(grade: Grade | str) -> dict[str, float]:
    """The four Kalibr numbers that best represent a grade (SI, axis means).

    ``*_noise_density`` is the white-noise density. ``*_random_walk`` is the rate random walk
    combined with the driving noise of the in-run Gauss-Markov bias: a GM state of sigma
    ``s`` and correlation time ``T`` walks like a random walk of density ``s sqrt(2 / T)``
    over times short against ``T`` (the regime a calibration filter's bias state sees), so
    ``K_kalibr = sqrt(K_rrw^2 + 2 s^2 / T)``. Turn-on bias, scale factor, misalignment,
    g-sensitivity, temperature and quantization have no Kalibr field and are dropped.
    """
    g = get_grade(grade)
    out = {}
    for sensor, prefix in ((g.gyro, "gyroscope"), (g.accel, "accelerometer")):
        w = 0.0 if sensor.white_noise is None else float(np.mean(sensor.white_noise.value))
        k2 = (
            0.0
            if sensor.rate_random_walk is None
            else float(np.mean(sensor.rate_random_walk.value)) ** 2
        )
        bi = sensor.bias_instability
        if bi is not None:
            sig = bi.sigma_from_level(float(np.mean(bi.level.value)))
            if bi.model == "gauss_markov":
                taus = [float(np.mean(bi.correlation_time.value))]
            else:
                from imugen.grades import flicker_taus

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
    fig = kalibr_figures(g)
    dropped = [
        t
        for s in (g.gyro, g.accel)
        for t in s.configured()
        if t not in ("white_noise", "rate_random_walk", "bias_instability")
    ]
    lines = [
        f"# Kalibr IMU noise model of imugen grade {g.name!r} (id {g.id}).",
        "# A SIMPLIFICATION of the full model: white noise and random walk only.",
        "# random_walk = sqrt(RRW^2 + 2 sigma_GM^2 / T_GM) (in-run Gauss-Markov bias as a walk).",
        f"# Dropped terms (no Kalibr field): {', '.join(sorted(set(dropped))) or 'none'}.",
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
    from imugen.io import atomic_output

    with atomic_output(out) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(out)
