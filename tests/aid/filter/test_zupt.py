"""ZUPT (imugen.aid.filter.zupt): a still, slow epoch sets the velocity to zero, axis by axis;
a moving one or a fast one leaves the state alone."""

import numpy as np

from imugen.aid import filter as A
from imugen.aid.filter import zupt
from imugen.aid.filter.context import Epoch


def test_zupt_only_when_still_and_slow(rig):
    r = rig(A.Options(zupt=True, zupt_speed_mps=0.2, gyro_cross_coupling=False))
    iv = A.NOMINAL.slice("v")
    r.x[iv] = (0.05, -0.02, 0.01)
    r.inp.ok[...] = False  # the filter's own speed
    e = r.epoch(r.x)
    P0 = r.wk.P.copy()
    moving = Epoch(e.s, e.j, e.k, True, False, e.w_b)
    assert zupt.update(moving, r.md, r.inp, r.wk, r.x, r.inp.tun[0], None) == 0
    assert np.array_equal(r.wk.P, P0) and not r.wk.dx.any()
    r.inp.ok[...] = True  # the GNSS speed, here above the threshold
    r.inp.zv[...] = 1.0
    assert zupt.update(e, r.md, r.inp, r.wk, r.x, r.inp.tun[0], None) == 0
    r.inp.ok[...] = False
    assert zupt.update(e, r.md, r.inp, r.wk, r.x, r.inp.tun[0], None) == A.F_ZUPT
    # three scalar updates of an uncorrelated prior 0.01 with noise 0.02^2: the velocity error
    # estimate is v P / (P + R) per axis
    dv = r.wk.dx[r.lay.slice("v")]
    np.testing.assert_allclose(dv, r.x[iv] * 0.01 / (0.01 + 0.02**2), rtol=1e-12)
