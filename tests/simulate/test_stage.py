"""Shards: seed hygiene, Parquet layout and metadata, labels, truth inputs, errors."""

import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from imugen.core.errors import InputError
from imugen.core.io import METADATA_KEY
from imugen.simulate import stage as S
from imugen.simulate.sources import StaticTruth
from imugen.tables import SEQUENCE
from imugen.tables import shard as tshard
from imugen.tables import truth as col

from helpers import simulate_shard

KW = {"static_s": 3.0, "rate_hz": 100.0}


def data_of(path):
    return pq.read_table(path)


def test_two_runs_are_bit_identical(tmp_path):
    a = simulate_shard(
        None, tmp_path / "a.parquet", "consumer", sequences=3, seed=11, shard=2, **KW
    )
    b = simulate_shard(
        None, tmp_path / "b.parquet", "consumer", sequences=3, seed=11, shard=2, **KW
    )
    assert data_of(tmp_path / "a.parquet").equals(data_of(tmp_path / "b.parquet"))
    assert data_of(tmp_path / "a.labels.parquet").equals(data_of(tmp_path / "b.labels.parquet"))
    a.pop("labels_file"), b.pop("labels_file")
    assert a == b


def test_shard_independent_of_n_and_order(tmp_path):
    alone = S.simulate(None, "industrial", sequences=2, seed=5, shard=3, **KW)
    # a "larger N" generated in another order: shards 5, 4, 3, 2, 1, 0
    many = {
        k: S.simulate(None, "industrial", sequences=2, seed=5, shard=k, **KW)
        for k in range(5, -1, -1)
    }
    for name in alone.data:
        np.testing.assert_array_equal(alone.data[name], many[3].data[name])
    pd.testing.assert_frame_equal(alone.labels, many[3].labels)
    # shards differ from each other
    assert not np.array_equal(many[2].data["dtheta"], many[3].data["dtheta"])
    assert not np.array_equal(many[2].gyro.b_on, many[3].gyro.b_on)


def test_sequence_does_not_depend_on_shard_size():
    small = S.simulate(None, "tactical", sequences=2, seed=1, shard=0, **KW)
    big = S.simulate(None, "tactical", sequences=5, seed=1, shard=0, **KW)
    for name in small.data:
        np.testing.assert_array_equal(small.data[name], big.data[name][:2])


def test_seed_and_grade_change_the_data():
    a = S.simulate(None, "industrial", sequences=1, seed=1, **KW).data["dv"]
    b = S.simulate(None, "industrial", sequences=1, seed=2, **KW).data["dv"]
    assert not np.array_equal(a, b)
    g1 = S.simulate(None, "paper_industrial", sequences=1, seed=1, **KW).data["dv"]
    g2 = S.simulate(None, "paper_tactical", sequences=1, seed=1, **KW).data["dv"]
    # different grade ids -> different streams, not scaled copies (the paper's defect)
    ratio = (g1[0, 1:] - g1[0, 1:].mean(0)) / (g2[0, 1:] - g2[0, 1:].mean(0))
    assert np.std(ratio) > 1


def test_switching_a_term_keeps_other_realizations():
    both = S.simulate(
        None, "industrial", sequences=2, seed=3, terms=["white_noise", "turn_on_bias"], **KW
    )
    white = S.simulate(None, "industrial", sequences=2, seed=3, terms=["white_noise"], **KW)
    d = both.data["dtheta"][:, 1:] - white.data["dtheta"][:, 1:]
    np.testing.assert_allclose(
        d, np.broadcast_to(both.gyro.b_on[:, None] * 0.01, d.shape), rtol=1e-9, atol=1e-19
    )
    np.testing.assert_array_equal(both.gyro.white, white.gyro.white)


