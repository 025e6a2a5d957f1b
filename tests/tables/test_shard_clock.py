"""The implicit clock of a shard: ``time_s`` stored once (metadata) and rebuilt bit for bit."""

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from imugen.core.errors import InputError
from imugen.tables import shard as tshard
from imugen.tables import truth as col

from helpers import simulate_shard

SEQ = tshard.SEQUENCE


@pytest.mark.parametrize(
    ("t0", "dt", "n"),
    [(0.0, 0.01, 62_001), (0.0, 1 / 3, 1000), (12.5, 0.001, 5000), (1.7e9, 0.005, 777)],
)
def test_uniform_clock_round_trips_bit_for_bit(t0, dt, n):
    t = t0 + np.arange(n, dtype=float) * dt  # how the truth builds its grid
    for hint in (dt, None) if t0 < 1e3 else (dt,):  # the mean step is found near t0 = 0
        clock = tshard.uniform_clock(t, hint)
        assert clock is not None and clock["samples"] == n
        assert np.array_equal(tshard.clock_times(clock).view(np.int64), t.view(np.int64))


def test_non_uniform_or_inexact_times_keep_their_column():
    t = np.arange(100) * 0.01
    assert tshard.uniform_clock(t + np.r_[0.0, 1e-12, np.zeros(98)]) is None  # one tick off
    assert tshard.uniform_clock(np.cumsum(np.full(100, 0.1))) is None  # accumulated sum
    assert tshard.uniform_clock(t[:1]) is None
    assert tshard.uniform_clock(np.r_[t[:-1], np.nan]) is None


def _truth(tmp_path, K=300, dt=0.02, t0=3.0):
    t = t0 + np.arange(K) * dt
    w = np.tile([0.0, 0.01, 0.1], (K, 1))
    f = np.tile([0.1, 0.0, 9.8], (K, 1))
    df = pd.DataFrame({col.TIME: t})
    for names, a in ((col.GYRO, w), (col.ACCEL, f), (col.DTHETA, w * dt), (col.DV, f * dt)):
        for i, c in enumerate(names):
            df[c] = a[:, i]
    df.loc[0, list(col.DTHETA) + list(col.DV)] = 0.0
    p = tmp_path / "truth.parquet"
    df.to_parquet(p)
    return p, t


def test_simulated_shard_stores_the_clock_once(tmp_path, monkeypatch):
    monkeypatch.setattr(tshard, "ROW_GROUP", 250)  # sequences straddle row groups
    truth, t = _truth(tmp_path)
    out, full = tmp_path / "s.parquet", tmp_path / "f.parquet"
    meta = simulate_shard(truth, out, "consumer", sequences=3, seed=2)
    simulate_shard(truth, full, "consumer", sequences=3, seed=2, explicit_time=True)
    assert col.TIME not in pq.ParquetFile(out).schema_arrow.names
    assert col.TIME in pq.ParquetFile(full).schema_arrow.names
    assert meta["clock"] == {"t0_s": 3.0, "dt_s": meta["clock"]["dt_s"], "samples": len(t)}
    assert tshard.read_meta(full)["clock"] is None
    # every reader gives time_s back, bit for bit, and the same table as the explicit shard
    a, b = tshard.read(out), tshard.read(full)
    assert a.schema.names == b.schema.names and a.equals(b)
    got = a.column(col.TIME).to_numpy()
    assert np.array_equal(got.view(np.int64), np.tile(t, 3).view(np.int64))
    assert np.array_equal(tshard.times(out), t) and np.array_equal(tshard.times(full), t)
    # filters on sequence and on time, as for a stored column
    ids = tshard.stored_ids(out, len(t), meta)
    flt = [(SEQ, "==", int(ids[1])), (col.TIME, ">=", 4.0), (col.TIME, "<", 5.0)]
    fa = tshard.read(out, [col.TIME, col.DV[2]], filters=flt)
    fb = tshard.read(full, [col.TIME, col.DV[2]], filters=flt)
    assert fa.equals(fb) and fa.num_rows == 50
    # per-sequence iteration with the time row
    cols = [col.DTHETA[0], col.TIME, col.DV[2]]
    for (ia, xa), (ib, xb) in zip(
        tshard.iter_sequences(out, cols, len(t), np.float64),
        tshard.iter_sequences(full, cols, len(t), np.float64),
        strict=True,
    ):
        assert ia == ib and np.array_equal(xa, xb)
    # 24 of 32 bytes per row (int64 sequence as dictionary, 6 float32)
    assert out.stat().st_size < 0.85 * full.stat().st_size


def test_old_shards_with_a_time_column_still_read(tmp_path):
    """A format-2 shard (time_s in every row, no clock in the metadata) reads as before."""
    truth, t = _truth(tmp_path)
    out = tmp_path / "s.parquet"
    simulate_shard(truth, out, "consumer", sequences=2, seed=5, explicit_time=True)
    tbl = pq.read_table(out)
    meta = tshard.read_meta(out)
    del meta["clock"]
    meta["format_version"] = 2
    old = tmp_path / "old.parquet"
    from imugen.core.io import write_parquet

    write_parquet(tbl.to_pandas(), meta, old)
    assert np.array_equal(tshard.times(old), t)
    names = [SEQ, col.TIME, *col.DV]
    got = tshard.read(old, names)
    assert got.schema.names == names
    for c in names:
        assert np.array_equal(got.column(c).to_numpy(), tbl.column(c).to_numpy())
    assert np.array_equal(got.column(col.TIME).to_numpy(), np.tile(t, 2))


def test_derived_shard_keeps_the_clock(tmp_path):
    truth, t = _truth(tmp_path)
    out, der = tmp_path / "s.parquet", tmp_path / "d.parquet"
    simulate_shard(truth, out, "consumer", sequences=2, seed=5)
    x = tshard.read(out)
    K = len(t)
    dth = np.stack([x.column(c).to_numpy().reshape(2, K) for c in col.DTHETA], -1)
    dv = np.stack([x.column(c).to_numpy().reshape(2, K) for c in col.DV], -1)
    tshard.write_like(der, (dth, dv), out)
    assert col.TIME not in pq.ParquetFile(der).schema_arrow.names
    assert tshard.read(der).equals(x)


def test_a_shard_without_time_or_clock_is_refused(tmp_path):
    truth, _ = _truth(tmp_path)
    out = tmp_path / "s.parquet"
    simulate_shard(truth, out, "consumer", sequences=1, seed=5)
    meta = tshard.read_meta(out)
    meta["clock"] = None
    from imugen.core.io import write_parquet

    write_parquet(pq.read_table(out).to_pandas(), meta, out)
    with pytest.raises(InputError, match="neither a time_s column nor"):
        tshard.read(out, [col.TIME])
