"""Gravitation between exact nodes in the rotating-Earth kernels: the stated error bound.

The kernels evaluate the exact gravitation every ``T = GRAVITY_NODE_S`` and use, in between,
the cubic in time through the block's predicted end and the three previous nodes. Oracles:

* the cubic's error along a path against the exact field is ``<= T^4/24 max|d^4G/dt^4|``,
  ``d^4G/dt^4 ~ Gamma snap`` (``|Gamma| <= GAMMA_MAX = 3.1e-6 s^-2``), and the bound is tight;
* the a-posteriori check (4th difference of five nodes, ``T^4 G^(4)``) accepts a block only when
  its real interpolation error is within ``GRAVITY_TOL_MPS2``, on airliner-speed paths with
  manoeuvres from gentle to violent;
* the kernel agrees with the exact gravitation at every step within the position error that
  tolerance can cause (``tol tau^2 (cosh(t/tau) - 1)``, ``tau = sqrt(R / 2g)``: the vertical
  channel's instability), and blocks failing the check are the every-step rule bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen.core import earth as E
from imugen.core.rotations import exp_dcm
from imugen.navigate import mechanize as M
from imugen.navigate._kernel import S_FB

from oracles.strapdown import exact_increments

WGS = E.OriginFrame.from_deg(45.0, 7.0, 10_000.0, model="wgs84")
V_AIRLINER = 214.0  # m/s (770 km/h)
TAU_V = math.sqrt(E.R_MEAN / (2.0 * 9.81))  # vertical-channel time constant [s], ~570


class Weave:
    """Straight flight at ``V_AIRLINER`` (east, climbing 5 m/s) with a weave ``amp sin(om t)``
    across track (``axis`` 1) or in height (``axis`` 2); level attitude. Exact in n."""

    def __init__(self, amp, period_s, axis=1):
        self.amp, self.om, self.axis = amp, 2.0 * math.pi / period_s, axis

    @property
    def snap(self):
        return self.amp * self.om**4

    def position(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        p = np.stack([V_AIRLINER * t, np.zeros_like(t), 5.0 * t], axis=1)
        p[:, self.axis] += self.amp * np.sin(self.om * t)
        return p

    def velocity(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        v = np.tile([V_AIRLINER, 0.0, 5.0], (len(t), 1))
        v[:, self.axis] += self.amp * self.om * np.cos(self.om * t)
        return v

    @staticmethod
    def attitude(t):
        return np.tile([1.0, 0.0, 0.0, 0.0], (len(np.atleast_1d(t)), 1))


def inertial_gravitation(path, t):
    """The field the kernel interpolates: gravitation along the path in the inertial frame."""
    w = E.earth_rate_n(WGS)
    return np.einsum(
        "mij,mj->mi", exp_dcm(w[None, :] * t[:, None]), E.gravitation_n(path.position(t), WGS)
    )


def block_errors(path, T, sub=20, span=40.0):
    """Per block ``[t_j, t_j + T]``: the cubic's max error on ``sub`` points against the exact
    field, and the check's estimate (nodes exact): ``max(|D_j|, |D_j-1|, |2.5 D_j - 1.5 D_j-1|)
    / 24``, ``D_j`` the 4th difference of the nodes ``j + 1 .. j - 3``."""
    t = np.arange(0.0, span, T / sub)
    g = inertial_gravitation(path, t)
    nodes = g[::sub]
    tau = np.arange(sub)[:, None] / sub
    err, est = [], []
    d4 = nodes[4:] - 4 * nodes[3:-1] + 6 * nodes[2:-2] - 4 * nodes[1:-3] + nodes[:-4]
    for j in range(4, len(nodes) - 1):
        n3, n2, n1, n0, ge = nodes[j - 3], nodes[j - 2], nodes[j - 1], nodes[j], nodes[j + 1]
        c2 = 0.5 * (ge + n1) - n0
        sv = 0.5 * (ge - n1)
        c3 = (n0 - n2 + 4 * c2 - 2 * sv) / 6
        c1 = sv - c3
        approx = n0 + tau * (c1 + tau * (c2 + tau * c3))
        err.append(float(np.max(np.abs(approx - g[sub * j : sub * j + sub]))))
        assert np.allclose(d4[j - 3], ge - 4 * n0 + 6 * n1 - 4 * n2 + n3, rtol=0, atol=1e-15)
        d, dp = d4[j - 3], d4[j - 4]
        est.append(float(np.max(np.abs([d, dp, 2.5 * d - 1.5 * dp]))) / 24.0)
    return np.array(err), np.array(est)


def test_node_spacing_meets_the_tolerance_for_its_design_snap():
    """T = 0.2 s: the cubic's bound T^4/24 Gamma snap is within 1e-8 m/s^2 up to 48 m/s^4."""
    T, tol = M.GRAVITY_NODE_S, M.GRAVITY_TOL_MPS2
    snap_design = 24.0 * tol / (M.GAMMA_MAX * T**4)
    assert 3.05e-6 < M.GAMMA_MAX < 3.15e-6
    assert snap_design >= 47.0
    for dt, m in ((0.1, 2), (0.05, 4), (0.02, 10), (0.01, 20), (0.001, 200), (1.0, 1)):
        assert int(M.kernel_params(WGS, dt)[M.K_MB]) == m
    assert M.kernel_params(WGS, 0.01)[M.K_D4] == 24.0 * tol / M.GRAVITY_CHECK_MARGIN


