"""A rig for the filter's compiled model functions: one sequence, one epoch, the kernel's named
tuples built as :func:`imugen.aid.filter.run` builds them, and the true state of an error
``dx`` (estimate minus truth) computed independently of the kernel's feedback."""

from __future__ import annotations

import numpy as np
import pytest

from imugen.aid.filter.context import Epoch, Inputs, Model, new_work
from imugen.aid.filter.propagate import step_params
from imugen.aid.filter.state import NOMINAL, NX
from imugen.aid.filter.tuning import N_TUNE
from imugen.core import earth
from imugen.core.earth import OriginFrame
from imugen.core.rotations import dcm_to_quat, euler_to_dcm, exp_dcm, quat_to_dcm

ORIGIN = (45.0, 7.0, 200.0)


class Rig:
    """One sequence at one epoch: nominal state ``x``, measured body rate ``w_meas``
    (the epoch's rate is ``(w_meas - b_g) / (1 + s_g)``), the kernel's :class:`Model`,
    :class:`Inputs` (GNSS fix ``zp``, ``zv``; companions ``cz``) and :class:`Work`."""

    def __init__(self, opts, model="flat", latency=0.0, lever=(0.6, 0.3, 1.2), seed=0):
        rng = np.random.default_rng(seed)
        self.opts, self.lay = opts, opts.layout
        self.frame = OriginFrame.from_deg(*ORIGIN, model=model)
        dt = 0.01
        prm = step_params(self.frame, dt)
        self.md = Model(
            prm=prm, opt=opts.switches(), ie=self.lay.offsets(), ix=NOMINAL.offsets(),
            feedback=self.lay.feedback_table(), dt=dt, g0=float(prm[earth.P_G0]),
            h0=float(self.frame.h0_m), wgs=model != "flat", geo=model == "geodetic",
        )  # fmt: skip
        S, J, K = 1, 1, 3
        tun = np.zeros((S, N_TUNE))
        tun[:, 0:3] = 1e-3  # gyro white noise (the NHC's gate and noise)
        self.inp = Inputs(
            dth=np.zeros((S, K, 3)), dvb=np.zeros((S, K, 3)), k0=np.zeros(S, np.int64),
            ep_idx=np.array([K - 1], np.int64), zp=rng.normal(size=(S, J, 3)),
            zv=rng.normal(size=(S, J, 3)), sp=np.ones((S, J, 3)), sv=np.ones((S, J, 3)),
            ok=np.ones((S, J), bool), lever=np.array([lever], float),
            lat=np.array([latency], float), cz=np.zeros((S, J, 4)), cmark=np.ones(J, np.int8),
            clever=np.zeros((S, 3)), tun=tun, x0=np.zeros((S, NX)),
            P0=np.zeros((S, self.lay.n, self.lay.n)), lv=np.zeros((S, 0, 3)),
            lvW=np.zeros((S, 0, 3, 3)), nvar=np.zeros((S, 0, 2)), carry=np.zeros((S, 2)),
        )  # fmt: skip
        self.wk = new_work(self.lay.n)
        np.fill_diagonal(self.wk.P, 0.01)
        x = np.zeros(NX)
        p = rng.normal(scale=50.0, size=3)
        if model == "geodetic":  # n = ECEF: near the origin
            p = self.frame.with_model("wgs84").ecef_from_n(p[None])[0]
        x[NOMINAL.slice("p")] = p
        x[NOMINAL.slice("v")] = (12.0, -3.0, 0.4)
        x[NOMINAL.slice("att")] = dcm_to_quat(euler_to_dcm(0.05, -0.03, 0.7)[None])[0]
        x[NOMINAL.slice("bg")] = rng.normal(scale=1e-3, size=3)
        self.w_meas = np.array([0.3, -0.2, 0.5])
        self.x = x

    def true_state(self, dx, x=None):
        """The state whose error is ``dx``: ``x - dx`` on additive blocks, ``C = Exp(-psi)
        C_hat`` (not through the kernel's feedback)."""
        x = (self.x if x is None else x).copy()
        for key in (b.key for b in self.lay.blocks):
            if key == "att":
                C = exp_dcm(-dx[self.lay.slice("att")]) @ quat_to_dcm(x[NOMINAL.slice("att")])
                x[NOMINAL.slice("att")] = dcm_to_quat(C[None])[0]
            else:
                i, m = NOMINAL.offset(key), min(NOMINAL.size(key), self.lay.size(key))
                x[i : i + m] -= dx[self.lay.offset(key) : self.lay.offset(key) + m]
        return x

    def epoch(self, x):
        """The epoch at state ``x``: ``wk.C`` set from its attitude; returns the Epoch."""
        self.wk.C[:] = quat_to_dcm(x[NOMINAL.slice("att")])
        w = (self.w_meas - x[NOMINAL.slice("bg")]) / (1.0 + x[NOMINAL.slice("sg")])
        return Epoch(0, 0, 2, True, True, tuple(float(a) for a in w))

    def h(self, m):
        """The dense row built by a row function with ``m`` non-zeros."""
        out = np.zeros(self.lay.n)
        out[self.wk.hz[:m]] = self.wk.h[self.wk.hz[:m]]
        return out

    def numerical_row(self, residual, eps=1e-6):
        """Central differences of ``residual(x) - residual(true_state(dx))`` in every error
        component: ``d r / d dx`` at ``dx = 0``."""
        n = self.lay.n
        out = np.zeros(n)
        for i in range(n):
            d = np.zeros(n)
            d[i] = eps
            out[i] = (residual(self.true_state(-d)) - residual(self.true_state(d))) / (2 * eps)
        return out


@pytest.fixture
def rig():
    """``rig(opts, model="flat", latency=0.0, ...)``: a :class:`Rig`."""
    return Rig
