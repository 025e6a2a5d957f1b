"""TLIO layout: ``<seq>/imu0_resampled.npy`` + ``imu0_resampled_description.json``.

``imu0_resampled.npy`` is ``(K, 17)`` float64: ``ts_us``, ``gyr_compensated_rotated_in_World``
(3), ``acc_compensated_rotated_in_World`` (3), ``qxyzw_World_Device`` (4),
``pos_World_Device`` (3), ``vel_World`` (3). World = the route's ENU frame (gravity aligned,
z up, as TLIO's); Device = body. The IMU columns are the MEASURED rates (with this sequence's
sensor errors; TLIO's own data are bias-compensated by its VIO) rotated into World with the
TRUE attitude; the specific force keeps gravity's reaction (+g on z at rest), as TLIO's does.
The split lists ``train_list.txt``, ``val_list.txt``, ``test_list.txt`` name the sequence
folders of each part of imugen's leakage-safe split.

Training with TLIO (checked against its ``src/main_net.py`` at commit ``d7051c4``, 2023-08-07,
the current ``master``; :func:`train_command`): the split lists are read from ``--root_dir``
(``<split>_list.txt``: the former ``--train_list``, ``--val_list``, ``--test_list`` options
are gone and refused), and ``--imu_freq`` must be the rate of the exported rows: the network's
input window is ``window_time * imu_freq`` rows (``--imu_base_freq`` is no longer used).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from imugen.export.common import measured_rates
from imugen.export.convert import clock, quat_scalar_last, rotate
from imugen.export.source import Sequence, TruthArrays

COLUMNS = [
    "ts_us(1)",
    "gyr_compensated_rotated_in_World(3)",
    "acc_compensated_rotated_in_World(3)",
    "qxyzw_World_Device(4)",
    "pos_World_Device(3)",
    "vel_World(3)",
]


def write(seq: Sequence, truth: TruthArrays, folder: Path, **_) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    t, w, f, kind = measured_rates(seq, truth)
    if kind == "samples":
        q, p, v = truth.q_nb, truth.p_n, truth.v_n
    else:  # interval means at midpoints: the state at the interval's midpoint (2nd order)
        q = truth.q_nb[1:] + truth.q_nb[:-1]
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        p = 0.5 * (truth.p_n[1:] + truth.p_n[:-1])
        v = 0.5 * (truth.v_n[1:] + truth.v_n[:-1])
    arr = np.column_stack(
        [clock(t, 1e-6).astype(float), rotate(q, w), rotate(q, f), quat_scalar_last(q), p, v]
    )
    np.save(folder / "imu0_resampled.npy", arr)
    desc = {
        "columns_name(width)": COLUMNS,
        "num_rows": len(arr),
        "approximate_frequency_hz": float(1.0 / truth.dt),
        "t_start_us": float(arr[0, 0]),
        "t_end_us": float(arr[-1, 0]),
        "imugen": {"sequence": int(seq.id), "imu": f"measured {kind}, rotated with true attitude"},
    }
    (folder / "imu0_resampled_description.json").write_text(json.dumps(desc, indent=2))
    return [folder / "imu0_resampled.npy", folder / "imu0_resampled_description.json"]


def train_command(root_dir: str, rate_hz: float, mode: str = "train", out_dir: str = "models",
                  model_path: str | None = None) -> str:  # fmt: skip
    """TLIO's command line for an export under ``root_dir`` at ``rate_hz`` (the truth's rate,
    ``approximate_frequency_hz`` of the descriptions): ``mode`` ``train`` or ``test`` (which
    needs ``model_path``). Run from TLIO's repository root."""
    rate = f"{float(rate_hz):g}"
    # TLIO samples a window every imu_freq / sample_freq rows (an integer): at most 20 Hz
    hz = float(rate_hz)
    sample = next((d for d in range(20, 0, -1) if (hz / d).is_integer()), hz)
    cmd = f"python3 src/main_net.py --mode {mode} --root_dir {root_dir} --out_dir {out_dir}"
    cmd += f" --imu_freq {rate} --window_time 1.0 --sample_freq {sample:g}"
    if mode == "test":
        cmd += f" --model_path {model_path or 'models/checkpoint_best.pt'}"
    return cmd
