"""GNSS rows (imugen.aid.filter.gnss): each row's sensitivity ``h`` is the derivative of its
residual ``z_pred - z`` with respect to the error state (estimate minus truth), by central
differences on the nominal state, in ``flat`` (n axes) and ``geodetic`` (local axes at the
antenna); latency and bias-state details."""

import numpy as np
import pytest

from imugen.aid import filter as A
from imugen.aid.filter import gnss
from imugen.aid.filter.geometry import local_level_nb


def _at(r, x):
    """The epoch at ``x`` and the fix's prediction (``wk.Lm`` at the antenna in geodetic)."""
    e = r.epoch(x)
    pred, predv, cl, cw, L = gnss.antenna(e, r.md, r.inp, x, r.wk)
    if r.md.geo:
        local_level_nb(pred[0], pred[1], pred[2], r.wk.Lm)
    return e, pred, predv, cl, cw, L


def _row(r, x, kind, a):
    """``(m, residual)`` of row ``a`` of the position (``kind`` "p") or velocity fix."""
    e, pred, predv, cl, cw, L = _at(r, x)
    tn = r.inp.tun[0]
    if kind == "p":
        fn = gnss.position_row_local if r.md.geo else gnss.position_row
        m, res, _ = fn(e, r.md, r.inp, x, r.wk, tn, a, pred, cl, L)
    else:
        fn = gnss.velocity_row_local if r.md.geo else gnss.velocity_row
        m, res, _ = fn(e, r.md, r.inp, x, r.wk, a, predv, cw)
    return m, res


@pytest.mark.parametrize("model", ["flat", "geodetic"])
@pytest.mark.parametrize("kind", ["p", "v"])
def test_rows_are_the_jacobian_of_the_residual(rig, model, kind):
    r = rig(A.Options(gnss_bias=True, gyro_cross_coupling=False), model=model)
    # a fix near the prediction (in geodetic the local axes turn with the position: their
    # derivative times the residual, 1e-7 per m, is left out of the row)
    _, pred, predv, *_ = _at(r, r.x)
    r.inp.zp[0, 0] = np.add(pred, (0.1, -0.1, 0.05))
    r.inp.zv[0, 0] = np.add(predv, (0.01, 0.02, -0.01))
    eps = 1e-3 if model == "geodetic" else 1e-5  # ECEF coordinates of 6e6 m
    for a in range(3):
        m, _ = _row(r, r.x, kind, a)
        h = r.h(m)
        num = r.numerical_row(lambda x, a=a: _row(r, x, kind, a)[1], eps)
        assert np.linalg.norm(h) > 0.9  # the row is not empty
        # geodetic velocity rows: the Earth rate's part of C (omega x l), Omega x (C l), is
        # rotated with psi to first order as C (w x l) is (a 7e-5 |l| error in those columns)
        atol = 2e-4 if (kind == "v" and model == "geodetic") else 1e-7
        np.testing.assert_allclose(h, num, rtol=1e-5, atol=atol)


def test_latency_puts_minus_latency_on_the_velocity_error(rig):
    """With latency ``L`` the position fix is ``p - L v + ...``: column ``dv`` is ``-L``."""
    r = rig(A.Options(gnss_bias=False, gyro_cross_coupling=False), latency=0.2)
    for a in range(3):
        h = r.h(_row(r, r.x, "p", a)[0])
        assert h[r.lay.offset("v") + a] == -0.2
        assert h[r.lay.offset("p") + a] == 1.0


def test_bias_states_keep_the_white_share_of_the_variance(rig):
    """With GNSS bias states the row's variance is the reported one times ``w^2 / (w^2 +
    b^2)``; the bias state's mean enters the residual."""
    r = rig(A.Options(gnss_bias=True))
    tn = r.inp.tun[0]
    tn[A.T_GW : A.T_GW + 3] = 0.3
    tn[A.T_GB_SD : A.T_GB_SD + 3] = 0.4
    r.inp.sp[...] = 2.0
    e, pred, _, cl, _, L = _at(r, r.x)
    _, res0, var = gnss.position_row(e, r.md, r.inp, r.x, r.wk, tn, 1, pred, cl, L)
    assert var == pytest.approx(4.0 * 0.09 / 0.25)
    x = r.x.copy()
    x[A.NOMINAL.offset("gnss_bias") + 1] = 0.7
    _, res1, _ = gnss.position_row(e, r.md, r.inp, x, r.wk, tn, 1, pred, cl, L)
    assert res1 - res0 == pytest.approx(0.7)
