"""Export formats: each writer read back by its consumer's library, compared with the source."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.export import convert
from imugen.export.source import iter_sequences, mounting_of, read_truth
from imugen.export.stage import export, parse_formats
from imugen.tables import truth as ttruth
from imugen.truth import build_truth, enu_table

from helpers import simulate_shard

M = 2
RATE = 50.0


@pytest.fixture(scope="module")
def route(tmp_path_factory):
    """A 40 s drive (a climbing curve) at 50 Hz, wgs84, two consumer sequences with rates,
    increments and series."""
    tmp = tmp_path_factory.mktemp("fmt")
    t = np.arange(0.0, 41.0, 1.0)
    enu = np.column_stack([300 * np.sin(t / 40.0), 200 * (1 - np.cos(t / 30.0)), 0.1 * t])
    df, meta = enu_table(enu, t, origin=(45.2, 7.6, 300.0))
    tdf, tmeta = build_truth(df, meta, rate_hz=RATE, earth="wgs84", verbose=False)
    truth = write_parquet(tdf, tmeta, tmp / "drive" / "truth.parquet")
    shard = tmp / "drive" / "imu" / "consumer" / "shard-000.parquet"
    simulate_shard(truth, shard, "consumer", sequences=M, seed=5, outputs="both", series=True)
    return truth, shard, tmp


@pytest.fixture(scope="module")
def exported(route):
    truth, shard, tmp = route
    out = tmp / "export"
    export(
        list(parse_formats("euroc,tum,tlio,ronin,kfgins,ros2")),
        truth,
        [shard],
        out,
        log=lambda m: None,
    )
    return out


def _seqs(route):
    truth, shard, _ = route
    tr = read_truth(truth)
    return tr, [
        (s.id, {k: v.copy() for k, v in s.data.items()}, dict(s.labels))
        for s in iter_sequences([shard], tr.K)
    ]


# --- conversions ------------------------------------------------------------------------------
def test_ned_frd_conversions_against_hand_cases():
    # facing East, level: heading 90 deg, roll = pitch = 0
    C = np.eye(3)
    e = np.degrees(convert.euler_ned_frd(convert.dcm_ned_frd(C)))
    assert np.allclose(e, [0.0, 0.0, 90.0])
    # nose up by 10 deg facing North (ENU yaw +90 deg): pitch +10, heading 0
    C = rot.euler_to_dcm(0.0, math.radians(10.0), math.radians(90.0))
    e = np.degrees(convert.euler_ned_frd(convert.dcm_ned_frd(C)))
    assert np.allclose(e, [0.0, 10.0, 0.0], atol=1e-9)
    # right wing down by 5 deg (imugen roll > 0): NED roll +5
    C = rot.euler_to_dcm(math.radians(5.0), 0.0, math.radians(90.0))
    assert np.allclose(np.degrees(convert.euler_ned_frd(convert.dcm_ned_frd(C)))[0], 5.0)
    v = np.array([1.0, 2.0, 3.0])
    assert np.allclose(convert.enu_to_ned(v), [2.0, 1.0, -3.0])
    assert np.allclose(convert.flu_to_frd(v), [1.0, -2.0, -3.0])
    C = rot.euler_to_dcm(0.3, -0.2, 1.1)
    Cn = convert.dcm_ned_frd(C)
    assert np.allclose(Cn @ Cn.T, np.eye(3)) and np.isclose(np.linalg.det(Cn), 1.0)
    # a body vector maps the same way through either frame pair
    vb = np.array([0.4, -1.2, 2.0])
    assert np.allclose(Cn @ convert.flu_to_frd(vb), convert.enu_to_ned(C @ vb))
    assert np.array_equal(convert.clock([0.0, 1.5e-9, 2.0], 1e-9, 7), [7, 9, 2_000_000_007])


def test_format_names_are_checked(route):
    with pytest.raises(InputError, match="unknown format"):
        parse_formats("euroc,kitti")
    truth, shard, tmp = route
    (tmp / "busy").mkdir()
    with pytest.raises(InputError, match="exists"):
        export(["tum"], truth, [shard], tmp / "busy", log=lambda m: None)
    assert not list(tmp.glob(".busy.*"))


# --- each format, read back --------------------------------------------------------------------
def test_euroc_read_by_evo_and_equal_to_the_shard(route, exported):
    evo_fi = pytest.importorskip("evo.tools.file_interface")
    tr, seqs = _seqs(route)
    sid, data, _ = seqs[0]
    folder = exported / "euroc" / f"drive_consumer_{sid:06d}" / "mav0"
    traj = evo_fi.read_euroc_csv_trajectory(
        str(folder / "state_groundtruth_estimate0" / "data.csv")
    )
    assert np.allclose(traj.positions_xyz, tr.p_n, atol=1e-6)
    assert np.allclose(traj.orientations_quat_wxyz, tr.q_nb, atol=1e-8)
    imu = np.loadtxt(folder / "imu0" / "data.csv", delimiter=",", comments="#")
    assert imu.shape == (tr.K, 7)
    assert np.array_equal(imu[:, 0].astype(np.int64), np.rint(tr.time_s * 1e9).astype(np.int64))
    w = np.column_stack([data[f"gyro_{a}_radps"] for a in "xyz"])
    assert np.allclose(imu[:, 1:4], w, rtol=1e-8, atol=1e-12)
    header = (folder / "imu0" / "data.csv").read_text().splitlines()[0]
    assert header.startswith("#timestamp [ns],w_RS_S_x [rad s^-1]")
    import yaml

    s = yaml.safe_load((folder / "imu0" / "sensor.yaml").read_text())
    assert s["rate_hz"] == RATE and s["gyroscope_noise_density"] > 0


def test_tum_navigation_matches_the_navigation_stage(route, exported):
    evo_fi = pytest.importorskip("evo.tools.file_interface")
    from imugen.navigate.stage import navigate

    truth, shard, _ = route
    tr, seqs = _seqs(route)
    gt = evo_fi.read_tum_trajectory_file(str(exported / "tum" / "truth.tum"))
    every = round(RATE / 10.0)
    assert np.allclose(gt.positions_xyz, tr.p_n[::every], atol=1e-5)
    nav = navigate(truth, shard, eval_rate_hz=10.0)
    for sid, _, _ in seqs:
        est = evo_fi.read_tum_trajectory_file(
            str(exported / "tum" / f"drive_consumer_{sid:06d}.tum")
        )
        err = nav[nav["sequence"] == sid][["err_e_m", "err_n_m", "err_u_m"]].to_numpy()
        # the stage reports East/North/Up at the true position: C_ln (n -> local level) there
        C = ttruth.origin_frame(tr.meta).C_ln(tr.p_n[::every])
        d = np.einsum("jik,jk->ji", C, est.positions_xyz - tr.p_n[::every])
        assert np.allclose(d, err, atol=2e-5 + 1e-6 * np.abs(err))


def test_tum_aided_read_by_evo_and_equal_to_the_aided_table(route, tmp_path, cli):
    """``imugen export --aided``: truth, free-inertial AND aided TUM files; evo reads the aided
    one back equal to the Parquet source, and evo's APE against truth.tum equals the table's
    own error columns at the associated epochs."""
    evo_fi = pytest.importorskip("evo.tools.file_interface")
    from evo.core import metrics, sync

    from imugen.aid import stage as aid
    from imugen.tables import aided as taided
    from imugen.tables import truth as ttruth

    truth, shard, _ = route
    g, a = tmp_path / "g.parquet", tmp_path / "a.parquet"
    aid.run(truth, shard, g, a, aid.AidOptions(eval_rate_hz=10.0))
    r = cli("export", str(truth), str(shard), "-o", str(tmp_path / "x"), "--format", "tum",
            "--aided", str(a))  # fmt: skip
    assert r.returncode == 0, r.stderr
    src = taided.read(a)
    gt = evo_fi.read_tum_trajectory_file(str(tmp_path / "x" / "tum" / "truth.tum"))
    _, seqs = _seqs(route)
    for sid, _, _ in seqs:
        stem = tmp_path / "x" / "tum" / f"drive_consumer_{sid:06d}"
        assert stem.with_suffix(".tum").is_file()
        est = evo_fi.read_tum_trajectory_file(str(stem.with_suffix(".aided.tum")))
        ref = src[src["sequence"] == sid]
        assert len(ref) > 100 and est.num_poses == len(ref)
        np.testing.assert_allclose(est.timestamps, ref["time_s"], atol=1e-9)
        np.testing.assert_allclose(est.positions_xyz, ref[list(ttruth.POS)], atol=1e-6)
        np.testing.assert_allclose(est.orientations_quat_wxyz, ref[list(ttruth.QUAT)], atol=1e-9)
        gt_s, est_s = sync.associate_trajectories(gt, est, max_diff=1e-4)
        ape = metrics.APE(metrics.PoseRelation.translation_part)
        ape.process_data((gt_s, est_s))
        own = ref.set_index(np.round(ref["time_s"].to_numpy(), 6)).loc[
            np.round(est_s.timestamps, 6), list(taided.ERR_POS)
        ]
        np.testing.assert_allclose(ape.error, np.linalg.norm(own, axis=1), atol=2e-5)
    # without --aided: no aided files; an aided table of the old layout is refused in one line
    export(["tum"], truth, [shard], tmp_path / "y", log=lambda m: None)
    assert not list((tmp_path / "y" / "tum").glob("*.aided.tum"))
    old = tmp_path / "old.parquet"
    write_parquet(src[list(taided.ERRORS)], {}, old)
    with pytest.raises(InputError, match="no navigation state"):
        export(["tum"], truth, [shard], tmp_path / "z", aided_paths=[old], log=lambda m: None)


def test_tlio_layout_and_rotation(route, exported):
    tr, seqs = _seqs(route)
    sid, data, _ = seqs[1]
    folder = exported / "tlio" / f"drive_consumer_{sid:06d}"
    arr = np.load(folder / "imu0_resampled.npy")
    desc = json.loads((folder / "imu0_resampled_description.json").read_text())
    assert arr.shape == (tr.K, 17) and desc["num_rows"] == tr.K
    assert desc["columns_name(width)"][3] == "qxyzw_World_Device(4)"
    q = np.column_stack([arr[:, 10], arr[:, 7:10]])  # back to scalar first
    assert np.allclose(q, tr.q_nb)
    C = rot.quat_to_dcm(q)
    f_b = np.einsum("kji,kj->ki", C, arr[:, 4:7])  # world -> body
    assert np.allclose(f_b, np.column_stack([data[f"accel_{a}_mps2"] for a in "xyz"]), atol=1e-9)
    lists = {
        p: (exported / "tlio" / f"{p}_list.txt").read_text().split()
        for p in ("train", "val", "test")
    }
    assert sorted(n for v in lists.values() for n in v) == sorted(
        f"drive_consumer_{s:06d}" for s, _, _ in seqs
    )


def test_ronin_hdf5(route, exported):
    h5py = pytest.importorskip("h5py")
    tr, seqs = _seqs(route)
    sid, data, _ = seqs[0]
    folder = exported / "ronin" / f"drive_consumer_{sid:06d}"
    with h5py.File(folder / "data.hdf5", "r") as h:
        assert np.allclose(
            h["synced/gyro_uncalib"][:], np.column_stack([data[f"gyro_{a}_radps"] for a in "xyz"])
        )
        assert np.allclose(h["pose/tango_pos"][:], tr.p_n)
        assert np.allclose(h["synced/time"][:], tr.time_s)
    info = json.loads((folder / "info.json").read_text())
    assert info["imu_acce_scale"] == [1.0, 1.0, 1.0] and info["ori_source"] == "game_rv"


def test_kfgins_files_in_ned_frd(route, exported):
    tr, seqs = _seqs(route)
    sid, data, _ = seqs[0]
    folder = exported / "kfgins" / f"drive_consumer_{sid:06d}"
    imu = np.loadtxt(folder / "imu.txt")
    assert imu.shape == (tr.K - 1, 7)
    assert np.allclose(imu[:, 0], tr.time_s[1:])
    dth = np.column_stack([data[f"dtheta_{a}_rad"] for a in "xyz"])[1:]
    assert np.allclose(imu[:, 1:4], dth * [1, -1, -1], rtol=1e-10, atol=1e-15)
    nav = np.loadtxt(folder / "truth.nav")
    tdf = pd.read_parquet(route[0])
    # heading from North clockwise = 90 deg - yaw (imugen yaw: 0 East, counter-clockwise)
    heading = np.mod(90.0 - np.degrees(tdf["yaw_rad"].to_numpy()), 360.0)
    d = np.mod(nav[:, 10] - heading + 180.0, 360.0) - 180.0
    assert np.max(np.abs(d)) < 1e-6
    assert np.allclose(nav[:, 8], np.degrees(tdf["roll_rad"]), atol=1e-6)
    assert np.allclose(nav[:, 9], np.degrees(tdf["pitch_rad"]), atol=1e-6)
    # NED velocity: vD = -vU (local level at the vehicle, within the 40 s scene's tilt)
    assert np.allclose(nav[:, 7], -tdf["v_u_mps"], atol=1e-3)
    assert abs(nav[0, 2] - 45.2) < 1e-7 and abs(nav[0, 3] - 7.6) < 1e-7  # spline fit: < 1 cm
    assert not (folder / "kf-gins.yaml").exists()  # no GNSS: no runnable config (test_kfgins)


def _bag(folder, topics=None):
    """``{topic: [(t_ns, message), ...]}`` of a bag, read with rosbags (any storage)."""
    from rosbags.highlevel import AnyReader

    out = {}
    with AnyReader([folder]) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        for conn, ts, raw in reader.messages(connections=conns):
            out.setdefault(conn.topic, []).append((ts, reader.deserialize(raw, conn.msgtype)))
    return out


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_ros2_bag_read_by_rosbags(route, exported, tmp_path, storage):
    """Both storages read back by rosbags: message counts, first and last values equal to the
    shard and the truth; no GNSS or companion topic without their tables; a static identity
    transform base_link -> imu_link (no mounting) with the static broadcaster's QoS."""
    pytest.importorskip("rosbags")
    truth, shard, _ = route
    tr, seqs = _seqs(route)
    if storage == "mcap":
        out = tmp_path / "bags"
        export(["ros2"], truth, [shard], out, storage="mcap", log=lambda m: None)
    else:
        out = exported
    for sid, data, _ in seqs:
        folder = out / "ros2" / f"drive_consumer_{sid:06d}"
        meta = (folder / "metadata.yaml").read_text()
        assert f"storage_identifier: {storage}" in meta
        assert list(folder.glob("*.mcap" if storage == "mcap" else "*.db3"))
        bag = _bag(folder)
        assert set(bag) == {"/tf_static", "/imu/data", "/ground_truth/odom", "/ground_truth/fix"}
        assert len(bag["/imu/data"]) == tr.K and len(bag["/ground_truth/odom"]) == tr.K
        assert len(bag["/ground_truth/fix"]) == len(range(0, tr.K, round(RATE / 10.0)))
        w = np.column_stack([data[f"gyro_{a}_radps"] for a in "xyz"])
        f = np.column_stack([data[f"accel_{a}_mps2"] for a in "xyz"])
        for i in (0, -1):
            ts, imu = bag["/imu/data"][i]
            assert ts == round(tr.time_s[i] * 1e9) and imu.orientation_covariance[0] == -1.0
            av, la = imu.angular_velocity, imu.linear_acceleration
            assert np.array_equal([av.x, av.y, av.z], w[i])
            assert np.array_equal([la.x, la.y, la.z], f[i])
            ts, od = bag["/ground_truth/odom"][i]
            q, p = od.pose.pose.orientation, od.pose.pose.position
            assert ts == round(tr.time_s[i] * 1e9) and od.child_frame_id == "base_link"
            assert np.array_equal([q.w, q.x, q.y, q.z], tr.q_nb[i])
            assert np.array_equal([p.x, p.y, p.z], tr.p_n[i])
        ((ts, tf),) = bag["/tf_static"]
        (x,) = tf.transforms
        assert (x.header.frame_id, x.child_frame_id) == ("base_link", "imu_link")
        r, d = x.transform.rotation, x.transform.translation
        assert [r.w, r.x, r.y, r.z, d.x, d.y, d.z] == [1.0, 0, 0, 0, 0, 0, 0]
    from rosbags.rosbag2 import Reader

    with Reader(folder) as reader:
        (c,) = [c for c in reader.connections if c.topic == "/tf_static"]
        (qos,) = c.ext.offered_qos_profiles
        assert qos.durability.name == "TRANSIENT_LOCAL" and qos.depth == 1


