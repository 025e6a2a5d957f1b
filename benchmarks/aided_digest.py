"""Fingerprint of the aided filter's outputs over every code path (a refactoring check).

Runs the filter (:mod:`imugen.aid.filter`) on small car scenes in ``flat``, ``wgs84`` and
``geodetic`` and on a still navigation-grade IMU (static gyrocompass alignment), with option
sets that reach every state block and every measurement (GNSS position / velocity with and
without bias states, latency and gate, NHC with mounting and lever-arm states, ZUPT, odometer
with and without its scale-factor state, barometer, scale factors, cross-coupling, an outage,
the stored covariance), and prints one SHA-256 per case over the bytes of every output array,
plus the flag counts (so a case that reaches nothing shows). Run it on two commits and diff
the outputs: equal digests mean bit-identical outputs. ``--save DIR`` also writes each case's
arrays (``DIR/<case>.npz``) and ``--compare DIR`` prints the largest relative difference per
array against such a folder.

``--former`` runs every case with the options that give the rules before issue 26 (no
accelerometer cross-coupling states, no NHC gate or speed rule, the former ZUPT rules) and
leaves out the arrays added since (``accel_cc``): its digests then equal those of a commit
before issue 26 when the former code paths are bit-identical.

Usage::

    python benchmarks/aided_digest.py [--save DIR | --compare DIR] [--sequences 3] [--former]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import hashlib  # noqa: E402
from dataclasses import fields  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from imugen import truth as TR  # noqa: E402
from imugen.aid import companions as CP  # noqa: E402
from imugen.aid import filter as A  # noqa: E402
from imugen.aid import gnss as G  # noqa: E402
from imugen.aid import scenarios as SC  # noqa: E402
from imugen.core import earth as E  # noqa: E402
from imugen.core import rotations as R  # noqa: E402
from imugen.simulate import stage as SIM  # noqa: E402
from imugen.simulate.sources import DEFAULT_STATIC_ORIGIN  # noqa: E402

if not hasattr(A, "run"):  # before the filter became a package (issue 23): one module
    from imugen.aid.filter import ekf as A

ORIGIN = (45.0, 7.0, 200.0)
LEVER = (0.6, 0.3, 1.2)
RECT = [[0, 0, 0], [400, 0, 0], [400, 200, 0], [0, 200, 0], [0, 0, 0], [400, 0, 0], [400, 200, 0]]
POS, VEL, QUAT = (
    ("e_m", "n_m", "u_m"),
    ("v_e_mps", "v_n_mps", "v_u_mps"),
    ("q_w", "q_x", "q_y", "q_z"),
)


FORMER = {
    "accel_cross_coupling": False, "nhc_gate_sigma": 0.0, "nhc_speed_ratio": 0.0,
    "zupt_min_still_s": 0.0, "zupt_speed_conf": 0.0, "zupt_crawl_mps": 0.0,
}  # fmt: skip
"""Options giving the filter's rules before issue 26 (``--former``)."""
NEW_ARRAYS = ("accel_cc",)
"""Output arrays added by issue 26 (left out with ``--former``)."""
_former = False


def _options(**kw):
    """``A.Options(**kw)``, with :data:`FORMER` under ``--former``."""
    return A.Options(**({**FORMER, **kw} if _former else kw))


def car(earth):
    enu = pd.DataFrame(np.array(RECT, float), columns=list(POS))
    meta = {
        "origin": dict(zip(("lat_deg", "lon_deg", "alt_m"), ORIGIN, strict=True)),
        "timed": False,
    }
    df, _ = TR.build_truth(enu, meta, rate_hz=100.0, earth=earth, vehicle="car", verbose=False)
    return df


def as_geodetic(df, frame):
    """The wgs84 truth re-expressed in ECEF (``geodetic`` columns)."""
    out = df.copy()
    q_ne = R.dcm_to_quat(frame.C_en.T[None])[0]
    q = df[list(QUAT)].to_numpy()
    for cols, x in (
        (POS, frame.ecef_from_n(df[list(POS)].to_numpy())),
        (VEL, df[list(VEL)].to_numpy() @ frame.C_en),
        (QUAT, R.quat_mul(np.broadcast_to(q_ne, q.shape), q)),
    ):
        for i, c in enumerate(cols):
            out[c] = x[:, i]
    return out, frame.with_model("geodetic")


