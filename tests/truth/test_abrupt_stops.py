"""Abrupt stops of sparse timed fixes (issue 27, "a truth is physical"): a car logged at 1 Hz
that brakes to rest within its last second before the stop. The truth brakes monotonically
into the stop (no speed bounce: a smoothing spline that rounds the stop speeds up before it to
make up the distance), within the car's acceleration and jerk limits, and stands exactly
still, horizontally and vertically, while stopped."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen import truth
from imugen.core import rotations as rot
from imugen.tables import truth as col
from imugen.truth import fit as tfit

ORIGIN = (45.0, 7.0, 300.0)
NOISE_H_M = 0.5  # per horizontal axis
NOISE_U_M = 0.3
GRADE = 0.03  # the road climbs 3 %: the vertical moves with the distance, and must stop too


def _abrupt_stop(v0, seed):
    """1 Hz fixes: ``v0`` m/s up to the fix at 59 s, braking to rest within the next second
    (the stop's first fix at 60 s), still until 90 s, then pulling away at 2 m/s^2."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 120.0)
    u = np.clip(t - 90.0, 0.0, None)
    s = np.where(t <= 59.0, v0 * t, v0 * 59.0 + 0.5 * v0)
    s = s + np.where(u < v0 / 2.0, u * u, (v0 / 2.0) ** 2 + v0 * (u - v0 / 2.0))
    enu = np.column_stack([s, np.zeros_like(s), GRADE * s])
    return t, enu + rng.normal(0.0, 1.0, enu.shape) * [NOISE_H_M, NOISE_H_M, NOISE_U_M]


def _speed_allowance(dt=1.0):
    """Two standard deviations of a fix-to-fix speed (one axis): the fixes' own speed noise."""
    return 2.0 * math.sqrt(2.0) * NOISE_H_M / dt


def _build(v0, seed):
    t, enu = _abrupt_stop(v0, seed)
    df, meta = truth.enu_table(enu, t, ORIGIN)
    return truth.build_truth(
        df,
        meta,
        rate_hz=20,
        earth="flat",
        verbose=False,
        vehicle="car",
        # the road profile is the subject: the rigid car's attitude is the path's (on its
        # suspension the body dives braking into the stop, tests/truth/test_road.py)
        vehicle_params={"suspension": "rigid"},
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_an_abrupt_stop_brakes_monotonically_and_stands_still(seed):
    """5.7 m/s to rest within one 1 s interval of fixes (5.7 m/s^2). Before, the fit's speed
    bounced to 10.2 m/s (then 8.8) before the stop; now it stays within the fixes' speed plus
    their noise (2 sigma of a fix-to-fix speed, 1.41 m/s), falls monotonically from the last
    fix before the stop to rest, stands exactly still (horizontal and vertical) while stopped,
    keeps within the car's acceleration and jerk limits (the gate finds nothing) and its body
    does not move vertically against the road's 3 % grade."""
    v0 = 5.7
    tr, meta = _build(v0, seed)
    assert meta["gate"] == []
    stops = meta["fit"]["stops"]
    ((a, b),) = [s for s in stops if s[0] > 50.0]
    assert 60.0 <= a <= 62.0 and 88.0 <= b <= 91.0
    tt = tr[col.TIME].to_numpy()
    v = tr[list(col.VEL)].to_numpy()
    speed = np.hypot(v[:, 0], v[:, 1])
    approach = (tt > 40.0) & (tt < a)
    assert speed[approach].max() < v0 + _speed_allowance()
    braking = (tt >= 59.0) & (tt <= a)
    assert np.all(np.diff(speed[braking]) <= 1e-9)
    still = (tt >= a) & (tt <= b)
    assert np.abs(v[still]).max() == 0.0  # horizontal and vertical
    assert np.ptp(tr[list(col.POS)].to_numpy()[still], axis=0).max() < 1e-9
    vp = truth.VEHICLES["car"]
    plaus = meta["plausibility"]
    assert plaus["max_accel_mps2"] <= vp.max_accel_mps2
    assert plaus["max_jerk_mps3"] <= vp.max_jerk_mps3
    # the vertical follows the road profile into the stop and out of it: its knots are finer
    # around the stop's edges (one per 1 s fix: 0.014 m/s of body vertical speed braking in)
    assert meta["fit"]["vertical"]["max_departure_m"] < 1e-4
    q = tr[list(col.QUAT)].to_numpy()
    vb = np.einsum("kji,kj->ki", rot.quat_to_dcm(q), v)
    assert np.abs(vb[:, 2]).max() < 5e-5


def test_the_join_at_a_stop_has_zero_speed_and_acceleration():
    """The timed spline joins a stop inside the route through a triple knot: velocity and
    acceleration are zero at the stop's edges (C2), the jerk free; the simple knot of before
    joined it C4 and left one free coefficient on the last interval (``c (t_stop - t)^5``)."""
    t, enu = _abrupt_stop(5.7, 0)
    motion, rep = tfit.fit_timed(t, enu, truth.VEHICLES["car"])
    for a, b in rep["stops"]:
        for edge, side in ((a, -1e-9), (b, 1e-9)):
            if t[0] < edge < t[-1]:
                x = np.array([edge + side])
                assert np.abs(motion.spline(x, 1)).max() < 1e-6
                assert np.abs(motion.spline(x, 2)).max() < 1e-5
    # knots of multiplicity 3 at the edges inside the route
    knots, counts = np.unique(motion.spline.t, return_counts=True)
    for a, b in rep["stops"]:
        for edge in (a, b):
            if t[0] < edge < t[-1]:
                assert counts[np.searchsorted(knots, edge)] == tfit.STOP_JOIN_MULTIPLICITY


def test_a_stop_harder_than_the_car_brakes_keeps_to_its_limits():
    """10.2 m/s to rest within the last second of fixes asks for 10.2 m/s^2, beyond the car's
    8: the stop's start moves a fix into the stop (its first fix within the noise of the stop's
    position, the car still braking) and the truth brakes within the car's limits, within
    about 3 noise estimates of every fix, without a bounce beyond the fixes' speed noise."""
    v0 = 10.2
    tr, meta = _build(v0, 0)
    assert meta["gate"] == []
    fit = meta["fit"]
    ((a, _),) = [s for s in fit["stops"] if s[0] > 50.0]
    assert a == 61.0  # the fix at 60 s: the car still braking, within the noise of the stop
    assert fit["max_distance_m"] < 3.0 * math.hypot(NOISE_H_M, NOISE_H_M) + 0.5
    tt = tr[col.TIME].to_numpy()
    speed = np.hypot(*tr[list(col.VEL)].to_numpy()[:, :2].T)
    assert speed[(tt > 40.0) & (tt < a)].max() < v0 + _speed_allowance()
    vp = truth.VEHICLES["car"]
    assert meta["plausibility"]["max_accel_mps2"] <= vp.max_accel_mps2
    assert meta["plausibility"]["max_jerk_mps3"] <= vp.max_jerk_mps3
