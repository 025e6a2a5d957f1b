"""Vehicle attitude: target frame from velocity and a reference vector, attitude holds at low
speed blended in by a quintic smoothstep, roll flips of coordinated flight."""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import BSpline
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from imugen.core import earth as ea
from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.core.jit import njit
from imugen.truth.fit import fit_height_profile
from imugen.truth.road import distance_steps
from imugen.truth.suspension import Suspension
from imugen.truth.vehicles import has_suspension


def _smoothstep(x, lo, hi):
    """Quintic smoothstep and its derivative (C^2): 0 below lo, 1 above hi."""
    u = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    s = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
    ds = 30.0 * u * u * (1.0 - u) ** 2 / (hi - lo)
    return s, ds


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _target_frame(v, a, r, rd):
    """Body frame with x along v and z along r's component perpendicular to x.

    Parameters
    ----------
    v, a : ndarray, shape (m, 3)
        Velocity and acceleration in n.
    r, rd : ndarray, shape (m, 3)
        Reference vector and its time derivative in n.

    Returns
    -------
    C_nb (m, 3, 3), omega_nb_b (m, 3), speed (m,), speed_dot (m,), rperp (m,), rperp_dot (m,)
    """
    sp_ = np.linalg.norm(v, axis=1)
    sps = np.maximum(sp_, 1e-9)
    x = v / sps[:, None]
    xa = _dot(x, a)
    xd = (a - x * xa[:, None]) / sps[:, None]
    xr = _dot(x, r)
    rp = r - x * xr[:, None]
    rpn = np.linalg.norm(rp, axis=1)
    rps = np.maximum(rpn, 1e-9)
    z = rp / rps[:, None]
    rpd = rd - xd * xr[:, None] - x * (_dot(xd, r) + _dot(x, rd))[:, None]
    zrpd = _dot(z, rpd)
    zd = (rpd - z * zrpd[:, None]) / rps[:, None]
    y = np.cross(z, x)
    yd = np.cross(zd, x) + np.cross(z, xd)
    C = np.stack([x, y, z], axis=-1)
    w = np.column_stack([_dot(yd, z), _dot(zd, x), _dot(xd, y)])
    return C, w, sp_, xa, rpn, zrpd


POLE_MARGIN_RAD = math.radians(1.0)  # headings from geographic North this far from a pole
_N_AXES = 256  # candidate transverse poles spread over the sphere