def arrays(df):
    return (
        df["time_s"].to_numpy(),
        df[list(POS)].to_numpy(),
        df[list(VEL)].to_numpy(),
        df[list(QUAT)].to_numpy(),
        df[["gyro_x_radps", "gyro_y_radps", "gyro_z_radps"]].to_numpy(),
    )


def car_scene(df, frame, S, grade="consumer"):
    t, p, v, q, w = arrays(df)
    sh = SIM.simulate(df, grade, sequences=S, seed=3, draw="ranges")
    gn = G.simulate_gnss(t, p, v, q, w, "standalone", sequences=S, seed=3, lever_arm_b_m=LEVER,
                         omega_ie_n=E.earth_rate_n(frame), frame=frame)  # fmt: skip
    baro = CP.simulate_barometer(t, p, frame, "bmp388", S, 3, 0)
    w_eb = w - np.einsum("kji,j->ki", R.quat_to_dcm(q), E.earth_rate_n(frame))
    odo = CP.simulate_odometer(t, v, q, w_eb, "abs", S, 3, 0)
    ce = CP.filter_input(gn.index, S, odo, baro, h0_m=frame.h0_m, lever_arm_b_m=(-1.2, 0.4, -0.3))
    return sh.data["dtheta"], sh.data["dv"], gn, ce, (p, v, q)


def cases(S):
    flat = E.OriginFrame.from_deg(*ORIGIN, model="flat")
    wgs = E.OriginFrame.from_deg(*ORIGIN, model="wgs84")
    dfw = car("wgs84")
    dfg, geo = as_geodetic(dfw, wgs)
    scenes = {
        "flat": (car_scene(car("flat"), flat, S), flat),
        "wgs84": (car_scene(dfw, wgs, S), wgs),
        "geodetic": (car_scene(dfg, geo, S), geo),
    }
    mount = dict(nhc_misalignment_sd_rad=(0.02, 0.03), nhc_lever_arm_sd_m=(0.2, 0.1, 0.2),
                 nhc_lever_arm_m=(1.0, 0.1, -0.3))  # fmt: skip
    full = _options(nhc=True, zupt=True, odometer=True, baro=True, **mount)
    variants = {
        "plain": (_options(gnss_bias=False, gyro_cross_coupling=False), {}),
        "default": (_options(), {}),
        "sf_nhc_zupt_gate": (
            _options(
                scale_factors=True, nhc=True, zupt=True, gate_sigma=4.0, nhc_sd_mps=(0.01, 0.02)
            ),
            {},
        ),
        "full_P": (full, {"store_P": True}),
        "odo_nosf_novel": (
            _options(
                odometer=True,
                odo_scale_state=False,
                baro=True,
                use_velocity=False,
                latency=False,
                zupt=True,
            ),
            {},
        ),
        "sf_nocc_mount_odo": (
            _options(
                scale_factors=True, gyro_cross_coupling=False, nhc=True, odometer=True, **mount
            ),
            {},
        ),
        "outage_full": (full, {"outage": True}),
    }
    for scene, ((dth, dvb, gn, ce, _), frame) in scenes.items():
        for name, (opts, kw) in variants.items():
            if scene != "flat" and name not in ("default", "full_P", "sf_nhc_zupt_gate"):
                continue
            yield f"{scene}-{name}", dth, dvb, frame, gn, ce, opts, kw
    # explicit start (initial_state) with a fixed tuning matrix from the drawn receiver
    (dth, dvb, gn, ce, (p, v, q)), frame = scenes["flat"]
    yield "flat-explicit_init", dth, dvb, frame, gn, ce, full, {"explicit": (p, v, q)}
    # a still navigation-grade IMU: static gyrocompass alignment, ZUPT
    M, Ts = S, 30.0
    wgs = E.OriginFrame.from_deg(*DEFAULT_STATIC_ORIGIN, model="wgs84")
    sh = SIM.simulate(None, "navigation", M, seed=6, draw="nominal", static_s=Ts + 20.0,
                      static_earth="wgs84")  # fmt: skip
    K = sh.data["dtheta"].shape[1]
    t = np.arange(K) * 0.01
    C_nb = np.eye(3)
    q = np.broadcast_to(R.dcm_to_quat(C_nb[None])[0], (K, 4)).copy()
    pz, vz = np.zeros((K, 3)), np.zeros((K, 3))
    w = np.broadcast_to(E.earth_rate_n(wgs), (K, 3)).copy()
    gs = G.simulate_gnss(t, pz, vz, q, w, "standalone", M, seed=6, draw="nominal",
                         omega_ie_n=E.earth_rate_n(wgs), frame=wgs)  # fmt: skip
    opts = _options(zupt=True)
    yield (
        "wgs84-static",
        sh.data["dtheta"],
        sh.data["dv"],
        wgs,
        gs,
        None,
        opts,
        {"grade": "navigation", "static_s": Ts},
    )


