"""Non-holonomic constraint rows (imugen.aid.filter.nhc): ``h`` is the derivative of the
predicted lateral / vertical vehicle velocity with respect to the error state, with the
mounting-angle and lever-arm states on, by central differences on the nominal state."""

import numpy as np
import pytest

from imugen.aid import filter as A
from imugen.aid.filter import nhc
from imugen.core.rotations import quat_to_dcm


def _row(r, x, r_):
    e = r.epoch(x)
    vel, lever = nhc.vehicle_velocity(e, r.md, x, r.wk)
    return nhc.row(e, r.md, x, r.wk, r.inp.tun[0], r_, vel, lever, 0.0)


@pytest.mark.parametrize("r_", [1, 2])
def test_rows_are_the_jacobian_of_the_vehicle_velocity(rig, r_):
    opts = A.Options(
        nhc=True, nhc_lever_arm_m=(1.2, -0.3, 0.5), nhc_lever_arm_sd_m=(0.1, 0.1, 0.1),
        nhc_misalignment_sd_rad=(0.02, 0.02), gyro_cross_coupling=False,
    )  # fmt: skip
    r = rig(opts)
    x = r.x
    x[A.NOMINAL.slice("mount")] = (0.01, -0.015)
    x[A.NOMINAL.slice("lever")] = (0.05, 0.02, -0.04)
    # a car: its velocity nearly along the body x
    x[A.NOMINAL.slice("v")] = quat_to_dcm(x[A.NOMINAL.slice("att")]) @ (10.0, 0.1, -0.05)
    m, _, var = _row(r, x, r_)
    h = r.h(m)
    num = r.numerical_row(lambda y: _row(r, y, r_)[1])
    assert var > 0.0 and np.linalg.norm(h[r.lay.slice("v")]) > 0.9
    for key in ("v", "att", "bg", "lever"):
        np.testing.assert_allclose(h[r.lay.slice(key)], num[r.lay.slice(key)], atol=1e-7)
    # the mounting angle of the row (yaw: lateral, pitch: vertical) is the forward speed;
    # exact for the yaw, to first order in the yaw and the lateral speed for the pitch
    i = r.lay.offset("mount") + (1 if r_ == 1 else 0)
    np.testing.assert_allclose(h[i], num[i], rtol=1e-3)
    other = r.lay.offset("mount") + (0 if r_ == 1 else 1)
    assert h[other] == 0.0 and abs(num[other]) < 0.02 * abs(num[i])
    assert np.all(h[r.lay.slice("ba")] == 0.0) and np.all(num[r.lay.slice("ba")] == 0.0)


def test_lever_arm_columns_only_from_rates_above_their_noise(rig):
    """At a rate within 15.8 sigma of its noise the lever-arm columns are zero (errors in
    variables); the gyro-bias columns stay."""
    opts = A.Options(
        nhc=True, nhc_lever_arm_m=(1.2, 0.0, 0.4), nhc_lever_arm_sd_m=(0.1, 0.1, 0.1),
        gyro_cross_coupling=False,
    )  # fmt: skip
    r = rig(opts)
    r.w_meas[:] = r.x[A.NOMINAL.slice("bg")] + 1e-4  # 1e-4 rad/s at a noise of 1e-3 / sqrt(dt)
    m, _, _ = _row(r, r.x, 1)
    h = r.h(m)
    assert np.all(h[r.lay.slice("lever")] == 0.0)
    assert np.linalg.norm(h[r.lay.slice("bg")]) > 0.0
