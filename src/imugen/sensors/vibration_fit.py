"""``imugen vibration fit``: a recording's vibration as a model (:mod:`imugen.sensors.vibration_model`).

The recording is a CSV or Parquet of the IMU: a time column (``time_s`` [s], or EuRoC's
``#timestamp`` [ns]) and the gyro and accelerometer columns (``gyro_{x,y,z}_radps`` and
``accel_{x,y,z}_mps2`` as imugen writes them, or EuRoC's ``w_RS_S_*``, ``a_RS_S_*``). Its
residual is the recording minus the truth's ideal IMU (an imugen truth table on the same clock,
interpolated to the recording's times), or minus its mean for a still, motor-running record.
The rotation is given (``--rotation-hz``), read from a column of rotor speeds in rpm
(``--rpm-column``; the mean of several), or estimated from the lines. The model is written as
YAML (``vibration:`` the model, ``fit_report:`` what the fit found); the presets and fitted
models are configuration, never part of the grades file.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import yaml

from imugen.core.errors import InputError
from imugen.core.io import atomic_output
from imugen.sensors.options import VibrationFitOptions
from imugen.sensors.vibration_model import fit_vibration

GYRO = ("gyro_x_radps", "gyro_y_radps", "gyro_z_radps")
ACCEL = ("accel_x_mps2", "accel_y_mps2", "accel_z_mps2")
_EUROC = {
    "w_rs_s_x": GYRO[0], "w_rs_s_y": GYRO[1], "w_rs_s_z": GYRO[2],
    "a_rs_s_x": ACCEL[0], "a_rs_s_y": ACCEL[1], "a_rs_s_z": ACCEL[2],
}  # fmt: skip


def _name(c: str) -> str:
    return c.strip().lstrip("#").strip().split(" [")[0].strip().lower()


def read_record(path) -> tuple[np.ndarray, dict]:
    """Times [s] (N,) and columns (name -> (N,)) of an IMU recording (CSV or Parquet)."""
    import pandas as pd

    path = Path(path)
    try:
        df = pd.read_parquet(path) if path.suffix.lower() == ".parquet" else pd.read_csv(path)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except Exception as exc:  # pandas' parser errors
        raise InputError(path, f"is not a readable CSV or Parquet table ({exc})") from None
    cols = {}
    for c in df.columns:
        n = _name(str(c))
        cols[_EUROC.get(n, n)] = df[c].to_numpy()
    if "timestamp" in cols:
        ns = np.asarray(cols["timestamp"], np.int64)
        t = (ns - ns[0]) * 1e-9
    elif "time_s" in cols:
        t = np.asarray(cols["time_s"], float)
    else:
        raise InputError(path, "has no time column (time_s [s] or EuRoC's #timestamp [ns])")
    missing = [c for c in (*GYRO, *ACCEL) if c not in cols]
    if missing:
        raise InputError(path, f"lacks the IMU columns {', '.join(missing)}")
    if len(t) < 256 or not np.all(np.diff(t) > 0):
        raise InputError(path, "needs at least 256 samples at increasing times")
    return t, cols


def residual(t, cols, truth_path=None) -> np.ndarray:
    """(N, 6) gyro and accelerometer residual: recording minus the truth (interpolated), or
    minus its mean."""
    X = np.column_stack([np.asarray(cols[c], float) for c in (*GYRO, *ACCEL)])
    if truth_path is None:
        return X - X.mean(axis=0)
    from imugen.tables import truth as ttable

    tr = ttable.read(truth_path, need_meta=False)
    tt = tr.time_s
    ideal = np.column_stack([tr.omega_ib_b, tr.f_b])
    ref = np.column_stack([np.interp(t, tt, ideal[:, j]) for j in range(6)])
    inside = (t >= tt[0]) & (t <= tt[-1])
    if inside.sum() < 256:
        raise InputError(truth_path, "covers too little of the recording's time span")
    return (X - ref)[inside]


def run(record, output, *, truth=None, rotation_hz=None, rpm_column=None, reference=None,
        f_min_hz=2.0) -> dict:  # fmt: skip
    """Fit the recording's vibration and write the YAML; returns its mapping."""
    t, cols = read_record(record)
    dt = float(np.median(np.diff(t)))
    rate = 1.0 / dt
    if np.max(np.abs(np.diff(t) - dt)) > 0.05 * dt:
        print(
            f"imugen: warning: {record}: irregular sampling; treated as {rate:.6g} Hz",
            file=sys.stderr,
        )
    X = residual(t, cols, truth)
    rot = rotation_hz
    if rpm_column:
        names = [c.strip() for c in rpm_column.split(",")]
        bad = [n for n in names if n not in cols]
        if bad:
            raise InputError(record, f"has no column {', '.join(bad)} (--rpm-column)")
        rpm = np.mean([np.asarray(cols[n], float) for n in names], axis=0)
        rot = (rpm / 60.0)[: len(X)]
    ref = None
    if reference is not None:
        tr_, cr = read_record(reference)
        ref = residual(tr_, cr)
    if rot is not None and np.ndim(rot) == 0 and not (math.isfinite(rot) and rot > 0):
        raise InputError("--rotation-hz", f"{rot!r} must be a positive number")
    model, rep = fit_vibration(X, rate, rot, reference=ref, f_min_hz=f_min_hz)
    out = {
        "vibration": _plain(model.as_dict()),
        "fit_report": _plain(
            {
                **rep,
                "record": str(record),
                "truth": None if truth is None else str(truth),
                "rate_hz": rate,
            }
        ),
    }
    with atomic_output(output) as tmp:
        tmp.write_text(yaml.safe_dump(out, sort_keys=False))
    return out


def _plain(x):
    """numpy scalars and tuples -> YAML-safe Python values."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, np.generic):
        return x.item()
    return x


def main(options: VibrationFitOptions, record, output) -> None:
    """``imugen vibration fit``."""
    o = options
    out = run(
        record, output, truth=o.truth, rotation_hz=o.rotation_hz, rpm_column=o.rpm_column,
        reference=o.reference, f_min_hz=o.f_min_hz,
    )  # fmt: skip
    m, r = out["vibration"], out["fit_report"]
    orders = ", ".join(f"{h['order']:g}" for h in m["harmonics"]) or "none"
    print(
        f"{output}: rotation {m['rotation_hz']:.4g} Hz ({r['rotation_source']}), orders {orders}, "
        f"{len(m['lines'])} fixed lines, broadband accel RMS "
        f"{', '.join(f'{x:.3g}' for x in m['accel_rms_mps2'])} m/s^2",
        file=sys.stderr,
    )
    for w in r["warnings"]:
        print(f"imugen: warning: {record}: {w}", file=sys.stderr)