def test_ros2_truth_read_by_evo(route, exported):
    evo_fi = pytest.importorskip("evo.tools.file_interface")
    from rosbags.rosbag2 import Reader

    tr, seqs = _seqs(route)
    folder = exported / "ros2" / f"drive_consumer_{seqs[0][0]:06d}"
    with Reader(folder) as reader:
        traj = evo_fi.read_bag_trajectory(reader, "/ground_truth/odom")
    assert np.allclose(traj.positions_xyz, tr.p_n) and np.allclose(traj.timestamps, tr.time_s)


def test_gnss_epochs_go_to_kfgins_and_ros2(route, tmp_path):
    pytest.importorskip("rosbags")
    from rosbags.highlevel import AnyReader

    from imugen.tables import gnss as tgnss

    truth, shard, _ = route
    tr, seqs = _seqs(route)
    rows = []
    for sid, _, _ in seqs:
        t = tr.time_s[:: int(RATE)]  # 1 Hz
        fix = np.where((t > 10) & (t < 15), 0, 1).astype(np.int8)  # a 4 s outage
        p = tr.p_n[:: int(RATE)] + 0.5
        p[fix == 0] = np.nan
        df = pd.DataFrame({"sequence": np.int64(sid), "time_s": t})
        for i, c in enumerate(tgnss.P):
            df[c] = p[:, i]
        for c in (*tgnss.V, *tgnss.OFFSET_P, *tgnss.OFFSET_V, *tgnss.ATTACK_P, *tgnss.ATTACK_V):
            df[c] = 0.0
        for c, sd in zip(tgnss.SIGMA_P, (1.0, 2.0, 3.0), strict=True):
            df[c] = sd
        for c in tgnss.SIGMA_V:
            df[c] = 0.1
        df[tgnss.FIX], df[tgnss.STATE] = fix, (1 - fix).astype(np.int8)
        rows.append(df)
    labels = pd.DataFrame({"sequence": [s for s, _, _ in seqs], "gnss_lever_arm_x_m": 0.5})
    labels["gnss_lever_arm_y_m"], labels["gnss_lever_arm_z_m"] = 0.2, 1.0
    g = tgnss.write(
        pd.concat(rows), labels, pd.DataFrame({"sequence": []}), {}, tmp_path / "g.parquet"
    )
    out = tmp_path / "exp"
    export(["kfgins", "ros2"], truth, [shard], out, gnss_paths=[g], log=lambda m: None)
    sid = seqs[0][0]
    pos = np.loadtxt(out / "kfgins" / f"drive_consumer_{sid:06d}" / "gnss.pos")
    assert len(pos) == int((rows[0]["fix"] > 0).sum())
    from imugen.tables.truth import origin_frame

    frame = origin_frame(tr.meta)
    lat, lon, h = frame.geodetic_from_n(rows[0][list(tgnss.P)].to_numpy()[rows[0]["fix"] > 0])
    assert np.allclose(pos[:, 2], np.degrees(lon), atol=1e-10)
    assert np.allclose(pos[:, 1], np.degrees(lat), atol=1e-10) and np.allclose(
        pos[:, 3], h, atol=1e-3
    )
    assert np.allclose(pos[:, 4:], [2.0, 1.0, 3.0])  # sigma lat (north), lon (east), height
    import yaml

    cfg = yaml.safe_load(
        (out / "kfgins" / f"drive_consumer_{sid:06d}" / "kf-gins.yaml").read_text()
    )
    assert cfg["gnsspath"] == "gnss.pos" and cfg["antlever"] == [0.5, -0.2, -1.0]  # FRD
    fixes = []
    with AnyReader([out / "ros2" / f"drive_consumer_{sid:06d}"]) as reader:
        conns = [c for c in reader.connections if c.topic == "/gnss/fix"]
        for conn, _, raw in reader.messages(connections=conns):
            fixes.append(reader.deserialize(raw, conn.msgtype).status.status)
    assert len(fixes) == len(rows[0]) and fixes.count(-1) == int((rows[0]["fix"] == 0).sum())


