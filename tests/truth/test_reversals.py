"""Untimed paths that double back are timed as a stop and a turn (issue 27)."""

from __future__ import annotations

import numpy as np
import pytest

from imugen import truth
from imugen.tables import truth as col
from imugen.truth.reversals import REVERSAL_STOP_S, find_reversals

ORIGIN = (46.0, 7.0, 500.0)


def _out_and_back(offset_m=0.0):
    """A rail line drawn out and back as one path: 3 km east on a gentle bend (vertices every
    25 m, climbing 0.2 %), then back along it ``offset_m`` to the side."""
    s = np.arange(0.0, 3000.0, 25.0)
    out = np.column_stack([s, 30.0 * np.sin(s / 600.0), 0.002 * s])
    back = out[::-1] + np.array([0.0, offset_m, 0.0])
    return np.vstack([out, back[1:]])


def test_reversals_are_found_where_the_path_turns_back_only():
    vp = truth.VEHICLES["car"]
    enu = _out_and_back()
    assert find_reversals(enu, vp) == [119]
    assert find_reversals(enu[:120], vp) == []  # the bend alone
    square = np.array([[0, 0, 0], [100, 0, 0], [100, 100, 0], [0, 100, 0], [0, 0, 0.0]])
    assert find_reversals(square, vp) == []  # right angles are corners, not reversals


@pytest.mark.parametrize("offset_m", [0.0, 2.0])
def test_doubled_back_untimed_path_stops_and_turns(offset_m):
    """Issue 27: the out-and-back rail line was a creep then a U-turn at full speed (207 m/s^2
    and a specific force of 338 m/s^2 on this shape); now it brakes to rest at the far end,
    waits, turns as it pulls away and comes back, within the car's limits."""
    vp = truth.VEHICLES["car"]
    df, meta = truth.enu_table(_out_and_back(offset_m), None, ORIGIN)
    tr, m = truth.build_truth(df, meta, rate_hz=10.0, earth="flat", vehicle="car", verbose=False)
    assert m["timing"]["reversals"] == 1
    t = tr[col.TIME].to_numpy()
    v = tr[list(col.VEL)].to_numpy()
    acc = np.linalg.norm(np.diff(v, axis=0), axis=1) / np.diff(t)
    assert acc.max() <= vp.max_accel_mps2
    f = np.linalg.norm(tr[list(col.ACCEL)].to_numpy(), axis=1)
    assert f.max() <= np.hypot(9.81, vp.max_accel_mps2) + 0.1
    rep = m["plausibility"]
    assert rep["warnings"] == [] and rep["max_attitude_step_excess_rad"] < 1e-4
    # at rest at the far end for the stop, not creeping for hours: about two legs at cruise
    speed = np.linalg.norm(v[:, :2], axis=1)
    far = tr[col.POS[0]].to_numpy() > 2900.0
    assert (far & (speed < 0.01)).sum() / 10.0 >= REVERSAL_STOP_S - 1.0
    assert t[-1] < 2 * 3000.0 / vp.cruise_mps + 120.0
    # facing back West once on its way back
    yaw = tr[col.EULER[2]].to_numpy()
    late = (t > t[-1] - 150.0) & (t < t[-1] - 60.0)
    assert np.all(np.cos(yaw[late]) < -0.9)
