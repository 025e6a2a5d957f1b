"""Oracles for imugen.navigate.mechanize: analytic motions with closed-form increments (no truth.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen.core import earth as E
from imugen.core import rotations_nb
from imugen.core.rotations import relative_rotation_vector
from imugen.navigate import mechanize as M

from oracles.strapdown import mechanize_numpy

FLAT = E.OriginFrame.from_deg(40.78, -73.97, 30.0, model="flat")
WGS = FLAT.with_model("wgs84")
Q_ID = np.array([1.0, 0.0, 0.0, 0.0])


# --- small independent SO(3) helpers (not imugen.core.rotations) -----------------------------------
def skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def expm_so3(phi):
    """Rodrigues, float64; phi shape (3,)."""
    th = float(np.linalg.norm(phi))
    K = skew(phi)
    if th < 1e-6:
        return np.eye(3) + K * (1 - th**2 / 6) + K @ K * (0.5 - th**2 / 24)
    return np.eye(3) + math.sin(th) / th * K + (1 - math.cos(th)) / th**2 * K @ K


def dcm_from_quat(q):
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_from_dcm(C):
    w = math.sqrt(max(0.0, 1 + np.trace(C))) / 2
    if w > 1e-3:
        return np.array(
            [
                w,
                (C[2, 1] - C[1, 2]) / (4 * w),
                (C[0, 2] - C[2, 0]) / (4 * w),
                (C[1, 0] - C[0, 1]) / (4 * w),
            ]
        )
    raise AssertionError("test helper only handles small-ish rotations")


def attitude_error(q_est, C_true):
    """Rotation angle between estimated quaternion(s) and true DCM(s) [rad]."""
    q_est = np.atleast_2d(q_est)
    C_true = C_true.reshape(-1, 3, 3)
    out = []
    for q, C in zip(q_est, C_true, strict=True):
        D = dcm_from_quat(q).T @ C
        # angle from the skew part (accurate for small angles)
        s = 0.5 * np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])
        out.append(np.linalg.norm(s))
    return np.array(out)


def w_int_A(w, dt):
    """Exp(W dt) - I and int_0^dt Exp(W tau) dtau without cancellation (W = [w x])."""
    wn = np.linalg.norm(w)
    th = wn * dt
    W = skew(w)
    s1 = math.sin(th) / wn
    s2 = 2 * math.sin(th / 2) ** 2 / wn**2
    # (dt - sin(th)/wn) / wn^2 = (th - sin th) / wn^3, series for tiny th
    s3 = (th**3 / 6 - th**5 / 120 + th**7 / 5040) / wn**3
    return s1 * W + s2 * W @ W, dt * np.eye(3) + s2 * W + s3 * W @ W


# --- exact-increment closure ---------------------------------------------------------------------
def test_still_flat_one_hour():
    dt, K = 0.01, 360001
    # level: exact
    dth = np.zeros((K - 1, 3))
    dv = np.tile([0.0, 0.0, FLAT.g0 * dt], (K - 1, 1))
    nav = M.mechanize(
        dth, dv, dt, [5.0, -3.0, 2.0], np.zeros(3), Q_ID, FLAT, every=1000, outputs=("p",)
    )
    assert np.max(np.linalg.norm(nav.p_n - [5.0, -3.0, 2.0], axis=1)) < 1e-12
    # tilted: the float64 increment C^T f dt is off by up to half an ulp of g dt (7e-18 m/s),
    # the same every step: a 7e-16 m/s^2 bias, 0.5 * 7e-16 * 3600^2 = 4.5e-9 m; allow 2e-8
    C = expm_so3(np.array([0.3, -0.2, 1.1]))
    f_b = C.T @ np.array([0.0, 0.0, FLAT.g0])
    dv = np.tile(f_b * dt, (K - 1, 1))
    nav = M.mechanize(
        dth,
        dv,
        dt,
        [5.0, -3.0, 2.0],
        np.zeros(3),
        quat_from_dcm(C),
        FLAT,
        every=1000,
        outputs=("p",),
    )
    err = np.linalg.norm(nav.p_n - [5.0, -3.0, 2.0], axis=1)
    print(f"still tilted flat 1 h: max position error {err.max():.3e} m")
    assert err.max() < 2e-8
    # slowly rotating about the vertical while still: dtheta != 0 every step, no drift
    C0 = expm_so3(np.array([0.2, 0.1, 0.0]))
    wz = 0.01  # rad/s about n's up axis: C(t) = Rz(wz t) C0, omega_b = C0^T (0, 0, wz)
    dth = np.tile(C0.T @ [0.0, 0.0, wz * dt], (K - 1, 1))
    dv = np.tile(C0.T @ [0.0, 0.0, FLAT.g0 * dt], (K - 1, 1))
    nav = M.mechanize(dth, dv, dt, np.zeros(3), np.zeros(3), quat_from_dcm(C0), FLAT, every=K - 1)
    C_end = expm_so3(np.array([0.0, 0.0, wz * dt * (K - 1)])) @ C0
    print(
        f"still rotating flat 1 h: position {np.linalg.norm(nav.p_end_n):.3e} m, "
        f"attitude {attitude_error(nav.q_end_nb, C_end)[0]:.3e} rad"
    )
    assert np.linalg.norm(nav.p_end_n) < 2e-8
    assert attitude_error(nav.q_end_nb, C_end)[0] < 1e-12


def test_still_wgs84_one_hour():
    """Still and tilted on the rotating Earth: the gyros see Omega, the accelerometers -g."""
    dt, K = 0.01, 360001
    p0 = np.array([120.0, -40.0, 15.0])
    C = expm_so3(np.array([0.05, 0.02, 2.0]))
    w = E.earth_rate_n(WGS)
    r = WGS.r0_n + p0
    G = E.gravitation_n(p0, WGS)
    A_I, intA = w_int_A(w, dt)
    dth = np.tile(C.T @ w * dt, (K - 1, 1))
    # dv = C^T [ (A(dt) - I)(W r) - int A G ]  (v_n = 0)
    dv = np.tile(C.T @ (A_I @ np.cross(w, r) - intA @ G), (K - 1, 1))
    nav = M.mechanize(
        dth, dv, dt, p0, np.zeros(3), quat_from_dcm(C), WGS, every=3600, outputs=("p", "q")
    )
    err = np.linalg.norm(nav.p_n - p0, axis=1)
    print(f"still wgs84 1 h: max position error {err.max():.3e} m")
    assert err.max() < 2e-7
    assert attitude_error(nav.q_end_nb, C)[0] < 1e-14


def circle_increments(V, w, dt, n):
    """Left turn at speed V, yaw rate w, level, flat: f_b = (0, V w, g) constant."""
    dth = np.zeros((n, 3))
    dth[:, 2] = w * dt
    dv = np.zeros((n, 3))
    dv[:, 0] = V * (math.cos(w * dt) - 1.0)
    dv[:, 1] = V * math.sin(w * dt)
    dv[:, 2] = FLAT.g0 * dt
    return dth, dv


def test_circle_flat_thousands_of_turns():
    V, dt, period = 12.0, 0.01, 800  # one turn = 8 s, 1000 turns
    w = 2 * math.pi / (period * dt)
    n = period * 1000
    psi0 = 0.4
    dth, dv = circle_increments(V, w, dt, n)
    q0 = np.array([math.cos(psi0 / 2), 0, 0, math.sin(psi0 / 2)])
    p0 = np.array([V / w * math.sin(psi0), -V / w * math.cos(psi0), 0.0])
    v0 = V * np.array([math.cos(psi0), math.sin(psi0), 0.0])
    nav = M.mechanize(dth, dv, dt, p0, v0, q0, FLAT, every=period)
    psi = psi0 + w * dt * nav.index
    p_true = np.stack([V / w * np.sin(psi), -V / w * np.cos(psi), 0 * psi], axis=1)
    err = np.linalg.norm(nav.p_n - p_true, axis=1)
    print(f"circle 1000 turns: position error at full turns max {err.max():.3e} m")
    assert err.max() < 1e-8
    verr = np.linalg.norm(nav.v_n - V * np.stack([np.cos(psi), np.sin(psi), 0 * psi], 1), axis=1)
    assert verr.max() < 1e-10
    # attitude: yaw = psi
    C_true = np.stack([expm_so3(np.array([0, 0, a])) for a in psi[-3:]])
    assert attitude_error(nav.q_nb[-3:], C_true).max() < 1e-10
    # sign convention: flipping the lateral specific force breaks closure by metres
    nav_bad = M.mechanize(dth, dv * [1, -1, 1], dt, p0, v0, q0, FLAT, every=period)
    assert np.linalg.norm(nav_bad.p_end_n - p_true[-1]) > 1.0


def straight_line_wgs84(v_n, p0, C, dt, n, nodes=8):
    """Exact increments of constant Earth-relative velocity along a straight line in n,
    constant attitude, rotating Earth: gravitation integral by Gauss-Legendre per interval."""
    w = E.earth_rate_n(WGS)
    A_I, _ = w_int_A(w, dt)
    xg, wg = np.polynomial.legendre.leggauss(nodes)
    tau = 0.5 * dt * (xg + 1.0)  # nodes in [0, dt]
    wt = 0.5 * dt * wg
    A_tau = np.stack([expm_so3(w * t) for t in tau])  # (nodes, 3, 3)
    k = np.arange(n)[:, None]
    t_k = k * dt
    # gravitation at p(t_k + tau) for all k, nodes
    P = p0 + (t_k[:, :, None] + tau[None, :, None]) * v_n  # (n, nodes, 3)
    G = E.gravitation_n(P.reshape(-1, 3), WGS).reshape(n, nodes, 3)
    J = np.einsum("j,jab,kjb->ka", wt, A_tau, G)
    r1 = WGS.r0_n + p0 + (t_k + dt) * v_n  # r_{k+1}
    # v_I(t_{k+1}) - v_I(t_k) = (A - I)(v + W r_{k+1}) + W v dt
    dvI = (v_n + np.cross(w, r1)) @ A_I.T + np.cross(w, v_n) * dt
    dv = (dvI - J) @ C  # C^T (.)
    dth = np.tile(C.T @ w * dt, (n, 1))
    return dth, dv


def test_straight_line_wgs84_with_earth_rate():
    dt, n = 0.01, 60000  # 10 minutes
    v_n = np.array([18.0, -11.0, 0.4])
    p0 = np.array([-50.0, 20.0, 3.0])
    yaw = math.atan2(v_n[1], v_n[0])
    C = expm_so3(np.array([0.0, 0.0, yaw])) @ expm_so3(np.array([0.0, -0.02, 0.0]))
    dth, dv = straight_line_wgs84(v_n, p0, C, dt, n)
    nav = M.mechanize(dth, dv, dt, p0, v_n, quat_from_dcm(C), WGS, every=100)
    p_true = p0 + nav.index[:, None] * dt * v_n
    err = np.linalg.norm(nav.p_n - p_true, axis=1)
    print(f"straight line wgs84 10 min: max {err.max():.3e} m, final {err[-1]:.3e} m")
    assert err.max() < 1e-6
    assert np.max(np.abs(nav.v_n - v_n)) < 1e-9
    assert attitude_error(nav.q_end_nb, C)[0] < 1e-11
    # the Earth rate matters: the same increments in a non-rotating frame fail by metres
    nav_flat = M.mechanize(dth, dv, dt, p0, v_n, quat_from_dcm(C), WGS.with_model("flat"), every=n)
    assert np.linalg.norm(nav_flat.p_end_n - p_true[-1]) > 1.0


# --- batching, decimation, chunking, NumPy twin -----------------------------------------------
def random_increments(S, n, seed):
    rng = np.random.default_rng(seed)
    dth = rng.normal(size=(S, n, 3)) * 2e-3 + [0, 0, 1e-3]
    dv = rng.normal(size=(S, n, 3)) * 1e-2 + [0, 0, 0.0981]
    return dth, dv


@pytest.mark.parametrize("frame", [FLAT, WGS], ids=["flat", "wgs84"])
def test_batch_equals_one_at_a_time(frame):
    S, n, dt = 5, 3000, 0.01
    dth, dv = random_increments(S, n, 7)
    rng = np.random.default_rng(8)
    p0 = rng.normal(size=(S, 3)) * 100
    v0 = rng.normal(size=(S, 3)) * 10
    q0 = rng.normal(size=(S, 4))
    q0 /= np.linalg.norm(q0, axis=1, keepdims=True)
    nav = M.mechanize(dth, dv, dt, p0, v0, q0, frame, seq_chunk=2)
    for s in range(S):
        one = M.mechanize(dth[s], dv[s], dt, p0[s], v0[s], q0[s], frame)
        assert np.array_equal(one.p_n, nav.p_n[s])
        assert np.array_equal(one.v_n, nav.v_n[s])
        assert np.array_equal(one.q_nb, nav.q_nb[s])
    # decimated / position-only outputs are the same samples
    dec = M.mechanize(dth, dv, dt, p0, v0, q0, frame, every=7, outputs=("p",))
    assert dec.v_n is None and dec.q_nb is None
    assert np.array_equal(dec.p_n, nav.p_n[:, ::7])
    assert np.array_equal(dec.p_end_n, nav.p_n[:, -1])
    # time chunks through the stateful Mechanizer give the same result
    mech = M.Mechanizer(frame, dt, p0, v0, q0)
    out = np.empty((S, n + 1, 3))
    out[:, 0] = p0
    for a, b in [(0, 2), (2, 3), (3, 1000), (1000, n)]:
        mech.run(dth[:, a:b], dv[:, a:b], out_p=out)
    assert np.array_equal(out, nav.p_n)
    assert np.array_equal(mech.q_nb, nav.q_end_nb)
    # the NumPy twin (no compensated sums) agrees to rounding
    P, V, Q = mechanize_numpy(dth, dv, dt, p0, v0, q0, frame)
    np.testing.assert_allclose(P, nav.p_n, rtol=0, atol=1e-9)
    # 1e-10: a block at the gravitation check's limit may fall back in one of the two only
    np.testing.assert_allclose(V, nav.v_n, rtol=0, atol=1e-10)
    np.testing.assert_allclose(Q, nav.q_nb, rtol=0, atol=1e-13)


def test_large_rotation_increments_use_exact_exponential():
    """|dtheta| above the series threshold: a fast spin closes too."""
    dt, n = 0.01, 4000
    w = 20.0  # rad/s about body x (0.2 rad per step)
    dth = np.tile([w * dt, 0.0, 0.0], (n, 1))
    # still, spinning about the body x axis aligned with East: gravity rotates in body
    ang = w * dt * np.arange(n)
    # f_b(t) = Rx(-w t) (0,0,g); dv = int_0^dt Rx(w tau)^T... closed form per interval
    g = FLAT.g0
    c0, s0 = np.cos(ang), np.sin(ang)
    # f_b(t) = (0, g sin(wt), g cos(wt)); in body of t_k: Rx(w tau) f_b(t_k + tau)
    # = (0, g sin(w t_k), g cos(w t_k)) constant => dv = f_b(t_k) dt
    dv = np.stack([0 * ang, g * s0 * dt, g * c0 * dt], axis=1)
    nav = M.mechanize(dth, dv, dt, np.zeros(3), np.zeros(3), Q_ID, FLAT, every=n)
    assert np.linalg.norm(nav.p_end_n) < 1e-9
    C_true = expm_so3(np.array([w * dt * n, 0.0, 0.0]))
    assert attitude_error(nav.q_end_nb, C_true)[0] < 1e-11


# --- rate-sampled IMU: convergence order -----------------------------------------------------------
def right_jacobian(phi):
    th = np.linalg.norm(phi)
    K = skew(phi)
    return np.eye(3) - (1 - math.cos(th)) / th**2 * K + (th - math.sin(th)) / th**3 * K @ K


class ConingSculling:
    """C_nb(t) = Exp(psi(t) e_z) Exp(phi(t)), phi = beta (cos wt, sin wt, 0) (coning), with a
    translational vibration at the same frequency (sculling) on a drifting circle; flat Earth."""

    beta, wc, psi_rate = 0.05, 2 * math.pi * 1.0, 0.2
    amp = np.array([0.3, 0.2, 0.1])

    def C(self, t):
        phi = self.beta * np.array([math.cos(self.wc * t), math.sin(self.wc * t), 0.0])
        return expm_so3(np.array([0, 0, self.psi_rate * t])) @ expm_so3(phi)

    def omega_b(self, t):
        phi = self.beta * np.array([math.cos(self.wc * t), math.sin(self.wc * t), 0.0])
        dphi = self.beta * self.wc * np.array([-math.sin(self.wc * t), math.cos(self.wc * t), 0])
        return expm_so3(phi).T @ np.array([0, 0, self.psi_rate]) + right_jacobian(phi) @ dphi

    def pva(self, t):
        w = self.wc
        a = self.amp
        V = 5.0
        p = np.array(
            [
                V * t + a[0] * math.sin(w * t),
                a[1] * math.cos(w * t) + 0.05 * t * t,
                a[2] * math.sin(2 * w * t),
            ]
        )
        v = np.array(
            [
                V + a[0] * w * math.cos(w * t),
                -a[1] * w * math.sin(w * t) + 0.1 * t,
                2 * w * a[2] * math.cos(2 * w * t),
            ]
        )
        acc = np.array(
            [
                -a[0] * w * w * math.sin(w * t),
                -a[1] * w * w * math.cos(w * t) + 0.1,
                -4 * w * w * a[2] * math.sin(2 * w * t),
            ]
        )
        return p, v, acc

    def rates(self, rate_hz, T):
        n = round(T * rate_hz) + 1
        t = np.arange(n) / rate_hz
        om = np.stack([self.omega_b(x) for x in t])
        g_n = np.array([0, 0, -FLAT.g0])
        f = np.stack([self.C(x).T @ (self.pva(x)[2] - g_n) for x in t])
        return om, f


def test_rate_sampled_converges_second_order():
    mot = ConingSculling()
    # the analytic angular rate matches the attitude it integrates (finite-difference check)
    t, h = 0.37, 1e-5
    Cd = (mot.C(t + h) - mot.C(t - h)) / (2 * h)
    Wb = mot.C(t).T @ Cd
    np.testing.assert_allclose([Wb[2, 1], Wb[0, 2], Wb[1, 0]], mot.omega_b(t), atol=1e-8)
    T = 10.0
    p0, v0, _ = mot.pva(0.0)
    q0 = quat_from_dcm(mot.C(0.0))
    pT = mot.pva(T)[0]
    CT = mot.C(T)
    errs, aerrs = [], []
    for rate in (10, 100, 1000):
        om, f = mot.rates(rate, T)
        nav = M.mechanize_rates(om, f, 1.0 / rate, p0, v0, q0, FLAT, outputs=())
        errs.append(np.linalg.norm(nav.p_end_n - pT))
        aerrs.append(attitude_error(nav.q_end_nb, CT)[0])
    order = np.log10(np.array(errs[:-1]) / np.array(errs[1:]))
    aorder = np.log10(np.array(aerrs[:-1]) / np.array(aerrs[1:]))
    print(f"rate-sampled position errors {errs} -> orders {order}; attitude {aerrs} -> {aorder}")
    assert np.all(order >= 1.9)
    assert np.all(aorder >= 1.9)
    # exact increments of the same motion would close; here 1 kHz must already be close
    assert errs[-1] < 1e-3


# --- precise angle increments from quaternion samples ---------------------------------------------
def _qmul(a, b):
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def test_dtheta_from_quaternions_is_precise_during_stops():
    rng = np.random.default_rng(5)
    qa = rng.normal(size=(500, 4))
    qa /= np.linalg.norm(qa, axis=1, keepdims=True)
    w = E.earth_rate_n(WGS)
    dt = 0.01
    Cs = np.stack([dcm_from_quat(q) for q in qa])
    # moving: q_b = q_a Exp(phi) in a non-rotating frame -> phi back (to rounding)
    phi = rng.normal(size=(500, 3)) * 0.02
    qb = _qmul(qa, np.stack([quat_from_dcm(expm_so3(p)) for p in phi]))
    np.testing.assert_allclose(relative_rotation_vector(qa, qb), phi, rtol=0, atol=1e-15)
    # held attitude on the rotating Earth: dtheta = C^T Omega dt, to ~1e-16 *relative*
    exact = np.einsum("nji,j->ni", Cs, w * dt)
    got = relative_rotation_vector(qa, qa, w, dt)
    assert np.max(np.abs(got - exact)) < 1e-20
    # general case agrees with the definition Log(q_a^* Exp(W dt) q_b)
    got = relative_rotation_vector(qa, qb, w, dt)
    ref = []
    for C, pb in zip(Cs, qb, strict=True):
        D = C.T @ expm_so3(w * dt) @ dcm_from_quat(pb)
        ang = math.acos(max(-1.0, min(1.0, (np.trace(D) - 1) / 2)))
        axis = np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]])
        ref.append(axis / (2 * math.sin(ang)) * ang)
    np.testing.assert_allclose(got, np.array(ref), rtol=0, atol=1e-13)


# --- kernel arithmetic ----------------------------------------------------------------------------
def test_fused_multiply_add_rounds_once():
    """``fma(a, b, c)`` is ``a b + c`` rounded once: the exact rational result, rounded."""
    from fractions import Fraction

    from imugen.core.jit import njit

    fused = njit(lambda a, b, c: rotations_nb.fma(a, b, c))
    a, b = 1.0 + 2.0**-30, 1.0 - 2.0**-30
    assert a * b - 1.0 == 0.0  # two roundings lose it
    assert fused(a, b, -1.0) == -(2.0**-60)
    rng = np.random.default_rng(3)
    for a, b, c in rng.normal(size=(200, 3)) * [1.0, 1e3, 1e-2]:
        assert fused(a, b, c) == float(Fraction(a) * Fraction(b) + Fraction(c))


def test_attitude_stays_unit_through_large_and_many_increments():
    """The renormalization (first order, from |q|^2 - 1 and |Exp(dtheta)|^2 - 1 only) keeps
    |q| at 1 to rounding over 360,000 steps of rates up to 30 rad/s at 100 Hz (series and
    closed-form branches of the exponential)."""
    rng = np.random.default_rng(11)
    n, dt = 360_000, 0.01
    dth = rng.normal(size=(2, n, 3)) * np.array([1e-3, 0.3])[:, None, None]
    dv = rng.normal(size=(2, n, 3)) * 1e-2
    nav = M.mechanize(dth, dv, dt, np.zeros(3), np.zeros(3), [1.0, 0, 0, 0], WGS, every=1000)
    norm = np.linalg.norm(nav.q_nb, axis=-1)
    print(f"max | |q| - 1 |: {np.max(np.abs(norm - 1.0)):.1e}")
    assert np.max(np.abs(norm - 1.0)) < 4e-16
