"""GNSS scenarios: every kind against its definition on a noiseless and a noisy receiver,
jamming noise against its stated variance (chi-square), draws reproducible and in range."""

import itertools
import math

import numpy as np
import pytest
from scipy.stats import chi2

from imugen.aid import gnss as G
from imugen.aid import scenarios as SC
from imugen.core.errors import InputError
from imugen.core.rotations import dcm_to_quat, euler_to_dcm

R, W, RATE = 50.0, 0.2, 100.0


def circle(T):
    """Car on a level circle (flat Earth), 100 Hz: time, p, v, q, omega."""
    t = np.arange(int(T * RATE) + 1) / RATE
    p = np.stack([R * np.cos(W * t), R * np.sin(W * t), 0.0 * t], -1)
    v = np.stack([-R * W * np.sin(W * t), R * W * np.cos(W * t), 0.0 * t], -1)
    q = dcm_to_quat(euler_to_dcm(0 * t, 0 * t, W * t + math.pi / 2))
    return t, p, v, q, np.tile([0.0, 0.0, W], (len(t), 1))


def quiet():
    cfg = {"id": 900, "rate_hz": 10.0, "latency_s": 0.0, "position_bias_tau_s": 60.0}
    for k in G.FIGURES:
        cfg.setdefault(k, 0.0)
    return G.receiver_from_config("quiet", cfg)


def fixes(M=1, receiver=None, T=120.0):
    t, p, v, q, w = circle(T=T)
    return G.simulate_gnss(t, p, v, q, w, receiver or quiet(), sequences=M, seed=5)


def test_outage_and_freeze_and_labels():
    g = fixes()
    r = SC.apply(
        g,
        [
            {"kind": "outage", "start_s": 30.0, "duration_s": 30.0},
            {"kind": "freeze", "start_s": 80.0, "duration_s": 10.0},
        ],
    )
    t = g.time_s
    out = (t >= 30.0) & (t < 60.0)
    assert np.all(r.gnss.fix[0, out] == 0) and np.all(np.isnan(r.gnss.p_n[0, out]))
    assert np.all(r.state[0, out] == 1) and np.all(r.gnss.fix[0, ~out] == g.fix[0, ~out])
    fr = (t >= 80.0) & (t < 90.0)
    k = np.flatnonzero(t < 80.0)[-1]
    np.testing.assert_array_equal(r.gnss.p_n[0, fr], np.broadcast_to(g.p_n[0, k], (fr.sum(), 3)))
    np.testing.assert_allclose(r.attack_p_n[0, fr], g.p_n[0, k] - g.p_n[0, fr])
    np.testing.assert_array_equal(r.state[0, fr], 8)
    rest = ~(out | fr)
    np.testing.assert_array_equal(r.gnss.p_n[0, rest], g.p_n[0, rest])
    assert list(r.intervals["kind"]) == ["outage", "freeze"]
    assert r.intervals["end_s"].tolist() == [60.0, 90.0]


def test_spoofing_offsets_follow_their_definitions():
    g = fixes()
    t = g.time_s
    az = math.radians(30.0)
    u = np.array([math.cos(az), math.sin(az), 0.0])
    cases = {
        "spoof_ramp": ({"rate_mps": 0.5, "azimuth_rad": az}, lambda x: 0.5 * x[:, None] * u),
        "spoof_step": ({"offset_m": 40.0, "azimuth_rad": az}, lambda x: 40.0 + 0 * x[:, None] * u),
        "spoof_oscillation": (
            {"amplitude_m": 8.0, "period_s": 20.0, "azimuth_rad": az},
            lambda x: 8.0 * np.sin(2 * math.pi * x / 20.0)[:, None] * u,
        ),
    }
    for kind, (prm, f) in cases.items():
        r = SC.apply(g, [{"kind": kind, "start_s": 20.0, "duration_s": 50.0, **prm}])
        m = (t >= 20.0) & (t < 70.0)
        want = f(t[m] - 20.0) * (u if kind == "spoof_step" else 1.0)
        np.testing.assert_allclose(r.gnss.p_n[0, m] - g.p_n[0, m], want, atol=1e-9)
        np.testing.assert_allclose(r.attack_p_n[0, m], want, atol=1e-9)
        # velocity offset is the time derivative of the position offset
        dvel = np.gradient(want, t[m], axis=0)
        np.testing.assert_allclose(r.attack_v_n[0, m][2:-2], dvel[2:-2], atol=2e-3 * 8)
        np.testing.assert_array_equal(r.gnss.sigma_p_n, g.sigma_p_n)
        assert np.all(r.state[0, m] == SC.KINDS[kind]) and np.all(r.state[0, ~m] == 0)


def test_meaconing_replays_the_antenna_late():
    g = fixes(receiver=G.get_receiver("standalone"))
    r = SC.apply(g, [{"kind": "meaconing", "start_s": 40.0, "duration_s": 30.0, "delay_s": 2.0}])
    t = g.time_s
    m = (t >= 40.0) & (t < 70.0)
    late = np.stack([np.interp(t[m] - 2.0, t, g.p_ant_n[0, :, a]) for a in range(3)], -1)
    noise = g.offset_p_n[0, m]
    np.testing.assert_allclose(r.gnss.p_n[0, m], late + noise, atol=1e-9)
    np.testing.assert_allclose(r.gnss.offset_p_n[0, m], r.gnss.p_n[0, m] - g.p_ant_n[0, m])


