"""Run the aided filter over a batch of sequences: :func:`run` (the Python face of the
compiled :mod:`imugen.aid.filter._kernel`) and its :class:`AidedResult`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imugen.aid.companions import CompanionEpochs
from imugen.aid.filter._kernel import kernel
from imugen.aid.filter.align import Initial, align
from imugen.aid.filter.context import Inputs, Model, Outputs
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
    nhc_lever_b_m : (S, J, 3)   estimated NHC lever arm, body [m] (the nominal when not
                                estimated, :attr:`Options.lever_states`)
    layout : StateLayout        the error state's blocks (``sd[..., layout.slice("v")]``)
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

    def sd_of(self, key: str) -> np.ndarray:
        """1-sigma of the error-state block ``key`` (:data:`imugen.aid.filter.state.BLOCKS`),
        ``(S, J, size)``."""
        return self.sd[..., self.layout.slice(key)]


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

    def part(a, lo, hi, dtype=float):
        return np.ascontiguousarray(a[lo:hi], dtype)

    for lo in range(0, S, seq_chunk):
        hi = min(S, lo + seq_chunk)
        inp = Inputs(
            dth=part(dth, lo, hi), dvb=part(dvb, lo, hi), k0=part(init.k0, lo, hi, np.int64),
            ep_idx=idx, zp=part(zp, lo, hi), zv=part(zv, lo, hi),
            sp=part(gnss.sigma_p_n, lo, hi), sv=part(gnss.sigma_v_n, lo, hi),
            ok=part(ok, lo, hi, bool), lever=part(lever, lo, hi), lat=part(lat, lo, hi),
            cz=part(cz, lo, hi), cmark=cmark, clever=part(clever, lo, hi),
            tun=part(tuning_T, lo, hi), x0=part(init.x0, lo, hi), P0=part(init.P0, lo, hi),
        )  # fmt: skip
        kernel(md, inp, Outputs(out_x[lo:hi], out_sd[lo:hi], out_P[lo:hi], flags[lo:hi]))

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
    )


def attitude_error(q_est, q_true) -> np.ndarray:
    """``psi`` with ``C_est = Exp(psi) C_true`` (rad, resolved in n); (..., 4) x2 -> (..., 3)."""
    return log_dcm(quat_to_dcm(q_est) @ np.swapaxes(quat_to_dcm(q_true), -1, -2))
