"""Loosely-coupled GNSS/INS: a batched error-state Kalman filter on the project's increments.

The filter integrates each sequence's IMU increments with its own strapdown (the nominal
state) and keeps the covariance of the error state (estimate minus truth); at each GNSS epoch
the measurements update the error state, which is fed back into the nominal state and reset.
Frames and conventions are the package's (:mod:`imugen`): n the navigation frame of the
route's :class:`~imugen.core.earth.OriginFrame` (ECEF in ``geodetic``), b the body, SI units.

The house (one subject per module):

* :mod:`~imugen.aid.filter.state` -- the state's blocks and every offset
  (:class:`StateLayout`, :func:`state_names`);
* :mod:`~imugen.aid.filter.options`, :mod:`~imugen.aid.filter.tuning` -- switches and the
  noise model from a grade's full error model (:class:`Options`, :class:`Tuning`);
* :mod:`~imugen.aid.filter.align` -- the start: alignment, initial state and covariance;
* :mod:`~imugen.aid.filter.propagate` (the strapdown) and
  :mod:`~imugen.aid.filter.error_model` (``Phi``, ``Q``) -- from one epoch to the next;
* one module per measurement -- :mod:`~imugen.aid.filter.gnss` (position, velocity, lever
  arm), :mod:`~imugen.aid.filter.zupt`, :mod:`~imugen.aid.filter.nhc`,
  :mod:`~imugen.aid.filter.odometer`, :mod:`~imugen.aid.filter.baro` -- each a compiled
  ``update`` building its rows for the shared :mod:`~imugen.aid.filter.kalman` update,
  registered in :mod:`~imugen.aid.filter.measurements` (a new measurement is a new module
  plus its line there);
* :mod:`~imugen.aid.filter._kernel` -- the compiled time loop (propagate -> updates ->
  feedback), :mod:`~imugen.aid.filter.context` its named tuples;
* :mod:`~imugen.aid.filter.ekf` -- :func:`run` over a batch of sequences and its
  :class:`AidedResult`;
* :mod:`~imugen.aid.filter.learner` -- what a learner plugs in (:class:`LearnedInputs`, a
  callable between compiled segments) and :mod:`~imugen.aid.filter.learned` its
  measurement (a body-frame velocity).

An optional innovation gate (``Options.gate_sigma``) rejects a scalar update whose normalized
innovation exceeds it (GNSS, odometer, barometer). In ``geodetic`` the output sigmas of
position, velocity and attitude are along the local East, North, Up at the estimate (the
stored ``P`` stays in n).
"""

from imugen.aid.filter.align import (
    HEADING_SD_RAD,
    LEVEL_SD_RAD,
    Initial,
    align,
    initial_covariance,
    initial_state,
)
from imugen.aid.filter.baro import F_BARO
from imugen.aid.filter.ekf import AidedResult, attitude_error, run
from imugen.aid.filter.gnss import F_GNSS_P, F_GNSS_V
from imugen.aid.filter.kalman import F_REJECT
from imugen.aid.filter.learned import F_LEARNED
from imugen.aid.filter.learner import FilterEstimate, LearnedInputs, LearnerWindow
from imugen.aid.filter.measurements import F_ALIGNED, FLAGS
from imugen.aid.filter.nhc import F_NHC
from imugen.aid.filter.odometer import F_ODO
from imugen.aid.filter.options import Options
from imugen.aid.filter.state import CC_PAIRS, NOMINAL, NX, StateLayout, state_names
from imugen.aid.filter.tuning import (
    LEVELS,
    MOTION_CORR_S,
    N_TUNE,
    T_GB_SD,
    T_GW,
    Tuning,
    companion_tuning,
    law_mean,
    law_rms,
    tuning_matrix,
)
from imugen.aid.filter.zupt import F_ZUPT

__all__ = [
    "CC_PAIRS",
    "FLAGS",
    "F_ALIGNED",
    "F_BARO",
    "F_GNSS_P",
    "F_GNSS_V",
    "F_LEARNED",
    "F_NHC",
    "F_ODO",
    "F_REJECT",
    "F_ZUPT",
    "HEADING_SD_RAD",
    "LEVELS",
    "LEVEL_SD_RAD",
    "MOTION_CORR_S",
    "NOMINAL",
    "NX",
    "N_TUNE",
    "T_GB_SD",
    "T_GW",
    "AidedResult",
    "FilterEstimate",
    "Initial",
    "LearnedInputs",
    "LearnerWindow",
    "Options",
    "StateLayout",
    "Tuning",
    "align",
    "attitude_error",
    "companion_tuning",
    "initial_covariance",
    "initial_state",
    "law_mean",
    "law_rms",
    "run",
    "state_names",
    "tuning_matrix",
]
