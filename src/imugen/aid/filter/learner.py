"""What a learner gives the filter and what it sees of it (the plug-in API of issue 26).

* :class:`LearnedInputs` -- inputs known in advance, arrays (NaN where absent):

  - an **IMU correction** (``dtheta``, ``dv``, (S, K, 3)) subtracted from the increments
    before the filter, whose own bias, scale-factor and cross-coupling states then model what
    the learner leaves. The contract is a *total* correction (the learner's estimate of the
    whole effective error, ``err_dtheta``, ``err_dv`` of the shard) with a tuning of what it
    leaves (:meth:`imugen.aid.filter.tuning.Tuning.from_grade` with ``terms`` or a scaled
    grade): consistent, NEES/dof inside the chi-square bounds for a perfect and a partial
    correction. A correction re-targeted at the filter's *current* estimate (the error it
    leaves, :meth:`imugen.aid.filter.ekf.AidedResult.filter_aware_target`) cancels every
    bias update of the filter: its bias states no longer describe the data (velocity NEES/dof
    3-5, r26 study); that target is for training and as a feature;
  - a **learned body-frame velocity** of the IMU with its covariance (TLIO, RINS-W):
    :mod:`imugen.aid.filter.learned`;
  - **adaptive NHC noise** (AI-IMU): lateral and vertical variances per epoch.

* a **learner callable** ``learner(window, estimate) -> dict`` (:func:`imugen.aid.filter.run`,
  ``learner=``) run between compiled segments of epochs: it sees the raw increments up to the
  segment's end (:class:`LearnerWindow`) and the filter's estimate at the segment's start
  (:class:`FilterEstimate`), and returns a dict with keys of :class:`LearnedInputs` for the
  next segment only (``dtheta``, ``dv``: (b - a, k_hi - k_lo + 1, 3); the epoch arrays:
  (b - a, j1 - j0, ...)). The kernel resumes from its state (``x``, ``P``, sample, the ZUPT
  detector), so a learner returning nothing reproduces the plain run.

Body-frame displacement over a window (TLIO's measurement) needs the position at the window's
start as a stochastic clone (three states copied at the start, ``h = [I, -I]``): not built.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imugen.aid.filter.state import NOMINAL
from imugen.core.errors import InputError

LEARNED_KEYS = ("dtheta", "dv", "body_velocity", "body_velocity_cov", "nhc_var")
"""Keys a learner callable may return (the fields of :class:`LearnedInputs`)."""


@dataclass
class LearnedInputs:
    """A learner's inputs to the filter (every field optional, SI, body axes).

    Attributes
    ----------
    dtheta, dv : (S, K, 3)  IMU correction [rad, m/s] subtracted from the increments (row k:
        interval ending at t_k, as the shard's)
    body_velocity : (S, J, 3)  IMU velocity in body axes at each epoch [m/s] (NaN: none)
    body_velocity_cov : (S, J, 3, 3) or (S, J, 3)  its covariance (or variances) [m^2/s^2]
    nhc_var : (S, J, 2)  NHC variances (lateral, vertical) [m^2/s^2] replacing the slip's
        (NaN: keep the slip's)
    """

    dtheta: np.ndarray | None = None
    dv: np.ndarray | None = None
    body_velocity: np.ndarray | None = None
    body_velocity_cov: np.ndarray | None = None
    nhc_var: np.ndarray | None = None

    def epoch_arrays(self, S: int, J: int):
        """``(lv, lvW, nvar)`` for the kernel: (S, J, 3) velocities, (S, J, 3, 3) whitening
        ``L^-1`` of their covariances (``R = L L^T``), (S, J, 2) NHC variances; (S, 0, ...)
        when absent."""
        lv, lvW = np.zeros((S, 0, 3)), np.zeros((S, 0, 3, 3))
        if self.body_velocity is not None:
            lv = _shaped(self.body_velocity, (S, J, 3), "body_velocity")
            if self.body_velocity_cov is None:
                raise InputError("learned", "body_velocity needs body_velocity_cov")
            R = np.asarray(self.body_velocity_cov, float)
            if R.shape == (S, J, 3):
                R = R[..., None] * np.eye(3)
            R = _shaped(R, (S, J, 3, 3), "body_velocity_cov")
            given = np.isfinite(lv).all(-1)
            R = np.where(given[..., None, None], R, np.eye(3))
            try:
                lvW = np.linalg.inv(np.linalg.cholesky(R))
            except np.linalg.LinAlgError:
                raise InputError("learned", "body_velocity_cov is not positive definite") from None
            lv = np.where(given[..., None], lv, np.nan)
        nv = np.zeros((S, 0, 2))
        if self.nhc_var is not None:
            nv = _shaped(self.nhc_var, (S, J, 2), "nhc_var")
            if np.any(nv[np.isfinite(nv)] < 0):
                raise InputError("learned", "nhc_var must be >= 0")
        return lv, np.ascontiguousarray(lvW), nv


def _shaped(a, shape, name) -> np.ndarray:
    a = np.asarray(a, float)
    if a.shape != shape:
        raise InputError("learned", f"{name} must be {shape}, got {a.shape}")
    return np.ascontiguousarray(a)


@dataclass
class LearnerWindow:
    """What a learner callable sees of the inputs before a segment.

    Attributes
    ----------
    a, b : int  sequences ``a:b`` of the run (one chunk of the kernel)
    j0, j1 : int  epochs ``j0:j1`` of the coming segment
    k_lo, k_hi : int  the samples it may correct (inclusive): those the segment integrates
    dtheta, dv : (S, K, 3)  the raw increments of the whole run (a causal learner reads rows
        up to ``k_hi`` only)
    time_s : (J,)  epoch times [s];  index : (J,)  their IMU samples
    """

    a: int
    b: int
    j0: int
    j1: int
    k_lo: int
    k_hi: int
    dtheta: np.ndarray
    dv: np.ndarray
    time_s: np.ndarray
    index: np.ndarray


@dataclass
class FilterEstimate:
    """The filter's state at the start of a segment (sequences ``a:b``).

    Attributes
    ----------
    x : (b - a, NX)  nominal state (blocks of :data:`imugen.aid.filter.state.NOMINAL`)
    P : (b - a, n, n)  error covariance (:attr:`names`)
    k : (b - a,)  the sample each sequence has reached (before its start: its start sample)
    names : list of str  error-state names
    """

    x: np.ndarray
    P: np.ndarray
    k: np.ndarray
    names: list

    def nominal(self, key: str) -> np.ndarray:
        """Block ``key`` of the nominal state, (b - a, size)."""
        return self.x[:, NOMINAL.slice(key)]

    @property
    def gyro_bias(self) -> np.ndarray:
        """(b - a, 3) estimated gyro bias [rad/s]."""
        return self.nominal("bg")

    @property
    def accel_bias(self) -> np.ndarray:
        """(b - a, 3) estimated accelerometer bias [m/s^2]."""
        return self.nominal("ba")
