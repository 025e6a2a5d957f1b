"""Barometer row (imugen.aid.filter.baro): ``h`` is the derivative of the predicted height
(flat: ``p_u``; wgs84: plus the local level's drop; geodetic: the ellipsoidal height) plus the
drift state with respect to the error state."""

import numpy as np
import pytest

from imugen.aid import filter as A
from imugen.aid.filter import baro


@pytest.mark.parametrize("model", ["flat", "wgs84", "geodetic"])
def test_row_is_the_jacobian_of_the_height(rig, model):
    r = rig(A.Options(baro=True, gyro_cross_coupling=False), model=model)
    r.x[A.NOMINAL.slice("baro_bias")] = 0.8
    m, res = baro.height_row(r.md, r.x, r.wk, 3.0)
    h = r.h(m)
    # geodetic: ECEF coordinates of 6e6 m, heights rounded to 1e-9 m: a step of 0.1 m
    eps = 0.1 if model == "geodetic" else 1e-3
    num = r.numerical_row(lambda x: baro.height_row(r.md, x, r.wk, 3.0)[1], eps)
    np.testing.assert_allclose(h, num, atol=1e-8)
    assert h[r.lay.offset("baro_bias")] == 1.0
    up = h[r.lay.slice("p")]
    assert np.linalg.norm(up) == pytest.approx(1.0, abs=1e-4)
    if model == "flat":
        assert res == pytest.approx(r.x[A.NOMINAL.offset("p") + 2] + 0.8 - 3.0)
