"""Navigation stage: a shard of measured IMU sequences -> strapdown -> errors against truth.

Each sequence starts from the true initial state (position, velocity, attitude at ``t_0``:
no initial-alignment error) and is mechanized with :mod:`imugen.mechanize` on the shard's
angle/velocity increments (or, when the shard holds rates only, on increments formed from
them by :func:`imugen.mechanize.increments_from_rates`), in the Earth model of the truth.
Sequences are streamed from the shard in batches, so memory is bounded by the batch size.

Output (Parquet, one row per sequence and evaluation epoch; epochs every
``round(rate / eval_rate_hz)`` samples from ``t_0``): ``sequence``, ``time_s``, position
error ``err_e_m``, ``err_n_m``, ``err_u_m`` (navigation minus truth, metres) and attitude
error ``err_att_rad`` (angle of the rotation from the true to the computed attitude).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from imugen import __version__
from imugen.errors import InputError
from imugen.mechanize import increments_from_rates, mechanize
from imugen.rotations import log_quat, quat_conj, quat_mul
from imugen.tables import nav as tnav
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth
from imugen.tables._parquet import SEQUENCE, TIME

BATCH_BYTES = 64 << 20
"""Budget of the float64 increment buffers of one batch (both sensors): with the reused
buffers it bounds a navigate job's memory whatever the shard's size and the IMU rate."""


def batch_size(samples: int, budget: int = BATCH_BYTES) -> int:
    """Sequences per batch so that two ``(batch, samples, 3)`` float64 buffers fit ``budget``."""
    return int(max(1, min(256, budget // (2 * 3 * 8 * max(int(samples), 1)))))


def navigate(
    truth_path,
    shard_path,
    *,
    eval_rate_hz: float = 1.0,
    batch: int | None = None,
) -> pd.DataFrame:
    """Mechanize every sequence of a shard and return its errors at the evaluation epochs.

    ``batch`` sequences are mechanized together (default :func:`batch_size`, from a fixed
    memory budget); the result does not depend on it.
    """
    truth_path, shard_path = Path(truth_path), Path(shard_path)
    smeta = tshard.read_meta(shard_path)
    truth = ttruth.read(truth_path, columns=[TIME, *ttruth.POS, *ttruth.VEL, *ttruth.QUAT])
    t = truth.time_s
    K = truth.K
    dt = truth.dt
    every = max(1, round(truth.rate_hz / eval_rate_hz))
    frame = truth.origin_frame()
    p_true = truth.p_n
    q_true = truth.q_nb
    p0, v0, q0 = p_true[0], truth.v_n[0], q_true[0]

    columns, kind = tshard.measurement(shard_path)
    n = smeta.get("samples_per_sequence")
    if n is not None and n != K:
        raise InputError(shard_path, f"has {n} samples per sequence where the truth has {K}")

    if batch is None:
        batch = batch_size(K)
    skip = 1 if kind == "increments" else 0
    frames = []
    for seq_ids, a, b in tshard.iter_blocks(shard_path, columns, K, int(batch), skip):
        if kind == "increments":
            dth, dvb = a, b
        else:
            dth, dvb = increments_from_rates(a, b, dt)
        nav = mechanize(dth, dvb, dt, p0, v0, q0, frame, every=every, outputs=("p", "q"))
        idx = nav.index
        err = nav.p_n - p_true[idx][None]
        dq = quat_mul(quat_conj(q_true[idx])[None], nav.q_nb)
        att = np.linalg.norm(log_quat(dq), axis=-1)
        n_seq, n_ep = err.shape[:2]
        frames.append(
            pd.DataFrame(
                {
                    SEQUENCE: np.repeat(seq_ids.astype(np.int64), n_ep),
                    TIME: np.tile(t[idx], n_seq),
                    tnav.ERR_POS[0]: err[..., 0].ravel(),
                    tnav.ERR_POS[1]: err[..., 1].ravel(),
                    tnav.ERR_POS[2]: err[..., 2].ravel(),
                    tnav.ERR_ATT: att.ravel(),
                }
            )
        )
    if not frames:
        raise InputError(shard_path, "holds no sequences")
    return pd.concat(frames, ignore_index=True)


def run(truth, shard, out, *, eval_rate_hz: float = 1.0, batch: int | None = None) -> Path:
    """Navigate a shard and write its error table atomically (Parquet with metadata)."""
    out = Path(out)
    df = navigate(truth, shard, eval_rate_hz=eval_rate_hz, batch=batch)
    smeta = tshard.read_meta(shard)
    meta = {
        "stage": "navigate",
        "imugen_version": __version__,
        "truth": Path(truth).name,
        "truth_sha256": ttruth.checksum(truth),
        "shard": Path(shard).name,
        "grade": smeta.get("grade"),
        "route": smeta.get("route"),
        "eval_rate_hz": eval_rate_hz,
        "increments": smeta.get("increments", "compensated"),
        "error": "navigation minus truth, ENU of the route origin",
    }
    tnav.write(df, meta, out)
    return out
