"""Still IMU logs read for ``imugen grade fit``: CSV, Parquet, EuRoC ``imu0/data.csv``, ROS 2 bags.

Every reader returns :class:`ImuLog`: gyro ``(K, 3)`` [rad/s] and accelerometer ``(K, 3)``
[m/s^2] in the log's own sensor axes, the sample rate, and what was cleaned.

Columns recognised (CSV and Parquet; the first complete set wins):

* imugen's ``gyro_{x,y,z}_radps``, ``accel_{x,y,z}_mps2`` (time ``time_s``, optional);
* EuRoC / ASL ``w_RS_S_{x,y,z} [rad s^-1]``, ``a_RS_S_{x,y,z} [m s^-2]`` with
  ``#timestamp [ns]`` (a directory holding ``mav0/imu0/data.csv`` or ``imu0/data.csv`` also
  works);
* ``gyro_{x,y,z}`` [rad/s] and ``accel_{x,y,z}`` [m/s^2], time ``time_s`` / ``t`` [s] or
  ``timestamp_ns`` [ns].

A ROS 2 bag (a directory with ``metadata.yaml``, or a ``.db3``/``.mcap`` file): the first
``sensor_msgs/msg/Imu`` topic (``angular_velocity``, ``linear_acceleration``, header stamps).

The rate comes from ``--rate-hz`` or, without it, from the median time step. Rows with a
non-finite value are dropped (and said); a log with a gap (a step above 1.5 x the median) is
refused: the Allan variance needs uniform sampling.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError

_SETS = (
    (
        tuple(f"gyro_{a}_radps" for a in "xyz") + tuple(f"accel_{a}_mps2" for a in "xyz"),
        (("time_s", 1.0),),
    ),
    (
        tuple(f"w_RS_S_{a} [rad s^-1]" for a in "xyz")
        + tuple(f"a_RS_S_{a} [m s^-2]" for a in "xyz"),
        (("#timestamp [ns]", 1e-9), ("#timestamp", 1e-9), ("timestamp", 1e-9)),
    ),
    (
        tuple(f"gyro_{a}" for a in "xyz") + tuple(f"accel_{a}" for a in "xyz"),
        (("time_s", 1.0), ("t", 1.0), ("timestamp_ns", 1e-9)),
    ),
)


@dataclass
class ImuLog:
    """A still IMU log in SI.

    Attributes
    ----------
    gyro, accel : ndarray, shape (K, 3)
        Angular rate [rad/s] and specific force [m/s^2], sensor axes.
    rate_hz : float
    source : str
        The file (and topic) read.
    notes : list of str
        What was cleaned.
    """

    gyro: np.ndarray
    accel: np.ndarray
    rate_hz: float
    source: str
    notes: list = field(default_factory=list)


def _from_columns(cols: dict, names, path) -> tuple[np.ndarray, np.ndarray | None]:
    stripped = {str(k).strip(): k for k in names}
    for want, times in _SETS:
        if all(w in stripped for w in want):
            Y = np.column_stack([np.asarray(cols(stripped[w]), np.float64) for w in want])
            t = None
            for tn, scale in times:
                if tn in stripped:
                    t = np.asarray(cols(stripped[tn]), np.float64) * scale
                    break
            return Y, t
    raise InputError(
        path,
        "no IMU columns found: expected gyro_{x,y,z}_radps + accel_{x,y,z}_mps2, EuRoC "
        "w_RS_S_* / a_RS_S_*, or gyro_{x,y,z} + accel_{x,y,z} (SI)",
    )


def _table(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    import pandas as pd

    try:
        if path.suffix.lower() == ".parquet":
            df = pd.read_parquet(path)
        else:
            df = pd.read_csv(path, skipinitialspace=True)
    except (OSError, ValueError) as exc:
        raise InputError(path, f"cannot read as a table: {str(exc).splitlines()[0]}") from None
    return _from_columns(lambda c: df[c].to_numpy(), list(df.columns), path)


def _ros2(path: Path) -> tuple[np.ndarray, np.ndarray, str]:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(path, "reading a ROS 2 bag needs rosbags (pip install rosbags)") from None
    bag = path if path.is_dir() else path.parent
    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as r:
            conns = [c for c in r.connections if c.msgtype == "sensor_msgs/msg/Imu"]
            if not conns:
                raise InputError(path, "no sensor_msgs/msg/Imu topic in the bag")
            topic = conns[0].topic
            conns = [c for c in conns if c.topic == topic]
            rows, ts = [], []
            for c, _, raw in r.messages(connections=conns):
                m = r.deserialize(raw, c.msgtype)
                w, a = m.angular_velocity, m.linear_acceleration
                rows.append((w.x, w.y, w.z, a.x, a.y, a.z))
                ts.append(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec)
    except InputError:
        raise
    except Exception as exc:  # rosbags raises its own types for damaged bags
        raise InputError(path, f"cannot read the ROS 2 bag: {exc}") from None
    return np.asarray(rows, np.float64).reshape(-1, 6), np.asarray(ts, np.float64), topic


def read_log(path, rate_hz: float | None = None) -> ImuLog:
    """Read a still IMU log (see the module docstring for the formats).

    Raises
    ------
    InputError
        Unreadable file, no IMU columns, no rate, too short, or not uniformly sampled.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(path, "no such file or directory")
    source = str(path)
    if path.is_dir() and not (path / "metadata.yaml").exists():
        for sub in ("mav0/imu0/data.csv", "imu0/data.csv", "data.csv"):
            if (path / sub).exists():
                path = path / sub
                break
    if path.is_dir() or path.suffix.lower() in (".db3", ".mcap"):
        Y, t, topic = _ros2(path)
        source += f" ({topic})"
    else:
        Y, t = _table(path)
    notes = []
    ok = np.all(np.isfinite(Y), axis=1)
    if t is not None:
        ok &= np.isfinite(t)
    if not ok.all():
        notes.append(f"dropped {int((~ok).sum())} rows with a missing or non-finite value")
        Y = Y[ok]
        t = None if t is None else t[ok]
    if len(Y) < 1000:
        raise InputError(path, f"{len(Y)} samples: too short to fit noise (need >= 1000)")
    if t is not None:
        dt = np.diff(t)
        med = float(np.median(dt))
        if not med > 0:
            raise InputError(path, "time stamps do not increase")
        if np.any(dt <= 0) or np.any(dt > 1.5 * med):
            bad = int(np.sum((dt <= 0) | (dt > 1.5 * med)))
            raise InputError(
                path, f"{bad} time steps are not about {med:.6g} s (gaps or repeats): a fit "
                "needs one uniformly sampled still record; cut the log at its gaps",
            )  # fmt: skip
        if rate_hz is None:
            rate_hz = 1.0 / med
    if rate_hz is None:
        raise InputError(path, "no time column: give --rate-hz")
    if not (rate_hz > 0 and np.isfinite(rate_hz)):
        raise InputError("--rate-hz", f"must be a positive number, got {rate_hz!r}")
    return ImuLog(Y[:, :3].copy(), Y[:, 3:].copy(), float(rate_hz), source, notes)
