"""ROS 2 bags written without ROS (the ``rosbags`` package): IMU, truth odometry and fix.

One bag per sequence (``<seq>/``, rosbag2 with sqlite3 storage, or MCAP with
``storage="mcap"``), REP-103 frames (ENU world ``map``, FLU body ``base_link`` = ``imu_link``):

* ``/imu/data`` ``sensor_msgs/msg/Imu``: measured angular rate and specific force (+g on z at
  rest), orientation unknown (``orientation_covariance[0] = -1``), noise covariances from this
  sequence's white-noise densities (``N^2 / dt``);
* ``/ground_truth/odom`` ``nav_msgs/msg/Odometry``: true pose in ``map`` and true twist in
  ``base_link`` (linear ``C_bn v_n``, angular ``omega_ib_b``), at every truth sample;
* ``/ground_truth/fix`` ``sensor_msgs/msg/NavSatFix``: the true geodetic position (WGS-84)
  at the navigation rate (a truth topic, not a receiver: it has zero covariance);
* ``/gnss/fix`` ``sensor_msgs/msg/NavSatFix`` (with the GNSS epochs of ``imugen aid``): the
  simulated receiver, frame ``gnss_antenna``, status FIX or NO_FIX (outages, lost jamming),
  covariance diagonal from the reported sigmas (East, North, Up).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imugen import rotations as rot
from imugen.errors import InputError
from imugen.formats.common import measured_rates, noise_figures
from imugen.formats.convert import clock
from imugen.formats.kfgins import _frame
from imugen.formats.source import Sequence, TruthArrays

TOPICS = {
    "imu": ("/imu/data", "sensor_msgs/msg/Imu"),
    "odom": ("/ground_truth/odom", "nav_msgs/msg/Odometry"),
    "fix": ("/ground_truth/fix", "sensor_msgs/msg/NavSatFix"),
    "gnss": ("/gnss/fix", "sensor_msgs/msg/NavSatFix"),
}


def _typestore():
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError("--format ros2", "needs rosbags (pip install rosbags)") from None
    return get_typestore(Stores.ROS2_HUMBLE)


def write(
    seq: Sequence,
    truth: TruthArrays,
    folder: Path,
    start_ns: int = 0,
    every: int = 10,
    storage: str = "sqlite3",
    **_,
) -> list[Path]:
    ts = _typestore()
    from rosbags.rosbag2 import StoragePlugin, Writer

    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    Vec, Quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    Point, Pose = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Pose"]
    PwC, Twist = T["geometry_msgs/msg/PoseWithCovariance"], T["geometry_msgs/msg/Twist"]
    TwC = T["geometry_msgs/msg/TwistWithCovariance"]
    Imu, Odom = T["sensor_msgs/msg/Imu"], T["nav_msgs/msg/Odometry"]
    Fix, Status = T["sensor_msgs/msg/NavSatFix"], T["sensor_msgs/msg/NavSatStatus"]

    def header(ns, frame):
        return Header(
            stamp=Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000)),
            frame_id=frame,
        )

    t, w, f, _kind = measured_rates(seq, truth)
    ns = clock(t, 1e-9, start_ns)
    fig = noise_figures(seq.labels)
    cw = np.diag([fig["gyroscope_noise_density"] ** 2 / truth.dt] * 3).ravel()
    ca = np.diag([fig["accelerometer_noise_density"] ** 2 / truth.dt] * 3).ravel()
    no_orientation = np.zeros(9)
    no_orientation[0] = -1.0
    ns_t = clock(truth.time_s, 1e-9, start_ns)
    C_bn = np.swapaxes(rot.quat_to_dcm(truth.q_nb), 1, 2)
    v_b = np.einsum("kij,kj->ki", C_bn, truth.v_n)
    zero36 = np.zeros(36)
    frame = _frame(truth)
    sl = slice(None, None, max(1, int(every)))
    lat, lon, h = frame.geodetic_from_n(truth.p_n[sl])
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    if folder.exists():
        raise InputError(folder, "exists; a bag is written into a new folder")
    folder.parent.mkdir(parents=True, exist_ok=True)
    with Writer(folder, version=8, storage_plugin=plugin) as wr:
        conn = {
            k: wr.add_connection(topic, typ, typestore=ts) for k, (topic, typ) in TOPICS.items()
        }
        for i in range(len(t)):
            msg = Imu(
                header=header(ns[i], "imu_link"),
                orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=no_orientation,
                angular_velocity=Vec(x=w[i, 0], y=w[i, 1], z=w[i, 2]),
                angular_velocity_covariance=cw,
                linear_acceleration=Vec(x=f[i, 0], y=f[i, 1], z=f[i, 2]),
                linear_acceleration_covariance=ca,
            )
            wr.write(conn["imu"], int(ns[i]), ts.serialize_cdr(msg, Imu.__msgtype__))
        for k in range(truth.K):
            p, q, g = truth.p_n[k], truth.q_nb[k], truth.gyro[k]
            msg = Odom(
                header=header(ns_t[k], "map"),
                child_frame_id="base_link",
                pose=PwC(
                    pose=Pose(
                        position=Point(x=p[0], y=p[1], z=p[2]),
                        orientation=Quat(x=q[1], y=q[2], z=q[3], w=q[0]),
                    ),
                    covariance=zero36,
                ),
                twist=TwC(
                    twist=Twist(
                        linear=Vec(x=v_b[k, 0], y=v_b[k, 1], z=v_b[k, 2]),
                        angular=Vec(x=g[0], y=g[1], z=g[2]),
                    ),
                    covariance=zero36,
                ),
            )
            wr.write(conn["odom"], int(ns_t[k]), ts.serialize_cdr(msg, Odom.__msgtype__))
        for j, k in enumerate(range(truth.K)[sl]):
            msg = Fix(
                header=header(ns_t[k], "base_link"),
                status=Status(status=0, service=1),
                latitude=float(np.degrees(lat[j])),
                longitude=float(np.degrees(lon[j])),
                altitude=float(h[j]),
                position_covariance=np.zeros(9),
                position_covariance_type=2,
            )
            wr.write(conn["fix"], int(ns_t[k]), ts.serialize_cdr(msg, Fix.__msgtype__))
        if seq.gnss is not None:
            from imugen.tables import gnss as tgnss

            g = seq.gnss
            pg = g[list(tgnss.P)].to_numpy()
            sg = g[list(tgnss.SIGMA_P)].to_numpy()
            fix = g[tgnss.FIX].to_numpy() > 0
            glat, glon, gh = frame.geodetic_from_n(np.nan_to_num(pg))
            ns_g = clock(g["time_s"].to_numpy(), 1e-9, start_ns)
            for i in range(len(g)):
                ok = bool(fix[i] and np.isfinite(pg[i]).all())
                cov = np.zeros(9)
                cov[[0, 4, 8]] = np.nan_to_num(sg[i]) ** 2
                msg = Fix(
                    header=header(ns_g[i], "gnss_antenna"),
                    status=Status(status=0 if ok else -1, service=1),
                    latitude=float(np.degrees(glat[i])) if ok else float("nan"),
                    longitude=float(np.degrees(glon[i])) if ok else float("nan"),
                    altitude=float(gh[i]) if ok else float("nan"),
                    position_covariance=cov,
                    position_covariance_type=2 if ok else 0,
                )
                wr.write(conn["gnss"], int(ns_g[i]), ts.serialize_cdr(msg, Fix.__msgtype__))
    return [folder]
