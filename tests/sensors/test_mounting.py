"""IMU mounting (misalignment + lever arm): oracles.

* the mounted increments equal the exact increments of the IMU point's own motion
  (:func:`imugen.navigate.mechanize.exact_increments` on ``p + C l``, ``C C_vb``), flat and wgs84,
  compensated and raw; the rates equal ``C_bv (f + alpha x l + omega x (omega x l))`` re-derived
  from the IMU point's acceleration;
* zero-error closure: a perfect IMU mounted with a drawn misalignment and lever arm navigates
  onto the IMU's truth as closely as an unmounted one onto the vehicle's;
* draws: per sequence, labelled, reproducible, the sigmas of the configuration.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imugen.core.earth import OriginFrame, earth_rate_n, gravity_n
from imugen.core.errors import InputError
from imugen.core.rotations import dcm_to_quat, euler_to_dcm, quat_to_dcm
from imugen.navigate.stage import navigate_arrays
from imugen.sensors import mounting as MT
from imugen.sensors.ideal import ArrayTruth
from imugen.simulate import stage as SIM
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth

from helpers import simulate_shard
from oracles.strapdown import exact_increments

ORIGIN = (45.0, 7.0, 300.0)
ANGLES = np.array([0.02, -0.015, 0.035])  # roll, pitch, yaw [rad]
LEVER = np.array([1.2, -0.4, 0.7])  # m


# --- an analytic vehicle motion -------------------------------------------------------------------
def pos(t):
    t = np.asarray(t, float)
    return np.column_stack(
        [12 * t + 8 * np.sin(0.3 * t), 40 * np.cos(0.2 * t), 0.5 * np.sin(0.5 * t)]
    )


def vel(t):
    t = np.asarray(t, float)
    return np.column_stack(
        [12 + 2.4 * np.cos(0.3 * t), -8 * np.sin(0.2 * t), 0.25 * np.cos(0.5 * t)]
    )


def acc(t):
    t = np.asarray(t, float)
    return np.column_stack(
        [-0.72 * np.sin(0.3 * t), -1.6 * np.cos(0.2 * t), -0.125 * np.sin(0.5 * t)]
    )


def euler(t):
    t = np.asarray(t, float)
    return 0.05 * np.sin(1.1 * t), 0.03 * np.sin(0.7 * t), 0.6 * t + 0.3 * np.sin(0.9 * t)


def C_nv(t):
    return euler_to_dcm(*euler(t))


def att(t):
    return dcm_to_quat(C_nv(t))


def d(fun, t, h=1e-3):
    """4th-order central difference of ``fun`` at ``t``."""
    return (fun(t - 2 * h) - 8 * fun(t - h) + 8 * fun(t + h) - fun(t + 2 * h)) / (12 * h)


def omega_nv_v(t):
    C = C_nv(t)
    W = np.einsum("kji,kjl->kil", C, d(C_nv, t))  # C^T dC/dt = [omega x]
    return np.column_stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]])


def imu_pos(t):
    return pos(t) + C_nv(t) @ LEVER


def imu_vel(t):
    return vel(t) + d(lambda x: C_nv(x) @ LEVER, t)


def imu_att(t):
    return dcm_to_quat(C_nv(t) @ euler_to_dcm(*ANGLES))


def rates(t, frame, p, v, a, C):
    """Ideal specific force in body axes at ``t`` of a motion (p, v, a callables, C attitude)."""
    Om = earth_rate_n(frame)
    f_n = a(t) + 2 * np.cross(Om, v(t)) - gravity_n(p(t), frame)
    return np.einsum("kji,kj->ki", C(t), f_n)


def vehicle_truth(frame, rate=100.0, T=30.0):
    t = np.arange(0.0, T + 0.5 / rate, 1.0 / rate)
    dth, dv = exact_increments(t, pos, vel, att, frame)
    Om = earth_rate_n(frame)
    C = C_nv(t)
    w = omega_nv_v(t) + np.einsum("kji,j->ki", C, Om)
    f = rates(t, frame, pos, vel, acc, C_nv)
    z = np.zeros((1, 3))
    return t, w, f, np.vstack([z, dth]), np.vstack([z, dv])


def mounting_for(truth, frame, t):
    if frame.model == "flat":
        return MT.Mounting(truth)
    step = 100
    grid = MT._grid(len(t), step)
    return MT.Mounting(truth, att(t), MT.gravitation_gradient(pos(t[grid]), frame), step)


def apply_chunks(m, angles, lever, dth, dv, raw, chunk):
    out = [np.empty((m.truth.K, 3)) for _ in range(4)]
    for k0 in range(0, m.truth.K, chunk):
        L = min(chunk, m.truth.K - k0)
        sh = m.shared(k0, L, raw)
        res = m.apply(k0, sh, angles, lever, dth[k0 : k0 + L], dv[k0 : k0 + L], raw)
        for o, r in zip(out, res, strict=True):
            o[k0 : k0 + L] = r
    return out


@pytest.mark.parametrize("earth", ["flat", "wgs84"])
def test_compensated_increments_are_those_of_the_imu_point(earth):
    frame = OriginFrame.from_deg(*ORIGIN, model=earth)
    t, w, f, dth, dv = vehicle_truth(frame)
    tr = ArrayTruth(t, w, f, dth, dv)
    m = mounting_for(tr, frame, t)
    ref_dth, ref_dv = exact_increments(t, imu_pos, imu_vel, imu_att, frame)
    for chunk in (len(t), 777):  # chunking cannot change the numbers
        _, _, odth, odv = apply_chunks(m, ANGLES, LEVER, dth, dv, False, chunk)
        assert np.all(odth[0] == 0) and np.all(odv[0] == 0)
        assert np.max(np.abs(odth[1:] - ref_dth)) < 1e-12
        # the lever-arm term alone is up to 1 m/s^2 (x 0.01 s); flat: exact to rounding;
        # wgs84: the gravitation gradient interpolated at 1 s spacing
        err = np.max(np.abs(odv[1:] - ref_dv))
        assert err < 2e-11, err
    # and the lever arm matters: without it the increments differ by far more
    _, _, _, odv0 = apply_chunks(m, ANGLES, 0 * LEVER, dth, dv, False, len(t))
    assert np.max(np.abs(odv0[1:] - ref_dv)) > 1e-3


def test_raw_increments_are_plain_integrals_of_the_imu_specific_force():
    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    t, w, f, dth, dv = vehicle_truth(frame)
    tr = ArrayTruth(t, w, f, dth, dv)
    rdth, rdv = tr.raw_chunk(0, tr.K)
    m = MT.Mounting(tr)
    Cbv = euler_to_dcm(*ANGLES).T
    # reference: Gauss-Legendre (8 nodes) of the IMU's specific force over every interval
    xg, wg = np.polynomial.legendre.leggauss(8)
    dt = t[1] - t[0]
    ref = np.zeros((len(t), 3))
    for x, wq in zip(xg, wg, strict=True):
        tau = t[:-1] + 0.5 * dt * (x + 1)
        f_imu = rates(tau, frame, imu_pos, imu_vel, lambda s: d(imu_vel, s), C_nv)
        ref[1:] += 0.5 * dt * wq * f_imu
    ref = ref @ Cbv.T
    for chunk in (len(t), 500):
        _, _, odth, odv = apply_chunks(m, ANGLES, LEVER, rdth, rdv, True, chunk)
        np.testing.assert_allclose(odth, rdth @ Cbv.T, rtol=0, atol=1e-15)
        # the vehicle's raw dv has the 4-point rule's error (dt^5); the lever-arm term too
        err = np.max(np.abs(odv - ref))
        assert err < 1e-9, err


def test_rates_are_the_imu_point_specific_force_and_rotated_rate():
    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    t, w, f, dth, dv = vehicle_truth(frame)
    tr = ArrayTruth(t, w, f, dth, dv)
    m = MT.Mounting(tr)
    ow, of, _, _ = apply_chunks(m, ANGLES, LEVER, dth, dv, False, 1000)
    Cbv = euler_to_dcm(*ANGLES).T
    np.testing.assert_allclose(ow, w @ Cbv.T, rtol=0, atol=1e-15)
    f_imu = rates(t, frame, imu_pos, imu_vel, lambda s: d(imu_vel, s), C_nv) @ Cbv.T
    # alpha by 4th-order differences of 100 Hz samples (2nd order at the two ends)
    err = np.abs(of - f_imu)
    assert np.max(err[2:-2]) < 2e-7, np.max(err[2:-2])
    assert np.max(err) < 1e-4
    assert np.max(np.abs(f @ Cbv.T - f_imu)) > 0.1  # the lever-arm term is there


def test_imu_states_are_the_imu_point_truth():
    frame = OriginFrame.from_deg(*ORIGIN, model="wgs84")
    t = np.linspace(0, 20, 201)
    C = C_nv(t)
    w = omega_nv_v(t) + np.einsum("kji,j->ki", C, earth_rate_n(frame))
    p, v, q = MT.imu_states(
        pos(t), vel(t), att(t), w, earth_rate_n(frame), ANGLES[None], LEVER[None]
    )
    np.testing.assert_allclose(p[0], imu_pos(t), atol=1e-12)
    np.testing.assert_allclose(v[0], imu_vel(t), atol=1e-8)
    np.testing.assert_allclose(quat_to_dcm(q[0]), quat_to_dcm(imu_att(t)), atol=1e-14)


# --- through the simulator and navigation ---------------------------------------------------------
def truth_frame(frame, T=120.0):
    t, w, f, dth, dv = vehicle_truth(frame, T=T)
    cols = {ttruth.TIME: t}
    for names, a in (
        (ttruth.POS, pos(t)),
        (ttruth.VEL, vel(t)),
        (ttruth.QUAT, att(t)),
        (ttruth.GYRO, w),
        (ttruth.ACCEL, f),
        (ttruth.DTHETA, dth),
        (ttruth.DV, dv),
    ):
        cols.update({c: a[:, i] for i, c in enumerate(names)})
    meta = {
        "origin": dict(zip(("lat_deg", "lon_deg", "alt_m"), ORIGIN, strict=True)),
        "earth": frame.model,
        "rate_hz": 100.0,
    }
    return pd.DataFrame(cols), meta


MOUNT = {"misalignment_sd_deg": [1.0, 1.0, 2.0], "lever_arm_m": [0.5, 0.0, 0.3]}


@pytest.mark.parametrize("increments", ["compensated", "raw"])
def test_zero_error_closure_with_mounting(increments):
    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    df, meta = truth_frame(frame)
    truth = ttruth.Truth(df, meta)
    kw = dict(sequences=3, seed=4, terms=[], increments=increments)
    res = {}
    for mount in (None, MOUNT):
        sh = SIM.simulate(df, "consumer", mounting=mount, **kw)
        nav = navigate_arrays(truth, sh)
        e = nav.groupby("sequence").last()
        res[mount is None] = (np.linalg.norm(e[["err_e_m", "err_n_m", "err_u_m"]], axis=1), e)
    plain, mounted = res[True][0], res[False][0]
    # the same closure as without mounting (compensated: 1e-6 m; raw: the two-sample
    # correction's own error, the same with and without the lever arm)
    assert np.all(mounted <= max(1e-6, 2 * plain.max())), (mounted, plain)
    assert res[False][1]["err_att_rad"].max() < 1e-8
    sh = SIM.simulate(df, "consumer", mounting=MOUNT, **kw)
    # navigating the mounted IMU against the vehicle's truth would be wrong by the lever arm
    wrong = navigate_arrays(truth, dict(sh.data), semantics=increments)  # no labels
    assert wrong.groupby("sequence")["err_att_rad"].last().min() > 1e-3


def test_draws_labels_and_reproducibility():
    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    df, _ = truth_frame(frame, T=2.0)
    spec = {"misalignment_sd_deg": [1.0, 2.0, 3.0], "lever_arm_m": [1, 2, 3], "lever_arm_sd_m": 0.5}
    sh = SIM.simulate(df, "consumer", sequences=400, seed=1, mounting=spec, terms=[])
    ang, lev = tshard.mounting(sh.labels)
    np.testing.assert_allclose(ang.std(axis=0), np.radians([1, 2, 3]), rtol=0.15)
    np.testing.assert_allclose(lev.mean(axis=0), [1, 2, 3], atol=0.1)
    np.testing.assert_allclose(lev.std(axis=0), 0.5, rtol=0.15)
    assert sh.meta["mounting"]["lever_arm_sd_m"] == [0.5] * 3
    # sequence j's draw does not depend on the shard's size; the labels follow ids
    sh2 = SIM.simulate(df, "consumer", sequences=3, seed=1, mounting=spec, terms=[], shard_size=400)
    a2, l2 = tshard.mounting(sh2.labels)
    np.testing.assert_array_equal(a2, ang[:3])
    np.testing.assert_array_equal(l2, lev[:3])
    ids = sh.labels[tshard.SEQUENCE].to_numpy()[[5, 2]]
    np.testing.assert_array_equal(tshard.mounting(sh.labels, ids)[1], lev[[5, 2]])
    # off: no mounting columns
    sh3 = SIM.simulate(df, "consumer", sequences=2, seed=1, terms=[])
    assert tshard.mounting(sh3.labels) is None and sh3.meta["mounting"] is None


@pytest.mark.parametrize(
    "bad",
    [{"misalignment_sd_deg": [1, 2]}, {"lever_arm_sd_m": -1}, {"lever": 1}, "yes"],
)
def test_bad_mounting_options_are_refused(bad):
    with pytest.raises(InputError):
        MT.MountingSpec.from_option(bad)


def test_off_forms():
    for off in (None, False, "off", {"enabled": False}):
        assert MT.MountingSpec.from_option(off) is None
    s = MT.MountingSpec.from_option({})
    assert np.allclose(np.degrees(s.misalignment_sd_rad), MT.DEFAULT_MISALIGNMENT_SD_DEG)


def test_wgs84_shard_file_closes_on_the_imu_truth(tmp_path):
    """Files end to end (wgs84: the gravitation-gradient term from the truth file): the shard
    navigated in the simulating pass and by ``navigate.run`` on the written shard close on the
    IMU's truth as an unmounted IMU closes on the vehicle's."""
    from imugen.evaluate.stage import segment_drift
    from imugen.navigate import stage as NV
    from imugen.tables import nav as tnav

    frame = OriginFrame.from_deg(*ORIGIN, model="wgs84")
    df, meta = truth_frame(frame, T=120.0)
    tpath = tmp_path / "truth.parquet"
    ttruth.write(df, meta, tpath)
    final = {}
    for mount in (None, MOUNT):
        name = "m" if mount else "p"
        out, nav = tmp_path / f"{name}.parquet", tmp_path / f"{name}-nav.parquet"
        simulate_shard(tpath, out, "consumer", sequences=2, seed=3, terms=[], dtype="float64",
                mounting=mount, navigate=nav)  # fmt: skip
        e = tnav.read(nav)
        again = NV.navigate(tpath, out)
        np.testing.assert_array_equal(again["err_e_m"].to_numpy(), e["err_e_m"].to_numpy())
        last = e.groupby("sequence").last()
        final[name] = np.linalg.norm(last[["err_e_m", "err_n_m", "err_u_m"]], axis=1)
        assert last["err_att_rad"].max() < 1e-9
        # relative drift restarts from the IMU's truth too
        drift = segment_drift(tpath, out, [30.0, 60.0])
        assert drift.to_numpy().max() < 1e-6, drift
    assert final["m"].max() < max(1e-6, 3 * final["p"].max()), final


# --- the aided filter's NHC against a mounted IMU ---------------------------------------------------
CAR_MOUNT = {
    "misalignment_sd_deg": [1.0, 1.0, 2.0],
    "lever_arm_m": [0.5, 0.2, 0.3],
    "lever_arm_sd_m": [0.05, 0.05, 0.05],
}


@pytest.fixture(scope="module")
def car():
    """A car driving a 400 m x 200 m rectangle (about 120 s at 100 Hz) and its truth; rigid
    (the path's attitude): NHC's closed form ``-u C_bv (1, 0, 0)`` and the mounting estimates'
    consistency are about the IMU's misalignment alone, not the body's dive and squat on its
    suspension (which tests/aid/test_companions.py covers with ``nhc_pitch_sd_rad``)."""
    from imugen import truth as T

    pts = np.array([[0, 0, 0], [400, 0, 0], [400, 200, 0], [0, 200, 0], [0, 0, 0]], float)
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": dict(zip(("lat_deg", "lon_deg", "alt_m"), ORIGIN, strict=True))}
    meta["timed"] = False
    df, _ = T.build_truth(
        enu, meta, rate_hz=100.0, earth="flat", vehicle="car", verbose=False,
        vehicle_params={"suspension": "rigid"},
    )  # fmt: skip
    meta = {**meta, "earth": "flat", "rate_hz": 100.0, "vehicle": "car"}
    return df, ttruth.Truth(df, meta)


def aided_run(
    car, M, seed, spec, opts, terms, receiver, white_gnss=False, perturb=True, odometer=None
):  # fmt: skip
    """Simulate M mounted sequences, their GNSS on the IMU's truth (the aid stage's
    :func:`imugen.aid.stage.gnss_for`), run the filter from the IMU's truth perturbed by P0 at
    sample 500 (``perturb=False``: exactly, small P0); return the result, the IMU truth arrays
    and the labels' mounting. ``odometer``: a preset whose wheel rolls with the vehicle (its
    reference point), drawn figures given to the filter."""
    from dataclasses import replace

    from imugen.aid import companions as CP
    from imugen.aid import filter as A
    from imugen.aid import stage as AID
    from imugen.core.rotations import exp_dcm

    df, truth = car
    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    sh = SIM.simulate(df, "consumer", sequences=M, seed=seed, draw="nominal", terms=terms,
                      mounting=spec)  # fmt: skip
    mount = tshard.mounting(sh.labels)
    params = AID.AidOptions(receiver=receiver, draw="nominal", lever_arm_b_m=(0.6, 0.3, 1.2))
    gn = AID.gnss_for(truth, sh.labels[tshard.SEQUENCE], params, seed, mount).gnss
    if white_gnss:  # white GNSS errors with known sigmas (no bias states)
        gn = replace(gn, p_n=gn.p_ant_n + gn.offset_p_n - gn.bias_n, sigma_p_n=gn.sigma_p_n * 0)
        gn.sigma_p_n[...] = (0.3, 0.3, 0.5)
    Om = earth_rate_n(frame)
    P_, V_, Q_ = MT.imu_states(truth.p_n, truth.v_n, truth.q_nb, truth.omega_ib_b, Om, *mount)
    tun = A.Tuning.from_grade("consumer", terms=terms)
    k0 = 500
    sd = ([0.5, 0.5, 0.8], 0.05, [0.01, 0.01, 0.02]) if perturb else (0.01, 0.001, 1e-4)
    ce, osd = None, 0.0
    if odometer is not None:
        t, w = truth.time_s, truth.omega_ib_b
        od = CP.simulate_odometer(t, truth.v_n, truth.q_nb, w, odometer, M, seed)
        ce = CP.filter_input(gn.index, M, od, oracle=True)
        osd = ce.odo_sf_sd
    sd = [np.broadcast_to(np.atleast_2d(np.asarray(x, float)), (M, 3)) for x in sd]
    P0 = A.initial_covariance(tun, opts, *sd, odo_sf_sd=osd)
    rng = np.random.default_rng(5)
    e = np.stack([rng.multivariate_normal(np.zeros(9), P0[s, :9, :9]) for s in range(M)])
    e *= perturb
    C = exp_dcm(e[:, 6:9]) @ quat_to_dcm(Q_[:, k0])
    init = A.initial_state(k0, P_[:, k0] + e[:, :3], V_[:, k0] + e[:, 3:6], dcm_to_quat(C), P0)
    Tm = A.tuning_matrix(tun, M, gnss_params=gn.params)
    res = A.run(sh.data["dtheta"], sh.data["dv"], 0.01, frame, gn, tun, opts, init,
                store_P=True, tuning_T=Tm, companions=ce)  # fmt: skip
    return res, (P_, V_, Q_), mount


def test_nhc_sees_the_misalignment_closed_form(car):
    """On the straight legs a mounted IMU's NHC residual (vehicle lateral and vertical
    velocity in the NOMINAL frame, at the nominal lever arm), evaluated on the filter's state
    (perfect IMU, noiseless GNSS, NHC off), is ``u C_bv (1, 0, 0)``: ``-u yaw``, ``-u pitch``
    to first order."""
    from imugen.aid import filter as A

    truth = car[1]
    opts = A.Options(gnss_bias=False, nhc=False)
    res, (_, V_, Q_), mount = aided_run(car, 4, 3, CAR_MOUNT, opts, [], "rtk", perturb=False)
    idx = res.index
    w = truth.omega_ib_b[idx]
    speed = np.linalg.norm(truth.v_n[idx], axis=1)
    # straight legs: no rotation, so the lever-arm term omega x l vanishes
    straight = (np.linalg.norm(w, axis=1) < 1e-5) & (speed > 5.0) & (idx > 1000)
    assert straight.sum() > 100
    e_fwd = MT.C_vb(mount[0])[:, 0, :]  # C_bv (1, 0, 0)
    u = speed[straight]
    expect = u[None, :, None] * e_fwd[:, None, 1:]
    # on the IMU's truth: the closed form, up to |omega x l| < 1e-5 m/s and the vehicle's
    # own lateral velocity on the legs (the ground model's, below 1e-4 m/s)
    k = idx[straight]
    C = quat_to_dcm(Q_[:, k])
    resid = np.einsum("skji,skj->ski", C, V_[:, k])
    np.testing.assert_allclose(resid[..., 1:], expect, rtol=0, atol=1e-4)
    # on the filter's state: the same, up to its heading error on straight legs (RTK fixes)
    C = quat_to_dcm(res.q_nb[:, straight])
    resid = np.einsum("skji,skj->ski", C, res.v_n[:, straight])
    np.testing.assert_allclose(resid[..., 1:].mean(1), expect.mean(1), rtol=0.1)
    # first order: -u yaw and -u pitch; at 2 deg and 10 m/s the residual is ~0.3 m/s
    np.testing.assert_allclose(e_fwd[:, 1:], -mount[0][:, [2, 1]], atol=2e-3)
    assert np.abs(expect).max() > 0.05


def test_filter_estimates_the_mounting_and_stays_consistent(car):
    """NEES of (p, v, psi) against the IMU's truth inside the chi-square bounds over Monte-Carlo
    runs when the filter carries the mounting states with the configured sigma; the nominal
    NHC alone is inconsistent; the two estimated angles converge to the forward-axis angles of
    the labels within their reported sigma."""
    from dataclasses import replace

    from scipy.stats import chi2

    from imugen.aid import filter as A

    M = 30
    terms = ["turn_on_bias", "white_noise", "bias_instability"]
    sd = tuple(np.radians(CAR_MOUNT["misalignment_sd_deg"][1:]))
    nominal = A.Options(
        gnss_bias=False,
        nhc=True,
        nhc_lever_arm_m=tuple(CAR_MOUNT["lever_arm_m"]),
        nhc_lever_arm_sd_m=tuple(CAR_MOUNT["lever_arm_sd_m"]),
    )
    out = {}
    for name, opts in (
        ("nominal", nominal),
        ("states", replace(nominal, nhc_misalignment_sd_rad=sd)),
    ):
        res, (P_, V_, Q_), mount = aided_run(car, M, 11, CAR_MOUNT, opts, terms, "standalone",
                                             white_gnss=True)  # fmt: skip
        idx = res.index
        qq = np.where(np.isnan(res.q_nb), [1.0, 0.0, 0.0, 0.0], res.q_nb)
        err = np.concatenate(
            [res.p_n - P_[:, idx], res.v_n - V_[:, idx], A.attitude_error(qq, Q_[:, idx])], -1
        )
        js = np.linspace(np.searchsorted(idx, 500) + 1, len(idx) - 1, 20).astype(int)
        P9 = res.P[:, js, :9, :9]
        nees = np.einsum(
            "...i,...i->...", err[:, js], np.linalg.solve(P9, err[:, js, :, None])[..., 0]
        )
        out[name] = nees.mean(axis=0)
        if opts.mounting:
            i = res.names.index("dmount_pitch")
            assert res.names[i + 1] == "dmount_yaw"
            z = (res.mount_angles[:, -1] - MT.forward_axis_angles(mount[0])) / res.sd[
                :, -1, i : i + 2
            ]
            assert np.all(np.sum(z**2, axis=0) < chi2.ppf(0.999, M)), z
            # observable: the sigmas shrank well below the prior
            assert np.all(res.sd[:, -1, i : i + 2] < 0.2 * np.array(sd))
    lo, hi = chi2.ppf([0.005, 0.995], 9 * M) / M
    states = out["states"]
    print(
        f"NEES mean {states.mean():.2f} (bounds {lo:.2f}-{hi:.2f}); nominal NHC median "
        f"{np.median(out['nominal']):.0f}"
    )
    assert np.sum((states < lo) | (states > hi)) <= 2, (states.round(1), lo, hi)
    assert lo < states.mean() < hi
    assert np.median(out["nominal"]) > 10 * hi, out["nominal"].round(0)


def test_odometer_is_mounting_aware(car):
    """Large misalignments (3, 3, 5 deg) and a 1 m lever arm (10 cm sigma) drawn, odometer on:
    the wheel's speed is along the vehicle's x at its reference point, which the filter takes
    through its mounting and lever-arm states, so NEES of (p, v, psi) stays in the chi-square
    99 % band of each epoch's Monte-Carlo mean (mean 9.3, none outside measured; 192 before,
    with the odometer taken along the IMU's x at the IMU; 15.7 with the odometer fixed but the
    NHC rotating the reference point's lateral velocity and not its forward part)."""
    from scipy.stats import chi2

    from imugen.aid import filter as A

    M = 30
    spec = {"misalignment_sd_deg": [3.0, 3.0, 5.0], "lever_arm_m": [1.0, 0.5, 0.5],
            "lever_arm_sd_m": [0.1, 0.1, 0.1]}  # fmt: skip
    opts = A.Options(
        gnss_bias=False, nhc=True, odometer=True, nhc_lever_arm_m=tuple(spec["lever_arm_m"]),
        nhc_lever_arm_sd_m=tuple(spec["lever_arm_sd_m"]),
        nhc_misalignment_sd_rad=tuple(np.radians(spec["misalignment_sd_deg"][1:])),
    )  # fmt: skip
    terms = ["turn_on_bias", "white_noise", "bias_instability"]
    res, (P_, V_, Q_), mount = aided_run(car, M, 11, spec, opts, terms, "standalone",
                                         white_gnss=True, odometer="abs")  # fmt: skip
    idx = res.index
    assert np.sum((res.flags & A.F_ODO) != 0) > 0.9 * M * len(idx)
    qq = np.where(np.isnan(res.q_nb), [1.0, 0.0, 0.0, 0.0], res.q_nb)
    err = np.concatenate(
        [res.p_n - P_[:, idx], res.v_n - V_[:, idx], A.attitude_error(qq, Q_[:, idx])], -1
    )
    js = np.linspace(np.searchsorted(idx, 500) + 1, len(idx) - 1, 20).astype(int)
    P9 = res.P[:, js, :9, :9]
    e = err[:, js]
    nees = np.einsum("...i,...i->...", e, np.linalg.solve(P9, e[..., None])[..., 0]).mean(0)
    lo, hi = chi2.ppf([0.005, 0.995], 9 * M) / M
    assert np.sum((nees < lo) | (nees > hi)) <= 2, (nees.round(1), lo, hi)
    assert lo < nees.mean() < hi
    # the mounting angles as in the NHC test: within their sigma
    i = res.names.index("dmount_pitch")
    z = (res.mount_angles[:, -1] - MT.forward_axis_angles(mount[0])) / res.sd[:, -1, i : i + 2]
    assert np.all(np.sum(z**2, axis=0) < chi2.ppf(0.999, M)), z


