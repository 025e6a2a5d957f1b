"""ZUPT (imugen.aid.filter.zupt): a still, slow epoch sets the velocity to zero, axis by axis;
a moving one or a fast one leaves the state alone; the IMU must have been still for
``zupt_min_still_s``, without a fix the filter's speed plus its sigma must pass the gate, and
the variance covers the crawl the detector cannot exclude."""

import numpy as np

from imugen.aid import filter as A
from imugen.aid.filter import measurements, zupt
from imugen.aid.filter.context import Epoch

FORMER = {"zupt_min_still_s": 0.0, "zupt_speed_conf": 0.0, "zupt_crawl_mps": 0.0}


def _win():
    win = measurements.new_windows()
    measurements.start(win)
    return win


def test_zupt_only_when_still_and_slow(rig):
    r = rig(A.Options(zupt=True, zupt_speed_mps=0.2, gyro_cross_coupling=False, **FORMER))
    iv = A.NOMINAL.slice("v")
    r.x[iv] = (0.05, -0.02, 0.01)
    r.inp.ok[...] = False  # the filter's own speed
    e = r.epoch(r.x)
    P0 = r.wk.P.copy()
    moving = Epoch(e.s, e.j, e.k, True, False, e.w_b)
    assert zupt.update(moving, r.md, r.inp, r.wk, r.x, r.inp.tun[0], _win()) == 0
    assert np.array_equal(r.wk.P, P0) and not r.wk.dx.any()
    r.inp.ok[...] = True  # the GNSS speed, here above the threshold
    r.inp.zv[...] = 1.0
    assert zupt.update(e, r.md, r.inp, r.wk, r.x, r.inp.tun[0], _win()) == 0
    r.inp.ok[...] = False
    assert zupt.update(e, r.md, r.inp, r.wk, r.x, r.inp.tun[0], _win()) == A.F_ZUPT
    # three scalar updates of an uncorrelated prior 0.01 with noise 0.02^2: the velocity error
    # estimate is v P / (P + R) per axis
    dv = r.wk.dx[r.lay.slice("v")]
    np.testing.assert_allclose(dv, r.x[iv] * 0.01 / (0.01 + 0.02**2), rtol=1e-12)


def test_still_time_sigma_gate_and_crawl_variance(rig):
    opts = A.Options(zupt=True, zupt_speed_mps=0.2, gyro_cross_coupling=False)
    r = rig(opts)
    iv = A.NOMINAL.slice("v")
    r.x[iv] = (0.05, -0.02, 0.01)
    r.inp.ok[...] = False
    np.fill_diagonal(r.wk.P, 1e-4)  # velocity sigma 0.01 m/s: speed + 1 sigma passes
    e = r.epoch(r.x)
    win = _win()

    def at(k, still=True):
        return Epoch(e.s, e.j, k, True, still, e.w_b)

    tn = r.inp.tun[0]
    # 10 Hz epochs: still for 0.1 ... 0.9 s: no update before the IMU has been still 1 s
    assert zupt.update(at(0, False), r.md, r.inp, r.wk, r.x, tn, win) == 0
    for k in range(10, 100, 10):
        assert zupt.update(at(k), r.md, r.inp, r.wk, r.x, tn, win) == 0
    assert not r.wk.dx.any()
    # a slow filter speed whose sigma is too large to exclude a cruise: no update
    np.fill_diagonal(r.wk.P, 0.04)
    assert zupt.update(at(100), r.md, r.inp, r.wk, r.x, tn, win) == 0
    np.fill_diagonal(r.wk.P, 1e-4)
    assert zupt.update(at(110), r.md, r.inp, r.wk, r.x, tn, win) == A.F_ZUPT
    var = 0.02**2 + 0.2**2 / 3.0  # the crawl's uniform variance added
    dv = r.wk.dx[r.lay.slice("v")]
    np.testing.assert_allclose(dv, r.x[iv] * 1e-4 / (1e-4 + var), rtol=1e-12)
    # motion resets the still time
    assert zupt.update(at(120, False), r.md, r.inp, r.wk, r.x, tn, win) == 0
    assert zupt.update(at(130), r.md, r.inp, r.wk, r.x, tn, win) == 0