def test_jamming_inflates_sigmas_and_noise_then_loses_the_fix():
    M = 300
    g = fixes(M=M, receiver=G.get_receiver("standalone"), T=60.0)
    iv = {"kind": "jamming", "start_s": 10.0, "duration_s": 30.0, "degrade_s": 20.0}
    iv["sigma_factor"] = 11.0
    r = SC.apply(g, [iv], seed=2)
    t = g.time_s
    deg = (t >= 10.0) & (t < 30.0)
    lost = (t >= 30.0) & (t < 40.0)
    k = 1.0 + 10.0 * (t[deg] - 10.0) / 20.0
    np.testing.assert_allclose(r.gnss.sigma_p_n[:, deg], g.sigma_p_n[:, deg] * k[None, :, None])
    assert np.all(r.gnss.fix[:, lost] == 0) and np.all(r.state[:, lost] == 3)
    assert np.all(r.gnss.fix[:, deg] == 1) and np.all(r.state[:, deg] == 2)
    # the extra error has variance (k^2 - 1) sigma^2: chi-square over all epochs and sequences
    sel = k > 1.5
    extra = r.attack_p_n[:, deg][:, sel]
    var = (k[sel] ** 2 - 1.0)[None, :, None] * g.sigma_p_n[:, deg][:, sel] ** 2
    stat = np.sum(extra**2 / var)
    dof = extra.size
    assert chi2.ppf(0.001, dof) < stat < chi2.ppf(0.999, dof)


def test_draws_are_reproducible_independent_and_in_range():
    a = SC.draw(["outage", "spoof_ramp"], 600.0, seed=1, shard=0, sequences=50)
    b = SC.draw(["outage"], 600.0, seed=1, shard=0, sequences=3)
    # a kind's duration and parameters ignore the others (its start makes room for them)
    assert [(x[0].duration_s, x[0].params) for x in a[:3]] == [(x[0].duration_s, {}) for x in b]
    for o, s in a:  # the intervals of a sequence never overlap
        assert o.end_s <= s.start_s + 1e-9 or s.end_s <= o.start_s + 1e-9
    durs = {x[0].duration_s for x in a}
    assert durs <= set(SC.OUTAGE_PRESETS_S) and len(durs) >= 3
    for o, s in a:
        assert o.start_s >= 60.0 and o.end_s <= 600.0 + 1e-9
        assert 0.1 <= s.params["rate_mps"] <= 2.0 and 30.0 <= s.duration_s <= 120.0
    c = SC.draw(["outage"], 600.0, seed=1, shard=1, sequences=3)
    assert [x[0] for x in c] != [x[0] for x in b]


def test_bad_intervals_are_refused():
    g = fixes(T=10.0)
    with pytest.raises(InputError, match="kind must be"):
        SC.apply(g, [{"kind": "tunnel", "start_s": 1, "duration_s": 2}])
    with pytest.raises(InputError, match="unknown key"):
        SC.apply(g, [{"kind": "outage", "start_s": 1, "duration_s": 2, "rate_mps": 1}])
    with pytest.raises(InputError, match="missing rate_mps"):
        SC.apply(g, [{"kind": "spoof_ramp", "start_s": 1, "duration_s": 2}])


def test_every_kind_drawn_together_never_overlaps_and_labels_stay_exact():
    """Seven kinds in 600 s: the former independent starts overlapped in every sequence
    ("spoofed" epochs with no fix); now the intervals tile the free time and an epoch whose
    fix a scenario took is labelled a loss."""
    kinds = list(SC.KINDS)
    ivs = SC.draw(kinds, 600.0, seed=3, sequences=40)
    for seq in ivs:
        s = sorted((iv.start_s, iv.end_s) for iv in seq)
        assert all(b[0] >= a[1] - 1e-9 for a, b in itertools.pairwise(s))
        assert s[0][0] >= 60.0 - 1e-9 and s[-1][1] <= 600.0 + 1e-9
    g = fixes(M=40, receiver=G.get_receiver("standalone"), T=600.0)
    r = SC.apply(g, ivs, seed=3)
    lost = (r.gnss.fix == 0) & (g.fix > 0)  # the receiver had a fix, a scenario took it
    assert np.all(np.isin(r.state[lost], [1, 3]))
    assert not np.any(np.isin(r.state[~lost], [1, 3]))


def test_overlapping_declared_intervals_are_labelled_by_what_the_receiver_gives():
    g = fixes(M=2, receiver=G.get_receiver("standalone"), T=60.0)
    ivs = [
        {"kind": "outage", "start_s": 10.0, "duration_s": 20.0},
        {"kind": "spoof_ramp", "start_s": 20.0, "duration_s": 20.0, "rate_mps": 1.0},
    ]
    r = SC.apply(g, ivs)
    t = g.time_s
    both = (t >= 20.0) & (t < 30.0)
    after = (t >= 30.0) & (t < 40.0)
    assert np.all(r.gnss.fix[:, both] == 0) and np.all(r.state[:, both] == 1)
    assert np.all(r.gnss.fix[:, after] > 0) and np.all(r.state[:, after] == SC.KINDS["spoof_ramp"])