# --- RoNIN's own loader logic, copied ----------------------------------------------------------
# The parts of RoNIN's loaders that read our files, copied from Sachini/ronin at commit
# 805b7f0f28bb164ce89ada9ac05a9470dbe3d715: source/data_utils.py (select_orientation_source),
# source/math_util.py (gyro_integration), source/data_glob_speed.py (GlobSpeedSequence.load)
# and source/data_glob_heading.py (HeadingSequence.load). numpy-quaternion's operations are
# replaced by imugen.core.rotations' (the same Hamilton product, scalar first); file reads unchanged.
def _ronin_gyro_integration(ts, gyro, init_q):
    output_q = np.zeros((gyro.shape[0], 4))
    output_q[0] = init_q
    dts = ts[1:] - ts[:-1]
    for i in range(1, gyro.shape[0]):
        w = gyro[i - 1]
        omega = 0.5 * np.array(
            [[0, -w[0], -w[1], -w[2]], [w[0], 0, w[2], -w[1]],
             [w[1], -w[2], 0, w[0]], [w[2], w[1], -w[0], 0]]
        )  # fmt: skip
        output_q[i] = output_q[i - 1] + np.dot(omega, output_q[i - 1]) * dts[i - 1]
        output_q[i] /= np.linalg.norm(output_q[i])
    return output_q


