"""RoNIN-style HDF5: ``<seq>/data.hdf5`` + ``<seq>/info.json`` (needs h5py), and the split lists.

``synced/time`` (s), ``synced/gyro_uncalib`` and ``synced/gyro`` (measured angular rate, body
frame; RoNIN subtracts ``info.imu_init_gyro_bias``, written as zeros so both are the measured
signal), ``synced/acce`` (measured specific force, +g on z at rest), ``synced/game_rv`` and
``pose/ekf_ori`` (TRUE attitude ``q_nb``, scalar first ``w, x, y, z`` as RoNIN's loaders read
it with ``quaternion.from_float_array``), ``pose/tango_pos`` (true position, ENU metres) and
``pose/tango_ori`` (true attitude). ``info.json`` carries every key RoNIN's loaders read
(``source/data_utils.py`` ``select_orientation_source``, ``source/data_glob_speed.py``
``GlobSpeedSequence.load``, ``source/data_glob_heading.py``, Sachini/ronin 805b7f0):

* ``imu_init_gyro_bias``, ``imu_end_gyro_bias``, ``imu_acce_bias`` zeros and
  ``imu_acce_scale`` ones (the synced signals are the measured ones, uncalibrated);
* ``grv_ori_error`` and ``ekf_ori_error`` 0 (those orientations are the truth) and
  ``gyro_integration_error``: the attitude error [deg] at the end of integrating the exported
  gyro from the true initial attitude, as RoNIN's ``gyro_integration`` does, against the same
  integration of the true rates (the sensor errors' share), so that RoNIN's source selection
  (``argmin`` of the three) picks the true orientation;
* ``start_calibration``, ``end_calibration`` (IMU to Tango frame) and ``align_tango_to_body``
  identity ``[1, 0, 0, 0]`` (the IMU is the body; Tango's pose is the IMU's);
* ``ori_source``, ``start_frame``, ``device``, ``length`` (s), ``imu_time_offset`` (0).

``list_train.txt``, ``list_val.txt``, ``list_test.txt`` (written by :func:`imugen.export.stage.export`)
name the sequence folders of each part of imugen's split, one a line, as RoNIN's ``--train_list``
etc. read them (relative to ``--root_dir``, the ``ronin`` folder).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.core.jit import njit
from imugen.export.common import measured_rates
from imugen.export.source import Sequence, TruthArrays

IDENTITY = [1.0, 0.0, 0.0, 0.0]


@njit(cache=True)
def _qmul(a, b):
    return (
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    )


@njit(cache=True)
def _qexp(x, y, z):
    th = math.sqrt(x * x + y * y + z * z)
    k = 0.5 if th < 1e-12 else math.sin(0.5 * th) / th
    return (math.cos(0.5 * th), k * x, k * y, k * z)


@njit(cache=True)
def _end_error_rad(w_est, w_ref, dt):
    """Angle [rad] of ``q_ref^-1 q_est`` after integrating body rates (n, 3) over the n - 1
    intervals ``dt`` (n - 1,) from a common start, each rate held over its interval."""
    e = (1.0, 0.0, 0.0, 0.0)
    for k in range(len(dt)):
        h = dt[k]
        a = _qexp(-w_ref[k, 0] * h, -w_ref[k, 1] * h, -w_ref[k, 2] * h)
        b = _qexp(w_est[k, 0] * h, w_est[k, 1] * h, w_est[k, 2] * h)
        e = _qmul(_qmul(a, e), b)
        n = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3])
        e = (e[0] / n, e[1] / n, e[2] / n, e[3] / n)
    v = math.sqrt(e[1] * e[1] + e[2] * e[2] + e[3] * e[3])
    return 2.0 * math.atan2(v, abs(e[0]))


def gyro_integration_error_deg(t, w_meas, w_true) -> float:
    """End attitude error [deg] of integrating ``w_meas`` (n, 3) rad/s at times ``t`` (n,) s
    against integrating ``w_true`` the same way (RoNIN's rule: ``gyro[i-1]`` over
    ``[t[i-1], t[i]]``)."""
    w_meas = np.ascontiguousarray(w_meas, dtype=np.float64)
    w_true = np.ascontiguousarray(w_true, dtype=np.float64)
    return math.degrees(_end_error_rad(w_meas, w_true, np.diff(np.asarray(t, np.float64))))


def write(seq: Sequence, truth: TruthArrays, folder: Path, **_) -> list[Path]:
    try:
        import h5py
    except ImportError:
        raise InputError("--format ronin", "needs h5py (pip install h5py)") from None
    folder.mkdir(parents=True, exist_ok=True)
    t, w, f, kind = measured_rates(seq, truth)
    if kind == "samples":
        q, p, w_true = truth.q_nb, truth.p_n, truth.gyro
    else:
        q = truth.q_nb[1:] + truth.q_nb[:-1]
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        p = 0.5 * (truth.p_n[1:] + truth.p_n[:-1])
        w_true = truth.dtheta[1:] / truth.dt
    path = folder / "data.hdf5"
    with h5py.File(path, "w", track_order=True) as h:
        h.create_dataset("synced/time", data=t)
        h.create_dataset("synced/gyro_uncalib", data=w)
        h.create_dataset("synced/gyro", data=w)
        h.create_dataset("synced/acce", data=f)
        h.create_dataset("synced/game_rv", data=q)
        h.create_dataset("pose/ekf_ori", data=q)
        h.create_dataset("pose/tango_pos", data=p)
        h.create_dataset("pose/tango_ori", data=q)
    info = {
        "type": "imugen",
        "device": "imugen",
        "length": float(t[-1] - t[0]),
        "imu_init_gyro_bias": [0.0, 0.0, 0.0],
        "imu_end_gyro_bias": [0.0, 0.0, 0.0],
        "imu_acce_bias": [0.0, 0.0, 0.0],
        "imu_acce_scale": [1.0, 1.0, 1.0],
        "gyro_integration_error": gyro_integration_error_deg(t, w, w_true),
        "grv_ori_error": 0.0,
        "ekf_ori_error": 0.0,
        "start_calibration": IDENTITY,
        "end_calibration": IDENTITY,
        "imu_time_offset": 0.0,
        "align_tango_to_body": IDENTITY,
        "ori_source": "game_rv",
        "start_frame": 0,
        "imugen": {
            "sequence": int(seq.id),
            "imu": f"measured {kind} with this sequence's sensor errors; orientations are true",
            "frames": "world = route ENU; body x forward, y left, z up; Tango = body",
            "ori_errors": "degrees at the end; gyro_integration_error: sensor errors' share",
        },
    }
    (folder / "info.json").write_text(json.dumps(info, indent=2))
    return [path, folder / "info.json"]
