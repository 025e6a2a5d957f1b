"""vehicle: multirotor (imugen.truth.multirotor): flatness attitude, rotor speeds, limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen.closure import closure_of_truth
from imugen.core import rotations as rot
from imugen.tables import truth as col
from imugen.truth.build import build_truth, enu_table

CONSTANT_YAW = {"yaw_path": "false"}


def figure_eight(period_s, radius_m=2.5, duration_s=8.0, rate_hz=25.0, ramp_s=2.0):
    """Positions of a lemniscate flown at 1.5 m from rest: its phase speeds up over
    ``ramp_s`` (a quintic smoothstep), then turns at ``2 pi / period_s``."""
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    u = np.clip(t / ramp_s, 0.0, 1.0)
    phase = np.where(t < ramp_s, ramp_s * (2.5 * u**4 - 3 * u**5 + u**6), t - 0.5 * ramp_s)
    th = 2 * math.pi * phase / period_s
    p = np.column_stack([radius_m * np.sin(th), radius_m * np.sin(th) * np.cos(th), 1.5 + 0 * t])
    return t, p


def _truth(period_s, earth="flat", params=None):
    t, p = figure_eight(period_s)
    df, meta = enu_table(p, t, (47.4, 8.5, 400.0))
    return build_truth(
        df, meta, rate_hz=100.0, earth=earth, vehicle="multirotor", vehicle_params=params,
        verbose=False,
    )  # fmt: skip


@pytest.mark.parametrize("drag", [(0.0, 0.0), (0.35, 0.25)])
def test_specific_force_along_body_z_up_to_drag_and_closure(drag):
    params = {"drag_x_1ps": drag[0], "drag_y_1ps": drag[1]} if drag[0] else None
    tr, tm = _truth(4.5, params=params)
    C = rot.quat_to_dcm(tr[list(col.QUAT)].to_numpy())
    v_b = np.einsum("mji,mj->mi", C, tr[list(col.VEL)].to_numpy())
    f_b = tr[list(col.ACCEL)].to_numpy()
    assert np.abs(f_b[:, 0] + drag[0] * v_b[:, 0]).max() < 1e-9
    assert np.abs(f_b[:, 1] + drag[1] * v_b[:, 1]).max() < 1e-9
    assert f_b[:, 2].min() > 0.0
    assert np.abs(v_b[:, :2]).max() > 1.0  # the drag term is not trivially zero
    res = closure_of_truth(tr, tm)
    assert res["final_position_error_m"] < 1e-6
    assert res["max_attitude_error_rad"] < 1e-9


def test_rotor_speeds_hover_and_aggressive_figure_eight():
    t = np.arange(0.0, 4.0, 0.1)
    df, meta = enu_table(np.tile([1.0, 2.0, 1.5], (len(t), 1)), t, (47.4, 8.5, 400.0))
    hover, _ = build_truth(
        df, meta, rate_hz=100.0, earth="flat", vehicle="multirotor", verbose=False
    )
    g = np.linalg.norm(hover[list(col.ACCEL)].to_numpy(), axis=1)  # local gravity, ~9.808
    np.testing.assert_allclose(hover[col.ROTORS[4]].to_numpy(), g, rtol=1e-12)  # 1 kg
    hover_rpm = 5500.0 * np.sqrt(g / 9.80665)  # the hover figures are for g0
    rpm = hover[list(col.ROTORS[:4])].to_numpy()
    np.testing.assert_allclose(rpm, np.repeat(hover_rpm[:, None], 4, axis=1), rtol=1e-9)
    tr, tm = _truth(4.5, params=CONSTANT_YAW)  # as racing figure-eights are flown
    rpm = tr[list(col.ROTORS[:4])].to_numpy()
    k_f = 9.80665 / (4 * (5500.0 * 2 * math.pi / 60) ** 2)  # the hover figures, 1 kg
    T = k_f * np.sum((rpm * 2 * math.pi / 60) ** 2, axis=1)
    np.testing.assert_allclose(T, tr[col.ROTORS[4]].to_numpy(), rtol=1e-9)  # thrust allocated
    mr = tm["plausibility"]["multirotor"]
    assert mr["max_tilt_rad"] > math.radians(30)  # aggressive: ~1 g lateral
    assert not [w for w in tm["plausibility"]["warnings"] if w.startswith("multirotor")]
    assert mr["rotor_saturated_low"] + mr["rotor_saturated_high"] == 0
    _, fm = _truth(1.8, params=CONSTANT_YAW)  # beyond a small quadrotor
    assert [w for w in fm["plausibility"]["warnings"] if w.startswith("multirotor")]


def test_closure_wgs84():
    tr, tm = _truth(4.5, earth="wgs84")
    res = closure_of_truth(tr, tm)
    assert res["final_position_error_m"] < 1e-6
    assert res["max_attitude_error_rad"] < 1e-9


def test_untimed_waypoints_are_flown():
    """An untimed multirotor route: speed profile, flatness attitude, plausible, closes."""
    p = np.array([[0, 0, 2], [20, 0, 2], [20, 20, 5], [0, 20, 5], [0, 0, 2.0]])
    df, meta = enu_table(p, None, (47.4, 8.5, 400.0))
    tr, tm = build_truth(df, meta, rate_hz=100.0, earth="flat", vehicle="multirotor", verbose=False)
    assert not tm["plausibility"]["warnings"]
    assert tm["plausibility"]["multirotor"]["rotor_saturated_high"] == 0
    assert closure_of_truth(tr, tm)["final_position_error_m"] < 1e-6