@pytest.mark.parametrize("amp, period_s, axis", [(20.0, 10.0, 1), (2.0, 2.5, 2), (1.0, 2.0, 1)])
def test_cubic_interpolation_error_bound(amp, period_s, axis):
    """Airliner-speed weaves: cubic error <= T^4/24 Gamma_max snap (+ rounding), and tight."""
    path = Weave(amp, period_s, axis)
    T = M.GRAVITY_NODE_S
    err, _ = block_errors(path, T)
    bound = T**4 / 24 * M.GAMMA_MAX * path.snap + 3e-14  # + rounding of the node values
    print(f"snap {path.snap:.3g} m/s^4: max error {err.max():.2e} m/s^2, bound {bound:.2e}")
    assert err.max() <= bound
    assert err.max() > 0.3 * bound  # the bound is tight, not vacuous


def test_straight_flight_interpolates_to_rounding():
    """No manoeuvre: the path's own snap is the Earth's rotation (Omega^4 R ~ 2e-10 m/s^4) and
    the field's curvature over ~1 km: the cubic is exact to rounding at T = 1 s."""
    err, est = block_errors(Weave(0.0, 1.0), 1.0, span=60.0)
    assert err.max() < 5e-14 and est.max() < 5e-14


@pytest.mark.parametrize(
    "amp, period_s, axis",
    [
        (2.0, 10.0, 2),
        (20.0, 10.0, 1),
        (20.0, 10.0, 2),
        (5.0, 4.0, 1),
        (2.0, 2.5, 2),
        (0.5, 3.0, 2),
        (1.0, 2.0, 1),
    ],
)
def test_check_accepts_only_blocks_within_tolerance(amp, period_s, axis):
    """The a-posteriori check (estimate <= tol / margin) never accepts a block whose cubic is off
    by more than the tolerance: for periods >= 4 T (omega T <= pi/2) the estimate is >= the
    real error (within 5 %) at every phase; gentle manoeuvres are all accepted."""
    path = Weave(amp, period_s, axis)
    err, est = block_errors(path, M.GRAVITY_NODE_S)
    accepted = est <= M.GRAVITY_TOL_MPS2 / M.GRAVITY_CHECK_MARGIN
    print(f"snap {path.snap:.3g}: {accepted.mean():.0%} accepted, max error {err.max():.2e}, "
          f"max error / estimate {np.max(err / est):.2f}")  # fmt: skip
    assert np.all(err[accepted] <= M.GRAVITY_TOL_MPS2)
    assert np.all(err <= 1.05 * est + 3e-14)
    if path.snap > 50.0:
        assert not accepted.any()  # violent weave: every block falls back
    if path.snap < 1.0:
        assert accepted.all()  # gentle manoeuvre: every block interpolates


