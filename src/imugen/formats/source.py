"""What the export formats read: the truth of a route and its shards, one sequence at a time.

Every format writer sees the same two objects: :class:`TruthArrays` (the route's truth, in
memory once: ``K`` rows of float64) and, per sequence, :class:`Sequence` (its measured IMU
columns, ``K`` rows, and its labels row). Shards are streamed sequence by sequence, so an
export holds one sequence in memory whatever the number of sequences.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from imugen import columns as col
from imugen.errors import InputError
from imugen.io import read_meta

SEQUENCE = "sequence"
RATE_COLUMNS = (*col.GYRO, *col.ACCEL)
INCREMENT_COLUMNS = (*col.DTHETA, *col.DV)
BIAS_COLUMNS = (*(f"gyro_bias_{a}_radps" for a in "xyz"), *(f"accel_bias_{a}_mps2" for a in "xyz"))


@dataclass
class TruthArrays:
    """A route's truth (``K`` samples): time (K,), p_n, v_n (K, 3), q_nb (K, 4), rates,
    increments (K, 3); ``meta`` is the truth file's metadata."""

    time_s: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    q_nb: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    meta: dict

    @property
    def K(self) -> int:
        return len(self.time_s)

    @property
    def dt(self) -> float:
        return float((self.time_s[-1] - self.time_s[0]) / (self.K - 1))


def read_truth(path) -> TruthArrays:
    """Read a truth Parquet whole (it is one route: a few tens of MB)."""
    meta = read_meta(path)
    df = pd.read_parquet(path)

    def a(names):
        return df[list(names)].to_numpy(np.float64)

    return TruthArrays(
        df[col.TIME].to_numpy(np.float64),
        a(col.POS),
        a(col.VEL),
        a(col.QUAT),
        a(col.GYRO),
        a(col.ACCEL),
        a(col.DTHETA),
        a(col.DV),
        meta,
    )


@dataclass
class Sequence:
    """One measured sequence: ``id``, columns by name (K,) float64, labels, shard metadata."""

    id: int
    data: dict[str, np.ndarray]
    labels: dict
    meta: dict = field(repr=False)

    def has(self, names) -> bool:
        return all(n in self.data for n in names)

    def stack(self, names) -> np.ndarray:
        return np.column_stack([self.data[n] for n in names])


def _labels_path(shard: Path) -> Path:
    return shard.with_name(shard.name[: -len(".parquet")] + ".labels.parquet")


def iter_sequences(shard_paths, K: int, only=None) -> Iterator[Sequence]:
    """Yield every sequence of the shards (file order), one at a time.

    ``only``: optional set of sequence ids to keep.
    """
    for p in map(Path, shard_paths):
        meta = read_meta(p)
        pf = pq.ParquetFile(p)
        names = [
            c
            for c in pf.schema_arrow.names
            if c in RATE_COLUMNS or c in INCREMENT_COLUMNS or c in BIAS_COLUMNS
        ]
        lp = _labels_path(p)
        if not lp.exists():
            raise InputError(lp, "labels sidecar missing (incomplete shard?)")
        lab = pd.read_parquet(lp).set_index(SEQUENCE)
        n = pf.metadata.num_rows
        if n % K:
            raise InputError(p, f"holds {n} rows: not whole sequences of the truth's {K} samples")
        buf = {c: np.empty(K) for c in names}
        fill, cur = 0, None
        for rb in pf.iter_batches(batch_size=1 << 16, columns=[SEQUENCE, *names]):
            seq = rb.column(0).to_numpy()
            cols = [rb.column(i + 1).to_numpy() for i in range(len(names))]
            pos = 0
            while pos < len(seq):
                m = min(K - fill, len(seq) - pos)
                if fill == 0:
                    cur = int(seq[pos])
                if not (seq[pos : pos + m] == cur).all():
                    raise InputError(p, "rows are not grouped by sequence with one row per sample")
                for c, v in zip(names, cols, strict=True):
                    buf[c][fill : fill + m] = v[pos : pos + m]
                fill += m
                pos += m
                if fill == K:
                    fill = 0
                    if only is None or cur in only:
                        row = lab.loc[cur].to_dict() if cur in lab.index else {}
                        yield Sequence(cur, buf, row, meta)
