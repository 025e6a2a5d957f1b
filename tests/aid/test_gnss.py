"""GNSS receiver model: lever arm and latency against an analytic circle, noise statistics
against their laws (standard errors stated), seeding."""

import math

import numpy as np
import pytest

from imugen.aid import gnss
from imugen.core.errors import InputError
from imugen.core.rotations import dcm_to_quat, euler_to_dcm

R, W, RATE = 50.0, 0.2, 100.0  # circle radius [m], turn rate [rad/s], IMU rate [Hz]


def circle(T=60.0, t0=0.0):
    """Car on a level circle (flat Earth): body x along the velocity, constant yaw rate."""
    t = t0 + np.arange(int(T * RATE) + 1) / RATE
    p = np.stack([R * np.cos(W * t), R * np.sin(W * t), 0.0 * t], -1)
    v = np.stack([-R * W * np.sin(W * t), R * W * np.cos(W * t), 0.0 * t], -1)
    yaw = W * t + math.pi / 2
    q = dcm_to_quat(euler_to_dcm(0 * t, 0 * t, yaw))
    w = np.tile([0.0, 0.0, W], (len(t), 1))
    return t, p, v, q, w


def exact_antenna(t, lb):
    """Closed-form antenna position and velocity on the circle."""
    yaw = W * t + math.pi / 2
    C = euler_to_dcm(0 * t, 0 * t, yaw)
    p = np.stack([R * np.cos(W * t), R * np.sin(W * t), 0.0 * t], -1) + C @ lb
    # d/dt (C l) = C (w x l)
    v = np.stack([-R * W * np.sin(W * t), R * W * np.cos(W * t), 0.0 * t], -1)
    v = v + C @ np.cross([0.0, 0.0, W], lb)
    return p, v


def quiet(latency=0.0, rate=10.0):
    cfg = {"id": 900, "rate_hz": rate, "latency_s": latency}
    for k in gnss.FIGURES:
        cfg.setdefault(k, 0.0)
    cfg["position_bias_tau_s"] = 60.0
    return gnss.receiver_from_config("quiet", cfg)


def test_lever_arm_and_latency_match_closed_form():
    t, p, v, q, w = circle()
    lb = np.array([1.5, -0.4, 1.2])
    for lat in (0.0, 0.05, 0.137):
        g = gnss.simulate_gnss(t, p, v, q, w, quiet(lat), lever_arm_b_m=lb)
        ok = g.valid[0]
        assert ok.sum() == len(g.time_s) - math.ceil(lat * 10 - 1e-9)
        pe, ve = exact_antenna(g.time_s - lat, lb)
        # Hermite interpolation between 100 Hz samples: O(dt^4) position error
        np.testing.assert_allclose(g.p_n[0, ok], pe[ok], atol=1e-6)
        np.testing.assert_allclose(g.v_n[0, ok], ve[ok], atol=1e-4)
        assert np.all(np.isnan(g.p_n[0, ~ok])) and np.all(g.fix[0, ~ok] == 0)


def test_noise_statistics_follow_the_model():
    t, p, v, q, w = circle(T=300.0)
    g = gnss.simulate_gnss(t, p, v, q, w, "standalone", sequences=200, seed=3, draw="nominal")
    f = g.receiver.figures
    ok = g.valid
    np.testing.assert_allclose((g.p_n - g.p_ant_n)[ok], g.offset_p_n[ok], atol=1e-9)
    b = g.bias_n
    white = g.offset_p_n - b
    J = b.shape[1]
    sw = np.array([f["position_white_h_m"].value] * 2 + [f["position_white_v_m"].value])
    sb = np.array([f["position_bias_h_m"].value] * 2 + [f["position_bias_v_m"].value])
    su = np.array([f["velocity_white_h_mps"].value] * 2 + [f["velocity_white_v_mps"].value])
    # white: M*J samples per axis -> relative s.e. of the std 1/sqrt(2 M J) = 0.1 %
    np.testing.assert_allclose(white.std(axis=(0, 1)), sw, rtol=0.01)
    np.testing.assert_allclose(g.offset_v_n.std(axis=(0, 1)), su, rtol=0.01)
    # GM bias at a fixed epoch: M independent draws of N(0, s_b^2) -> s.e. 5 %; use 4 epochs
    ends = b[:, [0, J // 3, 2 * J // 3, J - 1]]
    np.testing.assert_allclose(np.sqrt(np.mean(ends**2, axis=(0, 1))), sb, rtol=0.12)
    # lag-1 autocorrelation phi = exp(-T/tau)
    phi = math.exp(-0.1 / f["position_bias_tau_s"].value)
    r = np.sum(b[:, 1:] * b[:, :-1]) / np.sum(b[:, :-1] ** 2)
    assert r == pytest.approx(phi, abs=1e-3)
    # innovations of the GM recursion are white with variance s_b^2 (1 - phi^2)
    e = b[:, 1:] - phi * b[:, :-1]
    np.testing.assert_allclose(e.std(axis=(0, 1)), sb * math.sqrt(1 - phi**2), rtol=0.01)
    np.testing.assert_allclose(g.sigma_p_n[0, 0], np.sqrt(sw**2 + sb**2))


def test_seeding_per_sequence_and_draw_ranges():
    t, p, v, q, w = circle(T=20.0)
    a = gnss.simulate_gnss(t, p, v, q, w, "phone", sequences=5, seed=7, shard=2)
    b = gnss.simulate_gnss(t, p, v, q, w, "phone", sequences=2, seed=7, shard=2)
    np.testing.assert_array_equal(a.p_n[:2], b.p_n)  # a sequence does not depend on M
    c = gnss.simulate_gnss(t, p, v, q, w, "phone", sequences=2, seed=7, shard=3)
    assert not np.allclose(c.p_n, b.p_n, equal_nan=True)
    rec = gnss.get_receiver("phone")
    for k in gnss.FIGURES:
        fig = rec.figures[k]
        col = a.labels[f"gnss_{k}"].to_numpy()
        assert np.all((col >= fig.lo) & (col <= fig.hi)), k
    assert len(np.unique(a.labels["gnss_position_bias_h_m"])) == 5
    assert a.time_s[1] - a.time_s[0] == pytest.approx(1.0)  # phone preset: 1 Hz


def test_presets_and_errors():
    assert set(gnss.presets()) == {"phone", "standalone", "sbas", "rtk"}
    assert [r.fix_quality for r in gnss.presets().values()] == [1, 1, 2, 4]
    t, p, v, q, w = circle(T=5.0)
    with pytest.raises(InputError, match="integer multiple"):
        gnss.simulate_gnss(t, p, v, q, w, "standalone", rate_hz=3.0)
    with pytest.raises(InputError, match="unknown receiver"):
        gnss.get_receiver("survey")


def test_labels_carry_global_sequence_ids_beyond_int32():
    """A route id beyond 0 puts global ids past 2^31 (``route_id << 31 | index``): the labels
    keep them whole (an int32 cast wrapped them negative)."""
    t, p, v, q, w = circle(T=5.0)
    first = (3 << 31) + 4
    g = gnss.simulate_gnss(t, p, v, q, w, "phone", sequences=2, seed=7, first=first)
    assert g.labels["sequence"].to_numpy().tolist() == [first, first + 1]