def test_parquet_layout_metadata_and_labels(tmp_path, monkeypatch):
    monkeypatch.setattr(tshard, "ROW_GROUP", 200)
    out = tmp_path / "shard_0001.parquet"
    simulate_shard(
        None, out, "navigation", sequences=3, seed=7, shard=1, outputs="both", series=True, **KW
    )
    pf = pq.ParquetFile(out)
    assert pf.metadata.num_rows == 3 * 301
    assert pf.metadata.num_row_groups == 5  # written as it goes, in bounded row groups
    tbl = pf.read()
    sch = tbl.schema
    assert str(sch.field(SEQUENCE).type) == "int64"
    assert col.TIME not in sch.names  # the uniform clock is in the metadata (test_shard_clock)
    assert str(tshard.read(out, [col.TIME]).schema.field(col.TIME).type) == "double"
    for c in (
        *col.DTHETA,
        *col.DV,
        *col.GYRO,
        *col.ACCEL,
        *tshard.BIAS_SERIES["gyro"],
        *tshard.SF_SERIES["accel"],
        *tshard.EFFECTIVE_ERROR["increments"],
        *tshard.EFFECTIVE_ERROR["rates"],
    ):
        assert str(sch.field(c).type) == "float"
    df = tshard.read(out).to_pandas()
    # sorted by sequence then time; global ids route_id << 31 | (shard * M + j); the route of
    # a static IMU is "static"
    rid = tshard.route_id("static")
    assert list(df[SEQUENCE].unique()) == [(rid << 31) + i for i in (3, 4, 5)]
    assert df.groupby(SEQUENCE)[col.TIME].apply(lambda t: bool(np.all(np.diff(t) > 0))).all()
    assert np.all(df.groupby(SEQUENCE)[col.DTHETA[0]].first() == 0)
    meta = json.loads(sch.metadata[METADATA_KEY])
    for k in ("units", "grade", "preset_source", "seed", "shard", "spawn_key", "code_version"):
        assert k in meta
    assert (
        meta["spawn_key"] == [rid, 4, 1]
        and meta["seed"] == 7
        and meta["grade"]["name"] == "navigation"
    )
    assert meta["units"][col.DV[0]] == "m/s" and meta["units"][col.GYRO[0]] == "rad/s"
    assert meta["grade"]["config"]["gyro"]["white_noise"]["unit"] == "deg_per_sqrt_h"
    # labels sidecar: one row per sequence, every drawn parameter
    lab = pq.read_table(tshard.labels_path(out)).to_pandas()
    assert list(lab[SEQUENCE]) == [(rid << 31) + i for i in (3, 4, 5)]
    assert {
        "gyro_turn_on_bias_x_radps",
        "accel_scale_factor_z",
        "gyro_bias_instability_tau0_s",
        "accel_white_noise_x_m_per_s_per_sqrt_s",
    } <= set(lab.columns)
    # the file holds the same numbers as the in-memory generator (cast to float32)
    mem = S.simulate(
        None, "navigation", sequences=3, seed=7, shard=1, outputs="both", series=True, **KW
    )
    np.testing.assert_array_equal(
        df[list(col.DV)].to_numpy().reshape(3, 301, 3), mem.data["dv"].astype(np.float32)
    )
    assert not list(tmp_path.glob(".*.tmp"))


def test_float64_option(tmp_path):
    out = tmp_path / "s.parquet"
    simulate_shard(None, out, "consumer", sequences=1, seed=1, dtype="float64", **KW)
    mem = S.simulate(None, "consumer", sequences=1, seed=1, **KW)
    got = pq.read_table(out).to_pandas()[list(col.DTHETA)].to_numpy()
    np.testing.assert_array_equal(got, mem.data["dtheta"][0])