def _ronin_select_orientation_source(data_path, max_ori_error=20.0, grv_only=True, use_ekf=True):
    import h5py

    ori_names = ["gyro_integration", "game_rv"]
    ori_sources = [None, None, None]
    with open(data_path / "info.json") as f:
        info = json.load(f)
        ori_errors = np.array(
            [info["gyro_integration_error"], info["grv_ori_error"], info["ekf_ori_error"]]
        )
        init_gyro_bias = np.array(info["imu_init_gyro_bias"])
    with h5py.File(data_path / "data.hdf5") as f:
        ori_sources[1] = np.copy(f["synced/game_rv"])
        if grv_only or ori_errors[1] < max_ori_error:
            min_id = 1
        else:
            if use_ekf:
                ori_names.append("ekf")
                ori_sources[2] = np.copy(f["pose/ekf_ori"])
            min_id = np.argmin(ori_errors[: len(ori_names)])
            if min_id == 0:
                ts = f["synced/time"]
                gyro = f["synced/gyro_uncalib"] - init_gyro_bias
                ori_sources[0] = _ronin_gyro_integration(ts, gyro, ori_sources[1][0])
    return ori_names[min_id], ori_sources[min_id], ori_errors[min_id]


def _ronin_glob_speed_load(data_path, max_ori_error=20.0, grv_only=False, w=1):
    import h5py

    with open(data_path / "info.json") as f:
        info = json.load(f)
    info["ori_source"], ori, info["source_ori_error"] = _ronin_select_orientation_source(
        data_path, max_ori_error, grv_only
    )
    with h5py.File(data_path / "data.hdf5") as f:
        gyro_uncalib = f["synced/gyro_uncalib"]
        acce_uncalib = f["synced/acce"]
        gyro = gyro_uncalib - np.array(info["imu_init_gyro_bias"])
        acce = np.array(info["imu_acce_scale"]) * (acce_uncalib - np.array(info["imu_acce_bias"]))
        ts = np.copy(f["synced/time"])
        tango_pos = np.copy(f["pose/tango_pos"])
        init_tango_ori = np.asarray(f["pose/tango_ori"][0])
    ori_q = np.asarray(ori)
    rot_imu_to_tango = np.asarray(info["start_calibration"], float)
    init_rotor = rot.quat_mul(
        rot.quat_mul(init_tango_ori, rot_imu_to_tango), rot.quat_conj(ori_q[0])
    )
    ori_q = rot.quat_mul(init_rotor, ori_q)
    dt = (ts[w:] - ts[:-w])[:, None]
    glob_v = (tango_pos[w:] - tango_pos[:-w]) / dt
    gyro_q = np.concatenate([np.zeros([gyro.shape[0], 1]), gyro], axis=1)
    acce_q = np.concatenate([np.zeros([acce.shape[0], 1]), acce], axis=1)
    glob_gyro = rot.quat_mul(rot.quat_mul(ori_q, gyro_q), rot.quat_conj(ori_q))[:, 1:]
    glob_acce = rot.quat_mul(rot.quat_mul(ori_q, acce_q), rot.quat_conj(ori_q))[:, 1:]
    start_frame = info.get("start_frame", 0)
    return {
        "info": info,
        "ts": ts[start_frame:],
        "features": np.concatenate([glob_gyro, glob_acce], axis=1)[start_frame:],
        "targets": glob_v[start_frame:, :2],
        "orientations": ori_q[start_frame:],
        "gt_pos": tango_pos[start_frame:],
    }


