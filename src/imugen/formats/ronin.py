"""RoNIN-style HDF5: ``<seq>/data.hdf5`` + ``<seq>/info.json`` (needs h5py).

``synced/time`` (s), ``synced/gyro_uncalib`` and ``synced/gyro`` (measured angular rate, body
frame; RoNIN subtracts ``info.imu_init_gyro_bias``, written as zeros so both are the measured
signal), ``synced/acce`` (measured specific force, +g on z at rest), ``synced/game_rv`` and
``pose/ekf_ori`` (TRUE attitude ``q_nb``, scalar first ``w, x, y, z`` as RoNIN's loaders read
it with ``quaternion.from_float_array``), ``pose/tango_pos`` (true position, ENU metres) and
``pose/tango_ori`` (true attitude). ``info.json`` carries the keys RoNIN's sequence loaders read
(``imu_init_gyro_bias``, ``imu_acce_bias``, ``imu_acce_scale``, ``grv_ori_error``,
``ekf_ori_error``, ``ori_source``, ``start_frame``) and imugen's provenance.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from imugen.errors import InputError
from imugen.formats.common import measured_rates
from imugen.formats.source import Sequence, TruthArrays


def write(seq: Sequence, truth: TruthArrays, folder: Path, **_) -> list[Path]:
    try:
        import h5py
    except ImportError:
        raise InputError("--format ronin", "needs h5py (pip install h5py)") from None
    folder.mkdir(parents=True, exist_ok=True)
    t, w, f, kind = measured_rates(seq, truth)
    if kind == "samples":
        q, p = truth.q_nb, truth.p_n
    else:
        q = truth.q_nb[1:] + truth.q_nb[:-1]
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        p = 0.5 * (truth.p_n[1:] + truth.p_n[:-1])
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
        "imu_init_gyro_bias": [0.0, 0.0, 0.0],
        "imu_acce_bias": [0.0, 0.0, 0.0],
        "imu_acce_scale": [1.0, 1.0, 1.0],
        "grv_ori_error": 0.0,
        "ekf_ori_error": 0.0,
        "ori_source": "game_rv",
        "start_frame": 0,
        "device": "imugen",
        "imugen": {
            "sequence": int(seq.id),
            "imu": f"measured {kind} with this sequence's sensor errors; orientations are true",
            "frames": "world = route ENU; body x forward, y left, z up",
        },
    }
    (folder / "info.json").write_text(json.dumps(info, indent=2))
    return [path, folder / "info.json"]
