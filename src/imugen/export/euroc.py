"""EuRoC / ASL folders: ``mav0/imu0/data.csv`` + ``sensor.yaml`` and the ground truth.

Per sequence: ``mav0/imu0/data.csv`` (header ``#timestamp [ns],w_RS_S_x [rad s^-1],...,
a_RS_S_z [m s^-2]``; measured angular rate and specific force in the body frame, here the
sensor frame S = b, FLU), ``mav0/imu0/sensor.yaml`` (Kalibr noise figures of THIS sequence,
``T_BS`` identity, ``rate_hz``) and ``mav0/state_groundtruth_estimate0/data.csv`` (``p_RS_R``,
``q_RS`` scalar first, ``v_RS_R``, ``b_w_RS_S``, ``b_a_RS_S``; R = the route's ENU frame). The
biases are the true slow-bias series when the shard holds them (``simulate.series``), else the
turn-on biases of the labels: exact for a sequence without in-run bias terms (bias instability,
rate random walk, temperature bias all zero), otherwise only the bias's mean, which a warning
and ``sensor.yaml``'s comment say.
Read by evo (``evo_traj euroc``), OpenVINS, ORB-SLAM3, AirIMU loaders.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from imugen.export.common import measured_rates, noise_figures, write_rows
from imugen.export.convert import clock
from imugen.export.source import BIAS_COLUMNS, Sequence, TruthArrays

IMU_HEADER = (
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]"
)
GT_HEADER = (
    "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
    "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
    "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
    "b_a_RS_S_z [m s^-2]"
)


IN_RUN = ("_bias_instability_sigma", "_slow_bias_sigma", "_rate_random_walk_", "_temperature_bias_")
"""Label stems of bias terms that vary within a run."""


def in_run_bias(labels: dict) -> bool:
    """True when a sequence's labels show a bias that varies within the run."""
    return any(
        k.startswith(("gyro", "accel")) and any(s in k for s in IN_RUN) and v and np.isfinite(v)
        for k, v in labels.items()
    )


def biases(seq: Sequence, K: int) -> tuple[np.ndarray, str]:
    """``(b (K, 6), what)``: gyro [rad/s] and accelerometer [m/s^2] biases of a sequence and
    what they are (``"true"``, ``"true (constant)"`` or ``"turn-on only"``)."""
    if seq.has(BIAS_COLUMNS):
        return seq.stack(BIAS_COLUMNS), "true"
    lab = seq.labels
    b = [lab.get(f"gyro_turn_on_bias_{a}_radps", 0.0) for a in "xyz"]
    b += [lab.get(f"accel_turn_on_bias_{a}_mps2", 0.0) for a in "xyz"]
    what = "turn-on only" if in_run_bias(lab) else "true (constant)"
    return np.tile(np.asarray(b, float), (K, 1)), what


def write(
    seq: Sequence, truth: TruthArrays, folder: Path, start_ns: int = 0, warn=print, **_
) -> list[Path]:
    """Write one sequence as a EuRoC ``mav0`` folder under ``folder``."""
    imu = folder / "mav0" / "imu0"
    gt = folder / "mav0" / "state_groundtruth_estimate0"
    imu.mkdir(parents=True, exist_ok=True)
    gt.mkdir(parents=True, exist_ok=True)
    t, w, f, kind = measured_rates(seq, truth)
    ns = clock(t, 1e-9, start_ns)
    with open(imu / "data.csv", "w") as fh:
        fh.write(IMU_HEADER + "\n")
        block = np.column_stack([ns.astype(float), w, f])
        write_rows(fh, block, "%d" + ",%.9e" * 6)
    fig = noise_figures(seq.labels)
    b, what = biases(seq, truth.K)
    if what == "turn-on only":
        warn(
            "EuRoC ground-truth bias columns hold the turn-on biases only (the grade has in-run "
            "bias terms whose series the shard lacks: simulate with series: true for exact ones)"
        )
    sensor = {
        "sensor_type": "imu",
        "comment": f"imugen sequence {seq.id}: measured IMU ({kind}); noise figures of this "
        "sequence's draw (random_walk includes the in-run Gauss-Markov bias), a "
        f"simplification of the full error model; ground-truth biases: {what}",
        "T_BS": {"cols": 4, "rows": 4, "data": [float(x) for x in np.eye(4).ravel()]},
        "rate_hz": float(1.0 / truth.dt),
        **{k: float(v) for k, v in fig.items()},
    }
    (imu / "sensor.yaml").write_text(yaml.safe_dump(sensor, sort_keys=False))
    ns_t = clock(truth.time_s, 1e-9, start_ns)
    with open(gt / "data.csv", "w") as fh:
        fh.write(GT_HEADER + "\n")
        block = np.column_stack([ns_t.astype(float), truth.p_n, truth.q_nb, truth.v_n, b])
        write_rows(fh, block, "%d" + ",%.9e" * 16)
    return [imu / "data.csv", imu / "sensor.yaml", gt / "data.csv"]
