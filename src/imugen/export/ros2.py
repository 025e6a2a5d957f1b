"""ROS 2 bags written without ROS (the ``rosbags`` package): IMU, odometry, fixes and truth.

One bag per sequence (``<seq>/``, rosbag2 with sqlite3 storage, or MCAP with
``storage="mcap"``), REP-103/105 frames (ENU world ``map``, FLU vehicle ``base_link``, the IMU's
``imu_link``):

* ``/tf_static`` ``tf2_msgs/msg/TFMessage`` (one message, transient-local QoS as ROS's static
  broadcaster): ``base_link -> imu_link``, identity, or for a mounted sequence the drawn lever
  arm (m, vehicle axes) and misalignment ``C_vb`` (:mod:`imugen.sensors.mounting`); with GNSS epochs
  also ``base_link -> gnss_antenna`` (the drawn antenna lever arm);
* ``/imu/data`` ``sensor_msgs/msg/Imu``: measured angular rate and specific force (+g on z at
  rest), orientation unknown (``orientation_covariance[0] = -1``), noise covariances from this
  sequence's white-noise densities (``N^2 / dt``);
* ``/ground_truth/odom`` ``nav_msgs/msg/Odometry``: the IMU's true pose in ``map`` and true
  twist in its own frame (linear ``C_bn v_n``, angular ``omega_ib_b``), at every truth sample;
  child frame ``imu_link`` (= ``base_link`` without a mounting);
* ``/ground_truth/fix`` ``sensor_msgs/msg/NavSatFix``: the IMU's true geodetic position
  (WGS-84) at the navigation rate (a truth topic, not a receiver: it has zero covariance);
* ``/gnss/fix`` ``sensor_msgs/msg/NavSatFix`` (only with the GNSS epochs of ``imugen aid``):
  the simulated receiver, frame ``gnss_antenna``, status FIX or NO_FIX (outages, lost
  jamming), covariance diagonal from the reported sigmas (East, North, Up);
* ``/wheel/odometry`` ``nav_msgs/msg/Odometry`` (only with an odometer in the companion
  table of ``imugen aid``), what ``robot_localization`` and ``ros2_control``'s drive
  controllers exchange as wheel odometry: frame ``odom``, child ``base_link``,
  ``twist.linear.x`` the measured forward speed of the odometer's reference point at each
  epoch's end, variance ``s_w^2 + c^2 f^2 / 6 + (s_k u)^2`` (white speed noise, the
  difference of two tick roundings of ``c`` metres at rate ``f``, the scale-factor spread at
  the measured speed ``u``); the pose and the other twist axes are not measured (zero, with
  variance ``1e6``, the value these filters read as "do not fuse");
* ``/baro/pressure`` ``sensor_msgs/msg/FluidPressure`` (only with a barometer): the measured
  altitude as static pressure of the ICAO standard atmosphere (:func:`isa_pressure_pa`; its
  inverse gives the altitude back), variance ``(dp/dh)^2 (s_w^2 + s_b^2)`` (white noise plus
  the drift's stationary variance).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.export.common import measured_rates, noise_figures
from imugen.export.convert import clock
from imugen.export.source import Sequence, TruthArrays, mounting_of
from imugen.tables import truth as ttruth

TOPICS = {
    "tf": ("/tf_static", "tf2_msgs/msg/TFMessage"),
    "imu": ("/imu/data", "sensor_msgs/msg/Imu"),
    "odom": ("/ground_truth/odom", "nav_msgs/msg/Odometry"),
    "fix": ("/ground_truth/fix", "sensor_msgs/msg/NavSatFix"),
    "gnss": ("/gnss/fix", "sensor_msgs/msg/NavSatFix"),
    "wheel": ("/wheel/odometry", "nav_msgs/msg/Odometry"),
    "baro": ("/baro/pressure", "sensor_msgs/msg/FluidPressure"),
}
UNMEASURED_VAR = 1e6
"""Variance of the odometry fields a wheel odometer does not measure."""
ISA_P0_PA, ISA_T0_K, ISA_LAPSE_K_PER_M = 101325.0, 288.15, 0.0065
ISA_EXPONENT = 9.80665 * 0.0289644 / (8.31432 * ISA_LAPSE_K_PER_M)
"""``g0 M / (R* L)`` of the ICAO standard troposphere (5.25588; ``R* = 8.31432`` J/(mol K),
the gas constant of the standard)."""


def isa_pressure_pa(h_m):
    """Static pressure [Pa] of the ICAO standard troposphere at altitude ``h_m`` [m] (below
    11 km): ``p0 (1 - L h / T0)^(g0 M / (R L))``."""
    return ISA_P0_PA * (1.0 - ISA_LAPSE_K_PER_M * np.asarray(h_m, float) / ISA_T0_K) ** ISA_EXPONENT


def _typestore():
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError("--format ros2", "needs rosbags (pip install rosbags)") from None
    return get_typestore(Stores.ROS2_HUMBLE)


def _static_qos():
    """QoS of ROS's static transform broadcaster: keep last 1, reliable, transient local."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    t0 = QosTime(sec=0, nsec=0)  # 0: the RMW default (infinite)
    return Qos(
        QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
        t0, t0, QosLiveliness.AUTOMATIC, t0, False,
    )  # fmt: skip


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
    Tf, TfS = T["geometry_msgs/msg/Transform"], T["geometry_msgs/msg/TransformStamped"]
    Imu, Odom = T["sensor_msgs/msg/Imu"], T["nav_msgs/msg/Odometry"]
    Fix, Status = T["sensor_msgs/msg/NavSatFix"], T["sensor_msgs/msg/NavSatStatus"]

    def header(ns, frame):
        return Header(
            stamp=Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000)),
            frame_id=frame,
        )

    def put(key, ns, msg):
        wr.write(conn[key], int(ns), ts.serialize_cdr(msg, msg.__msgtype__))

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
    frame = ttruth.origin_frame(truth.meta)
    sl = slice(None, None, max(1, int(every)))
    lat, lon, h = frame.geodetic_from_n(truth.p_n[sl])
    mount = mounting_of(seq.labels)
    body = "base_link" if mount is None else "imu_link"
    links = [("imu_link", np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))]
    if mount is not None:
        from imugen.sensors.mounting import C_vb

        links[0] = ("imu_link", mount[1], rot.dcm_to_quat(C_vb(mount[0])))
    if seq.gnss is not None:
        lab = seq.gnss.attrs.get("labels", {})
        lever = np.array([float(lab.get(f"gnss_lever_arm_{a}_m", 0.0)) for a in "xyz"])
        links.append(("gnss_antenna", np.nan_to_num(lever), np.array([1.0, 0.0, 0.0, 0.0])))
    comp = seq.companions
    odo = baro = None
    if comp is not None:
        from imugen.tables import companions as tcomp

        odo = comp[comp[tcomp.SENSOR] == tcomp.ODOMETER]
        baro = comp[comp[tcomp.SENSOR] == tcomp.BAROMETER]
        odo, baro = (odo if len(odo) else None), (baro if len(baro) else None)
    topics = ["tf", "imu", "odom", "fix"]
    topics += [
        k for k, on in (("gnss", seq.gnss), ("wheel", odo), ("baro", baro)) if on is not None
    ]
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    if folder.exists():
        raise InputError(folder, "exists; a bag is written into a new folder")
    folder.parent.mkdir(parents=True, exist_ok=True)
    with Writer(folder, version=8, storage_plugin=plugin) as wr:
        conn = {}
        for k in topics:
            qos = [_static_qos()] if k == "tf" else ()
            conn[k] = wr.add_connection(*TOPICS[k], typestore=ts, offered_qos_profiles=qos)
        tfs = [
            TfS(
                header=header(start_ns, "base_link"),
                child_frame_id=child,
                transform=Tf(
                    translation=Vec(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                    rotation=Quat(x=float(q[1]), y=float(q[2]), z=float(q[3]), w=float(q[0])),
                ),
            )
            for child, p, q in links
        ]
        put("tf", start_ns, T["tf2_msgs/msg/TFMessage"](transforms=tfs))
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
            put("imu", ns[i], msg)
        for k in range(truth.K):
            p, q, g = truth.p_n[k], truth.q_nb[k], truth.gyro[k]
            msg = Odom(
                header=header(ns_t[k], "map"),
                child_frame_id=body,
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
            put("odom", ns_t[k], msg)
        for j, k in enumerate(range(truth.K)[sl]):
            msg = Fix(
                header=header(ns_t[k], body),
                status=Status(status=0, service=1),
                latitude=float(np.degrees(lat[j])),
                longitude=float(np.degrees(lon[j])),
                altitude=float(h[j]),
                position_covariance=np.zeros(9),
                position_covariance_type=2,
            )
            put("fix", ns_t[k], msg)
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
                put("gnss", ns_g[i], msg)
        if odo is not None:
            ns_o = clock(odo[tcomp.TIME].to_numpy(), 1e-9, start_ns)
            u = odo[tcomp.ODO_SPEED].to_numpy()
            var_u = wheel_speed_variance(comp.attrs.get("labels", {}), u)
            pose_cov = np.diag(np.full(6, UNMEASURED_VAR)).ravel()
            for i in range(len(odo)):
                tw = np.diag([var_u[i], *np.full(5, UNMEASURED_VAR)]).ravel()
                msg = Odom(
                    header=header(ns_o[i], "odom"),
                    child_frame_id="base_link",
                    pose=PwC(
                        pose=Pose(
                            position=Point(x=0.0, y=0.0, z=0.0),
                            orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                        ),
                        covariance=pose_cov,
                    ),
                    twist=TwC(
                        twist=Twist(
                            linear=Vec(x=u[i], y=0.0, z=0.0), angular=Vec(x=0.0, y=0.0, z=0.0)
                        ),
                        covariance=tw,
                    ),
                )
                put("wheel", ns_o[i], msg)
        if baro is not None:
            Press = T["sensor_msgs/msg/FluidPressure"]
            ns_b = clock(baro[tcomp.TIME].to_numpy(), 1e-9, start_ns)
            alt = baro[tcomp.BARO_ALT].to_numpy()
            lab = comp.attrs.get("labels", {})
            var_h = (
                float(lab.get("baro_white_m", 0.0)) ** 2
                + float(lab.get("baro_bias_sd_m", 0.0)) ** 2
            )
            p = isa_pressure_pa(alt)
            dpdh = -p * ISA_EXPONENT * ISA_LAPSE_K_PER_M / (ISA_T0_K - ISA_LAPSE_K_PER_M * alt)
            for i in range(len(baro)):
                msg = Press(
                    header=header(ns_b[i], "base_link"),
                    fluid_pressure=float(p[i]),
                    variance=float(dpdh[i] ** 2 * var_h),
                )
                put("baro", ns_b[i], msg)
    return [folder]


def wheel_speed_variance(labels: dict, speed_mps) -> np.ndarray:
    """Variance [m^2/s^2] of each wheel-speed epoch from the odometer's drawn parameters:
    ``s_w^2 + c^2 f^2 / 6 + (s_k u)^2`` (labels ``odo_white_mps``, ``odo_tick_m``,
    ``odo_rate_hz``, ``odo_scale_factor_sd``); ``speed_mps`` (n,) the measured speeds ``u``."""
    sw = float(labels.get("odo_white_mps", 0.0))
    quant = float(labels.get("odo_tick_m", 0.0)) * float(labels.get("odo_rate_hz", 0.0))
    sk = float(labels.get("odo_scale_factor_sd", 0.0))
    u = np.asarray(speed_mps, float)
    return sw * sw + quant * quant / 6.0 + (sk * u) ** 2
