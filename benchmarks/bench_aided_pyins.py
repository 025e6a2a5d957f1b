"""Side by side: imugen's aided filter and pyins' feedback EKF on the same data.

Scene: the car on a 400 m x 200 m rectangle (imugen truth, ``wgs84``, 100 Hz, about 178 s),
industrial IMU (every configured term, levels in the grade's ranges), standalone GNSS at 10 Hz
(receiver figures drawn in their ranges, 0.6/0.3/1.2 m lever arm), a 30 s outage from t = 100 s.
Both filters get the same increments and the same fixes, start at the same epoch (t = 20 s,
the truth perturbed by the same errors) and use the same IMU noise model (the grade's upper
levels). Converted for pyins: ENU/FLU -> NED/FRD (increments, lever arm), positions to
latitude/longitude/height, velocities to the local NED frame; pyins' position sigma is the
receiver's reported one (it has no GNSS-bias state), its velocity sigma the horizontal one.

Reported per filter: RMS horizontal position error while GNSS is on (from 30 s after the start,
outside the outage and the 5 s after it), median horizontal error at the end of the outage,
and the time per sequence.

pyins (PyPI ``python-ins``, MIT) runs in the interpreter given by ``--pyins-python`` (a separate
virtualenv: it pins its own pandas/numba versions).

Usage::

    python benchmarks/bench_aided_pyins.py --pyins-python /path/to/venv/bin/python [--sequences 8]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
import textwrap  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from imugen import truth as T  # noqa: E402
from imugen.aid import filter as A  # noqa: E402
from imugen.aid import gnss as G  # noqa: E402
from imugen.aid import scenarios as SC  # noqa: E402
from imugen.core.earth import OriginFrame, earth_rate_n  # noqa: E402
from imugen.core.rotations import dcm_to_quat, exp_dcm, quat_to_dcm  # noqa: E402
from imugen.simulate import stage as SIM  # noqa: E402

ORIGIN = (45.0, 7.0, 200.0)
T_START, T_OUT, OUTAGE = 20.0, 100.0, 30.0
D = np.diag([1.0, -1.0, -1.0])  # FLU <-> FRD
M_EN = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # ENU -> NED

PYINS_CODE = textwrap.dedent(
    """
    import sys, time, numpy as np, pandas as pd
    from pyins import filters, measurements, inertial_sensor
    d = np.load(sys.argv[1])
    out = {}
    M = d["inc"].shape[0]
    gm = inertial_sensor.EstimationModel(bias_sd=d["gb_sd"], noise=d["g_white"],
                                         bias_walk=d["g_walk"])
    am = inertial_sensor.EstimationModel(bias_sd=d["ab_sd"], noise=d["a_white"],
                                         bias_walk=d["a_walk"])
    cols = ["lat", "lon", "alt", "VN", "VE", "VD", "roll", "pitch", "heading"]
    res_p, res_h, times = [], [], []
    for s in range(M):
        inc = pd.DataFrame(d["inc"][s], index=d["inc_t"],
                           columns=["dt", "theta_x", "theta_y", "theta_z", "dv_x", "dv_y", "dv_z"])
        ok = d["ok"][s]
        pos = pd.DataFrame(d["lla"][s][ok], index=d["gt"][ok], columns=["lat", "lon", "alt"])
        vel = pd.DataFrame(d["vned"][s][ok], index=d["gt"][ok], columns=["VN", "VE", "VD"])
        meas = [measurements.Position(pos, float(d["pos_sd"][s]), d["lever"][s]),
                measurements.NedVelocity(vel, float(d["vel_sd"][s]), d["lever"][s])]
        pva = pd.Series(d["pva0"][s], index=cols, name=float(d["t0"]))
        t0 = time.perf_counter()
        r = filters.run_feedback_filter(pva, float(d["p0_sd"]), float(d["v0_sd"]),
                                        float(d["level_sd"]), float(d["az_sd"]), inc,
                                        gm, am, meas, time_step=0.1)
        times.append(time.perf_counter() - t0)
        tr = r.trajectory.reindex(d["gt"], method="nearest")
        res_p.append(tr[["lat", "lon", "alt"]].to_numpy())
        res_h.append(tr["heading"].to_numpy())
    np.savez(sys.argv[2], lla=np.array(res_p), heading=np.array(res_h), times=np.array(times))
    """
)


def scene(M: int):
    pts = np.array(
        [[0, 0, 0], [400, 0, 0], [400, 200, 0], [0, 200, 0], [0, 0, 0], [400, 0, 0], [400, 200, 0]],
        float,
    )
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": dict(zip(("lat_deg", "lon_deg", "alt_m"), ORIGIN, strict=True))}
    df, _ = T.build_truth(enu, meta, rate_hz=100.0, earth="wgs84", vehicle="car", verbose=False)
    frame = OriginFrame.from_deg(*ORIGIN, model="wgs84")
    t = df["time_s"].to_numpy()
    p = df[["e_m", "n_m", "u_m"]].to_numpy()
    v = df[["v_e_mps", "v_n_mps", "v_u_mps"]].to_numpy()
    q = df[["q_w", "q_x", "q_y", "q_z"]].to_numpy()
    w = df[["gyro_x_radps", "gyro_y_radps", "gyro_z_radps"]].to_numpy()
    sh = SIM.simulate(df, "industrial", sequences=M, seed=9)
    gn = G.simulate_gnss(
        t, p, v, q, w, "standalone", M, seed=9, lever_arm_b_m=(0.6, 0.3, 1.2),
        omega_ie_n=earth_rate_n(frame),
    )  # fmt: skip
    gn = SC.apply(gn, [{"kind": "outage", "start_s": T_OUT, "duration_s": OUTAGE}]).gnss
    return frame, t, p, v, q, sh, gn


def local(frame, p_n, vec_n):
    """n-frame vectors at positions p_n -> local NED at the point."""
    C = frame.C_ln(p_n)
    return np.einsum("ij,...jk,...k->...i", M_EN, C, vec_n)


def to_lla_deg(frame, p_n):
    lat, lon, h = frame.geodetic_from_n(p_n)
    return np.stack([np.degrees(lat), np.degrees(lon), h], -1)


def horizontal_error_m(frame, lla_deg, p_true_n):
    est = frame.n_from_geodetic(
        np.radians(lla_deg[..., 0]), np.radians(lla_deg[..., 1]), lla_deg[..., 2]
    )
    d = local(frame, p_true_n, est - p_true_n)
    return np.hypot(d[..., 0], d[..., 1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pyins-python", required=True)
    ap.add_argument("--sequences", type=int, default=8)
    ap.add_argument("--json")
    a = ap.parse_args()
    M = a.sequences
    frame, t, p, v, q, sh, gn = scene(M)
    dt = t[1] - t[0]
    tun = A.Tuning.from_grade("industrial", level="upper")
    k0 = round(T_START / dt)
    rng = np.random.default_rng(3)
    sd_p, sd_v, sd_lvl, sd_az = 2.0, 0.1, np.radians(0.5), np.radians(1.0)
    e_p = sd_p * rng.standard_normal((M, 3))
    e_v = sd_v * rng.standard_normal((M, 3))
    e_a = np.stack([sd_lvl * rng.standard_normal(M), sd_lvl * rng.standard_normal(M),
                    sd_az * rng.standard_normal(M)], -1)  # fmt: skip
    C0 = exp_dcm(e_a) @ quat_to_dcm(q[k0])  # the same start attitude for both filters
    p0, v0 = p[k0] + e_p, v[k0] + e_v
    opts = A.Options(gnss_bias=False)
    P0 = A.initial_covariance(tun, opts, sd_p, sd_v, [sd_lvl, sd_lvl, sd_az])
    init = A.initial_state(k0, p0, v0, dcm_to_quat(C0), np.repeat(P0, M, 0))
    t1 = time.perf_counter()
    res = A.run(sh.data["dtheta"], sh.data["dv"], dt, frame, gn, tun, opts, init)
    t_imugen = (time.perf_counter() - t1) / M
    idx = res.index
    ok_t = (res.time_s >= T_START + 30.0) & (
        (res.time_s < T_OUT) | (res.time_s >= T_OUT + OUTAGE + 5)
    )
    j_end = int(np.searchsorted(res.time_s, T_OUT + OUTAGE - 1e-9)) - 1
    e_imu = np.hypot(*(local(frame, p[idx], res.p_n - p[idx])[..., :2].transpose(2, 0, 1)))

    # pyins inputs
    gt = gn.time_s
    lla = to_lla_deg(frame, np.nan_to_num(gn.p_n))
    vned = local(frame, p[gn.index], np.nan_to_num(gn.v_n))
    inc = np.concatenate(
        [np.full((M, len(t) - 1, 1), dt), sh.data["dtheta"][:, 1:] @ D, sh.data["dv"][:, 1:] @ D],
        -1,
    )
    Cl = np.einsum("ij,jk,skl,lm->sim", M_EN, frame.C_ln(p0[0]), C0, D)
    rph0 = np.degrees(np.stack([np.arctan2(Cl[:, 2, 1], Cl[:, 2, 2]),
                                -np.arcsin(np.clip(Cl[:, 2, 0], -1, 1)),
                                np.arctan2(Cl[:, 1, 0], Cl[:, 0, 0])], -1))  # fmt: skip
    pva0 = np.concatenate([to_lla_deg(frame, p0), local(frame, p0, v0), rph0], -1)
    data = dict(
        inc=inc[:, k0:], inc_t=t[k0 + 1 :], ok=gn.valid & ((gt > T_START) & (gt < t[-1]))[None], lla=lla,
        vned=vned, gt=gt,
        lever=np.asarray(gn.params.lever_arm_b_m) @ D, pos_sd=gn.sigma_p_n[:, 1, 0],
        vel_sd=gn.sigma_v_n[:, 1, 0], pva0=pva0, t0=t[k0], p0_sd=sd_p, v0_sd=sd_v,
        level_sd=np.degrees(sd_lvl), az_sd=np.degrees(sd_az), gb_sd=tun.gyro_bias_sd,
        g_white=tun.gyro_white, g_walk=np.sqrt(tun.gyro_bias_q), ab_sd=tun.accel_bias_sd,
        a_white=tun.accel_white, a_walk=np.sqrt(tun.accel_bias_q),
    )  # fmt: skip
    out = {"sequences": M, "imugen_s_per_sequence": round(t_imugen, 4)}
    out["imugen_rms_h_m"] = float(np.sqrt(np.mean(e_imu[:, ok_t] ** 2)))
    out["imugen_end_of_outage_median_m"] = float(np.median(e_imu[:, j_end]))
    with tempfile.TemporaryDirectory() as tmp:
        fin, fout = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(fin, **data)
        r = subprocess.run([a.pyins_python, "-c", PYINS_CODE, str(fin), str(fout)],
                           capture_output=True, text=True)  # fmt: skip
        if r.returncode != 0:
            print("pyins failed:", r.stderr[-2000:])
        else:
            py = np.load(fout)
            e_py = horizontal_error_m(frame, py["lla"], p[gn.index])
            out["pyins_s_per_sequence"] = round(float(np.mean(py["times"])), 3)
            out["pyins_rms_h_m"] = float(np.sqrt(np.mean(e_py[:, ok_t] ** 2)))
            out["pyins_end_of_outage_median_m"] = float(np.median(e_py[:, j_end]))
    for k, val in out.items():
        print(f"{k:35s} {val}")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
