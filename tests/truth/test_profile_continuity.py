"""The speed profile's distance s(t) is continuous at its 0.02 s joints to an ulp, so the
truth's position is the integral of its velocity on routes of any length (the cause of the
84-minute residual of the damped closure on the 264 km road and the Pacific route)."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PPoly

from imugen.truth.profile import continuous


def _steady_run(n=500_000, h=0.02, v=13.9, s0=1.2e5):
    """Distance of a steady 13.9 m/s run in 0.02 s pieces from 120 km (past 2^17 m), chained
    as PPoly.antiderivative chains a speed profile's."""
    speed = PPoly(np.array([[0.0] * n, [v] * n]), h * np.arange(n + 1.0))
    s = speed.antiderivative(1)
    s.c[-1] += s0
    return s, n * h * v


def test_antiderivative_chain_drifts_and_continuous_does_not():
    s, exact = _steady_run()
    t_end = s.x[-1]
    drift = abs(float(s(t_end) - s(0.0)) - exact)
    fixed = continuous(s)
    err = abs(float(fixed(t_end) - fixed(0.0)) - exact)
    assert drift > 1e-7  # the chained constants step one way at every joint
    assert err < 1e-9
    # every joint within an ulp of the piece before it
    c, h = fixed.c, np.diff(fixed.x)
    end = c[-1, :-1] + c[-2, :-1] * h[:-1]
    assert np.max(np.abs(c[-1, 1:] - end)) <= 2 * np.spacing(2.0 * (1.2e5 + exact))
    # within the pieces nothing changes
    np.testing.assert_array_equal(fixed.c[:-1], s.c[:-1])
