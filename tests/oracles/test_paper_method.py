"""Oracles for benchmarks/paper_method.py (the paper's forward-difference + Euler baseline)."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "paper_method.py"
if not _PATH.exists():
    pytest.skip("benchmarks/paper_method.py not present", allow_module_level=True)
_spec = importlib.util.spec_from_file_location("paper_method", _PATH)
pm = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("paper_method", pm)
_spec.loader.exec_module(pm)

G0 = 9.79


def climbing_turn(t):
    """Helix-like 3-D path with varying speed: p, v, a (closed forms), each (K, 3)."""
    R, w, c = 40.0, 0.05, 0.3
    s = t + 0.02 * t**2  # phase argument, speed increases
    sd = 1.0 + 0.04 * t
    sdd = 0.04
    th = w * s
    p = np.stack([R * np.sin(th), R * (1 - np.cos(th)), c * s], axis=1)
    v = np.stack([R * w * np.cos(th) * sd, R * w * np.sin(th) * sd, c * sd], axis=1)
    a = np.stack(
        [
            -R * w * w * np.sin(th) * sd**2 + R * w * np.cos(th) * sdd,
            R * w * w * np.cos(th) * sd**2 + R * w * np.sin(th) * sdd,
            np.full_like(t, c * sdd),
        ],
        axis=1,
    )
    return p, v, a


def test_forward_euler_is_the_discrete_dual_of_the_synthesis():
    dt = 0.1
    t = np.arange(0.0, 120.0 + dt / 2, dt)
    p, _, _ = climbing_turn(t)
    imu = pm.synthesize(p, dt, G0)
    P, V, E = pm.mechanize(imu.gyro_b, imu.accel_b, dt, G0, p[0], imu.v_n[0], imu.euler[0])
    n = len(P)
    assert n == len(t) - 1
    scale = np.max(np.abs(p))
    assert np.max(np.abs(P - p[:n])) < 1e-9 * scale  # closes to rounding, by construction
    assert np.max(np.abs(V - imu.v_n)) < 1e-9
    assert np.max(np.abs(E - imu.euler)) < 1e-10


def test_sample_offsets_of_forward_differences():
    """Constant acceleration: v_k is exact at t_k + dt/2 and a_k (f_b) is exact.
    Constant jerk along a line: f_b at 'sample t_k' is the true f_b at t_{k+1}."""
    dt = 0.5
    t = np.arange(0.0, 20.0 + dt / 2, dt)
    u = np.array([3.0, 4.0, 0.0]) / 5.0  # heading: North-East, level
    a0, j = 0.7, 0.05
    v0 = 2.0
    # constant acceleration
    p = (v0 * t + 0.5 * a0 * t**2)[:, None] * u
    imu = pm.synthesize(p, dt, G0)
    tm = t[:-1] + dt / 2
    np.testing.assert_allclose(imu.v_n, (v0 + a0 * tm)[:, None] * u, rtol=0, atol=1e-11)
    np.testing.assert_allclose(imu.accel_b, np.tile([a0, 0.0, G0], (len(t) - 2, 1)), atol=1e-9)
    np.testing.assert_allclose(imu.gyro_b, 0.0, atol=1e-12)
    # constant jerk: f_x(t) = a0 + j t; the forward second difference gives a0 + j t_{k+1}
    p = (v0 * t + 0.5 * a0 * t**2 + j * t**3 / 6.0)[:, None] * u
    imu = pm.synthesize(p, dt, G0)
    fx_true = a0 + j * t[:-2]
    np.testing.assert_allclose(imu.accel_b[:, 0], fx_true + j * dt, rtol=0, atol=1e-9)
    assert np.max(np.abs(imu.accel_b[:, 0] - fx_true)) == pytest.approx(j * dt, rel=1e-6)


def test_left_turn_signs_and_first_order_error():
    """Level left turn at speed v, rate w: gyro_z ~ +w, f_y ~ +v w, errors O(dt)."""
    v, w = 10.0, 0.1
    for dt, tol in ((0.1, 0.02), (0.01, 0.002)):
        t = np.arange(0.0, 30.0 + dt / 2, dt)
        R = v / w
        p = np.stack([R * np.sin(w * t), R * (1 - np.cos(w * t)), 0 * t], axis=1)
        imu = pm.synthesize(p, dt, G0)
        np.testing.assert_allclose(imu.gyro_b[:, 2], w, rtol=1e-9)
        # |f| is right to O((w dt)^2), but a_k points at the heading of t_{k+1} while the body
        # axes follow the chord heading of t_k + dt/2: f_x = -v w sin(w dt / 2) = O(dt)
        assert np.allclose(imu.accel_b[:, 1], v * w, rtol=tol)
        assert np.allclose(imu.accel_b[:, 0], 0.0, atol=v * w * math.sin(w * dt / 2) * 1.01)
        assert np.max(np.abs(imu.accel_b[:, 0])) > 0.5 * v * w * math.sin(w * dt / 2)
        np.testing.assert_allclose(imu.accel_b[:, 2], G0, atol=1e-9)
