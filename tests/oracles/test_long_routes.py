"""Routes of any length in the ``geodetic`` (ECEF) formulation: closure and convergence oracles.

Synthetic stand-ins of issue 11's scenes, made analytically so that position, velocity,
acceleration, attitude and body rate are exact: the vehicle moves on a small (or great) circle
of the sphere of directions, ``r = (R_ell(u) + h(t)) u(t)``, ``u = cos th0 n + sin th0 (cos s a +
sin s b)``, with ``R_ell(u)`` the ellipsoid's geocentric radius along ``u`` (so ``h`` is the
height above the ellipsoid to 6e-6 h), body x along the circle's tangent, body z along ``u``;
then ``omega_eb_b = s' (0, sin th0, cos th0)`` exactly.

* a 264 km road drive (Piacenza -> Rimini-like: left-turning circle, speed 17-33 m/s, hills);
* a 429 km flight climbing to 6.8 km at 770 km/h;
* a 7,600 km airliner route across the antimeridian (Tokyo -> Pacific, 11 km, 900 km/h);
* a 1,100 km polar crossing over the North Pole.

Pure inertial navigation is unstable in the vertical (``exp(t / 570 s)``): over hours any
rounding grows past metres, whatever the integrator. Zero-error closure (<= 1e-6 m) is therefore
checked on 5-min windows at the start, at a feature (top of climb, the crossing of 180 deg, the
pole) and at the end, each started from the truth, and on the whole 38-min flight.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from imugen.closure import attitude_angle
from imugen.core import earth as E
from imugen.core.rotations import dcm_to_quat, exp_dcm, quat_to_dcm
from imugen.navigate import mechanize as M
from imugen.navigate._kernel import S_FB

from oracles.strapdown import exact_increments

A, B = E.A_WGS84, E.B_WGS84
C2 = A * A - B * B
W_E = np.array([0.0, 0.0, E.OMEGA_IE])


class CircleRoute:
    """Analytic motion on a circle of directions (see the module docstring), ECEF."""

    def __init__(self, lat_deg, lon_deg, heading_deg, theta0, dist, height, duration):
        lat, lon, az = map(math.radians, (lat_deg, lon_deg, heading_deg))
        C_le = E.C_en_from_geodetic(lat, lon)
        u0 = E.ecef_from_geodetic(lat, lon, 0.0)
        u0 = u0 / np.linalg.norm(u0)
        t0 = math.sin(az) * C_le[0] + math.cos(az) * C_le[1]
        t0 = t0 - u0 * (t0 @ u0)
        t0 /= np.linalg.norm(t0)
        l0 = np.cross(u0, t0)
        self.n = math.cos(theta0) * u0 + math.sin(theta0) * l0
        self.a = math.sin(theta0) * u0 - math.cos(theta0) * l0
        self.b = t0
        self.th0 = theta0
        self.rs = (E.R_MEAN) * math.sin(theta0)  # distance -> angle along the circle
        self.dist = dist  # t -> (D, D', D'') [m, m/s, m/s^2]
        self.height = height  # t -> (h, h', h'')
        self.T = duration

    def _dirs(self, t):
        D, Dd, Ddd = self.dist(t)
        s, sd, sdd = D / self.rs, Dd / self.rs, Ddd / self.rs
        cs, ss = np.cos(s)[:, None], np.sin(s)[:, None]
        k = cs * self.a + ss * self.b
        m = -ss * self.a + cs * self.b
        st, ct = math.sin(self.th0), math.cos(self.th0)
        u = ct * self.n + st * k
        ud = st * sd[:, None] * m
        udd = st * (sdd[:, None] * m - (sd * sd)[:, None] * k)
        return u, ud, udd, m, sd

    def kinematics(self, t):
        """(r, v, acc) [m, m/s, m/s^2], each (m, 3), Earth-relative in ECEF."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        u, ud, udd, _, _ = self._dirs(t)
        h, hd, hdd = self.height(t)
        uz, uzd, uzdd = u[:, 2], ud[:, 2], udd[:, 2]
        Q = B * B + C2 * uz * uz
        Qd = 2.0 * C2 * uz * uzd
        Qdd = 2.0 * C2 * (uzd * uzd + uz * uzdd)
        R = A * B / np.sqrt(Q)
        Rd = -0.5 * R * Qd / Q
        Rdd = 0.75 * R * Qd * Qd / (Q * Q) - 0.5 * R * Qdd / Q
        rho, rhod, rhodd = R + h, Rd + hd, Rdd + hdd
        r = rho[:, None] * u
        v = rhod[:, None] * u + rho[:, None] * ud
        acc = rhodd[:, None] * u + 2.0 * rhod[:, None] * ud + rho[:, None] * udd
        return r, v, acc

    def position(self, t):
        return self.kinematics(t)[0]

    def velocity(self, t):
        return self.kinematics(t)[1]

    def attitude(self, t):
        """q_eb: body x along the circle's tangent, z along u (scalar first), (m, 4)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        u, _, _, m, _ = self._dirs(t)
        C = np.stack([m, np.cross(u, m), u], axis=-1)
        q = dcm_to_quat(C)
        return q * np.where(q[:, :1] < 0.0, -1.0, 1.0)  # one hemisphere (scalar > 0 here)

    def rates(self, t):
        """Ideal instantaneous (omega_ib_b, f_b) at t, each (m, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        r, v, acc = self.kinematics(t)
        _, _, _, _, sd = self._dirs(t)
        C = quat_to_dcm(self.attitude(t))
        w_eb = sd[:, None] * np.array([0.0, math.sin(self.th0), math.cos(self.th0)])
        w_ib = w_eb + W_E @ C  # C^T Omega_e
        f_e = acc + 2.0 * np.cross(W_E, v) - E.gravity_e(r)
        return w_ib, np.einsum("mji,mj->mi", C, f_e)


# --- speed and height profiles (closed forms with two derivatives) -----------------------------
def _sech2(x):
    e = np.exp(-2.0 * np.abs(x))
    return 4.0 * e / (1.0 + e) ** 2


def _lc(x):
    ax = np.abs(x)
    return ax + np.log1p(np.exp(-2.0 * ax)) - math.log(2.0)


def ramp_profile(V, t1, t2, tau):
    """Speed V/2 (tanh((t-t1)/tau) - tanh((t-t2)/tau)): (D, D', D'') with D(0) = 0."""

    def f(t):
        t = np.asarray(t, dtype=float)
        x1, x2 = (t - t1) / tau, (t - t2) / tau
        D0 = 0.5 * V * tau * (_lc(-t1 / tau) - _lc(-t2 / tau))
        D = 0.5 * V * tau * (_lc(x1) - _lc(x2)) - D0
        Dd = 0.5 * V * (np.tanh(x1) - np.tanh(x2))
        Ddd = 0.5 * V / tau * (_sech2(x1) - _sech2(x2))
        return D, Dd, Ddd

    return f


def bump_height(h0, H, t3, t4, tau):
    """h0 + H/2 (tanh((t-t3)/tau) - tanh((t-t4)/tau)): climb, cruise, descent."""

    def f(t):
        t = np.asarray(t, dtype=float)
        x3, x4 = (t - t3) / tau, (t - t4) / tau
        s3, s4 = _sech2(x3), _sech2(x4)
        h = h0 + 0.5 * H * (np.tanh(x3) - np.tanh(x4))
        hd = 0.5 * H / tau * (s3 - s4)
        hdd = H / tau**2 * (-np.tanh(x3) * s3 + np.tanh(x4) * s4)
        return h, hd, hdd

    return f


def wave(c0, c1, w):
    """(c0 t + c1/w (1 - cos w t), its two derivatives): speed c0 + c1 sin(w t)."""

    def f(t):
        t = np.asarray(t, dtype=float)
        return (
            c0 * t + c1 / w * (1 - np.cos(w * t)),
            c0 + c1 * np.sin(w * t),
            c1 * w * np.cos(w * t),
        )

    return f


def hills(h0, H, w):
    def f(t):
        t = np.asarray(t, dtype=float)
        return h0 + H * np.sin(w * t), H * w * np.cos(w * t), -H * w * w * np.sin(w * t)

    return f


def road_264km():
    # left-turning circle of 150 km radius, 25 +- 8 m/s, hills of +-50 m
    T = 264e3 / 25.0
    return CircleRoute(
        45.05, 9.69, 110.0, math.asin(150e3 / E.R_MEAN), wave(25.0, 8.0, 2 * math.pi / 300),
        hills(100.0, 50.0, 2 * math.pi / 900), T,
    )  # fmt: skip


def flight_429km():
    V = 770 / 3.6
    t1, tau = 150.0, 40.0
    t2 = t1 + 429e3 / V
    return CircleRoute(
        45.63, 8.72, 95.0, math.pi / 2, ramp_profile(V, t1, t2, tau),
        bump_height(200.0, 6600.0, 400.0, t2 - 300.0, 150.0), t2 + t1,
    )  # fmt: skip


def antimeridian_7600km():
    V = 250.0
    t1, tau = 200.0, 50.0
    t2 = t1 + 7600e3 / V
    return CircleRoute(
        35.55, 139.78, 55.0, math.pi / 2, ramp_profile(V, t1, t2, tau),
        bump_height(10.0, 11000.0, 900.0, t2 - 700.0, 300.0), t2 + t1,
    )  # fmt: skip


def polar_1100km():
    V = 250.0
    t1, tau = 150.0, 60.0
    t2 = t1 + 1100e3 / V
    return CircleRoute(
        85.05, 30.0, 0.0, math.pi / 2, ramp_profile(V, t1, t2, tau),
        bump_height(10.0, 9000.0, 300.0, t2 - 300.0, 100.0), t2 + t1,
    )  # fmt: skip


ROUTES = {
    "road 264 km": road_264km,
    "flight 429 km": flight_429km,
    "antimeridian 7600 km": antimeridian_7600km,
    "polar 1100 km": polar_1100km,
}
GEO = E.OriginFrame(0.0, 0.0, 0.0, model="geodetic")


def truth(route, dt, t_end=None):
    t_end = route.T if t_end is None else t_end
    t = np.arange(0.0, t_end + 1e-9, dt)
    r, v, _ = route.kinematics(t)
    return t, r, v, route.attitude(t)


def test_stand_ins_are_the_scenes():
    """The synthetic routes have the lengths, heights, speeds and geography they stand for."""
    for name, make in ROUTES.items():
        rt = make()
        t = np.linspace(0.0, rt.T, 20001)
        r, v, acc = rt.kinematics(t)
        lat, lon, h = E.geodetic_from_ecef(r)
        length = np.sum(np.linalg.norm(np.diff(r, axis=0), axis=1))
        spd = np.linalg.norm(v, axis=1)
        km = {"road": 264, "flight": 429, "antimeridian": 7600, "polar": 1100}[name.split()[0]]
        assert length / 1e3 == pytest.approx(km, rel=0.02), name
        assert np.all(np.linalg.norm(acc, axis=1) < 3.0), name  # plausible accelerations
        if name.startswith("road"):
            assert 16 < spd.min() and spd.max() < 34 and np.ptp(h) < 101
        if name.startswith("flight"):
            assert h.max() == pytest.approx(6800.0, abs=30) and spd.max() == pytest.approx(
                770 / 3.6, rel=0.01
            )
        if name.startswith("anti"):
            assert np.any(np.diff(np.unwrap(lon)) != np.diff(lon))  # crosses +-180 deg
            assert np.degrees(lon).min() < -170 and np.degrees(lon).max() > 170
        if name.startswith("polar"):
            assert np.degrees(lat).max() > 89.9


def test_exact_increments_match_rates_and_kernel_inverse():
    """exact_increments (any model) against the analytic rates; flat and wgs84 frames too."""
    rt = flight_429km()
    dt = 0.01
    t = np.arange(1000.0, 1000.0 + 2.0 + 1e-9, dt)
    dth, dv = exact_increments(t, rt.position, rt.velocity, rt.attitude, GEO)
    w, f = rt.rates(t)
    # the 2nd-order rate scheme agrees with the exact increments to O(dt^3)
    dth_r, dv_r = M.increments_from_rates(w, f, dt)
    assert np.max(np.abs(dth_r - dth)) < 1e-12
    assert np.max(np.abs(dv_r - dv)) < 1e-9
    # the same motion in an origin (ENU) frame: same increments (frame-independent physics)
    fr = E.OriginFrame.from_deg(45.6, 8.7, 200.0, model="wgs84")
    C, r0 = fr.C_en, fr.r0_e

    def q_n(tt):
        from imugen.core.rotations import quat_mul

        return quat_mul(np.broadcast_to(dcm_to_quat(C), (len(tt), 4)), rt.attitude(tt))

    dth_n, dv_n = exact_increments(
        t, lambda tt: (rt.position(tt) - r0) @ C.T, lambda tt: rt.velocity(tt) @ C.T, q_n, fr
    )
    assert np.max(np.abs(dth_n - dth)) < 1e-15
    assert np.max(np.abs(dv_n - dv)) < 1e-13


# windows (start times [s]) checked per route: the start, a feature, the end
WINDOWS = {
    "road 264 km": (0.0, 5000.0, 10260.0),
    "flight 429 km": (0.0, 300.0, 2000.0),  # take-off and climb, top of climb, descent
    "antimeridian 7600 km": (0.0, 14300.0, 30100.0),  # the crossing of 180 deg at ~14,450 s
    "polar 1100 km": (0.0, 2200.0, 4300.0),  # the pole at ~2,350 s
}


def closure_window(rt, t0, span, dt):
    """Mechanize the exact increments of [t0, t0 + span] from the true state at t0.

    Returns the largest 3-D position error [m] (local level at the true position), the
    final attitude error [rad] and the errors (m, 5) at 1 s.
    """
    t = t0 + np.arange(0.0, span + 1e-9, dt)
    r, v, _ = rt.kinematics(t)
    q = rt.attitude(t)
    dth, dv = exact_increments(t, rt.position, rt.velocity, rt.attitude, GEO)
    every = round(1.0 / dt)
    nav = M.mechanize(dth, dv, dt, r[0], v[0], q[0], GEO, every=every)
    err = E.errors_local_level(r[::every], nav.p_n, v[::every])
    return (
        float(np.max(np.linalg.norm(err[:, :3], axis=1))),
        float(attitude_angle(q[-1], nav.q_end_nb)),
        err,
    )


@pytest.mark.parametrize("name", list(ROUTES))
def test_zero_error_closure_long_routes(name):
    rt = ROUTES[name]()
    for t0 in WINDOWS[name]:
        pos, att, err = closure_window(rt, t0, 300.0, 0.05)
        print(f"{name}, 5 min from {t0:.0f} s at 20 Hz: max position error {pos:.2e} m "
              f"(along {np.nanmax(np.abs(err[:, 3])):.1e}, cross "
              f"{np.nanmax(np.abs(err[:, 4])):.1e}), attitude {att:.2e} rad")  # fmt: skip
        assert pos <= 1e-6
        assert att <= 1e-9


def test_zero_error_closure_whole_flight_unaided():
    """The whole 429 km flight (38 min) from one initial state: <= 1e-6 m all along."""
    rt = flight_429km()
    pos, att, _ = closure_window(rt, 0.0, rt.T, 0.05)
    print(f"whole flight at 20 Hz: max {pos:.2e} m, final attitude {att:.2e} rad")
    assert pos <= 1e-6
    assert att <= 1e-9


@pytest.mark.parametrize("name", list(ROUTES))
def test_rate_sampled_converges_second_order_long_routes(name):
    rt = ROUTES[name]()
    t0 = {"road": 1000.0, "flight": 100.0, "antimeridian": 150.0, "polar": 2150.0}[name.split()[0]]
    errs = []
    for rate in (5.0, 10.0, 20.0):
        dt = 1.0 / rate
        t = t0 + np.arange(0.0, 300.0 + 1e-9, dt)
        r, v, _ = rt.kinematics(t)
        q = rt.attitude(t)
        w, f = rt.rates(t)
        nav = M.mechanize_rates(w, f, dt, r[0], v[0], q[0], GEO)
        e = E.errors_local_level(r[-1], nav.p_end_n, v[-1])
        errs.append(float(np.linalg.norm(e[:3])))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print(name, "final errors", errs, "orders", orders)
    assert np.all(np.abs(orders - 2.0) < 0.25)


def test_errors_local_level_geometry():
    # a vehicle heading north-east at 45 deg lat; nav 3 m ahead, 2 m left, 1 m up
    lat, lon = math.radians(45.0), math.radians(179.9)
    p = E.ecef_from_geodetic(lat, lon, 100.0)
    C = E.C_en_from_geodetic(lat, lon)
    fwd = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    left = np.array([-1.0, 1.0, 0.0]) / math.sqrt(2)
    d_l = 3 * fwd + 2 * left + np.array([0, 0, 1.0])
    err = E.errors_local_level(p, p + C.T @ d_l, C.T @ (20 * fwd + [0, 0, 5.0]))
    np.testing.assert_allclose(err, [*d_l, 3.0, 2.0], atol=1e-9)
    # standing still: along/cross undefined
    err = E.errors_local_level(p, p + C.T @ d_l, np.zeros(3))
    assert np.isnan(err[3]) and np.isnan(err[4])
    np.testing.assert_allclose(err[:3], d_l, atol=1e-9)


def test_local_level_reports_at_the_vehicle():
    rt = polar_1100km()
    t = np.array([0.0, 2300.0, 4500.0])  # before, at and after the pole
    r, v, _ = rt.kinematics(t)
    q = rt.attitude(t)
    lat, lon, _, v_l, q_lb = E.local_level(r, v, q)
    C_le = E.C_en_from_geodetic(lat, lon)
    np.testing.assert_allclose(v_l, np.einsum("mij,mj->mi", C_le, v), atol=1e-12)
    # body z is the geocentric direction: within the geocentric/geodetic angle (< 0.2 deg) of up
    z_l = quat_to_dcm(q_lb)[:, :, 2]
    assert np.all(z_l[:, 2] > math.cos(math.radians(0.2)))
    np.testing.assert_allclose(np.linalg.norm(q_lb, axis=1), 1.0, atol=1e-15)


def test_gravitation_nodes_interpolation_bound():
    """The kernels' cubic-in-time gravitation between exact nodes every T = 0.2 s: error
    <= T^4/24 max|d^4G/dt^4| ~ T^4/24 |Gamma| snap, |Gamma| <= 2 GM / r^3 = 3.1e-6 s^-2
    (tests/navigate/test_gravity_nodes.py: the check that enforces the tolerance)."""
    fr = E.OriginFrame.from_deg(45.0, 7.0, 300.0, model="wgs84")
    w = E.earth_rate_n(fr)
    T = M.GRAVITY_NODE_S
    # a 1 m weave of period 4 T (the fastest the nodes resolve); a straight line
    for amp, om in ((1.0, 2 * math.pi / (4 * T)), (0.0, 0.0)):
        t = np.arange(0.0, 20.0, T / 20)
        p = np.stack([60.0 * t, amp * np.sin(om * t), 5.0 * t], axis=1)
        g = np.einsum("mij,mj->mi", exp_dcm(w[None, :] * t[:, None]), E.gravitation_n(p, fr))
        nodes = g[::20]
        err = 0.0
        for j in range(3, len(nodes) - 1):  # interval [node j, node j+1] from j-2 .. j+1
            n2, n1, n0, ge = nodes[j - 2], nodes[j - 1], nodes[j], nodes[j + 1]
            c2 = 0.5 * (ge + n1) - n0
            sv = 0.5 * (ge - n1)
            c3 = (n0 - n2 + 4 * c2 - 2 * sv) / 6
            c1 = sv - c3
            tau = np.arange(20)[:, None] / 20
            approx = n0 + tau * (c1 + tau * (c2 + tau * c3))
            err = max(err, float(np.max(np.abs(approx - g[20 * j : 20 * j + 20]))))
        snap = amp * om**4
        bound = T**4 / 24 * 3.1e-6 * snap * 1.01 + 3e-14  # + rounding of the node values
        print(f"weave {amp} m: interpolation error {err:.2e} m/s^2, bound {bound:.2e}")
        assert err <= bound
        if snap:
            assert err > 0.3 * bound  # the bound is tight, not vacuous


def test_gravitation_nodes_against_exact_every_step():
    """Kernel with nodes every 0.2 s against the exact gravitation at every step: the 429 km
    flight's climb at 100 Hz (smooth: no block fails the check, agrees to 1e-9 m, 1 ulp of
    the ECEF position) and its closure."""
    rt = flight_429km()
    dt = 0.01
    t = 300.0 + np.arange(0.0, 120.0 + 1e-9, dt)
    r, v, _ = rt.kinematics(t)
    q = rt.attitude(t)
    dth, dv = exact_increments(t, rt.position, rt.velocity, rt.attitude, GEO)
    every = 100
    out = {}
    for node_s in (M.GRAVITY_NODE_S, 0.0):
        mech = M.Mechanizer(GEO, dt, r[0], v[0], q[0])
        mech.prm = M.kernel_params(GEO, dt, node_s)
        p = np.empty((1, len(t[::every]), 3))
        p[:, 0] = r[0]
        mech.run(dth[None], dv[None], out_p=p, every=every)
        out[node_s] = p[0]
        assert mech.state[0, S_FB] == 0
        err = E.errors_local_level(r[::every], p[0], v[::every])
        assert np.max(np.linalg.norm(err[:, :3], axis=1)) <= 1e-6
    assert int(M.kernel_params(GEO, dt)[M.K_MB]) == 20
    assert np.max(np.abs(out[M.GRAVITY_NODE_S] - out[0.0])) < 1e-9


def test_geodetic_and_origin_frame_kernels_agree():
    """The same increments from the same state: ECEF kernel vs origin-ENU kernel (wgs84), and
    the attitude relative to the local level at the vehicle from either."""
    from imugen.core.rotations import quat_mul

    rt = flight_429km()
    dt = 0.02
    t = 200.0 + np.arange(0.0, 300.0 + 1e-9, dt)
    r, v, _ = rt.kinematics(t)
    q = rt.attitude(t)
    dth, dv = exact_increments(t, rt.position, rt.velocity, rt.attitude, GEO)
    fr = E.OriginFrame.from_deg(45.6, 8.7, 200.0, model="wgs84")
    C = fr.C_en
    q_ne = dcm_to_quat(C)
    geo = M.mechanize(dth, dv, dt, r[0], v[0], q[0], GEO, every=50)
    enu = M.mechanize(
        dth, dv, dt, fr.n_from_ecef(r[0]), C @ v[0], quat_mul(q_ne, q[0]), fr, every=50
    )
    np.testing.assert_allclose(fr.ecef_from_n(enu.p_n), geo.p_n, rtol=0, atol=1e-8)
    np.testing.assert_allclose(enu.v_n @ C, geo.v_n, rtol=0, atol=1e-10)
    _, _, _, v_l, q_lb = E.local_level(geo.p_n, geo.v_n, geo.q_nb)
    C_lb = fr.C_ln(enu.p_n) @ quat_to_dcm(enu.q_nb)
    np.testing.assert_allclose(quat_to_dcm(q_lb), C_lb, rtol=0, atol=1e-12)
    np.testing.assert_allclose(v_l, np.einsum("mij,mj->mi", fr.C_ln(enu.p_n), enu.v_n), atol=1e-9)
