"""What the compiled functions of the filter pass each other: named tuples of arrays and
numbers (numba types them once; nothing is allocated per step).

* :class:`Model`: the constants of one kernel call (Earth model, step parameters, the
  measurement switches, the state offsets);
* :class:`Inputs`: one batch of S sequences (increments, start, epochs, measurements, tuning,
  initial state);
* :class:`Outputs`: the per-epoch results written by the kernel;
* :class:`Work`: the scratch arrays of one kernel call (the covariance, the error state, one
  measurement row, transition, integrals of the strapdown);
* :class:`Epoch`: the predicted quantities at one epoch that measurement models share.

A new measurement's data is a new field of :class:`Inputs` (filled in
:func:`imugen.aid.filter.ekf.run`); its model reads it as ``inp.<field>[e.s, e.j]``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from imugen.aid.filter.options import Switches
from imugen.aid.filter.state import Offsets
from imugen.core.jit import njit


class Model(NamedTuple):
    """Constants of one kernel call.

    Attributes
    ----------
    prm : (N_STEP_PARAMS,)  the Earth model's and the strapdown step's parameters
        (:func:`imugen.aid.filter.propagate.step_params`)
    opt : Switches  measurement switches and thresholds
    ie : Offsets  error-state offsets (``-1``: block absent)
    ix : Offsets  nominal-state offsets
    feedback : (m, 3) int64  additive feedback rows (nominal offset, error offset, count)
    dt : float  IMU interval [s]
    g0 : float  gravity of the flat model [m/s^2]
    h0 : float  the origin's ellipsoidal height [m] (the barometer's reference)
    wgs : bool  rotating Earth with gravitation (``wgs84`` or ``geodetic``)
    geo : bool  n is ECEF (``geodetic``)
    """

    prm: np.ndarray
    opt: Switches
    ie: Offsets
    ix: Offsets
    feedback: np.ndarray
    dt: float
    g0: float
    h0: float
    wgs: bool
    geo: bool


class Inputs(NamedTuple):
    """One batch of S sequences, K IMU samples and J epochs.

    Attributes
    ----------
    dth, dvb : (S, K, 3)  angle [rad] and velocity [m/s] increments (row k: interval ending at
        t_k; row 0 unused)
    k0 : (S,) int64  start sample of each sequence
    ep_idx : (J,) int64  IMU sample of each epoch
    zp, zv : (S, J, 3)  GNSS position [m] and velocity [m/s] in n (antenna; 0 where invalid)
    sp, sv : (S, J, 3)  their reported 1-sigma (local E, N, U)
    ok : (S, J) bool  usable fix
    lever : (S, 3)  GNSS antenna lever arm, body [m]
    lat : (S,)  GNSS latency [s]
    cz : (S, J, 4)  companion measurements (:class:`imugen.aid.companions.CompanionEpochs`)
    cmark : (J,) int8  odometer window ends
    clever : (S, 3)  odometer wheel from the vehicle reference point, vehicle axes [m]
    tun : (S, N_TUNE)  tuning matrix (:mod:`imugen.aid.filter.tuning`)
    x0 : (S, NX)  nominal state at ``k0``
    P0 : (S, n, n)  error covariance at ``k0``
    lv : (S, J, 3) or (S, 0, 3)  a learner's IMU velocity in body axes [m/s] (NaN: none;
        :mod:`imugen.aid.filter.learned`)
    lvW : (S, J, 3, 3) or (S, 0, 3, 3)  its whitening ``L^-1`` (``R = L L^T``)
    nvar : (S, J, 2) or (S, 0, 2)  a learner's NHC variances (lateral, vertical) [m^2/s^2]
        replacing the slip's (NaN: keep)
    carry : (S, 2)  what a segmented run resumes from besides ``x0``, ``P0``, ``k0``: the ZUPT
        detector's still time [s] and previous epoch sample (:mod:`imugen.aid.filter.zupt`)

    ``k0``, ``x0``, ``P0`` and ``carry`` are written back at the end of each sequence (the
    last epoch's sample, state, covariance): the next call over later epochs resumes there.
    """

    dth: np.ndarray
    dvb: np.ndarray
    k0: np.ndarray
    ep_idx: np.ndarray
    zp: np.ndarray
    zv: np.ndarray
    sp: np.ndarray
    sv: np.ndarray
    ok: np.ndarray
    lever: np.ndarray
    lat: np.ndarray
    cz: np.ndarray
    cmark: np.ndarray
    clever: np.ndarray
    tun: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    lv: np.ndarray
    lvW: np.ndarray
    nvar: np.ndarray
    carry: np.ndarray


class Outputs(NamedTuple):
    """Per-epoch results (after the updates; NaN before a sequence starts).

    Attributes
    ----------
    x : (S, J, NX)  nominal state
    sd : (S, J, n)  1-sigma of the error state (position, velocity, attitude along the local
        E, N, U in ``geodetic``)
    P : (S, J, n, n) or (S, 0, n, n)  covariance (when stored)
    flag : (S, J) int16  update flags
    fc : (S, K, 6) or (S, 0, 6)  the correction the filter applied to each increment (raw
        minus corrected angle [rad] and velocity [m/s]: its bias, scale-factor and
        cross-coupling estimates), per sample (when stored)
    """

    x: np.ndarray
    sd: np.ndarray
    P: np.ndarray
    flag: np.ndarray
    fc: np.ndarray


class Work(NamedTuple):
    """Scratch arrays of one kernel call (n: size of the error state).

    Attributes
    ----------
    P : (n, n)  error covariance;  dx : (n,)  error-state estimate of the epoch
    h : (n,)  one measurement row, non-zero at ``hz[:m]``;  hz : (n,) int64;  PHt : (n,)
    Phi, T : (n, n)  transition and product;  qdiag : (n,)  diagonal process noise
    nnz : (n,) int64, nzc : (n, n) int64  non-zero columns of each row of Phi
    C : (3, 3)  C_nb at the epoch (during the strapdown: before the step);  Cn : (3, 3)
    Lm, Xc, Xm, Cv : (3, 3)  local level, skew and vehicle-axes scratch
    dvn : (3,)  integrated ``C dv`` [m/s];  Cint, Cf, Cw : (3, 3)  ``int C dt``, ``int C
    diag(dv)``, ``int C diag(dtheta)``;  Ccc : (3, 6)  ``int C[:, r] dtheta_c`` per
    cross-coupling pair;  Cca : (3, 6)  ``int C[:, r] dv_c`` per accelerometer pair;
    th : (3,)  corrected angle over the interval (body) [rad]
    acc : (3,)  acceleration of the last IMU interval [m/s^2];  g_n : (3,)  gravitation at
    the current position [m/s^2]
    """

    P: np.ndarray
    dx: np.ndarray
    h: np.ndarray
    hz: np.ndarray
    PHt: np.ndarray
    Phi: np.ndarray
    T: np.ndarray
    qdiag: np.ndarray
    nnz: np.ndarray
    nzc: np.ndarray
    C: np.ndarray
    Cn: np.ndarray
    Lm: np.ndarray
    Xc: np.ndarray
    Xm: np.ndarray
    Cv: np.ndarray
    dvn: np.ndarray
    Cint: np.ndarray
    Cf: np.ndarray
    Cw: np.ndarray
    Ccc: np.ndarray
    Cca: np.ndarray
    th: np.ndarray
    acc: np.ndarray
    g_n: np.ndarray


class Epoch(NamedTuple):
    """The predicted quantities at one epoch that the measurement models share.

    Attributes
    ----------
    s, j : int  sequence (in the batch) and epoch
    k : int  IMU sample of the epoch
    started : bool  the sequence has been propagated (not its first epoch)
    still : bool  every sample since the previous epoch passed the ZUPT thresholds
    w_b : (3,) float  corrected angular rate at t_k, body [rad/s] (extrapolated from the last
        two intervals' means)
    """

    s: int
    j: int
    k: int
    started: bool
    still: bool
    w_b: tuple[float, float, float]


@njit(cache=True)
def new_work(n):
    """Zeroed :class:`Work` for an error state of size ``n``."""
    z33 = np.zeros((3, 3))
    return Work(
        np.zeros((n, n)), np.zeros(n), np.zeros(n), np.zeros(n, np.int64), np.zeros(n),
        np.zeros((n, n)), np.zeros((n, n)), np.zeros(n), np.zeros(n, np.int64),
        np.zeros((n, n), np.int64), z33, z33.copy(), z33.copy(), z33.copy(), z33.copy(),
        z33.copy(), np.zeros(3), z33.copy(), z33.copy(), z33.copy(), np.zeros((3, 6)),
        np.zeros((3, 6)), np.zeros(3), np.zeros(3), np.zeros(3),
    )  # fmt: skip