def test_workflow_passes_the_config_mounting(tmp_path):
    """``mounting.enabled`` reaches every simulate job as ``--mounting JSON`` (dry run); the
    schema refuses a malformed section."""

    import helpers as wf

    TINY, snakemake, write_config = wf.TINY, wf.snakemake, wf.write_config

    cfg = {**TINY, "mounting": {"enabled": True, "lever_arm_m": [0.5, 0.0, 0.3]}}
    write_config(tmp_path, cfg)
    proc = snakemake(tmp_path, "-n", "-p", "-j1")
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-2000:]
    sim = [ln for ln in out.splitlines() if "imugen simulate" in ln and "--navigate" in ln]
    assert sim and all("--mounting" in ln and '"lever_arm_sd_m": [0.05' in ln for ln in sim)
    write_config(tmp_path, TINY)
    out = snakemake(tmp_path, "-n", "-p", "-j1").stdout
    assert "imugen simulate" in out and "--mounting" not in out
    write_config(tmp_path, {**TINY, "mounting": {"enabled": True, "lever_arm_m": [1, 2]}})
    assert snakemake(tmp_path, "-n", "-j1").returncode != 0


def test_exports_carry_the_imu_truth(tmp_path):
    """EuRoC ground truth of a mounted sequence is the IMU's point and axes; the TUM export's
    free-inertial trajectory of a perfect mounted IMU lies on it."""
    from imugen.export.stage import export

    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    df, meta = truth_frame(frame, T=20.0)
    tpath = tmp_path / "drive" / "truth.parquet"
    ttruth.write(df, meta, tpath)
    shard = tmp_path / "drive" / "imu" / "consumer" / "shard-000.parquet"
    simulate_shard(tpath, shard, "consumer", sequences=2, seed=2, terms=[], dtype="float64",
            outputs="both", mounting=MOUNT)  # fmt: skip
    out = tmp_path / "export"
    export(["euroc", "tum"], tpath, [shard], out, log=lambda m: None, nav_rate_hz=10.0)
    labels = tshard.read_labels(shard)
    truth = ttruth.Truth(df, meta)
    p_imu, _, q_imu = MT.imu_states(
        truth.p_n, None, truth.q_nb, None, np.zeros(3), *tshard.mounting(labels)
    )
    for j, sid in enumerate(labels[tshard.SEQUENCE]):
        folder = out / "euroc" / f"drive_consumer_{sid:06d}" / "mav0"
        gt = np.loadtxt(folder / "state_groundtruth_estimate0" / "data.csv", delimiter=",")
        np.testing.assert_allclose(gt[:, 1:4], p_imu[j], atol=1e-6)
        q = gt[:, 4:8] * np.sign(gt[:, 4:5] * q_imu[j][:, :1])
        np.testing.assert_allclose(q, q_imu[j], atol=1e-8)
        assert np.abs(gt[:, 1:4] - truth.p_n).max() > 0.1  # not the vehicle's
        est = np.loadtxt(out / "tum" / f"drive_consumer_{sid:06d}.tum")
        np.testing.assert_allclose(est[:, 1:4], p_imu[j][::10], atol=1e-6)


