"""Run the aided filter over a batch of sequences: :func:`run` (the Python face of the
compiled :mod:`imugen.aid.filter._kernel`) and its :class:`AidedResult`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imugen.aid.companions import CompanionEpochs
from imugen.aid.filter import measurements
from imugen.aid.filter._kernel import kernel
from imugen.aid.filter.align import Initial, align
from imugen.aid.filter.context import Inputs, Model, Outputs, new_work
from imugen.aid.filter.error_model import transition_pattern
from imugen.aid.filter.learner import LEARNED_KEYS, FilterEstimate, LearnedInputs, LearnerWindow
from imugen.aid.filter.measurements import F_ALIGNED
from imugen.aid.filter.options import Options
from imugen.aid.filter.propagate import step_params
from imugen.aid.filter.state import NOMINAL, NX, StateLayout
from imugen.aid.filter.tuning import Tuning, companion_tuning, tuning_matrix
from imugen.core import earth
from imugen.core.earth import OriginFrame
from imugen.core.errors import InputError
from imugen.core.rotations import log_dcm, quat_to_dcm


@dataclass
class AidedResult:
    """Filter output at the GNSS epochs (after the updates; NaN before the filter starts).

    Attributes
    ----------
    time_s, index : (J,)        epoch times [s] and IMU sample indices
    p_n, v_n : (S, J, 3)        position [m] and velocity [m/s] of the IMU in n
    q_nb : (S, J, 4)            attitude
    gyro_bias, accel_bias : (S, J, 3)  estimated biases [rad/s, m/s^2]
    gyro_sf, accel_sf : (S, J, 3)      estimated scale factors (zeros when not estimated)
    gnss_bias : (S, J, 3)       estimated receiver position bias [m]
    sd : (S, J, n)              1-sigma of every error state (:attr:`names`; position,
                                velocity, attitude along the local E, N, U in ``geodetic``)
    P : (S, J, n, n) or None    full covariance (``store_P``)
    odo_sf : (S, J)             estimated odometer scale factor (zeros when not estimated)
    baro_bias : (S, J)          estimated barometer drift [m] (zeros when not estimated)
    flags : (S, J) int16        bits F_GNSS_P, F_GNSS_V, F_ZUPT, F_NHC, F_REJECT, F_ALIGNED,
                                F_ODO, F_BARO (:data:`imugen.aid.filter.measurements.FLAGS`)
    names : list of str         error-state names
    mount_angles : (S, J, 2)    estimated IMU pitch and yaw from the vehicle [rad] (zeros when
                                not estimated, :attr:`Options.mounting`)
    gyro_cc : (S, J, 6)         estimated gyro cross-coupling, pairs :data:`~imugen.aid.filter.state.CC_PAIRS` (zeros
                                when not estimated, ``Options.gyro_cross_coupling``)
    accel_cc : (S, J, 6)        estimated accelerometer cross-coupling, pairs as ``gyro_cc``
                                (zeros when not estimated, ``Options.accel_cross_coupling``)
    nhc_lever_b_m : (S, J, 3)   estimated NHC lever arm, body [m] (the nominal when not
                                estimated, :attr:`Options.lever_states`)
    layout : StateLayout        the error state's blocks (``sd[..., layout.slice("v")]``)
    correction : (S, K, 6) or None  per IMU sample, what the filter removed from the
                                increments it was given (raw minus corrected angle [rad] and
                                velocity [m/s]: its bias, scale-factor, cross-coupling
                                estimates; ``store_correction``)
    """

    time_s: np.ndarray
    index: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    q_nb: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    gyro_sf: np.ndarray
    accel_sf: np.ndarray
    gnss_bias: np.ndarray
    sd: np.ndarray
    P: np.ndarray | None
    flags: np.ndarray
    names: list
    odo_sf: np.ndarray | None = None
    baro_bias: np.ndarray | None = None
    mount_angles: np.ndarray | None = None
    gyro_cc: np.ndarray | None = None
    nhc_lever_b_m: np.ndarray | None = None
    layout: StateLayout | None = None
    accel_cc: np.ndarray | None = None
    correction: np.ndarray | None = None

    def sd_of(self, key: str) -> np.ndarray:
        """1-sigma of the error-state block ``key`` (:data:`imugen.aid.filter.state.BLOCKS`),
        ``(S, J, size)``."""
        return self.sd[..., self.layout.slice(key)]

    def filter_aware_target(self, err_dtheta, err_dv) -> np.ndarray:
        """(S, K, 6) the error left in each increment after the filter's own correction: the
        effective error (the shard's ``err_dtheta``, ``err_dv``, measured minus ideal) minus
        what the filter removed (:attr:`correction`, ``store_correction=True``). A training
        target and a feature (:mod:`imugen.aid.filter.learner`), NaN before the start."""
        if self.correction is None:
            raise InputError("aided", "run with store_correction=True for the filter-aware target")
        eff = np.concatenate([np.asarray(err_dtheta), np.asarray(err_dv)], axis=-1)
        if eff.shape != self.correction.shape:
            raise InputError("aided", f"errors {eff.shape}, correction {self.correction.shape}")
        out = eff - self.correction
        k0 = self._start_sample()
        out[np.arange(out.shape[1])[None, :] <= k0[:, None]] = np.nan
        return out

    def _start_sample(self) -> np.ndarray:
        """(S,) the sample of each sequence's first epoch (K when it never starts)."""
        ran = (self.flags & F_ALIGNED) != 0
        first = np.where(ran.any(1), ran.argmax(1), -1)
        K = self.correction.shape[1] if self.correction is not None else int(self.index[-1]) + 1
        return np.where(first >= 0, self.index[np.maximum(first, 0)], K)


def run(
    dtheta_b,
    dv_b,
    dt,
    frame: OriginFrame,
    gnss,
    tun: Tuning,
    opts: Options | None = None,
    init: Initial | None = None,
    *,
    tuning_T=None,
    store_P=False,
    seq_chunk=64,
    companions: CompanionEpochs | None = None,
    learned: LearnedInputs | None = None,
    learner=None,
    segment_epochs: int = 10,
    store_correction: bool = False,
) -> AidedResult:
    """Run the filter over a batch of sequences.

    Parameters
    ----------
    dtheta_b, dv_b : ndarray, shape (S, K, 3)
        IMU increments as in a shard (row k: interval ending at t_k; row 0 unused).
    dt : float
        IMU sample interval [s].
    frame : OriginFrame
        Origin and Earth model (``flat``, ``wgs84`` or ``geodetic``).
    gnss : imugen.aid.gnss.GnssData
        Fixes of the same S sequences (possibly altered by :mod:`imugen.aid.scenarios`): only
        ``index``, ``p_n``, ``v_n``, ``sigma_p_n``, ``sigma_v_n``, ``valid``,
        ``params.lever_arm_b_m`` and ``params.latency_s`` are read.
    tun : Tuning
    opts : Options
    init : Initial, optional
        Start state; default :func:`align`.
    tuning_T : ndarray (S, N_TUNE), optional
        Per-sequence tuning (default :func:`tuning_matrix` with the receiver's nominal figures);
        its companion columns are taken from ``companions`` when given.
    store_P : bool
        Also return the full covariance at every epoch.
    seq_chunk : int
        Sequences per kernel call.
    companions : CompanionEpochs, optional
        Odometer and barometer measurements at the GNSS epochs (needed by ``opts.odometer``
        and ``opts.baro``; :func:`imugen.aid.companions.filter_input`).
    learned : LearnedInputs, optional
        A learner's inputs known in advance (:mod:`imugen.aid.filter.learner`): an IMU
        correction (subtracted up front), learned body-frame velocities with their
        covariance, NHC variances.
    learner : callable, optional
        ``learner(window, estimate) -> dict`` called before every segment of
        ``segment_epochs`` epochs (:class:`~imugen.aid.filter.learner.LearnerWindow`,
        :class:`~imugen.aid.filter.learner.FilterEstimate`; keys of the dict: the fields of
        :class:`LearnedInputs`, for that segment only). Not with the odometer (its window is
        not carried across segments).
    store_correction : bool
        Also return the correction the filter applied to every increment
        (:attr:`AidedResult.correction`, (S, K, 6)).
    """
    opts = opts or Options()
    dth = np.asarray(dtheta_b, float)
    dvb = np.asarray(dv_b, float)
    if dth.ndim != 3 or dth.shape != dvb.shape or dth.shape[2] != 3:
        raise InputError("aided", f"increments must be (S, K, 3), got {dth.shape}, {dvb.shape}")
    S = dth.shape[0]
    if gnss.p_n.shape[0] != S:
        raise InputError("aided", f"GNSS has {gnss.p_n.shape[0]} sequences, IMU {S}")
    if tuning_T is None:
        tuning_T = tuning_matrix(tun, S, gnss_receiver=gnss.receiver)
    J = len(gnss.index)
    if companions is None:
        if opts.odometer or opts.baro:
            raise InputError("aided", "odometer/barometer updates need companion measurements")
        companions = CompanionEpochs(
            np.full((S, J, 4), np.nan), np.zeros(J, np.int8), np.zeros((S, 3)), *np.zeros((3, S))
        )
    else:
        tuning_T = companion_tuning(tuning_T, companions)
    if companions.z.shape != (S, J, 4):
        raise InputError("aided", f"companion epochs {companions.z.shape}, expected {(S, J, 4)}")
    if init is None:
        init = align(dth, dvb, dt, gnss, tun, opts, frame, tuning_T=tuning_T)
    lay = opts.layout
    n = lay.n
    if init.P0.shape[1:] != (n, n):
        raise InputError("aided", f"P0 must be ({n}, {n}) for these options")
    if init.x0.shape[1:] != (NX,):
        raise InputError("aided", f"x0 must be (S, {NX})")
    lrn = learned or LearnedInputs()
    for name, corr in (("dtheta", lrn.dtheta), ("dv", lrn.dv)):
        if corr is not None and np.shape(corr) != dth.shape:
            raise InputError("learned", f"{name} must be {dth.shape}, got {np.shape(corr)}")
    if lrn.dtheta is not None:  # an IMU correction known in advance: subtracted up front
        dth = dth - np.asarray(lrn.dtheta, float)
    if lrn.dv is not None:
        dvb = dvb - np.asarray(lrn.dv, float)
    if learner is not None and opts.odometer:
        raise InputError("aided", "a learner callable cannot run with the odometer updates")
    idx = np.ascontiguousarray(gnss.index, np.int64)
    J = len(idx)
    prm = step_params(frame, float(dt))
    md = Model(
        prm=prm, opt=opts.switches(), ie=lay.offsets(), ix=NOMINAL.offsets(),
        feedback=lay.feedback_table(), dt=float(dt), g0=float(prm[earth.P_G0]),
        h0=float(frame.h0_m), wgs=bool(prm[earth.P_MODEL] != 0.0),
        geo=bool(prm[earth.P_MODEL] == 2.0),
    )  # fmt: skip
    out_x = np.empty((S, J, NX))
    out_sd = np.empty((S, J, n))
    out_P = np.empty((S, J if store_P else 0, n, n))
    flags = np.zeros((S, J), np.int16)
    cz = np.asarray(companions.z, float)
    cmark = np.ascontiguousarray(companions.mark, np.int8)
    clever = np.asarray(companions.lever_b_m, float)
    zp = np.nan_to_num(np.asarray(gnss.p_n, float))
    zv = np.nan_to_num(np.asarray(gnss.v_n, float))
    ok = np.asarray(gnss.valid, bool)
    lever = np.asarray(gnss.params.lever_arm_b_m, float)
    lat = np.asarray(gnss.params.latency_s, float)

    lv, lvW, nvar = lrn.epoch_arrays(S, len(gnss.index))
    if learner is not None:  # the learner fills them segment by segment
        if not lv.shape[1]:
            lv, lvW = np.full((S, J, 3), np.nan), np.zeros((S, J, 3, 3))
        if not nvar.shape[1]:
            nvar = np.full((S, J, 2), np.nan)
    K = dth.shape[1]
    out_fc = np.zeros((S, K if store_correction else 0, 6))

    def part(a, lo, hi, dtype=float):
        return np.ascontiguousarray(a[lo:hi], dtype)

    def epochs(a, lo, hi, j0, j1):
        return np.ascontiguousarray(a[lo:hi, j0:j1] if a.shape[1] else a[lo:hi])

    seg = max(1, int(segment_epochs)) if learner is not None else max(J, 1)
    wk = new_work(n)  # the kernel's scratch buffers (it allocates nothing itself)
    transition_pattern(md.ie, md.wgs, wk.nnz, wk.nzc)
    win = measurements.new_windows()
    x_buf = np.zeros(NX)
    for lo in range(0, S, seq_chunk):
        hi = min(S, lo + seq_chunk)
        # the state each call resumes from (written back by the kernel): copies
        k0 = np.array(init.k0[lo:hi], np.int64)
        x0 = np.array(init.x0[lo:hi], float)
        P0 = np.array(init.P0[lo:hi], float)
        carry = np.tile([0.0, -1.0], (hi - lo, 1))
        th_c, dv_c = part(dth, lo, hi), part(dvb, lo, hi)
        if learner is not None:  # corrected segment by segment: never the caller's arrays
            th_c, dv_c = th_c.copy(), dv_c.copy()
        for j0 in range(0, J, seg):
            j1 = min(J, j0 + seg)
            if learner is not None:
                th_c, dv_c = _learner_step(
                    learner, lo, hi, j0, j1, idx, gnss, dth, dvb, th_c, dv_c, x0, P0, k0,
                    lay, lv, lvW, nvar,
                )  # fmt: skip
            inp = Inputs(
                dth=th_c, dvb=dv_c, k0=k0, ep_idx=np.ascontiguousarray(idx[j0:j1]),
                zp=epochs(zp, lo, hi, j0, j1), zv=epochs(zv, lo, hi, j0, j1),
                sp=epochs(np.asarray(gnss.sigma_p_n, float), lo, hi, j0, j1),
                sv=epochs(np.asarray(gnss.sigma_v_n, float), lo, hi, j0, j1),
                ok=epochs(ok, lo, hi, j0, j1), lever=part(lever, lo, hi),
                lat=part(lat, lo, hi), cz=epochs(cz, lo, hi, j0, j1),
                cmark=np.ascontiguousarray(cmark[j0:j1]), clever=part(clever, lo, hi),
                tun=part(tuning_T, lo, hi), x0=x0, P0=P0,
                lv=epochs(lv, lo, hi, j0, j1), lvW=epochs(lvW, lo, hi, j0, j1),
                nvar=epochs(nvar, lo, hi, j0, j1), carry=carry,
            )  # fmt: skip
            P_out = out_P[lo:hi, j0:j1] if store_P else out_P[lo:hi]
            out = Outputs(
                out_x[lo:hi, j0:j1], out_sd[lo:hi, j0:j1], P_out, flags[lo:hi, j0:j1],
                out_fc[lo:hi],
            )  # fmt: skip
            kernel(md, inp, out, wk, win, x_buf)

    def nominal(key):
        return out_x[..., NOMINAL.slice(key)]

    return AidedResult(
        time_s=np.asarray(gnss.time_s),
        index=idx,
        p_n=nominal("p"),
        v_n=nominal("v"),
        q_nb=nominal("att"),
        gyro_bias=nominal("bg"),
        accel_bias=nominal("ba"),
        gyro_sf=nominal("sg"),
        accel_sf=nominal("sa"),
        gnss_bias=nominal("gnss_bias"),
        sd=out_sd,
        P=out_P if store_P else None,
        flags=flags,
        names=lay.names,
        odo_sf=nominal("odo_sf")[..., 0],
        baro_bias=nominal("baro_bias")[..., 0],
        mount_angles=nominal("mount"),
        nhc_lever_b_m=nominal("lever") + np.asarray(opts.nhc_lever_arm_m, float),
        gyro_cc=nominal("cc"),
        layout=lay,
        accel_cc=nominal("ca"),
        correction=out_fc if store_correction else None,
    )


def _learner_step(
    learner, lo, hi, j0, j1, idx, gnss, dth, dvb, th_c, dv_c, x0, P0, k0, lay, lv, lvW, nvar
):  # fmt: skip
    """Call the learner before epochs ``j0:j1`` of sequences ``lo:hi`` and put what it returns
    into the segment's inputs; returns the (corrected) increments of the chunk."""
    k_lo = int(idx[j0 - 1]) + 1 if j0 > 0 else 1
    k_hi = int(idx[j1 - 1])
    win = LearnerWindow(
        lo, hi, j0, j1, k_lo, k_hi, dth, dvb, np.asarray(gnss.time_s), np.asarray(idx)
    )
    est = FilterEstimate(x0.copy(), P0.copy(), k0.copy(), lay.names)
    step = learner(win, est) or {}
    unknown = set(step) - set(LEARNED_KEYS)
    if unknown:
        raise InputError("learner", f"unknown keys {sorted(unknown)}; one of {LEARNED_KEYS}")
    rows = slice(k_lo, k_hi + 1)
    for key, arr in (("dtheta", th_c), ("dv", dv_c)):
        if step.get(key) is not None:
            corr = np.asarray(step[key], float)
            if corr.shape != arr[:, rows].shape:
                raise InputError("learner", f"{key} must be {arr[:, rows].shape}, got {corr.shape}")
            arr[:, rows] -= corr
    part = LearnedInputs(
        body_velocity=step.get("body_velocity"),
        body_velocity_cov=step.get("body_velocity_cov"),
        nhc_var=step.get("nhc_var"),
    )
    plv, plvW, pnv = part.epoch_arrays(hi - lo, j1 - j0)
    if plv.shape[1]:
        lv[lo:hi, j0:j1], lvW[lo:hi, j0:j1] = plv, plvW
    if pnv.shape[1]:
        nvar[lo:hi, j0:j1] = pnv
    return th_c, dv_c


def attitude_error(q_est, q_true) -> np.ndarray:
    """``psi`` with ``C_est = Exp(psi) C_true`` (rad, resolved in n); (..., 4) x2 -> (..., 3)."""
    return log_dcm(quat_to_dcm(q_est) @ np.swapaxes(quat_to_dcm(q_true), -1, -2))