def test_static_wgs84_truth():
    tr = StaticTruth(1.0, 100.0, earth="wgs84", origin=(30.0, 0.0, 0.0))
    _, w, f, dth, dv = tr.chunk(0, 5)
    om = 7.292115e-5
    np.testing.assert_allclose(
        w[0], [0.0, om * np.cos(np.radians(30)), om * np.sin(np.radians(30))], rtol=1e-12
    )
    assert f[0, 2] > 9.79 and abs(f[0, 0]) < 1e-12
    assert np.all(dth[0] == 0) and np.all(dv[0] == 0)
    # body rotation within the interval: int_0^dt Exp([w x] t) f dt, series to third order
    wf = np.cross(w[0], f[0])
    exp = f[0] * 0.01 + wf * 0.01**2 / 2 + np.cross(w[0], wf) * 0.01**3 / 6
    np.testing.assert_allclose(dv[1], exp, rtol=1e-12, atol=1e-20)


def test_truth_file_input(tmp_path):
    K = 200
    t = np.arange(K) * 0.02
    w = np.tile([0.0, 0.0, 0.1], (K, 1))
    f = np.tile([0.0, 0.0, 9.8], (K, 1))
    df = pd.DataFrame({col.TIME: t})
    for names, a in ((col.GYRO, w), (col.ACCEL, f), (col.DTHETA, w * 0.02), (col.DV, f * 0.02)):
        for i, c in enumerate(names):
            df[c] = a[:, i]
    df.loc[0, list(col.DTHETA) + list(col.DV)] = 0.0
    p = tmp_path / "truth.parquet"
    df.to_parquet(p)
    meta = simulate_shard(p, tmp_path / "o.parquet", "tactical", sequences=2, seed=1)
    assert meta["rate_hz"] == pytest.approx(50.0) and meta["truth"]["file"] == "truth.parquet"
    assert "path" not in meta["truth"] and len(meta["truth"]["sha256"]) == 64
    df.drop(columns=[col.DV[0]]).to_parquet(p)
    with pytest.raises(InputError, match="missing column"):
        simulate_shard(p, tmp_path / "o2.parquet", "tactical")
    assert not (tmp_path / "o2.parquet").exists()


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"grade": "no_such"}, "unknown grade"),
        ({"sequences": 0}, ">= 1"),
        ({"seed": -1}, ">= 0"),
        ({"outputs": "all"}, "one of"),
        ({"terms": ["gyro.colour"]}, "unknown term"),
        ({"temperature": {"kind": "sauna"}}, "unknown profile"),
        ({"static_s": -1.0}, "> 0"),
    ],
)
def test_input_errors(tmp_path, kw, match):
    args = {"grade": "consumer", "static_s": 1.0, **kw}
    with pytest.raises(InputError, match=match):
        simulate_shard(None, tmp_path / "x.parquet", **args)
    assert not list(tmp_path.iterdir())


def test_in_memory_and_written_metadata_agree(tmp_path):
    """simulate() and run() describe a shard identically (preset checksum included)."""
    from imugen.core.io import read_meta

    mem = S.simulate(None, "consumer", sequences=2, seed=3, shard=1, static_s=2.0, rate_hz=10.0)
    simulate_shard(None, tmp_path / "s.parquet", "consumer", 2, 3, 1, static_s=2.0, rate_hz=10.0)
    disk = read_meta(tmp_path / "s.parquet")
    assert mem.meta["preset_sha"] is not None and mem.meta["preset_sha"] == disk["preset_sha"]
    for key in ("grade", "seed", "shard", "sequence_ids", "spawn_key", "samples_per_sequence"):
        assert mem.meta[key] == disk[key], key


def test_labels_index_is_the_sequence_index_in_the_route():
    """``index`` of the labels = the low 31 bits of ``sequence`` = shard * shard_size + j."""
    kw = {"static_s": 1.0, "rate_hz": 10.0, "seed": 5}
    last = S.simulate(None, "consumer", sequences=2, shard=1, shard_size=3, **kw)
    assert last.labels["index"].tolist() == [3, 4]
    assert (last.labels["sequence"] & (2**31 - 1)).tolist() == [3, 4]
    assert last.labels["shard"].tolist() == [1, 1]
