"""The climb of an untimed airliner's flight plan is smooth (issue 27): its height is the exact
inverse of the distance flown (:class:`imugen.truth.flight._Climb`), so the flight geometry
has no ripple in its vertical acceleration that a 10 Hz IMU cannot integrate (a linear
interpolation on a grid of heights left kinks of 1.7e-4 m every ~50 m: a 2 mg vertical
acceleration at ~4 Hz at 200 m/s, and a 1.4e-5 m error of the 10 Hz position rule on the
Pacific route's climb)."""

import numpy as np
import pytest

from imugen.truth.flight import FlightPlan, _Climb
from imugen.truth.vehicles import VEHICLES

VP = VEHICLES["airliner"]


def test_climb_distance_and_height_are_exact_inverses():
    pts = ([100.0, 3148.0, 10668.0], [80.0, 128.6, 236.0])
    c = _Climb(pts, 10.0)
    x = np.linspace(0.0, 12_000.0, 20_001)
    d = c.distance(x)
    np.testing.assert_allclose(c.height(d), x, rtol=0, atol=1e-9)
    # the distance is the integral of v / roc (trapezoid on a fine grid, v linear in pieces)
    xf = np.linspace(0.0, 12_000.0, 1_200_001)
    v = np.interp(100.0 + xf, *pts)
    df = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(xf))]) / 10.0
    assert np.max(np.abs(np.interp(x, xf, df) - d)) < 1e-3
    # a schedule without speed change: a straight climb
    c0 = _Climb(([0.0, 1.0], [100.0, 100.0]), 5.0)
    np.testing.assert_allclose(c0.height(np.array([0.0, 200.0, 5e4])), [0.0, 10.0, 2500.0])


def test_plan_climb_has_no_ripple():
    """Fourth differences of the plan's height on its 25 m grid along the climb (away from the
    transitions and the schedule's breakpoint): ~0 for a smooth height, ~1e-4 m with kinks."""
    plan = FlightPlan(7_600e3, 20.0, 5.0, VP)
    r = plan.report
    d, h = plan.d, plan.h
    w = r["transitions_m"]
    d4 = np.abs(h[4:] - 4 * h[3:-1] + 6 * h[2:-2] - 4 * h[1:-3] + h[:-4])
    dm = d[2:-2]
    hm = h[2:-2]
    climb = (dm > r["lift_off_m"] + w[0] + 100.0) & (dm < r["top_of_climb_m"] - w[1])
    brk = np.abs(hm - (20.0 + VP.speed_limit_alt_m)) < 200.0  # the schedule's kink
    sel = climb & ~brk
    assert sel.sum() > 3000
    print(f"max 4th difference on the climb: {d4[sel].max():.2e} m")
    assert d4[sel].max() < 1e-7  # the smooth climb's own: 2e-8 m near lift-off


@pytest.mark.parametrize("v_mps", [150.0, 230.0])
def test_flight_geometry_vertical_acceleration_has_no_ripple(v_mps):
    """The geometry's vertical acceleration at a climb speed: its ripple (against a 200 m
    running mean) stays below 1e-4 m/s^2 (0.9-2.2e-2 m/s^2 before the exact climb)."""
    from scipy.interpolate import make_interp_spline

    plan = FlightPlan(1_000e3, 20.0, 5.0, VP)
    r = plan.report
    w = r["transitions_m"]
    G = make_interp_spline(plan.d, plan.h, k=5)  # as flight_geometry lifts the ground path
    hb = 20.0 + VP.speed_limit_alt_m  # the schedule's kink: the climb on each side of it
    s = np.arange(r["lift_off_m"] + w[0], r["top_of_climb_m"] - w[1], 1.0)
    hs = G(s)
    k = 200  # 4 periods of the old ripple (2 grid steps, 50 m)
    ripple = 0.0
    for part in (s[hs < hb - 500.0], s[hs > hb + 500.0]):
        a = G.derivative(2)(part) * v_mps**2
        mean = np.convolve(a, np.ones(k) / k, mode="same")[k:-k]
        ripple = max(ripple, float(np.abs(a[k:-k] - mean).max()))
    print(f"{v_mps} m/s: vertical acceleration ripple {ripple:.2e} m/s^2")
    assert ripple < 1e-4
