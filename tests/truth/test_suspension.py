"""Body roll and pitch of a car on its suspension (:mod:`imugen.truth.suspension`).

Oracles: the second-order step response (overshoot ``exp(-pi zeta / sqrt(1 - zeta^2))`` at
the half damped period), the steady roll of a constant-radius turn (gradient x ``v^2 / R``),
the sign of braking and accelerating pitch, the interpolant's derivatives against the ODE,
a rigid truth bit-identical to one with zero gradients, the lateral non-holonomic constraint
(zero), the vertical body velocity (``v sin theta_s``), zero-error closure with the suspension
on, and a real shared car track: plausible, with roll that follows the lateral acceleration.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from imugen import truth
from imugen.closure import closure_of_truth
from imugen.core import rotations as rot
from imugen.tables import truth as col
from imugen.truth.suspension import Response
from imugen.truth.vehicles import VEHICLES

from helpers import SHARED_TRAJ

ORIGIN = (31.63, -7.99, 480.6)
DAMPED = {"suspension": "damped"}


def _build(enu, t, vehicle_params=DAMPED, **kw):
    df, meta = truth.enu_table(enu, t, ORIGIN)
    kw.setdefault("verbose", False)
    kw.setdefault("earth", "flat")
    return truth.build_truth(df, meta, vehicle="car", vehicle_params=vehicle_params, **kw)


def _arr(tr, cols):
    return tr[list(cols)].to_numpy()


@pytest.mark.parametrize("zeta", [0.3, 0.5, 1.0, 1.5])
def test_step_response_overshoot_and_period(zeta):
    # a smooth step of the input (cosine ramp over 0.02 s, which the spline follows)
    f_n, K = 1.5, 0.02
    t = np.arange(0.0, 8.0, 1e-3)
    u = K * 0.5 * (1.0 - np.cos(np.pi * np.clip((t - 1.0) / 0.02, 0.0, 1.0)))
    resp = Response(t, u, f_n, zeta)
    x = resp(t)[0]
    assert x[-1] == pytest.approx(K, rel=1e-4)  # settles at gradient x input
    if zeta < 1.0:
        wd = 2 * math.pi * f_n * math.sqrt(1 - zeta * zeta)
        k = int(np.argmax(x))
        # overshoot of a step (the ramp lowers it by < 0.2 %) at the half damped period after
        # the ramp's middle
        overshoot = x[k] / K - 1.0
        expected = math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))
        assert overshoot == pytest.approx(expected, rel=2e-3)
        assert t[k] - 1.01 == pytest.approx(math.pi / wd, abs=2e-3)
    else:  # critically and over-damped: no overshoot
        assert x.max() <= K * (1 + 1e-9)
    # between the nodes the closed form satisfies the ODE: x'' (from the rate, central
    # differences) = w^2 (u - x) - 2 zeta w x', and the rate is the angle's derivative
    w = 2 * math.pi * f_n
    tm = np.arange(1.2, 4.0, 3.7e-4)  # off the nodes
    dt = 1e-5
    (xp, vp), (xm, vm), (x0, v0) = resp(tm + dt), resp(tm - dt), resp(tm)
    u0 = CubicSpline(t, u)(tm)
    np.testing.assert_allclose((vp - vm) / (2 * dt), w * w * (u0 - x0) - 2 * zeta * w * v0,
                               rtol=0, atol=1e-6 * K * w * w)  # fmt: skip
    np.testing.assert_allclose((xp - xm) / (2 * dt), v0, rtol=0, atol=1e-7 * K * w)


def test_response_is_smooth_across_the_nodes():
    # C^4: the angle's third derivative (second differences of the rate) is continuous
    # across a node, where a first-order hold's steps by w^2 x the input slope's change
    f_n, zeta, h = 1.5, 0.5, 0.02
    t = np.arange(0.0, 4.0 + h / 2, h)
    u = 0.02 * np.sin(2.3 * t) ** 2
    resp = Response(t, u, f_n, zeta)
    d = 1e-4
    for node in (1.0, 2.0, 3.0):
        tt = node + d * np.arange(-6, 7)
        d3 = np.diff(resp(tt)[1], 2) / d**2  # third derivative at tt[1:-1]
        assert np.abs(np.diff(d3)).max() < 1e-3 * np.abs(d3).max()


def _circle(R=50.0, v=15.0, T=120.0):
    t = np.arange(0.0, T, 0.5)
    th = v * t / R
    return t, np.column_stack([R * np.sin(th), R * (1 - np.cos(th)), 0 * t])


def test_constant_turn_steady_roll_is_gradient_times_lateral_accel():
    t, enu = _circle()
    tr, meta = _build(enu, t)
    vp = VEHICLES["car"]
    roll, pitch = tr["roll_rad"].to_numpy(), tr["pitch_rad"].to_numpy()
    v = _arr(tr, col.VEL)
    a_lat = np.hypot(v[:, 0], v[:, 1]) ** 2 / 50.0
    tt = tr[col.TIME].to_numpy()
    mid = (tt > 25.0) & (tt < 95.0)  # steady turning
    # turning left (+y): the body rolls outwards, right side down (roll > 0)
    np.testing.assert_allclose(roll[mid], vp.roll_gradient_radpmps2 * a_lat[mid], rtol=5e-3)
    assert np.abs(pitch[mid]).max() < 1e-6
    assert meta["plausibility"]["warnings"] == []
    assert meta["plausibility"]["max_body_lateral_speed_mps"] < 1e-9  # NHC: no lateral slip


def test_braking_dips_the_nose_and_accelerating_squats():
    # straight road: accelerate at 2 m/s^2 to 20 m/s, cruise, brake at 4 m/s^2 to 8 m/s
    t = np.arange(0.0, 40.0, 0.1)
    v = np.clip(np.minimum(np.minimum(2.0 * t, 20.0), 20.0 - 4.0 * (t - 25.0)), 8.0, None)
    v[t < 4.0] = 2.0 * t[t < 4.0]
    x = np.r_[0.0, np.cumsum(0.5 * (v[1:] + v[:-1]) * 0.1)]
    enu = np.column_stack([x, 0 * x, 0 * x])
    tr, meta = _build(enu, t)
    tt = tr[col.TIME].to_numpy()
    pitch = tr["pitch_rad"].to_numpy()
    K = VEHICLES["car"].pitch_gradient_radpmps2
    acc = (tt > 5) & (tt < 8)
    brake = (tt > 25.5) & (tt < 28.0)
    assert np.all(pitch[acc] > 0.5 * K * 2.0)  # squat: nose up
    assert np.all(pitch[brake] < -0.5 * K * 4.0)  # dive: nose down
    assert np.median(pitch[(tt > 26.5) & (tt < 28.0)]) == pytest.approx(-K * 4.0, rel=0.1)
    assert np.abs(tr["roll_rad"].to_numpy()).max() < 1e-9
    # a body rotation only: the body velocity keeps no y; its z is v sin(theta_s)
    C = rot.quat_to_dcm(_arr(tr, col.QUAT))
    v_b = np.einsum("kji,kj->ki", C, _arr(tr, col.VEL))
    assert np.abs(v_b[:, 1]).max() < 1e-9
    speed = np.linalg.norm(_arr(tr, col.VEL), axis=1)
    np.testing.assert_allclose(v_b[:, 2], -speed * np.sin(pitch), atol=1e-6)
    assert not [w for w in meta["plausibility"]["warnings"] if "pitch" in w or "roll" in w]


def test_rigid_is_bit_identical_to_zero_gradients_and_has_no_roll():
    t, enu = _circle(T=40.0)
    rigid, m1 = _build(enu, t, vehicle_params={"suspension": "rigid"})
    zero, _ = _build(
        enu, t, vehicle_params={**DAMPED, "roll_gradient_radpmps2": 0, "pitch_gradient_radpmps2": 0}
    )
    assert rigid.equals(zero)
    assert np.all(rigid["roll_rad"].to_numpy() == 0.0)
    assert "suspension" not in m1["ground_attitude"]


def test_car_is_on_its_suspension_by_default():
    # the car class's default model is the damped suspension: a default truth is the damped one
    assert VEHICLES["car"].suspension == "damped"
    assert all(VEHICLES[v].suspension == "rigid" for v in VEHICLES if v != "car")
    t, enu = _circle(T=40.0)
    default, m0 = _build(enu, t, vehicle_params=None)
    damped, _ = _build(enu, t)
    assert default.equals(damped)
    assert np.abs(default["roll_rad"].to_numpy()).max() > math.radians(1.0)
    assert m0["ground_attitude"]["suspension"]["model"] == "damped second order"


def test_input_is_capped_at_the_tyre_limit():
    # a 20 m circle at 15 m/s asks for 11.25 m/s^2 of lateral acceleration, beyond the 0.8 g
    # road tyres give (max_accel_mps2): the body rolls as if at that limit, not beyond (the
    # cap is smooth: exact below 3/4 of the limit, within 1 % of it from 1.3 times it on)
    vp = VEHICLES["car"]
    t, enu = _circle(R=20.0, v=15.0, T=60.0)
    tr, meta = _build(enu, t)
    rep = meta["ground_attitude"]["suspension"]
    assert rep["max_input_accel_uncapped_mps2"] > 1.3 * vp.max_accel_mps2  # the fit: ~11
    assert rep["input_cap_mps2"] == vp.max_accel_mps2 and rep["capped_fraction"] > 0.5
    tt, roll = tr[col.TIME].to_numpy(), tr["roll_rad"].to_numpy()
    mid = (tt > 15.0) & (tt < 45.0)
    at_limit = vp.roll_gradient_radpmps2 * vp.max_accel_mps2
    assert np.all(roll[mid] <= at_limit) and np.all(roll[mid] > 0.99 * at_limit)


def test_a_glitch_beyond_the_tyre_limit_rolls_no_further_than_the_limit():
    # a 1 s spike of 16 m/s^2 lateral (a GNSS glitch): the roll peaks at the capped input's
    # step response, gradient x 8 m/s^2 x (1 + overshoot), not at twice that
    from imugen.truth.suspension import Suspension

    vp = VEHICLES["car"]

    def inputs(t):
        return np.where((t >= 2.0) & (t < 3.0), 16.0, 0.0), 0.0 * t

    s = Suspension(0.0, 10.0, inputs, vp)
    roll = s(np.arange(0.0, 10.0, 1e-3))[0]
    z = vp.roll_damping
    peak = (
        vp.roll_gradient_radpmps2
        * vp.max_accel_mps2
        * (1 + math.exp(-math.pi * z / math.sqrt(1 - z * z)))
    )
    assert math.radians(4.0) < np.abs(roll).max() <= peak * 1.01
    assert s.report["max_input_accel_uncapped_mps2"] == 16.0


@pytest.mark.parametrize("earth", ["flat", "wgs84", "geodetic"])
def test_closure_with_suspension(earth):
    # S-curves with stops and speed changes, 1 Hz fixes
    t = np.arange(0.0, 200.0, 1.0)
    speed = np.where((t < 10) | ((t >= 90) & (t < 100)), 0.0, 12.0)
    s = np.cumsum(speed)
    enu = np.column_stack([s, 60.0 * np.sin(s / 50.0), 5.0 * np.sin(s / 300.0)])
    tr, meta = _build(enu, t, earth=earth)
    assert np.abs(tr["roll_rad"].to_numpy()).max() > math.radians(1.0)
    res = closure_of_truth(tr, meta)
    assert res["final_position_error_m"] < 1e-6
    assert res["max_attitude_error_rad"] < 1e-9
    assert meta["plausibility"]["max_rate_increment_radps"] < 1e-4


@pytest.mark.shared
@pytest.mark.skipif(not SHARED_TRAJ.is_dir(), reason="needs ../shared/data/trajectories")
def test_real_car_track_rolls_with_lateral_acceleration():
    from imugen.ingest.stage import ingest

    path = SHARED_TRAJ / "e_car_colorado_mountain_pass.gpx"
    if not path.is_file():
        pytest.skip("no shared car track")
    ing = ingest(path, path=1)  # ACTIVE LOG #2: 4.4 km over the pass
    tr, meta = truth.build_truth(
        ing.table, ing.meta, rate_hz=10, vehicle="car", earth="wgs84", verbose=False,
        vehicle_params=DAMPED,
    )  # fmt: skip
    rep = meta["plausibility"]
    assert rep["warnings"] == [], rep["warnings"]
    vp = VEHICLES["car"]
    roll = tr["roll_rad"].to_numpy()
    assert 0.1 < math.degrees(np.abs(roll).max()) <= math.degrees(vp.max_roll_rad)
    # lateral acceleration of the path: horizontal speed x turn rate about the vertical
    v = _arr(tr, col.VEL)
    vh = np.hypot(v[:, 0], v[:, 1])
    yaw = np.unwrap(tr["yaw_rad"].to_numpy())
    a_lat = vh * np.gradient(yaw, tr[col.TIME].to_numpy())
    r = np.corrcoef(roll, vp.roll_gradient_radpmps2 * a_lat)[0, 1]
    assert r > 0.9, r
