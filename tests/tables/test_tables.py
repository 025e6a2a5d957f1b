"""The contract layer: each table module writes what it reads, refuses what it cannot."""

import numpy as np
import pandas as pd
import pytest

from imugen.core.errors import InputError
from imugen.tables import SEQUENCE, TIME, enu, metrics, nav, shard, truth


def test_one_definition_of_the_shared_names():
    assert SEQUENCE == shard.SEQUENCE == "sequence" and TIME == truth.TIME == enu.TIME
    assert nav.COLUMNS[:2] == (SEQUENCE, TIME)
    assert shard.BIAS == (*shard.BIAS_SERIES["gyro"], *shard.BIAS_SERIES["accel"])
    assert shard.INCREMENTS == (*truth.DTHETA, *truth.DV)
    # every column has a unit
    assert set(truth.COLUMNS) <= set(truth.UNITS)
    assert set(shard.units(list(shard.GROUPS))) == {
        SEQUENCE, TIME, *(c for cols, _ in shard.GROUPS.values() for c in cols)
    }  # fmt: skip


def test_round_trips(tmp_path):
    df = pd.DataFrame({c: np.arange(4.0) for c in truth.COLUMNS})
    p = truth.write(df, {"rate_hz": 1.0, "origin": {}}, tmp_path / "t.parquet")
    tr = truth.read(p)
    assert tr.K == 4 and tr.rate_hz == 1.0 and tr.p_n.shape == (4, 3) and tr.q_nb.shape == (4, 4)
    assert truth.samples(p) == 4 and len(truth.checksum(p)) == 64
    assert np.vstack(list(truth.iter_batches(p, [TIME, *truth.POS], 3))).shape == (4, 4)
    n = pd.DataFrame({c: np.arange(3.0) for c in nav.COLUMNS}).astype({SEQUENCE: "int64"})
    nav.write(n, {"stage": "navigate"}, tmp_path / "n.parquet")
    assert nav.read(tmp_path / "n.parquet").equals(n)
    assert nav.read_meta(tmp_path / "n.parquet")["units"]["err_att_rad"] == "rad"
    m = pd.DataFrame({SEQUENCE: [5, 6], metrics.RMSE_TOTAL: [1.0, 2.0]}).set_index(SEQUENCE)
    metrics.write(m, {"grade": "g"}, tmp_path / "m.parquet")
    assert metrics.read(tmp_path / "m.parquet")[SEQUENCE].tolist() == [5, 6]
    e = pd.DataFrame({c: [0.0, 1.0] for c in enu.COLUMNS})
    enu.write(e, {"origin": {}}, tmp_path / "e.parquet")
    got, meta = enu.read(tmp_path / "e.parquet")
    assert got.equals(e) and meta == {"origin": {}}


def test_shard_writer_and_readers(tmp_path):
    K, ids = 5, shard.sequence_ids(shard.route_id("r"), [0, 1])
    data = {"dtheta": np.ones((2, K, 3)), "dv": np.zeros((2, K, 3))}
    labels = pd.DataFrame({SEQUENCE: ids})
    out = shard.write(tmp_path / "s.parquet", np.arange(K) * 0.1, data, ids, labels, {"x": 1})
    meta = shard.read_meta(out)
    assert meta["format"] == shard.FORMAT and meta["labels_file"] == "s.labels.parquet"
    assert shard.measurement(out) == (list(shard.INCREMENTS), "increments")
    assert shard.increment_kind(meta) == "compensated"
    assert shard.stored_ids(out, K).tolist() == ids.tolist()
    # each batch is a view valid until the next one
    got = [b[0].tolist() for b in shard.iter_blocks(out, list(shard.INCREMENTS), K, 1, skip=1)]
    assert got == [[ids[0]], [ids[1]]]
    assert shard.read_labels(out)[SEQUENCE].tolist() == ids.tolist()
    assert str(shard.schema_of(out).field(SEQUENCE).type) == "int64"
    # a writer closed without labels leaves nothing behind
    with pytest.raises(RuntimeError), shard.writer(tmp_path / "x.parquet", {}, ["dtheta", "dv"]):
        pass
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.labels.parquet", "s.parquet"]


def test_readers_refuse_clearly(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        truth.read(tmp_path / "none.parquet")
    (tmp_path / "junk.parquet").write_bytes(b"not parquet")
    with pytest.raises(InputError, match="cannot read as a Parquet"):
        shard.column_names(tmp_path / "junk.parquet")
    pd.DataFrame({"a": [1]}).to_parquet(tmp_path / "a.parquet")
    with pytest.raises(InputError, match="missing column"):
        nav.read(tmp_path / "a.parquet", [SEQUENCE])
    with pytest.raises(InputError, match="not a metrics table"):
        metrics.read(tmp_path / "a.parquet")
    with pytest.raises(InputError, match="neither increment nor rate"):
        shard.measurement(tmp_path / "a.parquet")
    with pytest.raises(InputError, match="labels sidecar missing"):
        shard.read_labels(tmp_path / "a.parquet")
    with pytest.raises(InputError, match="increment semantics"):
        shard.increment_kind({"increments": "cooked"})
