"""Still-log readers of ``imugen grade fit``: formats, cleaning and clear refusals."""

import numpy as np
import pandas as pd
import pytest

from imugen.core.errors import InputError
from imugen.sensors.imu_log import read_log


def _frame(K=2000, rate=200.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(K) / rate
    return t, rng.normal(0, 0.01, (K, 3)), rng.normal([0, 0, 9.8], 0.05, (K, 3))


def test_euroc_csv_and_directory(tmp_path):
    t, w, a = _frame()
    d = tmp_path / "mav0" / "imu0"
    d.mkdir(parents=True)
    cols = ["#timestamp [ns]"] + [f"w_RS_S_{x} [rad s^-1]" for x in "xyz"]
    cols += [f"a_RS_S_{x} [m s^-2]" for x in "xyz"]
    df = pd.DataFrame(np.column_stack([(t * 1e9).astype(np.int64), w, a]), columns=cols)
    df[cols[0]] = df[cols[0]].astype(np.int64)
    df.to_csv(d / "data.csv", index=False)
    lg = read_log(tmp_path)  # the dataset's directory
    assert lg.rate_hz == pytest.approx(200.0)
    assert np.allclose(lg.gyro, w) and np.allclose(lg.accel, a)


def test_imugen_parquet_with_rate_option_and_nan_rows(tmp_path):
    _, w, a = _frame()
    w[5, 1] = np.nan
    cols = {f"gyro_{x}_radps": w[:, i] for i, x in enumerate("xyz")}
    cols |= {f"accel_{x}_mps2": a[:, i] for i, x in enumerate("xyz")}
    p = tmp_path / "log.parquet"
    pd.DataFrame(cols).to_parquet(p)
    lg = read_log(p, rate_hz=100.0)
    assert lg.rate_hz == 100.0 and len(lg.gyro) == 1999
    assert "dropped 1 rows" in lg.notes[0]


def test_refusals(tmp_path):
    t, w, a = _frame()
    p = tmp_path / "x.csv"
    pd.DataFrame({"a": t, "b": t}).to_csv(p, index=False)
    with pytest.raises(InputError, match="no IMU columns"):
        read_log(p)
    cols = {f"gyro_{x}": w[:, i] for i, x in enumerate("xyz")}
    cols |= {f"accel_{x}": a[:, i] for i, x in enumerate("xyz")}
    pd.DataFrame(cols).to_csv(p, index=False)
    with pytest.raises(InputError, match="give --rate-hz"):
        read_log(p)
    tg = t.copy()
    tg[1000:] += 5.0  # a gap
    pd.DataFrame({"time_s": tg, **cols}).to_csv(p, index=False)
    with pytest.raises(InputError, match="gaps"):
        read_log(p)
    with pytest.raises(InputError, match="no such file"):
        read_log(tmp_path / "missing.csv")


def test_ros2_bag(tmp_path):
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    Imu = ts.types["sensor_msgs/msg/Imu"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    V3 = ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    t, w, a = _frame(K=1200)
    bag = tmp_path / "bag"
    with Writer(bag, version=8) as wr:
        c = wr.add_connection("/imu", Imu.__msgtype__, typestore=ts)
        for k in range(len(t)):
            ns = int(np.round(t[k] * 1e9)) + 10**9
            msg = Imu(
                Header(Time(ns // 10**9, ns % 10**9), "imu"),
                Q(0.0, 0.0, 0.0, 1.0), np.zeros(9), V3(*w[k]), np.zeros(9), V3(*a[k]), np.zeros(9),
            )  # fmt: skip
            wr.write(c, ns, ts.serialize_cdr(msg, Imu.__msgtype__))
    lg = read_log(bag)
    assert lg.rate_hz == pytest.approx(200.0, rel=1e-6)
    assert np.allclose(lg.gyro, w) and np.allclose(lg.accel, a)
    assert "/imu" in lg.source
