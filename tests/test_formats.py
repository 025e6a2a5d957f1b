"""Export formats: each writer read back by its consumer's library, compared with the source."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from imugen import rotations as rot
from imugen import simulate
from imugen.errors import InputError
from imugen.formats import convert, export, parse_formats
from imugen.formats.source import iter_sequences, read_truth
from imugen.io import write_parquet
from imugen.tables import truth as ttruth
from imugen.truth import build_truth, enu_table

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
    simulate.run(truth, shard, "consumer", sequences=M, seed=5, outputs="both", series=True)
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
    from imugen.navigate import navigate

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

    from imugen import aid
    from imugen.tables import aided as taided
    from imugen.tables import truth as ttruth

    truth, shard, _ = route
    g, a = tmp_path / "g.parquet", tmp_path / "a.parquet"
    aid.run(truth, shard, g, a, aid.AidParams(eval_rate_hz=10.0))
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
    import yaml

    cfg = yaml.safe_load((folder / "kf-gins.yaml").read_text())
    assert cfg["imudatalen"] == 7 and cfg["imudatarate"] == RATE and cfg["imunoise"]["arw"] > 0


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


def test_ros2_companions_tf_and_gnss_of_a_mounted_imu(route, tmp_path, cli):
    """A mounted IMU with an odometer, a barometer and GNSS (``imugen aid``): the static
    transforms close the truth (vehicle pose composed with base_link -> imu_link is the IMU's
    true pose in the bag); the wheel speeds are the table's, and their variance's white and
    tick terms match the scale-corrected errors (chi-square band over ~400 epochs); the
    pressures give the measured altitudes back through the inverse standard atmosphere, whose
    tabulated 11 km value they meet."""
    pytest.importorskip("rosbags")
    from imugen import aid
    from imugen.formats.ros2 import isa_pressure_pa
    from imugen.tables import companions as tcomp

    truth, _, _ = route
    shard = tmp_path / "drive" / "imu" / "consumer" / "shard-000.parquet"
    mount = {"enabled": True, "lever_arm_m": [0.8, -0.3, 0.4], "misalignment_sd_deg": [2, 2, 5]}
    simulate.run(truth, shard, "consumer", sequences=1, seed=9, outputs="both", mounting=mount)
    g, a, c = (tmp_path / f"{n}.parquet" for n in ("g", "a", "c"))
    params = aid.AidParams(
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
