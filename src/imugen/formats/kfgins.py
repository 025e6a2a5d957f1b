"""KF-GINS / i2Nav text files: increments ``imu.txt``, truth ``truth.nav`` and a config.

``imu.txt``: ``sow dtheta_x dtheta_y dtheta_z dvel_x dvel_y dvel_z`` (rad, m/s) in the FRD body
frame, one row per interval, stamped at the interval's END (KF-GINS' convention). KF-GINS
applies its own two-sample coning/sculling correction, so it expects RAW increments (plain
integrals): simulate with ``simulate.increments: raw``; compensated increments are exported
with a warning (their coning/sculling would be counted twice, an error of the order of the
correction itself). ``truth.nav``: ``week sow lat lon h vN vE vD roll pitch heading`` (deg,
m, m/s; NED at the vehicle, FRD body). ``kf-gins.yaml``: KF-GINS' configuration with the true
initial state and this sequence's noise figures (``imunoise``: arw, vrw, gbstd, abstd, gsstd,
asstd, corrtime). With the GNSS epochs of ``imugen aid``: ``gnss.pos`` (``sow lat lon h
sigma_lat sigma_lon sigma_h``, epochs with a fix) and the antenna lever arm in the config.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from imugen import rotations as rot
from imugen.errors import InputError
from imugen.formats.common import write_rows
from imugen.formats.convert import dcm_ned_frd, enu_to_ned, euler_ned_frd, flu_to_frd
from imugen.formats.source import INCREMENT_COLUMNS, Sequence, TruthArrays
from imugen.tables import truth as ttruth

DEG = 180.0 / math.pi


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


def write(seq: Sequence, truth: TruthArrays, folder: Path, warn=print, **_) -> list[Path]:
    if not seq.has(INCREMENT_COLUMNS):
        raise InputError(
            "--format kfgins", "needs increment columns (simulate.outputs increments or both)"
        )
    kind = seq.meta.get("increments", "compensated")
    if kind != "raw":
        warn(
            f"sequence {seq.id}: KF-GINS applies its own coning/sculling to raw increments; these "
            "are compensated increments (simulate.increments: raw avoids counting it twice)"
        )
    folder.mkdir(parents=True, exist_ok=True)
    inc = seq.stack(INCREMENT_COLUMNS)[1:]
    rows = np.column_stack([truth.time_s[1:], flu_to_frd(inc[:, :3]), flu_to_frd(inc[:, 3:])])
    with open(folder / "imu.txt", "w") as fh:
        write_rows(fh, rows, "%.6f" + " %.12e" * 6)
    nav = nav_rows(truth)
    with open(folder / "truth.nav", "w") as fh:
        write_rows(fh, nav, "%d %.6f %.11f %.11f %.4f %.6f %.6f %.6f %.8f %.8f %.8f")
    files = [folder / "imu.txt", folder / "truth.nav", folder / "kf-gins.yaml"]
    antlever = [0.0, 0.0, 0.0]
    if seq.gnss is not None:
        files.append(write_gnss_pos(seq.gnss, truth, folder / "gnss.pos"))
        gl = seq.gnss.attrs.get("labels", {})
        arm = [float(gl.get(f"gnss_lever_arm_{a}_m", 0.0)) for a in "xyz"]
        antlever = [float(x) for x in flu_to_frd(np.asarray(arm))]
    lab = seq.labels

    def axes(stem, scale):
        return [float(lab.get(stem.format(a=a), 0.0)) * scale for a in "xyz"]

    wn = np.mean(axes("gyro_white_noise_{a}_rad_per_sqrt_s", DEG * 60.0))
    vn = np.mean(axes("accel_white_noise_{a}_m_per_s_per_sqrt_s", 60.0))

    def bias_std(sensor, scale):
        # the bias the filter must absorb: in-run GM sigma and this draw's turn-on bias (RSS)
        unit = "radps" if sensor == "gyro" else "mps2"
        gm = np.asarray(axes(f"{sensor}_bias_instability_sigma0_{{a}}_{unit}", scale))
        on = np.asarray(axes(f"{sensor}_turn_on_bias_{{a}}_{unit}", scale))
        return float(np.sqrt(np.mean(gm**2 + on**2)))

    gb = bias_std("gyro", DEG * 3600.0)
    ab = bias_std("accel", 1e5)
    tau = [float(lab.get(f"{s}_bias_instability_tau0_s", 3600.0)) for s in ("gyro", "accel")]
    cfg = {
        "imupath": "imu.txt",
        "gnsspath": "gnss.pos" if seq.gnss is not None else "",
        "outputpath": ".",
        "imudatalen": 7,
        "imudatarate": float(round(1.0 / truth.dt, 9)),
        "starttime": float(nav[0, 1]),
        "endtime": -1,
        "initpos": [float(x) for x in nav[0, 2:5]],
        "initvel": [float(x) for x in nav[0, 5:8]],
        "initatt": [float(x) for x in nav[0, 8:11]],
        "initgyrbias": [0.0, 0.0, 0.0],
        "initaccbias": [0.0, 0.0, 0.0],
        "initgyrscale": [0.0, 0.0, 0.0],
        "initaccscale": [0.0, 0.0, 0.0],
        "imunoise": {
            "arw": float(wn),
            "vrw": float(vn),
            "gbstd": float(gb),
            "abstd": float(ab),
            "gsstd": float(np.mean(np.abs(axes("gyro_scale_factor_{a}", 1e6)))),
            "asstd": float(np.mean(np.abs(axes("accel_scale_factor_{a}", 1e6)))),
            "corrtime": float(np.mean(tau) / 3600.0),
        },
        "antlever": antlever,
    }
    head = (
        f"# KF-GINS configuration for imugen sequence {seq.id} (true initial state; "
        "imunoise from this sequence's drawn parameters; initial biases and scales 0: the filter "
        "estimates them, their true values are in the labels)\n"
    )
    (folder / "kf-gins.yaml").write_text(head + yaml.safe_dump(cfg, sort_keys=False))
    return files


def write_gnss_pos(gnss, truth: TruthArrays, path: Path, sow0: float = 0.0) -> Path:
    """KF-GINS ``gnss.pos``: ``sow lat lon h sigma_lat sigma_lon sigma_h`` (deg, deg, m, m, m, m)
    of the epochs with a fix, antenna position as the receiver reports it (errors, attacks)."""
    from imugen.tables import gnss as tgnss

    ok = (gnss[tgnss.FIX].to_numpy() > 0) & np.isfinite(gnss[tgnss.P[0]].to_numpy())
    g = gnss[ok]
    lat, lon, h = _frame(truth).geodetic_from_n(g[list(tgnss.P)].to_numpy())
    sd = g[list(tgnss.SIGMA_P)].to_numpy()
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
        write_rows(fh, rows, "%.6f %.11f %.11f %.4f %.4f %.4f %.4f")
    return path