def _ronin_body_heading(data_path):
    import h5py

    with open(data_path / "info.json") as f:
        info = json.load(f)
        rot_tango_to_body = info["align_tango_to_body"]
        start_frame = info.get("start_frame", 0)
    with h5py.File(data_path / "data.hdf5") as f:
        tango_ori = f["pose/tango_ori"][:]
    body_ori_q = rot.quat_mul(tango_ori, rot.quat_conj(np.asarray(rot_tango_to_body, float)))
    return body_ori_q[start_frame:]


def _ronin_list(path):  # source/ronin_resnet.py get_dataset_from_list
    with open(path) as f:
        return [s.strip().split(",")[0] for s in f.readlines() if len(s) > 0 and s[0] != "#"]


def _check_ronin(folder, t, w, f, q, p):
    """RoNIN's loader on one exported sequence gives the measured signals (t, w, f) rotated
    into the world by the true attitude q, true positions p and their velocities."""
    for kw in ({}, {"grv_only": True}, {"max_ori_error": -1.0}):  # -1: best of all sources
        seq = _ronin_glob_speed_load(folder, **kw)
        assert seq["info"]["ori_source"] == "game_rv" and seq["info"]["source_ori_error"] == 0
        np.testing.assert_allclose(seq["ts"], t, atol=1e-12)
        np.testing.assert_allclose(seq["orientations"], q, atol=1e-12)
        np.testing.assert_allclose(seq["features"][:, :3], convert.rotate(q, w), atol=1e-12)
        np.testing.assert_allclose(seq["features"][:, 3:], convert.rotate(q, f), atol=1e-10)
        np.testing.assert_allclose(seq["gt_pos"], p, atol=1e-9)
        assert seq["targets"].shape == (len(t) - 1, 2)
        np.testing.assert_allclose(seq["targets"], np.diff(p[:, :2], axis=0) / np.diff(t)[:, None])
    np.testing.assert_allclose(_ronin_body_heading(folder), q, atol=1e-12)


def test_ronin_read_by_ronins_loader(route, exported):
    """RoNIN's own loader logic reads every sequence: measured rates rotated by the true
    attitude, true positions; the orientation source is the true one whichever selection rule;
    ``gyro_integration_error`` is what RoNIN's gyro integration of our file gives; the lists
    are imugen's split."""
    tr, seqs = _seqs(route)
    root = exported / "ronin"
    for sid, data, _ in seqs:
        folder = root / f"drive_consumer_{sid:06d}"
        w = np.column_stack([data[f"gyro_{a}_radps"] for a in "xyz"])
        f = np.column_stack([data[f"accel_{a}_mps2"] for a in "xyz"])
        _check_ronin(folder, tr.time_s, w, f, tr.q_nb, tr.p_n)
        # gyro_integration_error: RoNIN's first-order integrator, ours against the truth's
        info = json.loads((folder / "info.json").read_text())
        q_est = _ronin_gyro_integration(tr.time_s, w, tr.q_nb[0])
        q_ref = _ronin_gyro_integration(tr.time_s, tr.gyro, tr.q_nb[0])
        e = rot.quat_mul(rot.quat_conj(q_ref[-1]), q_est[-1])
        expect = np.degrees(2 * np.arctan2(np.linalg.norm(e[1:]), abs(e[0])))
        assert expect > 0.05  # a consumer gyro drifts: the selection rule has a real choice
        assert info["gyro_integration_error"] == pytest.approx(expect, rel=1e-3)
    lists = {p: _ronin_list(root / f"list_{p}.txt") for p in ("train", "val", "test")}
    tlio = {p: (exported / "tlio" / f"{p}_list.txt").read_text().split() for p in lists}
    assert lists == tlio
    assert sorted(n for v in lists.values() for n in v) == [
        f"drive_consumer_{s:06d}" for s, _, _ in seqs
    ]


# --- the workflow's default: increments only (rates are interval means) ------------------------
@pytest.fixture(scope="module")
def incremental(route):
    """Two consumer sequences simulated with ``outputs="increments"`` (the workflow default)
    and no series, exported in the formats that want rates; the export's log lines."""
    truth, _, tmp = route
    shard = tmp / "drive" / "imu" / "consumer_inc" / "shard-000.parquet"
    simulate_shard(truth, shard, "consumer", sequences=M, seed=9, outputs="increments")
    out, lines = tmp / "export_inc", []
    export(["euroc", "tlio", "ronin"], truth, [shard], out, log=lines.append)
    tr = read_truth(truth)
    seqs = [
        (s.id, {k: v.copy() for k, v in s.data.items()}, dict(s.labels))
        for s in iter_sequences([shard], tr.K)
    ]
    return tr, seqs, out, lines


