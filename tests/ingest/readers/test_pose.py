"""Pose trajectories: readers (TUM, EuRoC, named CSV, ROS 2 bag) and their ingestion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen.core import earth as ea
from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.ingest.readers import read_route_file
from imugen.ingest.stage import ingest, write
from imugen.tables import enu as tenu

ORIGIN = "47.4,8.5,400"


def _poses(n=200, rate_hz=100.0):
    t = np.arange(n) / rate_hz
    p = np.column_stack([2 * np.sin(t), np.cos(t) - 1, 0.2 * t])
    q = rot.dcm_to_quat(rot.euler_to_dcm(0.1 * np.sin(3 * t), 0.2 * np.cos(t), 0.5 * t))
    return t, p, q


def _tum(path, t, p, q, t0=1.4e9):
    rows = [f"{t0 + t[i]:.6f} {p[i, 0]:.9f} {p[i, 1]:.9f} {p[i, 2]:.9f} "
            f"{q[i, 1]:.12f} {q[i, 2]:.12f} {q[i, 3]:.12f} {q[i, 0]:.12f}" for i in range(len(t))]  # fmt: skip
    path.write_text("# timestamp tx ty tz qx qy qz qw\n" + "\n".join(rows) + "\n")
    return path


def _euroc(path, t, p, q):
    head = ("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], "
            "q_RS_y [], q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1]")  # fmt: skip
    ns = 1403636579758555392 + np.round(t * 1e9).astype(np.int64)
    rows = [f"{ns[i]},{p[i, 0]:.9f},{p[i, 1]:.9f},{p[i, 2]:.9f},{q[i, 0]:.12f},{q[i, 1]:.12f},"
            f"{q[i, 2]:.12f},{q[i, 3]:.12f},0,0,0" for i in range(len(t))]  # fmt: skip
    path.write_text(head + "\n" + "\n".join(rows) + "\n")
    return path


def _csv(path, t, p, q):
    rows = [f"{q[i, 0]:.12f},{q[i, 1]:.12f},{q[i, 2]:.12f},{q[i, 3]:.12f},{t[i] * 1e3:.6f},"
            f"{p[i, 0]:.9f},{p[i, 1]:.9f},{p[i, 2]:.9f}" for i in range(len(t))]  # fmt: skip
    path.write_text("qw,qx,qy,qz,time_ms,x,y,z\n" + "\n".join(rows) + "\n")
    return path


def _angle(qa, qb):
    return np.linalg.norm(rot.log_quat(rot.quat_mul(rot.quat_conj(qa), qb)), axis=1)


@pytest.mark.parametrize("writer", [_tum, _euroc, _csv])
def test_readers_give_times_positions_attitudes(tmp_path, writer):
    t, p, q = _poses()
    (path,) = read_route_file(writer(tmp_path / "poses.txt", t, p, q))
    assert path.kind == "pose" and path.attitude_frame == "world"
    np.testing.assert_allclose(path.time_unix_s - path.time_unix_s[0], t, atol=1e-6)
    np.testing.assert_allclose(path.enu_m, p, atol=1e-8)
    assert _angle(path.attitude, q).max() < 1e-9


def test_ingest_in_two_steps_keeps_the_attitude(tmp_path):
    """TUM -> CSV stage -> ENU table: positions at the origin's world, attitudes relative to
    the local ENU at each point (identical to the origin's near it, to 1e-6 rad here)."""
    t, p, q = _poses()
    src = _tum(tmp_path / "f.tum", t, p, q)
    ing = ingest(src, origin=ORIGIN, vehicle="multirotor")
    assert ing.meta["pose"]["world"] == "enu"
    write(ing, tmp_path / "f.csv")
    ing2 = ingest(tmp_path / "f.csv")
    df = ing2.table
    np.testing.assert_allclose(df[list(tenu.ENU)].to_numpy(), p, atol=1e-6)
    q_l = df[list(tenu.ATTITUDE)].to_numpy()
    frame = ea.OriginFrame.from_deg(47.4, 8.5, 400.0, "wgs84")
    C_nl = np.swapaxes(frame.C_ln(p), 1, 2)
    q_n = rot.quat_mul(rot.dcm_to_quat(C_nl), q_l)
    assert _angle(q_n, q).max() < 1e-8
    assert 1e-8 < _angle(q_l, q).max() < 1e-5  # the level turns by the distance / R


def test_ned_and_ecef_worlds(tmp_path):
    t, p, q = _poses()
    C = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # NED -> ENU
    src = _tum(tmp_path / "ned.tum", t, p @ C.T, rot.quat_mul(rot.dcm_to_quat(C.T), q))
    df = ingest(src, origin=ORIGIN, pose_world="ned").table
    np.testing.assert_allclose(df[list(tenu.ENU)].to_numpy(), p, atol=1e-6)
    frame = ea.OriginFrame.from_deg(47.4, 8.5, 400.0, "wgs84")
    r_e = frame.ecef_from_n(p)
    q_e = rot.quat_mul(rot.dcm_to_quat(frame.C_en.T), q)
    src = _tum(tmp_path / "ecef.tum", t, r_e, q_e)
    ing = ingest(src, origin=ORIGIN, pose_world="ecef")
    np.testing.assert_allclose(ing.table[list(tenu.ENU)].to_numpy(), p, atol=1e-5)
    q_l = ing.table[list(tenu.ATTITUDE)].to_numpy()
    q_n = rot.quat_mul(rot.dcm_to_quat(np.swapaxes(frame.C_ln(p), 1, 2)), q_l)
    assert _angle(q_n, q).max() < 1e-7


def test_bad_poses_are_cleaned_or_refused(tmp_path):
    t, p, q = _poses()
    q[5] = [0.0, 0.0, 0.0, 0.0]
    q[9] *= -1.0
    ing = ingest(_tum(tmp_path / "f.tum", t, p, q), origin=ORIGIN)
    assert ing.meta["pose"]["dropped_invalid"] == 1
    assert len(ing.table) == len(t) - 1
    with pytest.raises(InputError, match="origin"):
        ingest(_tum(tmp_path / "g.tum", t, p, q))
    bad = tmp_path / "bad.tum"
    bad.write_text("1 2 3 4 5 6 7 8\n1 2 3 4 5 6 7\n")
    with pytest.raises(InputError, match="line 2"):
        read_route_file(bad)


def test_ros2_bag_of_the_exporter(tmp_path):
    """The odometry of `imugen export --format=ros2` reads back as its truth's poses."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    t, p, q = _poses(50)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    Odom = ts.types["nav_msgs/msg/Odometry"]
    H, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    g = ts.types
    bag = tmp_path / "bag"
    with Writer(bag, version=8) as wr:
        con = wr.add_connection("/ground_truth/odom", Odom.__msgtype__, typestore=ts)
        for i in range(len(t)):
            ns = 1_700_000_000_000_000_000 + round(t[i] * 1e9)
            pose = g["geometry_msgs/msg/Pose"](
                position=g["geometry_msgs/msg/Point"](x=p[i, 0], y=p[i, 1], z=p[i, 2]),
                orientation=g["geometry_msgs/msg/Quaternion"](
                    x=q[i, 1], y=q[i, 2], z=q[i, 3], w=q[i, 0]
                ),
            )
            cov = np.zeros(36)
            msg = Odom(
                header=H(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="map"),
                child_frame_id="imu_link",
                pose=g["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov),
                twist=g["geometry_msgs/msg/TwistWithCovariance"](
                    twist=g["geometry_msgs/msg/Twist"](
                        linear=g["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                        angular=g["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                    ),
                    covariance=cov,
                ),
            )
            wr.write(con, ns, ts.serialize_cdr(msg, Odom.__msgtype__))
    (db,) = bag.glob("*.db3")
    (path,) = read_route_file(db)
    assert path.name == "/ground_truth/odom"  # a candidate per pose topic
    np.testing.assert_allclose(path.time_unix_s - path.time_unix_s[0], t, atol=1e-6)
    np.testing.assert_allclose(path.enu_m, p)
    assert _angle(path.attitude, q).max() < 1e-12
    assert math.isclose(path.time_unix_s[0], 1.7e9)
    ing = ingest(bag, origin=ORIGIN, vehicle="multirotor")  # the bag's folder
    np.testing.assert_allclose(ing.table[list(tenu.ENU)].to_numpy(), p, atol=1e-6)