def run_case(dth, dvb, frame, gn, ce, opts, kw):
    tun = A.Tuning.from_grade(kw.get("grade", "consumer"))
    if kw.get("outage"):
        iv = [{"kind": "outage", "start_s": 80.0, "duration_s": 30.0}]
        gn = SC.apply(gn, iv, 2, frame=frame).gnss
    init = None
    T = None
    if "explicit" in kw:
        p, v, q = kw["explicit"]
        S = dth.shape[0]
        T = A.tuning_matrix(tun, S, gnss_params=gn.params)
        sd = [np.broadcast_to(x, (S, 3)) for x in ([0.5, 0.5, 0.8], 0.05, [0.01, 0.01, 0.02])]
        P0 = A.initial_covariance(tun, opts, *sd, T[:, A.T_GB_SD : A.T_GB_SD + 3],
                                  ce.odo_sf_sd, ce.baro_sd_m)  # fmt: skip
        init = A.initial_state(300, p[300], v[300], q[300], P0)
    if "static_s" in kw:
        init = A.align(dth, dvb, 0.01, gn, tun, opts, frame, static_s=kw["static_s"])
    res = A.run(dth, dvb, 0.01, frame, gn, tun, opts, init, tuning_T=T,
                store_P=kw.get("store_P", False), companions=ce)  # fmt: skip
    out = {}
    for f in fields(res):
        val = getattr(res, f.name)
        if _former and f.name in NEW_ARRAYS:
            continue
        if isinstance(val, np.ndarray):
            out[f.name] = np.ascontiguousarray(val)
    if init is None and "static_s" not in kw:
        ia = A.align(dth, dvb, 0.01, gn, tun, opts, frame,
                     tuning_T=A.companion_tuning(A.tuning_matrix(tun, dth.shape[0],
                                                                 gnss_receiver=gn.receiver), ce)
                     if ce is not None else None)  # fmt: skip
        # the alignment sets position, velocity and attitude (the first 10 nominal slots)
        assert not ia.x0[:, 10:].any()
        out["align_k0"], out["align_x0"], out["align_P0"] = ia.k0, ia.x0[:, :10].copy(), ia.P0
    out["names"] = np.array(res.names)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=3)
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--save")
    g.add_argument("--compare")
    ap.add_argument("--former", action="store_true", help="the rules before issue 26")
    a = ap.parse_args()
    global _former
    _former = a.former
    bits = {"gnss_p": 1, "gnss_v": 2, "zupt": 4, "nhc": 8, "reject": 16, "odo": 64, "baro": 128}
    for name, dth, dvb, frame, gn, ce, opts, kw in cases(a.sequences):
        out = run_case(dth, dvb, frame, gn, ce, opts, kw)
        h = hashlib.sha256()
        for k in sorted(out):
            h.update(k.encode())
            h.update(out[k].tobytes())
        fl = out["flags"]
        counts = " ".join(f"{b}={int(((fl & v) != 0).sum())}" for b, v in bits.items())
        print(f"{name:28s} {h.hexdigest()[:24]}  {counts}", flush=True)
        if a.save:
            Path(a.save).mkdir(parents=True, exist_ok=True)
            np.savez(Path(a.save) / f"{name}.npz", **out)
        if a.compare:
            ref = np.load(Path(a.compare) / f"{name}.npz")
            for k in sorted(out):
                if k not in ref.files:
                    print(f"    {k:14s} new")
                    continue
                if out[k].dtype.kind in "US":
                    same = np.array_equal(out[k], ref[k])
                    print(f"    {k:14s} {'equal' if same else 'DIFFERENT'}")
                    continue
                x, y = out[k].astype(float), ref[k].astype(float)
                if x.shape != y.shape:
                    print(f"    {k:14s} shape {x.shape} vs {y.shape}")
                    continue
                same = np.array_equal(x, y, equal_nan=True)
                d = np.abs(x - y)
                d = d[np.isfinite(d)]
                scale = np.nanmax(np.abs(y)) if np.isfinite(y).any() else 0.0
                rel = (d.max() / scale) if d.size and scale > 0 else 0.0
                print(f"    {k:14s} {'bit-identical' if same else f'max rel diff {rel:.2e}'}")


if __name__ == "__main__":
    main()
