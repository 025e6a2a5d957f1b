"""Vehicle attitude: target frame from velocity and a reference vector, attitude holds at low
speed blended in by a quintic smoothstep, roll flips of coordinated flight."""

from __future__ import annotations

import numpy as np

from imugen import earth as ea
from imugen import rotations as rot


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


class EarthField:
    """Gravity/up helpers on top of :mod:`imugen.earth` for one origin frame."""

    def __init__(self, frame: ea.OriginFrame):
        self.frame = frame
        self.flat = frame.model == "flat"
        self.Omega = ea.earth_rate_n(frame)

    def gravity(self, p):
        return ea.gravity_n(p, self.frame)

    def gravitation(self, p):
        return ea.gravitation_n(p, self.frame)

    def up_and_rate(self, p, v):
        """Local geodetic up at p in n, and its time derivative for velocity v (m,3)."""
        if self.flat:
            up = np.zeros_like(p)
            up[:, 2] = 1.0
            return up, np.zeros_like(p)
        lat, lon, h = self.frame.geodetic_from_n(p)
        C_ln = ea.C_en_from_geodetic(lat, lon) @ self.frame.C_en.T
        v_l = np.einsum("mij,mj->mi", C_ln, v)
        s2 = np.sin(lat) ** 2
        den = np.sqrt(1.0 - ea.E2_WGS84 * s2)
        RN = ea.A_WGS84 / den
        RM = ea.A_WGS84 * (1.0 - ea.E2_WGS84) / den**3
        ud_l = np.column_stack([v_l[:, 0] / (RN + h), v_l[:, 1] / (RM + h), np.zeros(len(p))])
        return C_ln[:, 2, :].copy(), np.einsum("mji,mj->mi", C_ln, ud_l)

    def gravity_rate(self, p, v):
        """d/dt g_n(p(t)) = (grad g) v by a central difference along v (10 m each side)."""
        if self.flat:
            return np.zeros_like(p)
        spd = np.linalg.norm(v, axis=1, keepdims=True)
        e = np.divide(v, spd, out=np.zeros_like(v), where=spd > 0)
        hstep = 10.0
        return (self.gravity(p + hstep * e) - self.gravity(p - hstep * e)) * (spd / (2 * hstep))


def _level_attitude(up):
    """C_nb with body z = ``up`` and body x toward n's East projected on the level; (3,) -> (3, 3)."""
    x = np.array([1.0, 0.0, 0.0]) - up * up[0]
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - up * up[1]
    x = x / np.linalg.norm(x)
    return np.stack([x, np.cross(up, x), up], axis=-1)


_QX = np.array([0.0, 1.0, 0.0, 0.0])  # rotation by pi about body x


def _flip_roll(out, rows, sQ, sG):
    """Turn the attitude of ``rows`` by pi about body x (z -> -z): q * (0,1,0,0), w -> (wx,-wy,-wz)."""
    out[rows, sQ] = rot.quat_mul(out[rows, sQ], _QX)
    g = out[rows, sG]
    g[..., 1:] *= -1.0
    out[rows, sG] = g


def attitude_pass(out, ci, motion, times, E, vp, chunk):
    """Kinematics and attitude of every sample (pass 1), written into ``out``.

    Fills position, velocity, ``q_nb`` and ``omega_nb_b`` (rate of b relative to n, without
    the Earth rate) of the truth table ``out`` (K, columns) whose column indices are ``ci``.

    Returns
    -------
    f_n : ndarray, shape (K, 3)
        Specific force in n [m/s^2] (``C_nb`` is final only after the holds).
    stats : dict
        ``accel_rms_mps2``, ``accel_max_mps2``, ``attitude_hold_windows``,
        ``max_blend_angle_rad``.
    """
    K = len(times)
    iP, iV, iQ, iG = ci["pos"], ci["vel"], ci["quat"], ci["gyro"]
    sigma = np.empty(K)
    sigma_d = np.empty(K)
    f_n_all = np.empty((K, 3))
    acc_ss, acc_max = 0.0, 0.0
    for k0 in range(0, K, chunk):
        k1 = min(K, k0 + chunk)
        p, v, a, j = motion.eval(times[k0:k1])
        an = np.linalg.norm(a, axis=1)
        acc_ss += float(np.sum(an * an))
        acc_max = max(acc_max, float(an.max()))
        f_n = a + 2.0 * np.cross(E.Omega, v) - E.gravity(p)
        if vp.attitude == "level":
            r, rd = E.up_and_rate(p, v)
        else:
            r = f_n
            rd = j + 2.0 * np.cross(E.Omega, a) - E.gravity_rate(p, v)
        C, w, spd, spd_d, rpn, rpn_d = _target_frame(v, a, r, rd)
        s1, ds1 = _smoothstep(spd, *vp.hold_speed_mps)
        s2, ds2 = _smoothstep(rpn, *vp.hold_perp)
        sigma[k0:k1] = s1 * s2
        sigma_d[k0:k1] = ds1 * spd_d * s2 + s1 * ds2 * rpn_d
        out[k0:k1, iP] = p
        out[k0:k1, iV] = v
        out[k0:k1, iQ] = rot.dcm_to_quat(C)
        out[k0:k1, iG] = w
        f_n_all[k0:k1] = f_n
    n_hold, phi_max = _blend_holds(out, ci, sigma, sigma_d, E, vp)
    stats = {
        "accel_rms_mps2": float(np.sqrt(acc_ss / K)),
        "accel_max_mps2": acc_max,
        "attitude_hold_windows": n_hold,
        "max_blend_angle_rad": phi_max,
    }
    return f_n_all, stats


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
            up, _ = E.up_and_rate(out[:1, iP], np.zeros((1, 3)))
            q_h = rot.dcm_to_quat(_level_attitude(up[0]))
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
