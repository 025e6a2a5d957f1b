"""MAT export: round trip through scipy.io.loadmat (v5) and h5py (v7.3) on synthetic files."""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd
import pytest
import scipy.io

from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.export import mat as export
from imugen.tables import truth as col
from imugen.tables.shard import labels_path

K, M, E = 37, 3, 5
LONG_LABEL = "accel_rate_random_walk_x_mps2_per_sqrt_s"  # > 31 characters


def make_route(
    tmp,
    shards=(0, 1),
    *,
    grade="consumer",
    rates=False,
    series=False,
    dtype=np.float32,
    rows_per_group=50,
    seed=0,
):
    """Truth, shards (+ labels) and navigation tables as the pipeline writes them.

    Returns the paths and the raw frames to compare against.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(K) * 0.01
    truth = pd.DataFrame({c: rng.standard_normal(K) for c in col.COLUMNS})
    truth[col.TIME] = t
    tpath = write_parquet(
        truth,
        {
            "origin": {"lat_deg": 45.5, "lon_deg": 5.25, "alt_m": 200.0},
            "earth": "wgs84",
            "rate_hz": 100.0,
            "samples": K,
        },
        tmp / "route_a" / "truth.parquet",
    )
    meas = [*col.DTHETA, *col.DV]
    if rates:
        meas += [*col.GYRO, *col.ACCEL]
    if series:
        meas += [f"gyro_bias_{a}_radps" for a in "xyz"] + [f"accel_sf_{a}" for a in "xyz"]
        meas += [f"gyro_sf_{a}" for a in "xyz"] + [f"accel_bias_{a}_mps2" for a in "xyz"]
    spaths, npaths, frames, navs = [], [], [], []
    for sh in shards:
        ids = sh * M + np.arange(M)
        df = pd.DataFrame({"sequence": np.repeat(ids, K).astype(np.int32), col.TIME: np.tile(t, M)})
        for c in meas:
            df[c] = rng.standard_normal(M * K).astype(dtype)
        meta = {
            "grade": {"name": grade, "id": 4, "description": "test grade"},
            "seed": 11,
            "shard": sh,
            "sequences": M,
            "sequence_ids": [int(ids[0]), int(ids[-1])],
            "samples_per_sequence": K,
            "rate_hz": 100.0,
        }
        sp = tmp / "route_a" / "imu" / grade / f"shard-{sh:03d}.parquet"
        write_parquet(df, meta, sp, row_group_size=rows_per_group)
        lab = pd.DataFrame(
            {
                "sequence": ids.astype(np.int32),
                "shard": np.int32(sh),
                "index": np.arange(M, dtype=np.int32),
                "seed": np.int64(11),
                "grade_id": np.int32(4),
                "gyro_turn_on_bias_x_radps": rng.standard_normal(M),
                LONG_LABEL: rng.standard_normal(M),
            }
        )
        write_parquet(lab, meta, labels_path(sp))
        nav = pd.DataFrame(
            {
                "sequence": np.repeat(ids, E).astype(np.int32),
                col.TIME: np.tile(np.arange(E, dtype=float), M),
            }
        )
        for c in ("err_e_m", "err_n_m", "err_u_m", "err_att_rad"):
            nav[c] = rng.standard_normal(M * E)
        npth = tmp / "route_a" / "nav" / grade / f"shard-{sh:03d}.parquet"
        write_parquet(nav, {"stage": "navigate"}, npth, row_group_size=7)
        spaths.append(sp)
        npaths.append(npth)
        frames.append(df)
        navs.append(nav)
    shards_df = pd.concat(frames, ignore_index=True).sort_values(["sequence", col.TIME])
    nav_df = pd.concat(navs, ignore_index=True).sort_values(["sequence", col.TIME])
    return tpath, spaths, npaths, truth, shards_df, nav_df


def seq_block(df, sid, cols):
    """(rows, len(cols)) values of one sequence, straight from the frame."""
    return df.loc[df["sequence"] == sid, list(cols)].to_numpy()


@pytest.fixture
def route(tmp_path):
    return make_route(tmp_path, shards=(1, 0), rates=True, series=True)  # out of order


def test_v5_round_trip(tmp_path, route):
    tpath, spaths, npaths, truth, sdf, ndf = route
    out = tmp_path / "consumer.mat"
    res = export.export_mat(tpath, spaths, out, grade="consumer", nav_paths=npaths)
    assert res["version"] == "5"
    raw = out.read_bytes()
    assert raw.startswith(b"MATLAB 5.0 MAT-file") and b"Created on" not in raw[:116]
    assert raw[124:128] == b"\x00\x01IM"  # version 0x0100, little-endian marker
    d = scipy.io.loadmat(out)
    S = 2 * M
    ids = np.arange(S)
    np.testing.assert_array_equal(d["sequence_id"], ids.reshape(S, 1))
    assert d["sequence_id"].dtype == np.int64
    # truth: K x n, double, same values
    assert d["truth_time_s"].shape == (K, 1)
    np.testing.assert_array_equal(d["truth_time_s"][:, 0], truth[col.TIME])
    for name, cols in [
        ("truth_pos_enu_m", col.POS),
        ("truth_vel_enu_mps", col.VEL),
        ("truth_quat_nb", col.QUAT),
        ("truth_rpy_rad", col.EULER),
        ("truth_gyro_radps", col.GYRO),
        ("truth_accel_mps2", col.ACCEL),
        ("truth_dtheta_rad", col.DTHETA),
        ("truth_dv_mps", col.DV),
    ]:
        assert d[name].shape == (K, len(cols)) and d[name].dtype == np.float64
        np.testing.assert_array_equal(d[name], truth[list(cols)].to_numpy())
    # per-sequence arrays: K x 3 x S, single, [:, :, s] is sequence ids[s]
    for name, cols in [
        ("imu_dtheta_rad", col.DTHETA),
        ("imu_dv_mps", col.DV),
        ("imu_gyro_radps", col.GYRO),
        ("imu_accel_mps2", col.ACCEL),
        ("true_gyro_bias_radps", [f"gyro_bias_{a}_radps" for a in "xyz"]),
        ("true_accel_sf", [f"accel_sf_{a}" for a in "xyz"]),
    ]:
        a = d[name]
        assert a.shape == (K, 3, S) and a.dtype == np.float32
        for s in ids:
            np.testing.assert_array_equal(a[:, :, s], seq_block(sdf, s, cols))
    # navigation: E x 3 x S and E x S
    np.testing.assert_array_equal(d["nav_time_s"][:, 0], np.arange(E, dtype=float))
    assert d["nav_err_enu_m"].shape == (E, 3, S) and d["nav_err_att_rad"].shape == (E, S)
    for s in ids:
        np.testing.assert_array_equal(
            d["nav_err_enu_m"][:, :, s], seq_block(ndf, s, ["err_e_m", "err_n_m", "err_u_m"])
        )
        np.testing.assert_array_equal(
            d["nav_err_att_rad"][:, s], seq_block(ndf, s, ["err_att_rad"])[:, 0]
        )
    # labels and info structs
    c = scipy.io.loadmat(out, simplify_cells=True)
    lab = c["labels"]
    assert set(lab) == {
        "shard",
        "index",
        "seed",
        "grade_id",
        "gyro_turn_on_bias_x_radps",
        LONG_LABEL,
    }
    assert d["labels"][0, 0]["shard"].shape == (S, 1)
    np.testing.assert_array_equal(lab["shard"], np.repeat([0, 1], M))
    np.testing.assert_array_equal(lab["index"], np.tile(np.arange(M), 2))
    info = c["info"]
    assert info["grade"] == "consumer" and info["grade_id"] == 4 and info["seed"] == 11
    assert info["origin"] == {"lat_deg": 45.5, "lon_deg": 5.25, "alt_m": 200.0}
    assert info["earth"] == "wgs84" and info["rate_hz"] == 100.0 and info["route"] == "route_a"
    assert (info["samples"], info["sequences"], info["epochs"]) == (K, S, E)
    assert "East-North-Up" in info["frames"] and "y left" in info["frames"]
    assert info["units"]["imu_dv_mps"] == "m/s" and info["units"]["truth_quat_nb"] == "1"
    assert info["mat_version"] == "5" and info["imugen_version"]


def test_v5_without_nav_or_rates(tmp_path):
    tpath, spaths, _, _, sdf, _ = make_route(tmp_path, shards=(0,), dtype=np.float64)
    out = tmp_path / "x.mat"
    res = export.export_mat(tpath, spaths, out, grade="consumer")
    d = scipy.io.loadmat(out)
    assert "imu_gyro_radps" not in d and "nav_err_enu_m" not in d and res["epochs"] == 0
    assert d["imu_dv_mps"].dtype == np.float64  # as stored
    np.testing.assert_array_equal(d["imu_dv_mps"][:, :, 2], seq_block(sdf, 2, col.DV))


def test_byte_reproducible_and_order_independent(tmp_path, route):
    tpath, spaths, npaths, *_ = route
    a, b = tmp_path / "a.mat", tmp_path / "b.mat"
    export.export_mat(tpath, spaths, a, grade="consumer", nav_paths=npaths)
    export.export_mat(tpath, spaths[::-1], b, grade="consumer", nav_paths=npaths[::-1])
    assert a.read_bytes() == b.read_bytes()


def test_wrong_grade_and_mismatched_nav(tmp_path, route):
    tpath, spaths, npaths, *_ = route
    with pytest.raises(InputError, match="grade 'consumer', not 'tactical'"):
        export.export_mat(tpath, spaths, tmp_path / "x.mat", grade="tactical")
    with pytest.raises(InputError, match="navigation sequences do not match"):
        export.export_mat(tpath, spaths, tmp_path / "x.mat", grade="consumer", nav_paths=npaths[:1])
    assert not (tmp_path / "x.mat").exists()


def test_v73_needs_h5py(tmp_path, route, monkeypatch):
    tpath, spaths, *_ = route
    monkeypatch.setattr(export, "V5_MAX_BYTES", 100)
    monkeypatch.setitem(sys.modules, "h5py", None)  # import h5py -> ImportError
    with pytest.raises(InputError, match=r"2 GiB MAT v5 limit.*pip install h5py"):
        export.export_mat(tpath, spaths, tmp_path / "x.mat", grade="consumer")
    with pytest.raises(InputError, match="beyond the MAT v5 limit"):
        export.export_mat(tpath, spaths, tmp_path / "x.mat", grade="consumer", version="5")


def _char(ds):
    assert ds.attrs["MATLAB_class"] == b"char"
    return ds[()].astype("<u2").tobytes().decode("utf-16-le")


def test_v73_round_trip(tmp_path, route, monkeypatch):
    h5py = pytest.importorskip("h5py")
    tpath, spaths, npaths, truth, sdf, ndf = route
    monkeypatch.setattr(export, "V5_MAX_BYTES", 100)  # every IMU variable is "too big"
    out, out2 = tmp_path / "big.mat", tmp_path / "big2.mat"
    res = export.export_mat(tpath, spaths, out, grade="consumer", nav_paths=npaths)
    export.export_mat(tpath, spaths, out2, grade="consumer", nav_paths=npaths)
    assert res["version"] == "7.3"
    raw = out.read_bytes()
    assert raw == out2.read_bytes()
    assert raw.startswith(b"MATLAB 7.3 MAT-file") and raw[124:128] == b"\x00\x02IM"
    assert raw[512:520] == b"\x89HDF\r\n\x1a\n"  # HDF5 superblock after the 512-byte userblock
    S = 2 * M
    with h5py.File(out, "r") as f:
        assert f.userblock_size == 512
        # no creation/modification times anywhere (byte-reproducible at any clock time)
        times = []
        f.visititems(lambda n, o: times.append((n, h5py.h5o.get_info(o.id).ctime)))
        assert len(times) > 20 and all(t == 0 for _, t in times)
        cls = f["imu_dv_mps"].attrs.get_id("MATLAB_class").get_type()
        assert isinstance(cls, h5py.h5t.TypeStringID) and not cls.is_variable_str()
        # MATLAB is column-major: a MATLAB K x 3 x S array is an HDF5 (S, 3, K) dataset
        dv = f["imu_dv_mps"]
        assert dv.shape == (S, 3, K) and dv.dtype == np.float32
        assert dv.attrs["MATLAB_class"] == b"single"
        for s in range(S):
            np.testing.assert_array_equal(dv[s].T, seq_block(sdf, s, col.DV))
            np.testing.assert_array_equal(f["imu_gyro_radps"][s].T, seq_block(sdf, s, col.GYRO))
            np.testing.assert_array_equal(
                f["nav_err_enu_m"][s].T, seq_block(ndf, s, ["err_e_m", "err_n_m", "err_u_m"])
            )
            np.testing.assert_array_equal(
                f["nav_err_att_rad"][s], seq_block(ndf, s, ["err_att_rad"])[:, 0]
            )
        assert f["nav_err_att_rad"].shape == (S, E)
        pos = f["truth_pos_enu_m"]
        assert pos.shape == (3, K) and pos.attrs["MATLAB_class"] == b"double"
        np.testing.assert_array_equal(pos[()].T, truth[list(col.POS)].to_numpy())
        assert f["truth_time_s"].shape == (1, K)  # MATLAB K x 1
        assert f["sequence_id"].attrs["MATLAB_class"] == b"int64"
        np.testing.assert_array_equal(f["sequence_id"][()], np.arange(S).reshape(1, S))
        lab = f["labels"]
        assert lab.attrs["MATLAB_class"] == b"struct"
        fields = [b"".join(x).decode() for x in lab.attrs["MATLAB_fields"]]
        assert LONG_LABEL in fields and "shard" in fields
        np.testing.assert_array_equal(lab["shard"][()].ravel(), np.repeat([0, 1], M))
        info = f["info"]
        assert _char(info["grade"]) == "consumer" and _char(info["mat_version"]) == "7.3"
        assert info["origin"]["lat_deg"][()].item() == 45.5
        assert info["origin"]["lat_deg"].shape == (1, 1)
        assert _char(info["units"]["imu_dv_mps"]) == "m/s"


def test_streamed_v5_element_matches_scipy():
    """The hand-written element of a per-sequence array is byte-identical to scipy's."""
    import io

    rng = np.random.default_rng(5)
    for dtype, dims in [(np.float32, (7, 3, 5)), (np.float64, (4, 3)), (np.float32, (3, 3, 1))]:
        a = rng.standard_normal(dims).astype(dtype)
        buf = io.BytesIO()
        scipy.io.savemat(buf, {"imu_dv_mps": a}, do_compression=False)
        prefix, nbytes, pad = export._v5_matrix_prefix("imu_dv_mps", dims, dtype)
        assert buf.getvalue()[128:] == prefix + a.tobytes(order="F") + bytes(pad)
        assert nbytes == a.nbytes


def test_rows_not_grouped_by_sequence(tmp_path, route):
    tpath, spaths, *_ = route
    df = pd.read_parquet(spaths[0])
    meta = export.read_meta(spaths[0])
    df = df.iloc[np.argsort(np.tile(np.arange(K), M), kind="stable")]  # interleave sequences
    write_parquet(df, meta, spaths[0])
    with pytest.raises(InputError, match="not grouped by sequence"):
        export.export_mat(tpath, spaths, tmp_path / "x.mat", grade="consumer")