def _sphere_directions(n):
    """``n`` unit vectors spread evenly over the sphere (Fibonacci lattice), shape (n, 3)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    az = math.pi * (3.0 - math.sqrt(5.0)) * i
    rho = np.sqrt(1.0 - z * z)
    return np.column_stack([rho * np.cos(az), rho * np.sin(az), z])


class EarthField:
    """Gravity/up helpers on top of :mod:`imugen.core.earth` for one origin frame."""

    def __init__(self, frame: ea.OriginFrame):
        self.frame = frame
        self.flat = frame.model == "flat"
        self.ecef = frame.model == "geodetic"
        self.Omega = ea.earth_rate_n(frame)

    def height(self, p):
        """Height of the vehicle for the attitude logic, (m,) [m]: n's Up in ``flat``, the
        ellipsoidal height otherwise (far from the origin ``u`` is not a height)."""
        return p[:, 2] if self.flat else self.frame.geodetic_from_n(p)[2]

    def horizontal_speed(self, p, v, a=None, axis=None):
        """Horizontal speed ``v_h`` (m,) and, with ``a``, its rate (m,): in n's East-North
        plane in ``flat`` and ``wgs84``, in the local level at the vehicle in ``geodetic``
        (``a_l = C_ln a - omega_nl_l x v_l``, that level's North towards ``axis``:
        :meth:`local`)."""
        if self.ecef and a is None:  # |v - (v . up) up| with the geodetic up at p
            sl, cl, co, so, _ = ea.geodetic_parts(p[:, 0], p[:, 1], p[:, 2])
            vu = cl * (co * v[:, 0] + so * v[:, 1]) + sl * v[:, 2]
            return np.sqrt(np.maximum(np.einsum("mi,mi->m", v, v) - vu * vu, 0.0)), None
        if self.ecef:
            C_ln, v, w_nl = self.local(p, v, axis)
            a = np.einsum("mij,mj->mi", C_ln, a) - np.cross(w_nl, v)
        vh = np.hypot(v[:, 0], v[:, 1])
        if a is None:
            return vh, None
        vh_d = np.divide(
            v[:, 0] * a[:, 0] + v[:, 1] * a[:, 1], vh, out=np.zeros_like(vh), where=vh > 0
        )
        return vh, vh_d

    def gravity(self, p):
        return ea.gravity_n(p, self.frame)

    def gravitation(self, p):
        return ea.gravitation_n(p, self.frame)

    def local(self, p, v, axis=None):
        """Local level at the vehicle: ``C_ln`` (m,3,3), velocity in it ``v_l`` (m,3) and its
        rotation rate relative to n in it, ``omega_nl_l`` (m,3) (transport rate).

        The level's North points towards the Earth's axis (ENU at the vehicle), or with
        ``axis`` (ECEF unit vector, (3,); :meth:`heading_axis`) towards that axis: a
        transverse pole, so that the level and its rate stay defined at the geographic poles
        (:meth:`_local_about`)."""
        if self.flat:
            return np.broadcast_to(np.eye(3), (len(p), 3, 3)), v, np.zeros_like(v)
        if axis is not None:
            return self._local_about(p, v, axis)
        lat, _, h = self.frame.geodetic_from_n(p)
        C_ln = self.frame.C_ln(p)
        v_l = np.einsum("mij,mj->mi", C_ln, v)
        s2 = np.sin(lat) ** 2
        den = np.sqrt(1.0 - ea.E2_WGS84 * s2)
        RN = ea.A_WGS84 / den + h
        RM = ea.A_WGS84 * (1.0 - ea.E2_WGS84) / den**3 + h
        w = np.column_stack([-v_l[:, 1] / RM, v_l[:, 0] / RN, v_l[:, 0] * np.tan(lat) / RN])
        return C_ln, v_l, w

    def heading_axis(self, p):
        """Reference axis of the headings of a route through ``p`` (m, 3) in n: None (the
        Earth's axis: headings from geographic North) in ``flat`` and when the route keeps
        ``POLE_MARGIN_RAD`` from both poles; else the ECEF unit axis (3,) farthest from every
        local vertical of the route (the normal of the plane the verticals lie closest to, or
        the best of ``_N_AXES`` directions spread over the sphere), a transverse pole.

        Raises
        ------
        InputError
            When every candidate axis comes within ``POLE_MARGIN_RAD`` of the route's
            vertical (a route all over the globe).
        """
        if self.flat:
            return None
        p = np.asarray(p, float)
        p = p[:: max(1, len(p) // 20_000)]
        r = self.frame.ecef_from_n(p)
        sl, cl, co, so, _ = ea.geodetic_parts(r[:, 0], r[:, 1], r[:, 2])
        if np.max(np.abs(sl)) <= math.cos(POLE_MARGIN_RAD):
            return None
        u = np.column_stack([cl * co, cl * so, sl])
        cand = np.vstack([np.linalg.eigh(u.T @ u)[1][:, 0], _sphere_directions(_N_AXES)])
        worst = np.max(np.abs(u @ cand.T), axis=0)
        j = int(np.argmin(worst))
        if worst[j] > math.cos(POLE_MARGIN_RAD):
            raise InputError(
                None,
                "the route's verticals cover the globe: no heading reference axis keeps "
                f"{math.degrees(POLE_MARGIN_RAD):g} deg from them; split the route",
            )
        return cand[j]

    def _local_about(self, p, v, k):
        """:meth:`local` with the level's North towards the ECEF unit axis ``k``.

        Axes at the vehicle: up ``u`` (ellipsoid normal), North ``n' = m / |m|`` with
        ``m = k - (k . u) u``, East ``n' x u``. Relative to the Earth the level turns at
        ``omega = omega_h + omega_u u``: the normal tilts at ``omega_h = u x (K v)``,
        ``K = P / (R_N + h) + c m_z m_z^T`` (``P = I - u u^T``, ``m_z = e_z - sin(lat) u``,
        ``c = a e^2 / (W^3 (R_M + h) (R_N + h))``: the ellipsoid's curvature, written without
        the geographic North, so smooth at the poles), and about the vertical at
        ``omega_u = (k . u) (e' . du/dt) / |m|`` (``k = e_z``: ``tan(lat) v_E / (R_N + h)``).
        """
        C_en = self.frame.C_en
        r = self.frame.ecef_from_n(p)
        v_e = v @ C_en  # C_ne v per row
        sl, cl, co, so, h = ea.geodetic_parts(r[:, 0], r[:, 1], r[:, 2])
        u = np.column_stack([cl * co, cl * so, sl])
        ku = u @ k
        m = k[None, :] - ku[:, None] * u
        mn = np.linalg.norm(m, axis=1)
        north = m / mn[:, None]
        east = np.cross(north, u)
        W2 = 1.0 - ea.E2_WGS84 * sl * sl
        W = np.sqrt(W2)
        RN = ea.A_WGS84 / W + h
        RM = ea.A_WGS84 * (1.0 - ea.E2_WGS84) / (W * W2) + h
        mz = -sl[:, None] * u
        mz[:, 2] += 1.0
        c = ea.A_WGS84 * ea.E2_WGS84 / (W * W2 * RM * RN)
        Kv = (v_e - _dot(v_e, u)[:, None] * u) / RN[:, None] + (c * _dot(mz, v_e))[:, None] * mz
        w_h = np.cross(u, Kv)
        w_u = ku * _dot(east, np.cross(w_h, u)) / mn
        C_le = np.stack([east, north, u], axis=1)
        w_l = np.column_stack([_dot(east, w_h), _dot(north, w_h), w_u])
        return C_le @ C_en.T, np.einsum("mij,mj->mi", C_le, v_e), w_l

    def gravity_rate(self, p, v):
        """d/dt g_n(p(t)) = (grad g) v by a central difference along v (10 m each side)."""
        if self.flat:
            return np.zeros_like(p)
        spd = np.linalg.norm(v, axis=1, keepdims=True)
        e = np.divide(v, spd, out=np.zeros_like(v), where=spd > 0)
        hstep = 10.0
        return (self.gravity(p + hstep * e) - self.gravity(p - hstep * e)) * (spd / (2 * hstep))


_QX = np.array([0.0, 1.0, 0.0, 0.0])  # rotation by pi about body x


def _flip_roll(out, rows, sQ, sG):
    """Turn the attitude of ``rows`` by pi about body x (z -> -z): q * (0,1,0,0), w -> (wx,-wy,-wz)."""
    out[rows, sQ] = rot.quat_mul(out[rows, sQ], _QX)
    g = out[rows, sG]
    g[..., 1:] *= -1.0
    out[rows, sG] = g


def attitude_pass(out, ci, motion, times, E, vp, chunk, ground=None):
    """Kinematics and attitude of every sample (pass 1), written into ``out``.

    Fills position, velocity, ``q_nb`` and ``omega_nb_b`` (rate of b relative to n, without
    the Earth rate) of the truth table ``out`` (K, columns) whose column slices are ``ci``.
    Ground vehicles take the :class:`GroundAttitude` ``ground``; aircraft blend it with
    coordinated flight by the weight ``beta = 1 - (1 - b_v)(1 - b_h)``: quintic smoothsteps
    of the speed (0.8 to 1 x ``airborne_speed_mps``) and of the height above the route's
    lowest point (0.5 to 1 x ``airborne_height_m``).

    Returns
    -------
    f_n : ndarray, shape (K, 3)
        Specific force in n [m/s^2].
    stats : dict
        Acceleration and jerk figures, hold windows, blend angles, ``airborne`` (K,) bool.
    """
    K = len(times)
    sP, sV, sQ, sG = ci["pos"], ci["vel"], ci["quat"], ci["gyro"]
    air = vp.attitude == "coordinated"
    f_n_all = np.empty((K, 3))
    if air:
        sigma = np.empty(K)
        sigma_d = np.empty(K)
        beta = np.ones(K)
        beta_d = np.zeros(K)
    if ground is not None and air:
        q_g = np.empty((K, 4))
        w_g = np.empty((K, 3))
        h_low = float(E.height(motion.position(np.linspace(motion.t0, motion.t1, 20001))).min())
    acc_ss, acc_max, jerk_max = 0.0, 0.0, 0.0
    s_prev = 0.0
    for k0 in range(0, K, chunk):
        k1 = min(K, k0 + chunk)
        p, v, a, j = motion.eval(times[k0:k1])
        an = np.linalg.norm(a, axis=1)
        acc_ss += float(np.sum(an * an))
        acc_max = max(acc_max, float(an.max()))
        jerk_max = max(jerk_max, float(np.linalg.norm(j, axis=1).max()))
        f_n = a + 2.0 * np.cross(E.Omega, v) - E.gravity(p)
        out[k0:k1, sP] = p
        out[k0:k1, sV] = v
        f_n_all[k0:k1] = f_n
        if air:
            rd = j + 2.0 * np.cross(E.Omega, a) - E.gravity_rate(p, v)
            C, w, spd, spd_d, rpn, rpn_d = _target_frame(v, a, f_n, rd)
            s1, ds1 = _smoothstep(spd, *vp.hold_speed_mps)
            s2, ds2 = _smoothstep(rpn, *vp.hold_perp)
            sigma[k0:k1] = s1 * s2
            sigma_d[k0:k1] = ds1 * spd_d * s2 + s1 * ds2 * rpn_d
            out[k0:k1, sQ] = rot.dcm_to_quat(C)
            out[k0:k1, sG] = w
        if ground is None:
            continue
        steps = distance_steps(motion, ground.E, times[max(k0 - 1, 0) : k1])
        s = s_prev + (np.r_[0.0, np.cumsum(steps)] if k0 == 0 else np.cumsum(steps))
        s_prev = float(s[-1])
        C, w = ground.attitude(s, p, v, a, times[k0:k1])
        if air:
            # airborne: fast, or well above the lowest point of the route (a slow glider)
            bs, dbs = _smoothstep(spd, 0.8 * vp.airborne_speed_mps, vp.airborne_speed_mps)
            h_d = v[:, 2] if E.flat else E.local(p, v)[1][:, 2]  # up velocity at the vehicle
            bh, dbh = _smoothstep(
                E.height(p) - h_low, 0.5 * vp.airborne_height_m, vp.airborne_height_m
            )
            beta[k0:k1] = 1.0 - (1.0 - bs) * (1.0 - bh)
            beta_d[k0:k1] = dbs * spd_d * (1.0 - bh) + dbh * h_d * (1.0 - bs)
            q_g[k0:k1] = rot.dcm_to_quat(C)
            w_g[k0:k1] = w
        else:
            out[k0:k1, sQ] = rot.dcm_to_quat(C)
            out[k0:k1, sG] = w
    stats = {
        "accel_rms_mps2": float(np.sqrt(acc_ss / K)),
        "accel_max_mps2": acc_max,
        "jerk_max_mps3": jerk_max,
        "attitude_hold_windows": 0,
        "max_blend_angle_rad": 0.0,
    }
    if air:
        n_hold, phi_max = _blend_holds(out, ci, sigma, sigma_d, E, vp)
        stats["attitude_hold_windows"] = n_hold
        stats["max_blend_angle_rad"] = phi_max
        if ground is not None:
            stats["max_ground_air_angle_rad"] = _blend_ground_air(out, ci, q_g, w_g, beta, beta_d)
    # airborne: any flight attitude blended in (ground limits hold where the ground model is alone)
    stats["airborne"] = beta > 0.0 if air else np.zeros(K, dtype=bool)
    return f_n_all, stats


def _blend_ground_air(out, ci, q_g, w_g, beta, beta_d):
    """Attitude ``q_g Exp(beta Log(q_g^-1 q_air))`` and its exact rate, in place of the
    coordinated-flight attitude ``out``; returns the largest blended angle [rad]."""
    sQ, sG = ci["quat"], ci["gyro"]
    g0 = beta <= 0.0
    out[g0, sQ] = q_g[g0]
    out[g0, sG] = w_g[g0]
    mid = (beta > 0.0) & (beta < 1.0)
    if not mid.any():
        return 0.0
    qg, wg, b, bd = q_g[mid], w_g[mid], beta[mid, None], beta_d[mid, None]
    q_rel = rot.quat_mul(rot.quat_conj(qg), out[mid, sQ])
    phi = rot.log_quat(q_rel)
    w_rel = out[mid, sG] - np.einsum("mji,mj->mi", rot.quat_to_dcm(q_rel), wg)
    phi_d = np.einsum("mij,mj->mi", rot.right_jacobian_inv(phi), w_rel)
    psi = b * phi
    out[mid, sQ] = rot.quat_mul(qg, rot.exp_quat(psi))
    out[mid, sG] = np.einsum("mji,mj->mi", rot.exp_dcm(psi), wg) + np.einsum(
        "mij,mj->mi", rot.right_jacobian(psi), bd * phi + b * phi_d
    )
    return float(np.linalg.norm(phi, axis=1).max())


def _blend_holds(out, ci, sigma, sigma_d, E, vp):
    """Hold the attitude where ``sigma < 1``: ``q_hold Exp(sigma Log(q_hold^-1 q_target))``.

    Returns the number of hold windows and the largest blended angle [rad].
    """
    K = len(sigma)
    sQ, sG, iP = ci["quat"], ci["gyro"], ci["pos"]
    below = sigma < 1.0
    edges = np.flatnonzero(np.diff(np.r_[0, below.astype(np.int8), 0]))
    can_flip = vp.attitude == "coordinated"
    n_hold = 0
    phi_max = 0.0
    flip = False  # aircraft: body z along -f_perp in the current segment (pushed over)
    seg_start = 0
    for i0, i1 in zip(edges[::2], edges[1::2], strict=True):  # run = [i0, i1)
        n_hold += 1
        if flip:
            _flip_roll(out, slice(seg_start, i0), sQ, sG)
        if i0 > 0:
            q_h = out[i0 - 1, sQ].copy()
        elif i1 < K:
            q_h = out[i1, sQ].copy()
        else:  # never a defined attitude: level, facing East of the local level
            C_ln, _, _ = E.local(out[:1, iP], np.zeros((1, 3)))
            q_h = rot.dcm_to_quat(np.ascontiguousarray(C_ln[0].T))
        sl = slice(i0, i1)
        sg = sigma[sl]
        q_rel = rot.quat_mul(rot.quat_conj(q_h)[None, :], out[sl, sQ])
        if can_flip:  # per sample, the roll sign closest to the held attitude
            f = np.abs(q_rel[:, 1]) > np.abs(q_rel[:, 0])
            _flip_roll(out, np.flatnonzero(f) + i0, sQ, sG)
            q_rel[f] = rot.quat_mul(q_rel[f], _QX)
        w_v = out[sl, sG]
        phi = rot.log_quat(q_rel)
        phi[sg <= 0] = 0.0
        if np.any(sg > 0):
            phi_max = max(phi_max, float(np.linalg.norm(phi[sg > 0], axis=1).max()))
        psi = sg[:, None] * phi
        q = rot.quat_mul(q_h, rot.exp_quat(psi))
        w = sigma_d[sl, None] * phi + sg[:, None] * np.einsum(
            "mij,mj->mi", rot.right_jacobian(psi) @ rot.right_jacobian_inv(phi), w_v
        )
        w[sg <= 0] = 0.0
        out[sl, sQ] = q
        out[sl, sG] = w
        if can_flip and i1 < K:
            qe = rot.quat_mul(rot.quat_conj(q_h), out[i1, sQ])
            flip = bool(abs(qe[1]) > abs(qe[0]))
        seg_start = i1
    if flip:
        _flip_roll(out, slice(seg_start, K), sQ, sG)
    return n_hold, phi_max


# ------------------------------------------------------------------------------------------
# ground vehicles: attitude as functions of the horizontal distance travelled
# ------------------------------------------------------------------------------------------
G_LEAN = 9.80665  # gravity of the lean of a coordinated turn [m/s^2]
_PAD = 6  # coefficients added at each end of the node splines
SLIP_CURVATURE_MARGIN = 1.0  # the attitude follows paths up to this fraction of max curvature
SLIP_GAP_RAD = math.radians(10.0)  # ... and velocity directions this close to the reachable heading
SLIP_MARGIN_M = 2.0  # distance over which it leaves / rejoins the velocity direction [m]
# ... and pitch follows paths whose vertical curvature is within this x max_pitch / grade_smooth_m
# (car: 0.021 rad/m; the height wiggles of a noisy fit beyond are left to the grade model)
SLIP_PITCH_FACTOR = 3.0
OMEGA_Z_STEP_S = 0.5  # step of the central difference of the local North's turn rate [s]


@njit(cache=True)
def _rate_limit(d, step):
    """Slope limiter ``|x[j+1] - x[j]| <= step`` following ``d`` forward: where the path
    turns faster (a reversal through a stop), the heading turns as the vehicle moves on."""
    n = d.shape[0]
    f = np.empty(n)
    f[0] = d[0]
    for j in range(1, n):
        f[j] = min(max(d[j], f[j - 1] - step), f[j - 1] + step)
    return f


def soft_bound(x, m):
    """Identity within ``0.75 m``, then saturating smoothly (C^2) below ``m``; and its
    derivative. Used for pitch and lean bounds: small angles are kept exactly."""
    a = 0.75 * m
    ax = np.abs(x)
    u = np.maximum(ax - a, 0.0) / (m - a)
    th = np.tanh(u)
    y = np.where(ax <= a, x, np.sign(x) * (a + (m - a) * th))
    dy = np.where(ax <= a, 1.0, 1.0 - th * th)
    return y, dy


def _smooth(x, sigma):
    """Gaussian filter (``sigma`` samples) with odd reflection at the ends: linear trends
    are kept to the ends and a slope bound of ``x`` holds for the result."""
    m = min(len(x) - 1, math.ceil(4 * sigma))
    xp = np.r_[2 * x[0] - x[m:0:-1], x, 2 * x[-1] - x[-2 : -m - 2 : -1]]
    return gaussian_filter1d(xp, sigma, mode="nearest")[m : m + len(x)]


def _node_spline(values, ds, x0=0.0):
    """Quintic B-spline whose coefficients are ``values`` at nodes ``x0 + j ds`` (their Greville
    abscissae), extended by odd reflection (trends continue past the ends): variation
    diminishing, so its slope stays within the values' slope ``max |diff| / ds`` and it is
    exactly constant where they are."""
    v = np.r_[values, np.full(max(0, _PAD + 1 - len(values)), values[-1])]
    c = np.r_[2 * v[0] - v[_PAD:0:-1], values, 2 * v[-1] - v[-2 : -_PAD - 2 : -1]]
    knots = x0 + (np.arange(len(c) + 6) - _PAD - 3) * ds
    return BSpline(knots, c, 5)


class GroundAttitude:
    """Attitude of a ground vehicle against the horizontal distance travelled ``s``.

    Headings are angles in the local level at the vehicle from its North: geographic North,
    or on a route passing within ``POLE_MARGIN_RAD`` of a geographic pole the direction of a
    transverse pole far from the whole route (:meth:`EarthField.heading_axis`), so that the
    level, the headings and their rates stay defined and smooth through the pole.

    * heading ``Psi(s)``: the direction of the horizontal velocity (local level) at distance
      nodes ``ds = max(0.1 / max_curvature, 0.1 m)`` apart, unwrapped, slope-limited to
      ``|dPsi/ds| <= max_curvature`` (forward: no anticipation of a turn), Gaussian-smoothed (sigma
      ``max(heading_smooth_m, heading_smooth_s x median moving speed)``)
      and represented by a variation-diminishing quintic B-spline: the yaw rate
      ``Psi'(s) v_h`` never exceeds ``v_h max_curvature`` (no turning on the spot; a reversal
      turns through a U of radius ``1 / max_curvature``, never by a branch flip);
    * pitch ``Theta(s) = bound(atan(H'(s)), max_pitch)``: the grade of the height profile
      :func:`imugen.truth.fit.fit_height_profile`, smoothed at the height noise;
    * where the path is plausible, heading and pitch are those of the velocity in the local
      level at the vehicle (``atan2(v_N, v_E)``, ``atan(v_U / v_h)``) with their exact rates, so
      the body velocity has no y and no z component (the non-holonomic constraint). The blend
      ``x = x_s + W(s) (x_v - x_s)`` with node-spline weights of distance is exactly 1 there and
      exactly 0 within ``SLIP_MARGIN_M`` of a node the vehicle crosses below twice
      ``stop_speed_mps`` (the direction is undefined at a stop), of a turn tighter than
      ``max_curvature`` or of a velocity more than ``SLIP_GAP_RAD`` off the direction the
      heading can turn to (its rate-limited values above, before their smoothing: a reversal); for the pitch, within ``grade_smooth_m`` of a vertical curvature beyond
      ``SLIP_PITCH_FACTOR x max_pitch / grade_smooth_m`` (height wiggles of a noisy fit, the
      steps of an altimeter's record: the grade spreads them, the slip integrates to ~0 over
      that length). The plausibility report
      gives the resulting slip;
    * roll 0, or for ``lean`` vehicles the lean of a coordinated turn
      ``-bound(atan(a_lat / g), max_roll)`` (into the turn), ``a_lat = v_h^2 Psi'(s)`` (plus,
      off ``flat``, ``v_h`` x the local North's own turn about the vertical:
      :meth:`lateral_accel`); ``bound`` is :func:`soft_bound`;
    * on a suspension (:func:`imugen.truth.vehicles.has_suspension`: ``suspension`` ``damped``) the
      body rolls by ``phi_s(t)`` about its x axis and then pitches by ``theta_s(t)`` about its
      y axis, ``C_lb = Rz(psi) Ry(-theta) Rx(phi + phi_s) Ry(-theta_s)``
      (:class:`imugen.truth.suspension.Suspension`, driven by the same ``a_lat`` and
      ``a_lon = dv_h/dt``): a rotation of the body only, so its velocity keeps no y component
      (the vertical one is ``v sin theta_s``, the dive and squat of the body), and the angles
      are functions of time (the body still rocks for a moment after the vehicle stops).

    Where the vehicle does not move, ``s`` and so the whole attitude are exactly constant.

    Parameters
    ----------
    motion : TimedMotion or PathMotion
    E : EarthField
    vp : VehicleParams
    heights : (ndarray (N,), ndarray (N,)) or None
        Input times [s] and heights [m] of a timed route (None: the motion's own heights).
    noise_up_m : float
        Noise of those heights [m].
    profile : (BSpline, dict) or None
        A height profile ``H(s)`` already fitted and its report (a motion's or path's on the road profile,
        :func:`imugen.truth.road.motion_on_road`, :func:`imugen.truth.road.path_on_road`):
        used instead of fitting one.
    grid_dt : float
        Step of the internal time grid of the distance [s].
    turns : sequence of (float, float)
        Intervals [s] of turns at rest: stops at a reversal (:mod:`imugen.truth.reversals`)
        where the velocity direction of the leg driven next differs by ``J`` (about 180 deg)
        from the one arriving. The heading's nodes are continued across the stop without
        that jump and the heading turns by ``J`` in time over the interval (a quintic
        smoothstep: rate and its derivative zero at both ends), so that the vehicle arrives
        and pulls away facing its velocity (no slide sideways as it pulls away).
    """

    def __init__(
        self, motion, E, vp, heights=None, noise_up_m=0.0, profile=None, grid_dt=0.1, turns=()
    ):
        self.E, self.vp = E, vp
        self.turns = []  # (t0, t1, J) of the turns at rest
        n = max(2, math.ceil((motion.t1 - motion.t0) / grid_dt) + 1)
        tg = np.linspace(motion.t0, motion.t1, n)
        sg = np.r_[0.0, np.cumsum(distance_steps(motion, E, tg))]
        L = float(sg[-1])
        self.length_m = L
        k = vp.max_curvature_1pm
        ds = max(0.1 / k, 0.1)
        ns = math.ceil(L / ds)
        if ns > 2_000_000:
            ns = 2_000_000
        self.report = {"length_m": L, "max_curvature_1pm": k}
        # headings from geographic North, or from a transverse pole on a route near a pole
        self.axis = E.heading_axis(motion.position(tg))
        self.report["heading_reference"] = (
            "geographic North" if self.axis is None else f"transverse pole {self.axis.tolist()}"
        )
        if ns < 4:  # does not move: level, facing East of the local level
            self.ds = max(L, 1.0)
            self.Psi = _node_spline(np.zeros(2), self.ds)
            self.Theta = _node_spline(np.zeros(2), self.ds)
            self.W = self.Wp = _node_spline(np.zeros(2), self.ds)
            self.report["grade"] = {"method": "level (does not move)"}
            self.suspension = None
            return
        ds = L / ns
        self.ds = ds
        sn = np.linspace(0.0, L, ns + 1)
        # direction of the horizontal velocity at the mid-nodes (the vehicle moves there)
        up = np.r_[True, np.diff(sg) > 0]
        tn = np.interp(sn[:-1] + 0.5 * ds, sg[up], tg[up])
        p_n, v_n, a_n, _ = motion.eval(tn)
        C_ln, v_l, w_nl = E.local(p_n, v_n, self.axis)
        ok = np.hypot(v_l[:, 0], v_l[:, 1]) > 1e-6
        if not ok.any():
            ok[:] = True
        d = np.unwrap(np.arctan2(v_l[ok, 1], v_l[ok, 0]))
        d = np.interp(np.arange(ns), np.flatnonzero(ok), d)
        mid = sn[:-1] + 0.5 * ds
        for t0, t1 in turns:  # the jump of the velocity direction at a reversal's stop
            s0, s1 = (float(np.interp(x, tg, sg)) for x in (t0, t1))
            inside = np.flatnonzero((mid[1:] >= s0) & (mid[1:] <= s1)) + 1
            if len(inside) > 1:  # creeping through the turn: its whole change, held
                j0, j1 = int(inside[0]), int(inside[-1])
                jump = float(d[j1] - d[j0 - 1])
                d[j0 : j1 + 1] = d[j0 - 1]
                d[j1 + 1 :] -= jump
                self.turns.append((float(t0), float(t1), jump))
                continue
            s_k = 0.5 * (s0 + s1)
            near = np.flatnonzero(np.abs(mid[1:] - s_k) <= max(1.0, 2.0 * ds)) + 1
            if not len(near):
                continue
            j = int(near[np.argmax(np.abs(d[near] - d[near - 1]))])
            jump = float(d[j] - d[j - 1])
            d[j:] -= jump
            self.turns.append((float(t0), float(t1), jump))
        self.report["turns_at_rest_deg"] = [math.degrees(J) for _, _, J in self.turns]
        vg = np.diff(sg) / np.diff(tg)
        v_med = (
            float(np.median(vg[vg > vp.stop_speed_mps])) if np.any(vg > vp.stop_speed_mps) else 0.0
        )
        smooth_m = max(vp.heading_smooth_m, vp.heading_smooth_s * v_med)
        self.report["heading_smooth_m"] = smooth_m
        lim = _rate_limit(d, k * ds)
        psi = _smooth(lim, max(1.0, smooth_m / ds))
        self.Psi = _node_spline(psi, ds, 0.5 * ds)
        # where the path is plausible, the attitude follows the velocity (W = 1): not near stops
        # (direction undefined), not where the path turns tighter than the vehicle can or the
        # velocity leaves the vehicle heading (a reversal)
        a_l = np.einsum("mij,mj->mi", C_ln, a_n) - np.cross(w_nl, v_l)
        vh2 = np.maximum(v_l[:, 0] ** 2 + v_l[:, 1] ** 2, 1e-18)
        kappa = np.abs(v_l[:, 0] * a_l[:, 1] - v_l[:, 1] * a_l[:, 0]) / vh2**1.5
        # the velocity leaves the heading the vehicle can turn to (a reversal): against the
        # rate-limited directions (their smoothing alone, at a bend within the limit, is no gap)
        gap = np.abs(np.angle(np.exp(1j * (d - lim))))
        bad = (kappa > SLIP_CURVATURE_MARGIN * k) | (gap > SLIP_GAP_RAD)
        slow = np.zeros(ns, bool)  # nodes the vehicle crosses slowly (0.1 s grid)
        p_g = motion.position(tg) if E.ecef else None
        vgh = self.E.horizontal_speed(p_g, motion.velocity(tg))[0]
        slow[np.clip((sg[vgh < 2.0 * vp.stop_speed_mps] / ds).astype(np.int64), 0, ns - 1)] = True
        # pitch: not where the path's vertical curvature exceeds max pitch / grade smoothing
        # length (a height wiggle of the fit, not a road's vertical curve)
        vu = v_l[:, 2]
        hl_d = (v_l[:, 0] * a_l[:, 0] + v_l[:, 1] * a_l[:, 1]) / np.sqrt(vh2)
        kv = np.abs(np.sqrt(vh2) * a_l[:, 2] - vu * hl_d) / ((vh2 + vu * vu) * np.sqrt(vh2))
        steep = kv > SLIP_PITCH_FACTOR * vp.max_pitch_rad / vp.grade_smooth_m
        # ... nor within grade_smooth_m of such a node: the grade model spreads a height step
        # (an altimeter's record: level runs, then a climb) over that length, so the body
        # vertical slip it leaves integrates to ~0 there; followed on the level runs, the
        # velocity's pitch would leave the whole climb of each step to slip, of one sign
        # over a slope
        steep = maximum_filter1d(steep, 2 * math.ceil(vp.grade_smooth_m / ds) + 1)
        self.W = self._weight(bad | slow, ds)
        self.Wp = self._weight(steep | slow, ds)
        self.report["follows_velocity_fraction"] = {
            "heading": float(np.mean(self.W(sn[:-1] + 0.5 * ds) > 1.0 - 1e-9)),
            "pitch": float(np.mean(self.Wp(sn[:-1] + 0.5 * ds) > 1.0 - 1e-9)),
        }
        # grade: heights against distance, from the input points when there are some
        if profile is not None:
            H, grep = profile
        else:
            if heights is not None:
                t_in, h_in = heights
                s_in = np.interp(t_in, tg, sg)
            else:
                s_in, h_in = sg, self.E.height(motion.position(tg))
            H, grep = fit_height_profile(
                s_in, h_in, noise_up_m, vp.grade_bin_m, vp.grade_smooth_m, vp.fit_floor_m
            )
        if H is None:
            theta = np.zeros(ns + 1)
        else:
            theta, _ = soft_bound(np.arctan(H.derivative(1)(sn)), vp.max_pitch_rad)
        self.Theta = _node_spline(theta, ds)
        self.report["grade"] = grep
        self.suspension = None
        if has_suspension(vp):
            self.suspension = Suspension(motion.t0, motion.t1, self._accel(motion, tg, sg), vp)
            self.report["suspension"] = self.suspension.report

    def turn_offset(self, t):
        """Heading added by the turns at rest at times ``t`` (m,) [s]: (angle, rate) (m,)
        [rad, rad/s], ``J`` times a quintic smoothstep over each turn's interval."""
        o, o_d = np.zeros_like(t), np.zeros_like(t)
        for t0, t1, J in self.turns:
            T = t1 - t0
            x = np.clip((t - t0) / T, 0.0, 1.0)
            o += J * x**3 * (10.0 - 15.0 * x + 6.0 * x * x)
            o_d += J * 30.0 * x * x * (1.0 - x) ** 2 / T
        return o, o_d

    def lateral_accel(self, s, p, v, vh, a=None, vh_d=None):
        """Lateral acceleration of the path in the local level at the vehicle, ``a_lat =
        v_h (v_h Psi'(s) + omega_z)`` (m,) [m/s^2] (positive to the left), at distances ``s``
        (m,) with position and velocity in n (m,3) and horizontal speed ``vh`` (m,)
        (:meth:`EarthField.horizontal_speed`); with the acceleration ``a`` (m,3) and ``vh_d``
        (m,), also its time derivative (m,) [m/s^3]. The suspension's lateral input and a
        bicycle's lean.

        ``v_h Psi' + omega_z`` is the turn rate relative to the Earth about the local vertical:
        off ``flat`` the heading ``Psi`` is measured from a local North that itself turns
        about the vertical along the path (``omega_z``, the transport rate's vertical
        component: meridians converge), which is no lateral acceleration of the vehicle.
        ``omega_z`` is a function ``L(p) v`` of the position and velocity, so its rate
        ``L_p v . v + L a`` is the central difference of ``L(p + h v)(v + h a)`` over
        ``h = OMEGA_Z_STEP_S``, exact but for ``h^2 / 6`` times its third derivative along the
        line (``~ omega_z (v h / R)^2``: below 1e-20 rad/s^2 at any speed on the ground)."""
        s = np.clip(s, 0.0, self.length_m)
        rate = a is not None
        k1 = self.Psi(s, 1)
        if self.E.flat:
            w_z = w_zd = np.zeros_like(vh)
        else:
            w_z = self.E.local(p, v, self.axis)[2][:, 2]
            if rate:
                h = OMEGA_Z_STEP_S
                up = self.E.local(p + h * v, v + h * a, self.axis)[2][:, 2]
                dn = self.E.local(p - h * v, v - h * a, self.axis)[2][:, 2]
                w_zd = (up - dn) / (2.0 * h)
        a_lat = vh * (vh * k1 + w_z)
        if not rate:
            return a_lat
        a_lat_d = 2.0 * vh * vh_d * k1 + vh**3 * self.Psi(s, 2) + vh_d * w_z + vh * w_zd
        return a_lat, a_lat_d

    def _accel(self, motion, tg, sg):
        """``inputs(t) -> (a_lat, a_lon)`` of the suspension: :meth:`lateral_accel` and
        ``dv_h/dt`` [m/s^2] (distance ``s`` interpolated on the grid ``tg``, ``sg``)."""

        def inputs(t):
            p, v, a, _ = motion.eval(t)
            vh, vh_d = self.E.horizontal_speed(p, v, a, self.axis)
            return self.lateral_accel(np.interp(t, tg, sg), p, v, vh), vh_d

        return inputs

    def _weight(self, bad, ds):
        """Node spline of the weight of the velocity direction: exactly 0 within ``m`` nodes
        (``SLIP_MARGIN_M``, at least 3: the spline's support) of a ``bad`` node, rising over
        the next ``2 m`` (Gaussian of sigma ``m / 2`` truncated at ``m``), exactly 1 beyond."""
        m = max(3, math.ceil(SLIP_MARGIN_M / ds))
        b = maximum_filter1d(bad.astype(float), 4 * m + 1, mode="nearest")
        w = 1.0 - gaussian_filter1d(b, 0.5 * m, mode="nearest", truncate=2.0)
        w[w > 1.0 - 1e-12] = 1.0
        w[w < 1e-12] = 0.0
        return _node_spline(np.clip(w, 0.0, 1.0), ds, 0.5 * ds)

    def attitude(self, s, p, v, a, t=None):
        """``C_nb`` (m,3,3) and ``omega_nb_b`` (m,3) at distances ``s`` (m,) with position,
        velocity and acceleration in n (m,3), at times ``t`` (m,) [s] (needed on a
        suspension)."""
        vp = self.vp
        C_ln, v_l, w_nl = self.E.local(p, v, self.axis)
        # ds/dt: the horizontal speed whose integral is the distance s
        vh, vh_d = self.E.horizontal_speed(p, v, a, self.axis)
        s = np.clip(s, 0.0, self.length_m)
        k1 = self.Psi(s, 1)
        # spline attitude blended with the velocity direction by W(s), Wp(s):
        # x = x_s + W (x_v - x_s), dx/dt = x_s' v_h + W' v_h (x_v - x_s) + W (dx_v/dt - x_s' v_h)
        psi, psi_d = self.Psi(s), k1 * vh
        if self.turns:  # turns at rest (t is given with them)
            o, o_d = self.turn_offset(np.asarray(t, float))
            psi, psi_d = psi + o, psi_d + o_d
        theta, theta_d = self.Theta(s), self.Theta(s, 1) * vh
        on = (self.W(s) > 0.0) | (self.Wp(s) > 0.0)
        if on.any():
            vl, vhs = v_l[on], vh[on]
            al = np.einsum("mij,mj->mi", C_ln[on], a[on]) - np.cross(w_nl[on], vl)
            hl = np.maximum(np.hypot(vl[:, 0], vl[:, 1]), 1e-9)  # level speed at the vehicle
            hl_d = (vl[:, 0] * al[:, 0] + vl[:, 1] * al[:, 1]) / hl
            psi_s = psi[on]
            psi_v = psi_s + np.angle(np.exp(1j * (np.arctan2(vl[:, 1], vl[:, 0]) - psi_s)))
            psi_vd = (vl[:, 0] * al[:, 1] - vl[:, 1] * al[:, 0]) / (hl * hl)
            tv = np.arctan2(vl[:, 2], hl)
            tvd = (hl * al[:, 2] - vl[:, 2] * hl_d) / (hl * hl + vl[:, 2] ** 2)
            theta_v, dtb = soft_bound(tv, vp.max_pitch_rad)
            for x, xd, W, xv, xvd in (
                (psi, psi_d, self.W, psi_v, psi_vd),
                (theta, theta_d, self.Wp, theta_v, dtb * tvd),
            ):
                so = s[on]
                xs, xsd, w0, w1 = x[on], xd[on], W(so), W(so, 1)
                x[on] = xs + w0 * (xv - xs)
                xd[on] = xsd * (1.0 - w0) + w1 * vhs * (xv - xs) + w0 * xvd
        if vp.lean:
            # lean into the turn: a left turn (Psi' > 0) lowers the left side (roll < 0)
            a_lat, a_lat_d = self.lateral_accel(s, p, v, vh, a, vh_d)
            X, X_d = -a_lat / G_LEAN, -a_lat_d / G_LEAN
            phi, dphi = soft_bound(np.arctan(X), vp.max_roll_rad)
            phi_d = dphi * X_d / (1.0 + X * X)
        else:
            phi = phi_d = np.zeros_like(s)
        susp = self.suspension is not None
        if susp:
            phi_s, phi_sd, theta_s, theta_sd = self.suspension(t)
            phi, phi_d = phi + phi_s, phi_d + phi_sd
        C_lb = rot.euler_to_dcm(phi, theta, psi)
        sf, cf, st, ct = np.sin(phi), np.cos(phi), np.sin(theta), np.cos(theta)
        w_lb = np.column_stack(
            [
                phi_d + psi_d * st,
                -theta_d * cf + psi_d * ct * sf,
                theta_d * sf + psi_d * ct * cf,
            ]
        )
        if susp:  # then the pitch on the suspension, about the rolled body's y axis
            zero = np.zeros_like(theta_s)
            R = rot.euler_to_dcm(zero, theta_s, zero)  # Ry(-theta_s)
            C_lb = C_lb @ R
            w_lb = np.einsum("mji,mj->mi", R, w_lb)
            w_lb[:, 1] -= theta_sd
        C_nb = np.swapaxes(C_ln, 1, 2) @ C_lb
        w = w_lb + np.einsum("mji,mj->mi", C_lb, w_nl)
        return C_nb, w