def test_increments_exported_as_interval_mean_rates(incremental):
    """EuRoC, TLIO and RoNIN get ``dtheta/dt``, ``dv/dt`` stamped at the interval midpoints."""
    tr, seqs, out, _ = incremental
    dt = tr.dt
    t_mid = tr.time_s[1:] - 0.5 * dt
    q_mid = tr.q_nb[1:] + tr.q_nb[:-1]
    q_mid /= np.linalg.norm(q_mid, axis=1, keepdims=True)
    p_mid = 0.5 * (tr.p_n[1:] + tr.p_n[:-1])
    for sid, data, _ in seqs:
        name = f"drive_consumer_{sid:06d}"
        w = np.column_stack([data[f"dtheta_{a}_rad"] for a in "xyz"])[1:] / dt
        f = np.column_stack([data[f"dv_{a}_mps"] for a in "xyz"])[1:] / dt
        imu = np.loadtxt(out / "euroc" / name / "mav0" / "imu0" / "data.csv", delimiter=",")
        assert imu.shape == (tr.K - 1, 7)
        assert np.array_equal(imu[:, 0].astype(np.int64), np.rint(t_mid * 1e9).astype(np.int64))
        np.testing.assert_allclose(imu[:, 1:4], w, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(imu[:, 4:], f, rtol=1e-9, atol=1e-15)
        arr = np.load(out / "tlio" / name / "imu0_resampled.npy")
        assert arr.shape == (tr.K - 1, 17)
        assert np.array_equal(arr[:, 0], np.rint(t_mid * 1e6))
        q = np.column_stack([arr[:, 10], arr[:, 7:10]])
        C = rot.quat_to_dcm(q)
        np.testing.assert_allclose(np.einsum("kji,kj->ki", C, arr[:, 1:4]), w, atol=1e-12)
        np.testing.assert_allclose(np.einsum("kji,kj->ki", C, arr[:, 4:7]), f, atol=1e-10)
        # the midpoint attitude lies halfway between its neighbours (within 1e-9 rad)
        half = rot.relative_rotation_vector(tr.q_nb[:-1], q) - rot.relative_rotation_vector(
            q, tr.q_nb[1:]
        )
        assert np.max(np.abs(half)) < 1e-9
        _check_ronin(out / "ronin" / name, t_mid, w, f, q_mid, p_mid)


def test_euroc_biases_and_noise_figures_are_this_sequences(route, exported, incremental):
    """Bias columns: the true series when simulated with ``series``; else the turn-on labels,
    with one warning (not one per sequence) that they lack the in-run part. ``sensor.yaml``:
    this sequence's drawn white noise and the walk ``sqrt(RRW^2 + 2 sigma^2 / T)``."""
    import yaml

    from imugen.tables import shard as tshard

    _, seqs = _seqs(route)
    for sid, data, _ in seqs:  # series in the shard: exact
        gt = np.loadtxt(
            exported / "euroc" / f"drive_consumer_{sid:06d}" / "mav0"
            / "state_groundtruth_estimate0" / "data.csv", delimiter=",",
        )  # fmt: skip
        b = np.column_stack([data[c] for c in tshard.BIAS])
        assert np.ptp(b[:, 0]) > 0  # the in-run part moves
        np.testing.assert_allclose(gt[:, 11:], b, rtol=1e-8, atol=1e-15)
    tr, seqs, out, lines = incremental
    assert sum("turn-on biases only" in m for m in lines) == 1
    for sid, _, lab in seqs:
        folder = out / "euroc" / f"drive_consumer_{sid:06d}" / "mav0"
        gt = np.loadtxt(folder / "state_groundtruth_estimate0" / "data.csv", delimiter=",")
        on = [lab[f"gyro_turn_on_bias_{a}_radps"] for a in "xyz"]
        on += [lab[f"accel_turn_on_bias_{a}_mps2"] for a in "xyz"]
        assert np.all(np.asarray(on) != 0)
        np.testing.assert_allclose(gt[:, 11:], np.tile(on, (tr.K, 1)), rtol=1e-8)
        s = yaml.safe_load((folder / "imu0" / "sensor.yaml").read_text())
        assert "turn-on only" in s["comment"]
        for sensor, key, dens, rrw, unit in (
            ("gyro", "gyroscope", "rad_per_sqrt_s", "radps_per_sqrt_s", "radps"),
            ("accel", "accelerometer", "m_per_s_per_sqrt_s", "mps2_per_sqrt_s", "mps2"),
        ):
            n = [lab[f"{sensor}_white_noise_{a}_{dens}"] for a in "xyz"]
            assert np.ptp(n) == 0 and n[0] > 0  # the consumer grade draws one figure per sensor
            assert s[f"{key}_noise_density"] == pytest.approx(n[0], rel=1e-12)
            sig = lab[f"{sensor}_bias_instability_sigma0_x_{unit}"]
            tau = lab[f"{sensor}_bias_instability_tau0_s"]
            walk = math.hypot(lab[f"{sensor}_rate_random_walk_x_{rrw}"], sig * math.sqrt(2 / tau))
            assert walk > 0 and s[f"{key}_random_walk"] == pytest.approx(walk, rel=1e-12)
        assert s["rate_hz"] == RATE


def test_tlio_clock_is_integer_microseconds_from_the_route_start(route, exported):
    tr, seqs = _seqs(route)
    for sid, _, _ in seqs:
        folder = exported / "tlio" / f"drive_consumer_{sid:06d}"
        ts = np.load(folder / "imu0_resampled.npy")[:, 0]
        desc = json.loads((folder / "imu0_resampled_description.json").read_text())
        assert ts[0] == 0 and np.array_equal(ts, np.rint(ts))
        assert np.array_equal(ts.astype(np.int64), np.rint(tr.time_s * 1e6).astype(np.int64))
        assert desc["t_start_us"] == ts[0] and desc["t_end_us"] == ts[-1]
        np.testing.assert_allclose(np.diff(ts), 1e6 / RATE, atol=0.5)


# --- a mounted IMU: its own truth ----------------------------------------------------------------
def test_tum_truth_of_a_mounted_imu(route):
    """An ideal IMU mounted off the vehicle's point and axes: its free-inertial trajectory
    against ``SEQ.truth.tum`` has APE ~0; against the vehicle's ``truth.tum`` the lever arm."""
    evo_fi = pytest.importorskip("evo.tools.file_interface")
    from evo.core import metrics, sync

    truth, _, tmp = route
    shard = tmp / "drive" / "imu" / "mounted" / "shard-000.parquet"
    mount = {"misalignment_sd_deg": [1.0, 1.0, 2.0], "lever_arm_m": [0.5, 0.2, 0.3]}
    simulate_shard(truth, shard, "consumer", sequences=1, seed=3, terms=[], mounting=mount)
    out = tmp / "export_mounted"
    export(["tum"], truth, [shard], out, log=lambda m: None)
    (est_path,) = [p for p in (out / "tum").glob("drive_*.tum") if p.name.count(".") == 1]
    gt_imu = evo_fi.read_tum_trajectory_file(str(est_path.with_suffix(".truth.tum")))
    gt_veh = evo_fi.read_tum_trajectory_file(str(out / "tum" / "truth.tum"))
    est = evo_fi.read_tum_trajectory_file(str(est_path))

    def ape(gt, relation):
        a, b = sync.associate_trajectories(gt, est, max_diff=1e-4)
        m = metrics.APE(relation)
        m.process_data((a, b))
        return m.error, a.num_poses

    err, n = ape(gt_imu, metrics.PoseRelation.translation_part)
    assert n == gt_veh.num_poses and np.max(err) < 1e-3
    err, _ = ape(gt_imu, metrics.PoseRelation.rotation_angle_deg)
    assert np.max(err) < 1e-6
    (seq,) = iter_sequences([shard], read_truth(truth).K)
    angles, lever = mounting_of(seq.labels)
    assert np.linalg.norm(lever) > 0.3 and np.max(np.abs(angles)) > 0
    err, _ = ape(gt_veh, metrics.PoseRelation.translation_part)  # the lever arm
    assert np.allclose(err, np.linalg.norm(lever), atol=1e-3)
    err, _ = ape(gt_veh, metrics.PoseRelation.rotation_angle_deg)
    assert np.min(err) > 0.01
    # an unmounted export writes no per-sequence truth
    assert not list((route[2] / "export" / "tum").glob("*.truth.tum"))


# --- streaming -----------------------------------------------------------------------------------
def test_export_streams_and_says_what_it_wrote(route):
    """Exporting 8 sequences holds one at a time: the traced peak is within a fraction of one
    sequence's data of exporting 1 (holding them all would add 7). Each format's log line
    states the sequences, files and megabytes actually written."""
    import re
    import tracemalloc

    from imugen.tables import shard as tshard

    truth, _, tmp = route
    shard = tmp / "drive" / "imu" / "eight" / "shard-000.parquet"
    simulate_shard(truth, shard, "consumer", sequences=8, seed=11, outputs="both")
    ids = tshard.read_labels(shard, tshard.read_meta(shard))["sequence"].tolist()
    K = read_truth(truth).K
    one_seq = 12 * K * 8  # rates and increments, float64
    fmts = ["euroc", "tlio", "ronin"]
    export(fmts, truth, [shard], tmp / "warm", sequences=ids[:1], log=lambda m: None)
    peaks, lines = {}, []
    for n in (1, 8):
        lines.clear()
        tracemalloc.start()
        export(fmts, truth, [shard], tmp / f"n{n}", sequences=ids[:n], log=lines.append)
        peaks[n] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    print(f"traced peak: 1 sequence {peaks[1]} B, 8 sequences {peaks[8]} B, one {one_seq} B")
    assert peaks[8] < peaks[1] + one_seq, (peaks, one_seq)
    summary = [m for m in lines if not m.startswith("imugen: warning")]
    assert len(summary) == len(fmts)
    for fmt, line in zip(fmts, summary, strict=True):
        m = re.fullmatch(r"(.+): (\w+), (\d+) sequences, (\d+) files, ([\d.]+) MB", line)
        assert m and m[1] == str(tmp / "n8" / fmt) and m[2] == fmt and int(m[3]) == 8
        files = [p for p in (tmp / "n8" / fmt).rglob("*") if p.is_file()]
        assert int(m[4]) == len(files) and len(files) >= 8 * 2
        assert float(m[5]) == round(sum(p.stat().st_size for p in files) / 1e6, 1) > 0


def test_ros2_companions_tf_and_gnss_of_a_mounted_imu(route, tmp_path, cli):
    """A mounted IMU with an odometer, a barometer and GNSS (``imugen aid``): the static
    transforms close the truth (vehicle pose composed with base_link -> imu_link is the IMU's
    true pose in the bag); the wheel speeds are the table's, and their variance's white and
    tick terms match the scale-corrected errors (chi-square band over ~400 epochs); the
    pressures give the measured altitudes back through the inverse standard atmosphere, whose
    tabulated 11 km value they meet."""
    pytest.importorskip("rosbags")
    from imugen.aid import stage as aid
    from imugen.export.ros2 import isa_pressure_pa
    from imugen.tables import companions as tcomp

    truth, _, _ = route
    shard = tmp_path / "drive" / "imu" / "consumer" / "shard-000.parquet"
    mount = {"enabled": True, "lever_arm_m": [0.8, -0.3, 0.4], "misalignment_sd_deg": [2, 2, 5]}
    simulate_shard(truth, shard, "consumer", sequences=1, seed=9, outputs="both", mounting=mount)
    g, a, c = (tmp_path / f"{n}.parquet" for n in ("g", "a", "c"))
    params = aid.AidOptions(
        eval_rate_hz=10.0, odometer="abs", barometer="bmp388", lever_arm_b_m=(0.1, 0.2, 1.5)
    )
    aid.run(truth, shard, g, a, params, out_companions=c)
    r = cli("export", truth, shard, "-o", tmp_path / "x", "--format", "ros2", "--gnss", g,
            "--companions", c)  # fmt: skip
    assert r.returncode == 0, r.stderr
    tr = read_truth(truth)
    (seq,) = iter_sequences([shard], tr.K)
    (folder,) = (tmp_path / "x" / "ros2").iterdir()
    bag = _bag(folder)
    assert set(bag) == {"/tf_static", "/imu/data", "/ground_truth/odom", "/ground_truth/fix",
                        "/gnss/fix", "/wheel/odometry", "/baro/pressure"}  # fmt: skip
    # transforms: base_link -> imu_link closes vehicle truth onto the IMU truth in the bag
    ((_, tf),) = bag["/tf_static"]
    links = {x.child_frame_id: x.transform for x in tf.transforms}
    assert set(links) == {"imu_link", "gnss_antenna"}
    d, r_ = links["imu_link"].translation, links["imu_link"].rotation
    lever = np.array([d.x, d.y, d.z])
    assert np.allclose(lever, [seq.labels[f"lever_arm_{a}_m"] for a in "xyz"])
    q_vb = np.array([r_.w, r_.x, r_.y, r_.z])
    od = [m for _, m in bag["/ground_truth/odom"]]
    assert od[0].child_frame_id == "imu_link"
    q_imu = np.array([[m.pose.pose.orientation.w, m.pose.pose.orientation.x,
                       m.pose.pose.orientation.y, m.pose.pose.orientation.z] for m in od])  # fmt: skip
    p_imu = np.array([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z]
                      for m in od])  # fmt: skip
    q_pred = rot.quat_mul(tr.q_nb, np.broadcast_to(q_vb, tr.q_nb.shape))
    assert np.allclose(np.abs(np.sum(q_pred * q_imu, axis=1)), 1.0, atol=1e-12)
    p_pred = tr.p_n + np.einsum("kij,j->ki", rot.quat_to_dcm(tr.q_nb), lever)
    assert np.allclose(p_pred, p_imu, atol=1e-9)
    ga = links["gnss_antenna"].translation
    assert np.allclose([ga.x, ga.y, ga.z], [0.1, 0.2, 1.5])
    # wheel odometry: the table's speeds; variance terms against the errors
    odo = tcomp.read_odometer(c)
    lab = tcomp.read_labels(c).iloc[0]
    wheel = bag["/wheel/odometry"]
    assert len(wheel) == len(odo) > 300
    u = np.array([m.twist.twist.linear.x for _, m in wheel])
    assert np.array_equal(u, odo["odo_speed_mps"].to_numpy())
    assert [t for t, _ in wheel] == list(np.rint(odo["time_s"].to_numpy() * 1e9).astype(int))
    var = np.array([m.twist.covariance[0] for _, m in wheel])
    sk_u2 = (lab["odo_scale_factor_sd"] * u) ** 2
    white_tick = var - sk_u2
    e = odo["odo_error_mps"].to_numpy() - lab["odo_scale_factor"] * odo["odo_true_speed_mps"]
    ratio = np.mean(e**2 / white_tick)
    assert 0.75 < ratio < 1.3, ratio
    assert wheel[0][1].child_frame_id == "base_link" and wheel[0][1].pose.covariance[0] == 1e6
    # barometer: inverse ISA gives the altitudes back; the 11 km tabulated pressure
    baro = tcomp.read_barometer(c)
    pres = bag["/baro/pressure"]
    p = np.array([m.fluid_pressure for _, m in pres])
    n = 5.25588
    h = 288.15 / 0.0065 * (1.0 - (p / 101325.0) ** (1.0 / n))
    assert np.allclose(h, baro["baro_altitude_m"], atol=1e-4)  # n to 6 digits: 0.1 mm
    assert abs(isa_pressure_pa(11000.0) - 22632.1) < 0.5 and isa_pressure_pa(0.0) == 101325.0
    dp = isa_pressure_pa(h + 0.5) - isa_pressure_pa(h - 0.5)
    var_h = lab["baro_white_m"] ** 2 + lab["baro_bias_sd_m"] ** 2
    assert np.allclose([m.variance for _, m in pres], dp**2 * var_h, rtol=1e-5)
    from imugen.tables import gnss as tgnss

    assert len(bag["/gnss/fix"]) == len(tgnss.read(g))