@pytest.mark.parametrize("periods_of_T", [3.2, 2.4])
def test_check_near_the_nodes_nyquist(periods_of_T):
    """Faster than 4 T: the estimate may fall below the error (aliasing); the margin of 2 still
    holds down to periods of pi T (1.26 s). Below that the error is bounded by the motion's
    amplitude instead: <= 4 Gamma_max A (cubic's Lebesgue constant + 1 < 4)."""
    amp = 0.01
    period_s = periods_of_T * M.GRAVITY_NODE_S
    path = Weave(amp, period_s, 2)
    err, est = block_errors(path, M.GRAVITY_NODE_S)
    accepted = est <= M.GRAVITY_TOL_MPS2 / M.GRAVITY_CHECK_MARGIN
    ratio = np.max(err / est)
    print(f"period {period_s} s: error / estimate <= {ratio:.2f}, max error {err.max():.2e}")
    if period_s >= math.pi * M.GRAVITY_NODE_S:
        assert ratio <= M.GRAVITY_CHECK_MARGIN
        assert np.all(err[accepted] <= M.GRAVITY_TOL_MPS2)
    assert err.max() <= 4.0 * M.GAMMA_MAX * amp


def run_kernel(path, dt, span, node_s, every):
    t = np.arange(0.0, span + 1e-9, dt)
    dth, dv = exact_increments(t, path.position, path.velocity, path.attitude, WGS)
    p0, v0, q0 = path.position(t[:1])[0], path.velocity(t[:1])[0], path.attitude(t[:1])[0]
    mech = M.Mechanizer(WGS, dt, p0, v0, q0)
    mech.prm = M.kernel_params(WGS, dt, node_s)
    p = np.empty((1, len(t[::every]), 3))
    v = np.empty_like(p)
    p[:, 0] = p0
    v[:, 0] = v0
    mech.run(dth[None], dv[None], out_p=p, out_v=v, every=every)
    return p[0], v[0], mech.state[0, S_FB]


@pytest.mark.parametrize("rate_hz", [20.0, 100.0])
@pytest.mark.parametrize("amp, period_s", [(2.0, 10.0), (1.0, 2.5)])
def test_kernel_within_the_bound_of_exact_gravity_every_step(rate_hz, amp, period_s):
    """Height weaves at 214 m/s over 120 s, 2 m of 10 s: snap 0.31 m/s^4 (every block
    interpolated), 1 m of 2.5 s: 39 m/s^4 (near the design snap: some blocks fall back): positions vs the exact
    gravitation every step within tol tau^2 (cosh(t/tau) - 1) (+ rounding of ~3e4 m),
    velocities within tol t (the closure error itself is the 3-point rule's, ``O(dt^3)``)."""
    path = Weave(amp, period_s, 2)
    dt, span = 1.0 / rate_hz, 120.0
    every = int(rate_hz) // 4
    p, v, nfb = run_kernel(path, dt, span, M.GRAVITY_NODE_S, every)
    p1, v1, _ = run_kernel(path, dt, span, 0.0, every)
    n_blocks = (round(span / dt) - 4 * round(M.GRAVITY_NODE_S / dt)) // round(M.GRAVITY_NODE_S / dt)
    print(f"{rate_hz} Hz, snap {path.snap:.2f}: {nfb:.0f} of {n_blocks} blocks fell back")
    assert (nfb == 0) if path.snap < 1.0 else (0 < nfb < n_blocks)
    t = np.arange(len(p)) * every * dt
    bound = M.GRAVITY_TOL_MPS2 * TAU_V**2 * (np.cosh(t / TAU_V) - 1.0) + 4e-12
    diff = np.max(np.abs(p - p1), axis=1)
    print(f"{rate_hz} Hz: max |p - p_exact| {diff.max():.2e} m (bound at the end {bound[-1]:.2e})")
    assert np.all(diff <= bound)
    assert np.all(np.max(np.abs(v - v1), axis=1) <= M.GRAVITY_TOL_MPS2 * t + 1e-13)


def test_failed_blocks_are_the_every_step_rule():
    """Violent weave (1 m, period 2 s, snap 97 m/s^4): every block fails the check and the run
    is the exact-gravitation-every-step run bit for bit, stored samples inside blocks included."""
    path = Weave(1.0, 2.0, 1)
    dt, span = 0.01, 20.0
    p, v, nfb = run_kernel(path, dt, span, M.GRAVITY_NODE_S, 7)
    p1, v1, _ = run_kernel(path, dt, span, 0.0, 7)
    m = round(M.GRAVITY_NODE_S / dt)
    assert nfb == (round(span / dt) - 4 * m) // m
    np.testing.assert_array_equal(p, p1)
    np.testing.assert_array_equal(v, v1)