def test_aid_stage_on_a_mounted_shard(car, tmp_path):
    """The aid stage end to end on a mounted shard (perfect IMU, RTK fixes, NHC for the car):
    the filter carries the mounting states and its errors against the IMU's truth stay at the
    RTK level (a comparison with the vehicle's truth would show the 1.1 m lever arm)."""
    from imugen.aid import stage as AID
    from imugen.tables import aided as taided

    df, truth = car
    tpath = tmp_path / "car" / "truth.parquet"
    ttruth.write(df, truth.meta, tpath)
    shard = tmp_path / "car" / "imu" / "consumer" / "shard-000.parquet"
    spec = {**CAR_MOUNT, "lever_arm_m": [0.5, 0.2, 1.0]}
    simulate_shard(tpath, shard, "consumer", sequences=2, seed=4, terms=[], mounting=spec)
    params = AID.AidOptions(receiver="rtk", draw="nominal", outage_durations_s=())
    opts = AID.filter_options(params, "car", tshard.read_meta(shard)["mounting"])
    assert opts.nhc and opts.mounting and opts.nhc_lever_arm_m == (0.5, 0.2, 1.0)
    _, apath = AID.run(tpath, shard, tmp_path / "g.parquet", tmp_path / "a.parquet", params)
    nav = taided.read(apath)
    late = nav[nav["time_s"] > 30.0]
    err = np.linalg.norm(late[["err_e_m", "err_n_m", "err_u_m"]].to_numpy(), axis=1)
    print(f"aided 95 % error {np.percentile(err, 95):.3f} m")
    assert len(late) and np.percentile(err, 95) < 0.1, np.percentile(err, 95)


def test_loader_increments_target_is_the_mounted_imus(tmp_path):
    """A perfect mounted IMU's measured increments equal the loader's ``increments`` target
    (float32), which differs from the vehicle's by far more."""
    from imugen.dataset import RouteFiles, WindowDataset

    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    df, meta = truth_frame(frame, T=10.0)
    tpath = tmp_path / "drive" / "truth.parquet"
    ttruth.write(df, meta, tpath)
    shard = tmp_path / "drive" / "imu" / "consumer" / "shard-000.parquet"
    simulate_shard(tpath, shard, "consumer", sequences=3, seed=2, terms=[], mounting=MOUNT)
    ds = WindowDataset([RouteFiles("drive", tpath, (shard,), "consumer")], window=50, stride=25)
    x, y = ds.get_batch(np.arange(len(ds)))
    scale = np.abs(y).max(axis=(0, 1))
    assert np.max(np.abs(x - y) / scale) < 1e-5
    plain = WindowDataset([RouteFiles("drive", tpath, (shard,), "consumer")], window=50, stride=25)
    plain._mount = None  # the vehicle's increments
    assert np.max(np.abs(x - plain.get_batch(np.arange(len(ds)))[1]) / scale) > 1e-3
