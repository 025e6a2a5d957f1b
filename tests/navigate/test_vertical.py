"""The damped vertical channel (imugen.navigate.vertical, the kernel's height loop): closed-form
loop responses, the free channel's growth, the default rule and zero-error closure of a long
route."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from imugen.core import earth as E
from imugen.navigate import mechanize as M
from imugen.navigate import vertical as V

from oracles.strapdown import exact_increments

WGS = E.OriginFrame.from_deg(45.0, 7.0, 300.0, model="wgs84")


def still(frame, span, dt):
    """Exact increments of a vehicle standing level at the origin for ``span`` s."""
    t = np.arange(0.0, span + 1e-9, dt)

    def pos(tt):
        return np.zeros((len(tt), 3))

    def att(tt):
        return np.tile([1.0, 0.0, 0.0, 0.0], (len(tt), 1))

    dth, dv = exact_increments(t, pos, pos, att, frame)
    return t, dth, dv


def height_errors(frame, span, dt, gains, dh0=0.0, dv0=0.0, bias=0.0):
    """Still vehicle, navigation started ``dh0`` m high, ``dv0`` m/s rising, accelerometer
    bias ``bias`` m/s^2 on body z; reference = the true height. Returns (t, dh(t))."""
    t, dth, dv = still(frame, span, dt)
    dv = dv.copy()
    dv[:, 2] += bias * dt
    h_true = M.reference_heights(np.zeros((1, 3)), frame)[0]
    href = np.full((1, len(t)), h_true)
    every = round(M.GRAVITY_NODE_S / dt)  # the loop's updates (at the samples before them)
    nav = M.mechanize(dth, dv, dt, [0.0, 0.0, dh0], [0.0, 0.0, dv0], [1.0, 0, 0, 0], frame,
                      outputs=("p",), every=every, gains=gains, href=href)  # fmt: skip
    return t[::every], M.reference_heights(nav.p_n, frame) - h_true


def linear_response(gains, gamma, t, dh0, dv0, bias):
    """The continuous loop's height error from (dh0, dv0, b = 0) with a bias: closed form
    (matrix exponential of the error dynamics (dh, dv, b, da))."""
    k1, k2, k3 = gains
    A = np.array([[-k1, 1.0, 0.0, 0.0], [gamma - k2, 0.0, -1.0, 1.0], [k3, 0.0, 0.0, 0.0],
                  [0.0, 0.0, 0.0, 0.0]])  # fmt: skip
    x0 = np.array([dh0, dv0, 0.0, bias])
    return np.array([(expm(A * tt) @ x0)[0] for tt in t])


def discrete_response(gains, gamma, n, dh0, dv0, bias, T=M.GRAVITY_NODE_S):
    """The kernel's loop in closed form: the free channel (dh'' = gamma dh + da) over T, then
    the impulses b += k3 dh T, dh -= k1 dh T, dv -= (k2 dh + b) T at every node but the first;
    the height error at the n nodes (before their impulse)."""
    k1, k2, k3 = gains
    F = expm(np.array([[0.0, 1.0, 0.0, 0.0], [gamma, 0.0, 0.0, 1.0], [0.0] * 4, [0.0] * 4]) * T)
    J = np.array([[1.0 - k1 * T, 0.0, 0.0, 0.0], [-(k2 + k3 * T) * T, 1.0, -T, 0.0],
                  [k3 * T, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])  # fmt: skip
    x = np.array([dh0, dv0, 0.0, bias])
    out = [x[0]]
    x = F @ x
    for _ in range(n - 1):
        out.append(x[0])
        x = F @ (J @ x)
    return np.array(out)


GAMMA = V.gravity_gradient_up(WGS.lat0_rad, WGS.h0_m)


@pytest.mark.parametrize(
    ("order", "tau", "dh0", "dv0"),
    [(3, 100.0, 1.0, 0.0), (3, 100.0, 0.0, 0.05), (2, 60.0, 1.0, 0.0), (3, 30.0, 0.5, 0.02)],
)
def test_loop_response_is_the_closed_form(order, tau, dh0, dv0):
    """A step (dh0) or a ramp (dv0) in the height error decays as the designed loop: the
    kernel's impulses every 0.2 s follow their discrete closed form to 1e-4 of the initial
    error (what is left: the Coriolis coupling with the horizontal, ``(2 Omega t)^2``), and the continuous loop (every pole at -1/tau) within its sampling (k1 T = 1.2 %
    per update at tau = 100 s)."""
    gains = V.loop_gains(tau, order, GAMMA)
    t, dh = height_errors(WGS, 8 * tau, 0.1, gains, dh0, dv0)
    scale = max(abs(dh0), abs(dv0) * tau)
    disc = discrete_response(gains, GAMMA, len(t), dh0, dv0, 0.0)
    cont = linear_response(gains, GAMMA, t, dh0, dv0, 0.0)
    print(f"order {order}, tau {tau}: max |dh - discrete| {np.max(np.abs(dh - disc)):.2e} m, "
          f"|dh - continuous| {np.max(np.abs(dh - cont)):.2e} m")  # fmt: skip
    assert np.max(np.abs(dh - disc)) <= 1e-4 * scale
    assert np.max(np.abs(dh - cont)) <= 3.0 * gains[0] * M.GRAVITY_NODE_S * scale
    assert abs(dh[-1]) <= 0.03 * scale  # decayed: (1 + 8 + 32) e^-8 = 1.4 % for order 3
    # the design: triple (double) pole at -1/tau
    k1, k2, k3 = gains
    poles = np.roots([1.0, k1, k2 - GAMMA, k3] if order == 3 else [1.0, k1, k2 - GAMMA])
    np.testing.assert_allclose(poles, -1.0 / tau, atol=2e-2 / tau)


def test_bias_steady_state_second_and_third_order():
    """An accelerometer bias da: the 2nd-order loop settles at da tau^2, the 3rd-order loop at
    zero (its b absorbs the bias)."""
    da, tau = 1e-4, 30.0
    for order, expect in ((2, da * tau**2), (3, 0.0)):
        gains = V.loop_gains(tau, order, GAMMA)
        t, dh = height_errors(WGS, 15 * tau, 0.1, gains, bias=da)
        ref = linear_response(gains, GAMMA, t, 0.0, 0.0, da)
        disc = discrete_response(gains, GAMMA, len(t), 0.0, 0.0, da)
        print(f"order {order}: bias {da} m/s^2 -> {dh[-1]:.4e} m (expected {expect:.4e} m)")
        assert ref[-1] == pytest.approx(expect, abs=1e-3 * da * tau**2)
        assert np.max(np.abs(dh - disc)) <= 1e-3 * da * tau**2
        assert dh[-1] == pytest.approx(expect, abs=0.03 * da * tau**2)


def test_free_channel_grows_with_the_growth_time():
    """Free: a planted 1 mm height error grows as cosh(t / tau), tau = 1/sqrt(Gamma) ~ 569 s."""
    tau = V.growth_time_s(WGS.lat0_rad, WGS.h0_m)
    assert 565.0 < tau < 572.0
    t, dh = height_errors(WGS, 2000.0, 0.2, None, dh0=1e-3)
    expect = 1e-3 * np.cosh(t / tau)
    print(f"free: {dh[-1]:.4e} m at {t[-1]:.0f} s, cosh law {expect[-1]:.4e} m")
    np.testing.assert_allclose(dh[1:], expect[1:], rtol=0.01)
    # and the damped channel holds the same start
    _, dd = height_errors(WGS, 2000.0, 0.2, V.loop_gains(100.0, 3, GAMMA), dh0=1e-3)
    assert abs(dd[-1]) < 1e-7  # vs 1.7e-2 m free


def test_default_rule():
    tau = V.growth_time_s(WGS.lat0_rad, WGS.h0_m)
    assert V.resolve("auto", WGS, 3 * tau - 1).mode == "free"
    vc = V.resolve("auto", WGS, 3 * tau + 1)
    assert vc.mode == "damped" and vc.reference == "truth"
    np.testing.assert_allclose(vc.gains, [0.03, 3e-4 + GAMMA, 1e-6])
    meta = vc.meta()
    assert meta["growth_time_s"] == pytest.approx(tau) and meta["requested"] == "auto"
    assert V.resolve("auto", WGS.with_model("flat"), 1e5).mode == "free"  # neutral channel
    assert V.resolve("damped", WGS, 10.0).mode == "damped"
    assert V.resolve("free", WGS, 1e5).mode == "free"
    with pytest.raises(ValueError, match="vertical channel"):
        V.resolve("baro", WGS, 10.0)


def test_the_record_says_how_the_rule_decided():
    tau = V.growth_time_s(WGS.lat0_rad, WGS.h0_m)
    rule = V.resolve("auto", WGS, 19268.0).meta()["rule"]
    assert rule.startswith(
        "auto: damped when duration > 3 x growth time on a rotating Earth: damped"
    )
    factor = V.resolve("auto", WGS, 19268.0).growth_factor
    assert f"19,268 s > {3 * tau:,.0f} s = 3 x {tau:.0f} s" in rule and f"x{factor:.3g} " in rule
    rule = V.resolve("auto", WGS, 619.0).meta()["rule"]
    assert ": free (619 s <= " in rule
    rule = V.resolve("free", WGS, 19268.0).meta()["rule"]
    assert rule.startswith("free, as requested") and "19,268 s > " in rule
    rule = V.resolve("auto", WGS.with_model("flat"), 1e5).meta()["rule"]
    assert ": free (flat Earth: constant gravity, the free channel is neutral" in rule


def test_meaningless_reason_explains_itself():
    msg = V.meaningless_reason(V.resolve("free", WGS, 19268.0).meta())
    assert "cosh(t / 569 s)" in msg and "19,268 s" in msg and "damped" in msg
    assert V.meaningless_reason(V.resolve("damped", WGS, 19268.0).meta()) == ""


def test_meaningless_warning_of_evaluate_gives_the_growth():
    from imugen.evaluate.stage import warn_meaningless

    record = V.resolve("free", WGS, 19268.0).meta()
    with pytest.warns(UserWarning, match=r"grows as cosh\(t / 569 s\), x.* over this 19,268 s"):
        assert warn_meaningless("consumer", 1e12, 5000.0, False, record)
    with pytest.warns(UserWarning) as rec:
        warn_meaningless("consumer", 1e12, 5000.0, False, None)  # older tables: no record
    assert "cosh" not in str(rec[0].message)
