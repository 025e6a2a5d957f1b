"""Aided-filter consistency: Monte-Carlo NEES per grade, every configured error term on.

Scene: a car once round a 400 m x 200 m rectangle (imugen truth, flat Earth, 100 Hz, about
120 s, four 90-degree turns), IMU of each grade (nominal draw, every configured term:
turn-on bias, bias instability, white noise, rate random walk, scale factor, cross-coupling,
g-sensitivity, quantization, range), standalone GNSS at 10 Hz (nominal draw, Gauss-Markov
bias modelled by the filter's bias states with the drawn figures) with a 0.6/0.3/1.2 m lever
arm and a 30 s outage from t = 60 s. The filter starts at t = 5 s from an initial error drawn
from its own P0 (no alignment), tuning ``Tuning.from_grade(grade, "nominal")``, default
options (gyro cross-coupling states on unless ``--no-cross-coupling``).

Reported per grade: mean NEES per degree of freedom over the sequences and the epochs after
t = 15 s (position 3, attitude 3, gyro + accelerometer biases 6, the bias truth being the
labelled slow bias plus the static error on gravity ``(G + E) (0, 0, g0)`` the filter
estimates with it), the fraction of epochs whose Monte-Carlo mean is outside the two-sided
99 % chi-square bounds, and the horizontal RMSE with GNSS and at the end of the outage.

Usage::

    python benchmarks/bench_aided_nees.py [--sequences 40] [--grades consumer industrial tactical]
        [--no-cross-coupling] [--draw ranges] [--level law] [--nhc] [--zupt] [--former]

Run it with ``PYTHONPATH`` on another source tree to compare versions of the filter.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.stats import chi2  # noqa: E402

from imugen import truth as T  # noqa: E402
from imugen.aid import filter as A  # noqa: E402
from imugen.aid import gnss as G  # noqa: E402
from imugen.core import units  # noqa: E402
from imugen.core.earth import OriginFrame  # noqa: E402
from imugen.core.rotations import dcm_to_quat, exp_dcm, quat_to_dcm  # noqa: E402
from imugen.simulate import stage as SIM  # noqa: E402

ORIGIN = (45.0, 7.0, 200.0)
LEVER = (0.6, 0.3, 1.2)
OUTAGE_S = (60.0, 90.0)
K0 = 500


def scene():
    """Truth frame of one lap of the rectangle (flat, 100 Hz)."""
    pts = np.array([[0, 0, 0], [400, 0, 0], [400, 200, 0], [0, 200, 0], [0, 0, 0]], float)
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": dict(zip(("lat_deg", "lon_deg", "alt_m"), ORIGIN, strict=True))}
    meta["timed"] = False
    df, _ = T.build_truth(enu, meta, rate_hz=100.0, earth="flat", vehicle="car", verbose=False)
    return df


def nees(e, P):
    """(..., d) errors and (..., d, d) covariances -> (...) NEES."""
    return np.einsum("...i,...i->...", e, np.linalg.solve(P, e[..., None])[..., 0])


def run_grade(
    df, grade: str, M: int, seed: int = 11, opts: A.Options | None = None, model_terms=None,
    draw: str = "nominal", level: str = "nominal",
) -> dict:  # fmt: skip
    """Monte-Carlo run of one grade: NEES per dof (pos, vel, att, bias; with ZUPT also at the
    ZUPT epochs), bound misses, RMSE.

    ``model_terms``: the terms the filter's tuning models (default all; the IMU always has
    every configured term). ``draw``: the IMU's and the receiver's figures ``"nominal"`` (the
    filter's GNSS bias model then is the drawn figures, an oracle) or drawn in their
    ``"ranges"`` (the filter then knows only the law: ``level="law"``)."""
    t = df["time_s"].to_numpy()
    p = df[["e_m", "n_m", "u_m"]].to_numpy()
    v = df[["v_e_mps", "v_n_mps", "v_u_mps"]].to_numpy()
    q = df[["q_w", "q_x", "q_y", "q_z"]].to_numpy()
    w = df[["gyro_x_radps", "gyro_y_radps", "gyro_z_radps"]].to_numpy()
    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    sh = SIM.simulate(df, grade, sequences=M, seed=seed, draw=draw, series=True)
    gn = G.simulate_gnss(
        t, p, v, q, w, "standalone", sequences=M, seed=seed, draw=draw, lever_arm_b_m=LEVER
    )
    fix = gn.fix.copy()
    tt = np.asarray(gn.time_s)
    fix[:, (tt >= OUTAGE_S[0]) & (tt < OUTAGE_S[1])] = 0
    gn = replace(gn, fix=fix)
    tun = A.Tuning.from_grade(grade, level, terms=model_terms)
    opts = opts or A.Options()
    if draw == "nominal":
        Tm = A.tuning_matrix(tun, M, gnss_params=gn.params)
    else:
        gl = "law" if level == "law" else "nominal"
        Tm = A.tuning_matrix(tun, M, gnss_receiver=gn.receiver, gnss_level=gl)
    gb = Tm[:, A.T_GB_SD : A.T_GB_SD + 3]
    sd_p = np.sqrt(gb**2 + Tm[:, A.T_GW : A.T_GW + 3] ** 2)
    P0 = A.initial_covariance(tun, opts, sd_p, 0.05, [0.01, 0.01, 0.02], gb)
    rng = np.random.default_rng(5)
    n = opts.n
    e0 = np.stack([rng.multivariate_normal(np.zeros(n), P0[s])[:9] for s in range(M)])
    C = exp_dcm(e0[:, 6:9]) @ quat_to_dcm(q[K0])
    init = A.initial_state(K0, p[K0] + e0[:, 0:3], v[K0] + e0[:, 3:6], dcm_to_quat(C), P0)
    res = A.run(
        sh.data["dtheta"], sh.data["dv"], 0.01, frame, gn, tun, opts, init, tuning_T=Tm,
        store_P=True,
    )  # fmt: skip
    idx = res.index
    js = np.flatnonzero(res.time_s >= 15.0)
    ep = res.p_n[:, js] - p[idx[js]]
    ev = res.v_n[:, js] - v[idx[js]]
    ea = A.attitude_error(res.q_nb[:, js], q[idx[js]])
    g0 = units.G0
    E_a = np.einsum("si,ij->sij", sh.accel.sf, np.eye(3))
    if not opts.accel_cross_coupling:  # else its states carry the error on gravity g0 cc[:, 2]
        E_a = E_a + sh.accel.cc
    bg = sh.data["gyro_bias"][:, idx[js]] + g0 * sh.gyro.gs[:, None, :, 2]
    ba = sh.data["accel_bias"][:, idx[js]] + g0 * E_a[:, None, :, 2]
    eb = np.concatenate([res.gyro_bias[:, js] - bg, res.accel_bias[:, js] - ba], -1)
    P = res.P[:, js]
    out = {"grade": grade}
    for name, e, sl, d in (
        ("pos", ep, slice(0, 3), 3),
        ("vel", ev, slice(3, 6), 3),
        ("att", ea, slice(6, 9), 3),
        ("bias", eb, slice(9, 15), 6),
    ):
        eps = nees(e, P[..., sl, sl]).mean(axis=0)  # mean over runs, per epoch
        lo, hi = chi2.ppf([0.005, 0.995], d * M) / M
        out[f"nees_{name}"] = float(eps.mean() / d)
        out[f"out_{name}"] = float(np.mean((eps < lo) | (eps > hi)))
    zu = (res.flags[:, js] & A.F_ZUPT) != 0
    if zu.any():  # velocity NEES/dof at the ZUPT epochs: mean and 95th percentile
        nz = nees(ev, P[..., 3:6, 3:6])[zu] / 3
        out["zupt_epochs"] = int(zu.sum())
        out["nees_vel_zupt"] = float(nz.mean())
        out["nees_vel_zupt_p95"] = float(np.percentile(nz, 95))
    tj = res.time_s[js]
    with_fix = (tj < OUTAGE_S[0]) | (tj >= OUTAGE_S[1] + 5.0)
    hz = np.hypot(ep[..., 0], ep[..., 1])
    out["rmse_h_m"] = float(np.sqrt(np.mean(hz[:, with_fix] ** 2)))
    je = np.searchsorted(tj, OUTAGE_S[1]) - 1
    out["outage_end_h_m"] = float(np.median(hz[:, je]))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequences", type=int, default=40)
    ap.add_argument("--grades", nargs="+", default=["consumer", "industrial", "tactical"])
    ap.add_argument(
        "--no-cross-coupling", action="store_true", help="no gyro/accelerometer cc states"
    )
    ap.add_argument("--draw", default="nominal", choices=["nominal", "ranges"])
    ap.add_argument("--level", default="nominal", choices=list(A.LEVELS))
    ap.add_argument("--nhc", action="store_true", help="non-holonomic constraint (slip 0.01)")
    ap.add_argument("--zupt", action="store_true", help="zero-velocity updates")
    ap.add_argument(
        "--former", action="store_true", help="the rules before issue 26 (aided_digest.FORMER)"
    )
    a = ap.parse_args(argv)
    df = scene()
    cc = not a.no_cross_coupling
    kw = {"gyro_cross_coupling": cc, "accel_cross_coupling": cc}
    if a.former:
        from aided_digest import FORMER

        kw |= FORMER
    opts = A.Options(**kw, nhc=a.nhc, zupt=a.zupt, nhc_sd_mps=(0.01, 0.01))
    rows = [run_grade(df, g, a.sequences, opts=opts, draw=a.draw, level=a.level) for g in a.grades]
    print(pd.DataFrame(rows).round(3).to_string(index=False))


if __name__ == "__main__":
    main()