def _lists(folder):
    return {p: (folder / f"{p}_list.txt").read_text().split() for p in ("train", "val", "test")}


def test_split_lists_hold_a_route_out_in_every_export(route, tmp_path, cli):
    """Per-route exports with ``--holdout-routes``: the held-out route's sequences are in its
    test list and nowhere else, the other route's never in test; with ``--split-by route`` a
    route's sequences share one part, the part a whole-dataset split of many routes gives it."""
    from imugen.dataset import split

    truth, shard, _ = route
    _, seqs = _seqs(route)
    for name in ("city", "drive"):
        r = cli("export", truth, shard, "-o", tmp_path / name, "--format", "tlio", "--route",
                name, "--holdout-routes", "city,nowhere", "--val-fraction", "0.5")  # fmt: skip
        assert r.returncode == 0, r.stderr
    city, drive = _lists(tmp_path / "city" / "tlio"), _lists(tmp_path / "drive" / "tlio")
    assert sorted(city["test"]) == [f"city_consumer_{s:06d}" for s, _, _ in seqs]
    assert city["train"] == city["val"] == [] and drive["test"] == []
    assert sorted(drive["train"] + drive["val"]) == [f"drive_consumer_{s:06d}" for s, _, _ in seqs]
    assert drive["train"] and drive["val"]  # two sequences, train and val 0.5 each
    # by route: one export per route, each route whole in the part of the global split
    names = [f"r{i}" for i in range(12)]
    keys = [(n, 1000 * i + j) for i, n in enumerate(names) for j in range(2)]
    whole = split(keys, {"train": 0.6, "val": 0.2, "test": 0.2}, seed=3, by="route")
    assert all(whole.values())  # no repair needed: the global cut is the hash cut
    part_of = {r: p for p, ks in whole.items() for r, _ in ks}
    for name in names[:2]:
        export(["tlio"], truth, [shard], tmp_path / f"x{name}", route=name, split_by="route",
               split_seed=3, val_fraction=0.2, test_fraction=0.2, log=lambda m: None)  # fmt: skip
        got = _lists(tmp_path / f"x{name}" / "tlio")
        assert len(got[part_of[name]]) == len(seqs) and sum(map(len, got.values())) == len(seqs)
    with pytest.raises(InputError, match="leave some for train"):
        export(["tlio"], truth, [shard], tmp_path / "bad", val_fraction=0.5, test_fraction=0.5)
    r = cli(
        "export", truth, shard, "-o", tmp_path / "bad", "--format", "tlio", "--val-fraction", "-1"
    )
    assert r.returncode == 2 and "--val-fraction" in r.stderr and not (tmp_path / "bad").exists()
