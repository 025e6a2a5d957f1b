"""The shared scalar update (imugen.aid.filter.kalman) against the textbook Kalman update
of a dense row; the innovation gate; a fresh state."""

import numpy as np

from imugen.aid.filter import kalman
from imugen.aid.filter.context import new_work


def _work(n, rng):
    wk = new_work(n)
    a = rng.normal(size=(n, n))
    wk.P[:] = a @ a.T + n * np.eye(n)
    wk.dx[:] = rng.normal(scale=0.1, size=n)
    return wk


def test_scalar_update_is_the_kalman_update():
    rng = np.random.default_rng(1)
    n = 9
    wk = _work(n, rng)
    P, dx = wk.P.copy(), wk.dx.copy()
    m = kalman.clear(wk)
    h = np.zeros(n)
    for i, v in ((4, 0.7), (0, -1.2), (7, 2.0)):  # any order of the non-zeros
        m = kalman.put(wk, m, i, v)
        h[i] = v
    r, var = 0.4, 0.3
    assert kalman.scalar_update(wk, m, r, var, 0.0)
    s = h @ P @ h + var
    K = P @ h / s
    np.testing.assert_allclose(wk.dx, dx + K * (r - h @ dx), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(wk.P, P - np.outer(K, h @ P), rtol=1e-12, atol=1e-12)
    kalman.symmetrize(wk.P)
    assert np.array_equal(wk.P, wk.P.T)


def test_gate_rejects_a_large_innovation_and_leaves_the_state():
    rng = np.random.default_rng(2)
    wk = _work(4, rng)
    P, dx = wk.P.copy(), wk.dx.copy()
    m = kalman.put(wk, kalman.clear(wk), 1, 1.0)
    s = P[1, 1] + 0.1
    big = dx[1] + 3.5 * np.sqrt(s)
    assert not kalman.scalar_update(wk, m, big, 0.1, 3.0)
    assert np.array_equal(wk.P, P) and np.array_equal(wk.dx, dx)
    assert kalman.scalar_update(wk, m, big, 0.1, 4.0)


def test_fresh_state_is_uncorrelated_with_its_prior():
    rng = np.random.default_rng(3)
    wk = _work(5, rng)
    kalman.fresh_state(wk.P, wk.dx, 2, 0.5)
    assert wk.P[2, 2] == 0.25 and wk.dx[2] == 0.0
    assert not np.delete(wk.P[2], 2).any() and not np.delete(wk.P[:, 2], 2).any()
