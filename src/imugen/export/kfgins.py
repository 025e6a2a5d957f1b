"""KF-GINS / i2Nav text files: increments ``imu.txt``, truth ``truth.nav``, GNSS and a config.

Files (KF-GINS README "Data format", ``src/fileio/*fileloader.h``, ``src/kf_gins.cpp``):

* ``imu.txt``: ``sow dtheta_x dtheta_y dtheta_z dvel_x dvel_y dvel_z`` (s, rad, m/s) in the FRD
  body frame, one row per interval, stamped at the interval's END. KF-GINS applies its own
  two-sample coning/sculling correction to RAW increments (``simulate.increments: raw``);
  compensated increments are exported with one warning per export.
* ``truth.nav``: ``week sow lat lon h vN vE vD roll pitch yaw`` (-, s, deg, deg, m, m/s, deg;
  NED at the vehicle, FRD body, ZYX Euler angles), the layout of KF-GINS' own
  ``KF_GINS_Navresult.nav`` (week written 0, as KF-GINS does).
* ``gnss.pos`` (with the GNSS epochs of ``imugen aid``): ``sow lat lon h sd_N sd_E sd_D``
  (s, deg, deg, m, m, m, m) of the epochs with a fix.
* ``kf-gins.yaml`` (only with ``gnss.pos``: KF-GINS cannot run without one): every key
  ``loadConfig``/``main`` read, with yaml-cpp's types (ints where it reads ``int``, 3-lists where
  it reads vectors). Paths are relative: run ``KF-GINS kf-gins.yaml`` from the folder.
  ``starttime`` is the first ``imu.txt`` time and the initial state the truth there.

``imunoise`` (:func:`imunoise`) is this sequence's drawn figures in KF-GINS units; the initial
error sigmas (``init{bg,ba,sg,sa}std``) are the grade's (:func:`init_error_std`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.export.common import gm_components, write_rows
from imugen.export.convert import dcm_ned_frd, enu_to_ned, euler_ned_frd, flu_to_frd
from imugen.export.source import INCREMENT_COLUMNS, Sequence, TruthArrays
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth

DEG = 180.0 / math.pi
GPS_WEEK_S = 604800.0
"""KF-GINS refuses times beyond one GPS week ("Process time ERROR!")."""
TIME_FMT = "%.6f"
"""Text of the time column of ``imu.txt`` (``starttime`` is written as the same number)."""
INIT_POS_STD_M = 0.01
INIT_VEL_STD_MPS = 0.01
INIT_ATT_STD_DEG = 0.01
"""Initial position, velocity, attitude sigmas: the initial state is the truth itself."""
NO_INRUN_CORR_H = 1000.0
"""``corrtime`` [h] when neither sensor has an in-run Gauss-Markov bias: biases and scale
factors are constants over any route, which a correlation time this long represents."""
ARW = DEG * 60.0  # rad/sqrt(s) -> deg/sqrt(h)
VRW = 60.0  # m/s/sqrt(s) -> m/s/sqrt(h)
DEG_PER_H = DEG * 3600.0  # rad/s -> deg/h
MGAL = 1e5  # m/s^2 -> mGal
PPM = 1e6


def _frame(truth: TruthArrays):
    return ttruth.origin_frame(truth.meta)


def nav_rows(truth: TruthArrays, sow0: float = 0.0, week: int = 0) -> np.ndarray:
    """(K, 11) truth rows: week, sow, lat, lon [deg], h [m], vN, vE, vD, roll, pitch, heading [deg].

    Velocity and attitude are taken relative to the local level at the vehicle (``C_ln``).
    """
    frame = _frame(truth)
    lat, lon, h = frame.geodetic_from_n(truth.p_n)
    C_ln = frame.C_ln(truth.p_n)
    v_l = np.einsum("kij,kj->ki", C_ln, truth.v_n)
    C_lb = C_ln @ rot.quat_to_dcm(truth.q_nb)
    eul = euler_ned_frd(dcm_ned_frd(C_lb)) * DEG
    return np.column_stack(
        [
            np.full(truth.K, float(week)),
            sow0 + truth.time_s,
            np.degrees(lat),
            np.degrees(lon),
            h,
            enu_to_ned(v_l),
            eul,
        ]
    )


def check(truth: TruthArrays, shard_paths, gnss_paths, warn=print) -> None:
    """Checks of an export to KF-GINS made once, before anything is written.

    InputError for a shard without increment columns (KF-GINS reads increments) and for a
    route KF-GINS cannot process (longer than a GPS week; a rate below 10 Hz that is not a
    whole number of Hz: KF-GINS then takes ``dt = 1 / imudatarate``, an int). One warning each
    for compensated increments, a missing GNSS table (no ``kf-gins.yaml`` then) and a flat-earth
    truth.
    """
    compensated = []
    for p in map(Path, shard_paths):
        if not set(INCREMENT_COLUMNS) <= set(tshard.column_names(p)):
            raise InputError(
                p,
                "holds no increment columns, which KF-GINS reads: simulate with "
                "outputs: increments or both (and increments: raw)",
            )
        if tshard.increment_kind(tshard.read_meta(p)) != "raw":
            compensated.append(p.name)
    if truth.time_s[-1] > GPS_WEEK_S:
        raise InputError("--format kfgins", "the route is longer than a GPS week (604800 s)")
    rate = 1.0 / truth.dt
    if truth.dt >= 0.1 and abs(rate - round(rate)) > 1e-9 * rate:
        raise InputError(
            "--format kfgins", f"KF-GINS needs a whole number of Hz below 10 Hz, got {rate:g} Hz"
        )
    if compensated:
        warn(
            f"{len(compensated)} shard(s) hold compensated increments ({compensated[0]}, ...): "
            "KF-GINS applies its own coning/sculling correction, so it is counted twice "
            "(simulate.increments: raw avoids it)"
        )
    if not gnss_paths:
        warn(
            "kfgins: no GNSS epochs (--gnss): imu.txt and truth.nav written, kf-gins.yaml not "
            "(KF-GINS cannot run without gnss.pos)"
        )
    if _frame(truth).model == "flat":
        warn(
            "kfgins: the truth is on a flat, non-rotating earth; KF-GINS navigates on the "
            "rotating WGS84 ellipsoid and will see the difference as sensor error"
        )


def _grade(meta: dict):
    from imugen.sensors.grades import get_grade, grade_from_config

    g = meta.get("grade") or {}
    if isinstance(g, dict) and g.get("config"):
        return grade_from_config(g["name"], g["config"], g.get("origin", "shard metadata"))
    return get_grade(g.get("name") if isinstance(g, dict) else g)


def _axes(labels: dict, stem: str) -> np.ndarray:
    return np.array([float(labels.get(stem.format(a=a), 0.0)) for a in "xyz"])


def _inrun(labels: dict, sensor: str) -> tuple[np.ndarray, float]:
    """``(q (3,), T)`` of a sensor's in-run bias: driving PSD ``q = sum_c 2 sigma_c^2 / tau_c +
    K^2`` [(rad/s)^2/s or (m/s^2)^2/s] (the components of the bias instability and of a
    ``slow_bias``) and its Gauss-Markov time ``T = sum sigma_c^2 /
    sum (sigma_c^2 / tau_c)`` [s] (``tau_0`` for one component; nan without one)."""
    unit, rw = ("radps", "radps_per_sqrt_s") if sensor == "gyro" else ("mps2", "mps2_per_sqrt_s")
    s2, s2_tau = np.zeros(3), np.zeros(3)
    for tname, sname in gm_components(labels, sensor):
        tau = float(labels[f"{sensor}_{tname}"])
        sig = _axes(labels, f"{sensor}_{sname}_{{a}}_{unit}")
        if tau > 0:
            s2, s2_tau = s2 + sig**2, s2_tau + sig**2 / tau
    q = 2.0 * s2_tau + _axes(labels, f"{sensor}_rate_random_walk_{{a}}_{rw}") ** 2
    T = float(np.sum(s2) / np.sum(s2_tau)) if np.sum(s2_tau) > 0 else math.nan
    return q, T


def imunoise(labels: dict, grade) -> dict:
    """KF-GINS ``imunoise`` of one sequence (per-axis lists, KF-GINS units).

    ``arw``, ``vrw``: the sequence's white-noise densities [deg/sqrt(h), m/s/sqrt(h)].
    ``gbstd``, ``abstd`` [deg/h, mGal] with ``corrtime`` [h]: KF-GINS has one first-order
    Gauss-Markov bias per axis and one correlation time for both sensors. ``corrtime`` is the
    gyro's in-run time (the accelerometer's without a gyro one; :data:`NO_INRUN_CORR_H` with
    neither) and each std is chosen so that the Gauss-Markov driving noise ``2 std^2 /
    corrtime`` equals the sensor's (its in-run processes plus its rate random walk): with one
    in-run component of that time, ``gbstd`` is its sigma exactly. ``gsstd``, ``asstd``
    [ppm]: the grade's scale-factor sigma (the top of its range; the sequence's label is a
    realization, not a level), as ``imugen grade import`` reads them back.
    """
    qg, Tg = _inrun(labels, "gyro")
    qa, Ta = _inrun(labels, "accel")
    T = Tg if math.isfinite(Tg) else Ta if math.isfinite(Ta) else NO_INRUN_CORR_H * 3600.0

    def sf(s):
        p = grade.sensor(s).scale_factor
        return np.zeros(3) if p is None else np.asarray(p.hi if p.hi is not None else p.value)

    return {
        "arw": _axes(labels, "gyro_white_noise_{a}_rad_per_sqrt_s") * ARW,
        "vrw": _axes(labels, "accel_white_noise_{a}_m_per_s_per_sqrt_s") * VRW,
        "gbstd": np.sqrt(qg * T / 2.0) * DEG_PER_H,
        "abstd": np.sqrt(qa * T / 2.0) * MGAL,
        "gsstd": sf("gyro") * PPM,
        "asstd": sf("accel") * PPM,
        "corrtime": T / 3600.0,
    }


def init_error_std(grade, terms=None) -> dict:
    """``initbgstd``, ``initbastd`` [deg/h, mGal], ``initsgstd``, ``initsastd`` [ppm]: the
    initial sigmas of the filter's bias and scale states, those of imugen's own filter
    (:meth:`imugen.aid.filter.Tuning.from_grade` at the top of the grade's ranges: turn-on, in-run
    and the static error on gravity KF-GINS sees as a bias)."""
    from imugen.aid.filter import Tuning

    tun = Tuning.from_grade(grade, "upper", terms=terms)
    return {
        "initbgstd": tun.gyro_bias_sd * DEG_PER_H,
        "initbastd": tun.accel_bias_sd * MGAL,
        "initsgstd": tun.gyro_sf_sd * PPM,
        "initsastd": tun.accel_sf_sd * PPM,
    }


def _floats(v) -> list[float] | float:
    a = np.asarray(v, float)
    return float(a) if a.ndim == 0 else [float(x) for x in a]


def write(seq: Sequence, truth: TruthArrays, folder: Path, warn=print, **_) -> list[Path]:
    if not seq.has(INCREMENT_COLUMNS):
        raise InputError(
            "--format kfgins", "needs increment columns (simulate.outputs increments or both)"
        )
    folder.mkdir(parents=True, exist_ok=True)
    inc = seq.stack(INCREMENT_COLUMNS)[1:]
    rows = np.column_stack([truth.time_s[1:], flu_to_frd(inc[:, :3]), flu_to_frd(inc[:, 3:])])
    with open(folder / "imu.txt", "w") as fh:
        write_rows(fh, rows, TIME_FMT + " %.12e" * 6)
    nav = nav_rows(truth)
    with open(folder / "truth.nav", "w") as fh:
        write_rows(fh, nav, "%d %.6f %.11f %.11f %.4f %.6f %.6f %.6f %.8f %.8f %.8f")
    files = [folder / "imu.txt", folder / "truth.nav"]
    if seq.gnss is None:
        return files
    start = float(TIME_FMT % truth.time_s[1])  # the first imu.txt time, as KF-GINS parses it
    gnss = folder / "gnss.pos"
    t_fix = write_gnss_pos(seq.gnss, truth, gnss)
    files.append(gnss)
    if not np.any(t_fix > start):
        warn(f"sequence {seq.id}: no GNSS fix after {start} s: kf-gins.yaml not written")
        return files
    gl = seq.gnss.attrs.get("labels", {})
    lever = flu_to_frd(np.array([float(gl.get(f"gnss_lever_arm_{a}_m", 0.0)) for a in "xyz"]))
    grade = _grade(seq.meta)
    terms = seq.meta.get("terms")
    terms = None if not terms else sorted(set().union(*terms.values()))
    x0 = nav[1]  # the truth at starttime: KF-GINS' initial state is that of the first record
    cfg = {
        "imupath": "imu.txt",
        "gnsspath": "gnss.pos",
        "outputpath": ".",
        "imudatalen": 7,
        "imudatarate": round(1.0 / truth.dt),
        "starttime": start,
        "endtime": -1,
        "initpos": _floats(x0[2:5]),
        "initvel": _floats(x0[5:8]),
        "initatt": _floats(x0[8:11]),
        "initgyrbias": [0.0, 0.0, 0.0],
        "initaccbias": [0.0, 0.0, 0.0],
        "initgyrscale": [0.0, 0.0, 0.0],
        "initaccscale": [0.0, 0.0, 0.0],
        "initposstd": [INIT_POS_STD_M] * 3,
        "initvelstd": [INIT_VEL_STD_MPS] * 3,
        "initattstd": [INIT_ATT_STD_DEG] * 3,
        **{k: _floats(v) for k, v in init_error_std(grade, terms).items()},
        "imunoise": {k: _floats(v) for k, v in imunoise(seq.labels, grade).items()},
        "antlever": _floats(lever),
    }
    head = (
        f"# KF-GINS configuration for imugen sequence {seq.id}: run `KF-GINS kf-gins.yaml` in "
        "this folder (relative paths).\n# Initial state: the truth at starttime (the first "
        "imu.txt record); initial biases and scales 0 (their true values are in the labels).\n"
        "# Units: initpos deg, deg, m; initvel m/s (NED); initatt deg (roll, pitch, yaw); "
        "init*std m, m/s, deg; bias deg/h, mGal; scale ppm;\n# imunoise: arw deg/sqrt(h), "
        "vrw m/s/sqrt(h), gbstd deg/h, abstd mGal, gsstd/asstd ppm, corrtime h; antlever m "
        "(FRD, from the IMU).\n"
    )
    text = yaml.safe_dump(cfg, sort_keys=False, default_flow_style=None, width=200)
    (folder / "kf-gins.yaml").write_text(head + text)
    return [*files, folder / "kf-gins.yaml"]


def write_gnss_pos(gnss, truth: TruthArrays, path: Path, sow0: float = 0.0) -> np.ndarray:
    """Write KF-GINS ``gnss.pos``: ``sow lat lon h sd_N sd_E sd_D`` (s, deg, deg, m, m, m, m) of
    the epochs with a fix, antenna position as the receiver reports it (errors, attacks).
    Returns the times written (n,) [s] as KF-GINS reads them."""
    from imugen.tables import gnss as tgnss

    ok = (gnss[tgnss.FIX].to_numpy() > 0) & np.isfinite(gnss[tgnss.P[0]].to_numpy())
    g = gnss[ok]
    lat, lon, h = _frame(truth).geodetic_from_n(g[list(tgnss.P)].to_numpy())
    sd = g[list(tgnss.SIGMA_P)].to_numpy()  # East, North, Up
    rows = np.column_stack(
        [
            sow0 + g[ttruth.TIME].to_numpy(),
            np.degrees(lat),
            np.degrees(lon),
            h,
            sd[:, 1],
            sd[:, 0],
            sd[:, 2],
        ]
    )
    with open(path, "w") as fh:
        write_rows(fh, rows, TIME_FMT + " %.11f %.11f %.4f %.4f %.4f %.4f")
    return np.array([float(TIME_FMT % t) for t in rows[:, 0]])
