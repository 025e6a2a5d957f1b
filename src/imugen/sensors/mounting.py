"""IMU mounting on the vehicle: a small misalignment and a lever arm drawn per sequence.

The truth (:mod:`imugen.truth`) is the motion of the vehicle reference point and of the
vehicle body frame ``v`` (x forward, y left, z up). A real IMU sits at a lever arm ``l_v``
(m, vehicle axes) from that point, and its case axes ``b`` are rotated from the vehicle's by a
small misalignment ``C_vb = Rz(yaw) Ry(-pitch) Rx(roll)`` (the attitude convention of
:func:`imugen.core.rotations.euler_to_dcm`: a positive pitch tilts the IMU's nose up). Both are
drawn per sequence (stream ``mounting``): ``roll, pitch, yaw ~ N(0, sd^2)`` per angle and
``l_v ~ N(nominal, sd^2)`` per axis, and labelled (:data:`imugen.tables.shard.MOUNTING`). The
non-holonomic constraint, exact for the vehicle (no lateral or vertical velocity of the
reference point in ``v``), is then violated by the IMU as a real one is: straight at speed
``u`` the IMU sees ``v_b = u (1, -yaw, -pitch)`` to first order.

What the mounted IMU measures (``omega = omega_ib_v``, ``f = f_v`` the truth's, ``alpha =
d omega / dt``, ``Gamma`` the gravitation gradient, ``C_bv = C_vb^T``)
    rates: ``omega_b = C_bv omega``; ``f_b = C_bv (f + alpha x l + omega x (omega x l) -
    C_vn Gamma C_nv l)``. ``alpha`` by 4th-order central differences of the truth's rate
    samples (2nd order one-sided at the two ends).
    compensated increments (interval ``[t_{k-1}, t_k]``, ``R_k = Exp(dtheta_k)`` the truth's
    attitude change): ``dtheta_b = C_bv dtheta`` (exact: ``Log(C^T R C) = C^T Log R``);
    ``dv_b = C_bv (dv + R_k (omega_k x l) - omega_{k-1} x l - dt/2 (g_{k-1} + R_k g_k))``,
    ``g_k = C_vn Gamma C_nv l`` at ``t_k``. The lever-arm term is the change of the lever
    arm's inertial velocity ``C_iv (omega x l)`` between the interval's ends, resolved in the
    frame at its start: exact at any rate, whatever the rotation within the interval (no
    sculling approximation); the gravitation-gradient term is the trapezoid of a term below
    ``3e-6 |l|`` m/s^2 (zero in ``flat``).
    raw increments (plain integrals): ``dtheta_b = C_bv dtheta``; ``dv_b = C_bv (dv + (omega_k
    - omega_{k-1}) x l + Q_k l - dt/2 (g_{k-1} + g_k))``, ``Q_k = int [omega x]^2 dt`` by the
    4-point rule of :func:`imugen.navigate.mechanize.interval_integrals` (the truth's own raw
    quadrature): ``int alpha x l dt`` is exact.
The gravitation gradient is the one at the route origin (finite differences of
:func:`imugen.core.earth.gravitation_n`; relative error ``distance / R`` of a term that is itself
``2 g / R |l|``); it needs the truth's attitude, so it is applied to ``wgs84`` truth files (a
truth given as arrays: left out). The vehicle's truth therefore becomes, for the IMU:
``p_imu = p + C_nv l``, ``v_imu = v + C_nv ((omega - C_vn Omega_n) x l)``, ``C_nb = C_nv
C_vb`` (:func:`imu_states`): what free-inertial navigation of the shard starts from and is
compared with. In :mod:`imugen.simulate.stage` the transform runs on the truth's chunks before the
case vibration (:mod:`imugen.sensors.vibration`, which shakes the IMU about its mount) and the sensor
errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imugen.core.errors import InputError
from imugen.core.jit import njit
from imugen.core.rotations import dcm_to_quat, euler_to_dcm, quat_mul, quat_to_dcm

DEFAULT_MISALIGNMENT_SD_DEG = (1.0, 1.0, 2.0)
"""Roll, pitch, yaw 1-sigma of an IMU bolted to a car without a calibrated mount (deg)."""
DEFAULT_LEVER_ARM_SD_M = (0.05, 0.05, 0.05)
"""Lever-arm 1-sigma around the nominal, vehicle x, y, z (m): a lever arm measured with a tape."""
KEYS = ("enabled", "misalignment_sd_deg", "lever_arm_m", "lever_arm_sd_m")


@dataclass(frozen=True)
class MountingSpec:
    """Distribution of the mounting (SI).

    Attributes
    ----------
    misalignment_sd_rad : (3,)  roll, pitch, yaw 1-sigma [rad]
    lever_arm_m : (3,)          nominal lever arm in vehicle axes [m]
    lever_arm_sd_m : (3,)       lever-arm 1-sigma per axis [m]
    """

    misalignment_sd_rad: tuple = tuple(math.radians(x) for x in DEFAULT_MISALIGNMENT_SD_DEG)
    lever_arm_m: tuple = (0.0, 0.0, 0.0)
    lever_arm_sd_m: tuple = DEFAULT_LEVER_ARM_SD_M

    @classmethod
    def from_option(cls, option, source="mounting") -> MountingSpec | None:
        """The spec of a config/CLI option: None, ``"off"``, False or ``{"enabled": false}``
        give None; a dict with any of :data:`KEYS` (degrees and metres at this edge; missing
        keys take the documented defaults)."""
        if option in (None, False, "off"):
            return None
        if not isinstance(option, dict):
            raise InputError(source, f"must be an object with keys {', '.join(KEYS)}")
        extra = sorted(set(option) - set(KEYS))
        if extra:
            raise InputError(source, f"unknown key(s) {', '.join(extra)}; keys: {', '.join(KEYS)}")
        if not option.get("enabled", True):
            return None

        def vec(key, default, lo):
            v = option.get(key, default)
            if isinstance(v, int | float) and not isinstance(v, bool):
                v = (v, v, v)
            try:
                a = np.asarray(v, dtype=float)
            except (TypeError, ValueError):
                a = np.zeros(0)
            if a.shape != (3,) or not np.all(np.isfinite(a)) or (lo is not None and a.min() < lo):
                need = "three finite numbers" + ("" if lo is None else " >= 0")
                raise InputError(source, f"{key} must be {need}, got {v!r}")
            return tuple(float(x) for x in a)

        sd_deg = vec("misalignment_sd_deg", DEFAULT_MISALIGNMENT_SD_DEG, 0.0)
        return cls(
            tuple(math.radians(x) for x in sd_deg),
            vec("lever_arm_m", (0.0, 0.0, 0.0), None),
            vec("lever_arm_sd_m", DEFAULT_LEVER_ARM_SD_M, 0.0),
        )

    def as_dict(self) -> dict:
        """Metadata form (datasheet units, as configured)."""
        return {
            "misalignment_sd_deg": [math.degrees(x) for x in self.misalignment_sd_rad],
            "lever_arm_m": list(self.lever_arm_m),
            "lever_arm_sd_m": list(self.lever_arm_sd_m),
        }

    def draw(self, rng: np.random.Generator):
        """One sequence's ``(angles (3,) roll/pitch/yaw [rad], lever arm (3,) [m])``: six
        normals, always all drawn."""
        z = rng.standard_normal(6)
        return (
            np.asarray(self.misalignment_sd_rad) * z[:3],
            np.asarray(self.lever_arm_m) + np.asarray(self.lever_arm_sd_m) * z[3:],
        )


def C_vb(angles) -> np.ndarray:
    """Mounting rotation(s) from roll/pitch/yaw angles (..., 3) [rad] -> (..., 3, 3)."""
    a = np.asarray(angles, dtype=float)
    return euler_to_dcm(a[..., 0], a[..., 1], a[..., 2])


# --- what the mounted IMU measures ---------------------------------------------------------------
@njit(cache=True)
def _apply_kernel(
    k0, dt, Cbv, lv, w, wp, alpha, f, dth, dv, Q, G, Gp, raw, use_g, ow, of, odth, odv
):
    L = w.shape[0]
    m = np.empty(3)
    a = np.empty(3)
    x = np.empty(3)
    for j in range(L):
        wx, wy, wz = w[j, 0], w[j, 1], w[j, 2]
        # omega x l, omega x (omega x l), alpha x l
        cx = wy * lv[2] - wz * lv[1]
        cy = wz * lv[0] - wx * lv[2]
        cz = wx * lv[1] - wy * lv[0]
        m[0] = alpha[j, 1] * lv[2] - alpha[j, 2] * lv[1] + wy * cz - wz * cy
        m[1] = alpha[j, 2] * lv[0] - alpha[j, 0] * lv[2] + wz * cx - wx * cz
        m[2] = alpha[j, 0] * lv[1] - alpha[j, 1] * lv[0] + wx * cy - wy * cx
        if use_g:
            for i in range(3):
                m[i] -= G[j, i, 0] * lv[0] + G[j, i, 1] * lv[1] + G[j, i, 2] * lv[2]
        for i in range(3):
            ow[j, i] = Cbv[i, 0] * wx + Cbv[i, 1] * wy + Cbv[i, 2] * wz
            of[j, i] = (
                Cbv[i, 0] * (f[j, 0] + m[0])
                + Cbv[i, 1] * (f[j, 1] + m[1])
                + Cbv[i, 2] * (f[j, 2] + m[2])
            )
            odth[j, i] = Cbv[i, 0] * dth[j, 0] + Cbv[i, 1] * dth[j, 1] + Cbv[i, 2] * dth[j, 2]
        if k0 + j == 0:
            for i in range(3):
                odv[j, i] = 0.0
            continue
        # previous sample's omega x l
        px = wp[j, 1] * lv[2] - wp[j, 2] * lv[1]
        py = wp[j, 2] * lv[0] - wp[j, 0] * lv[2]
        pz = wp[j, 0] * lv[1] - wp[j, 1] * lv[0]
        if raw:
            for i in range(3):
                a[i] = Q[j, i, 0] * lv[0] + Q[j, i, 1] * lv[1] + Q[j, i, 2] * lv[2]
            x[0] = dv[j, 0] + cx - px + a[0]
            x[1] = dv[j, 1] + cy - py + a[1]
            x[2] = dv[j, 2] + cz - pz + a[2]
            if use_g:
                for i in range(3):
                    gk = G[j, i, 0] * lv[0] + G[j, i, 1] * lv[1] + G[j, i, 2] * lv[2]
                    gp = Gp[j, i, 0] * lv[0] + Gp[j, i, 1] * lv[1] + Gp[j, i, 2] * lv[2]
                    x[i] -= 0.5 * dt * (gk + gp)
        else:
            # R = Exp(dtheta) (Rodrigues); u = omega_k x l - dt/2 g_k rotated by R
            ux, uy, uz = cx, cy, cz
            if use_g:
                ux -= 0.5 * dt * (G[j, 0, 0] * lv[0] + G[j, 0, 1] * lv[1] + G[j, 0, 2] * lv[2])
                uy -= 0.5 * dt * (G[j, 1, 0] * lv[0] + G[j, 1, 1] * lv[1] + G[j, 1, 2] * lv[2])
                uz -= 0.5 * dt * (G[j, 2, 0] * lv[0] + G[j, 2, 1] * lv[1] + G[j, 2, 2] * lv[2])
            tx, ty, tz = dth[j, 0], dth[j, 1], dth[j, 2]
            t2 = tx * tx + ty * ty + tz * tz
            if t2 < 1e-6:
                s1 = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
                s2 = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
            else:
                th = math.sqrt(t2)
                s1 = math.sin(th) / th
                s2 = (1.0 - math.cos(th)) / t2
            # t x u, t x (t x u)
            ax = ty * uz - tz * uy
            ay = tz * ux - tx * uz
            az = tx * uy - ty * ux
            bx = ty * az - tz * ay
            by = tz * ax - tx * az
            bz = tx * ay - ty * ax
            x[0] = dv[j, 0] + ux + s1 * ax + s2 * bx - px
            x[1] = dv[j, 1] + uy + s1 * ay + s2 * by - py
            x[2] = dv[j, 2] + uz + s1 * az + s2 * bz - pz
            if use_g:
                for i in range(3):
                    x[i] -= (
                        0.5 * dt * (Gp[j, i, 0] * lv[0] + Gp[j, i, 1] * lv[1] + Gp[j, i, 2] * lv[2])
                    )
        for i in range(3):
            odv[j, i] = Cbv[i, 0] * x[0] + Cbv[i, 1] * x[1] + Cbv[i, 2] * x[2]


def _alpha(w, dt, lo_pad, hi_pad):
    """Angular acceleration at the rows of ``w`` between ``lo_pad`` and ``len - hi_pad``:
    4th-order central differences, 2nd-order one-sided where a neighbour is missing."""
    n = len(w)
    out = np.empty((n - lo_pad - hi_pad, 3))
    for r in range(lo_pad, n - hi_pad):
        if r >= 2 and r + 2 < n:
            d = (w[r - 2] - 8.0 * w[r - 1] + 8.0 * w[r + 1] - w[r + 2]) / (12.0 * dt)
        elif r >= 1 and r + 1 < n:
            d = (w[r + 1] - w[r - 1]) / (2.0 * dt)
        elif r == 0:
            d = (-3.0 * w[0] + 4.0 * w[1] - w[2]) / (2.0 * dt)
        else:
            d = (3.0 * w[r] - 4.0 * w[r - 1] + w[r - 2]) / (2.0 * dt)
        out[r - lo_pad] = d
    return out


def _alpha_fast(w, dt, lo_pad, hi_pad):
    """Vectorized :func:`_alpha` (interior rows at once; the edge rows by :func:`_alpha`)."""
    n = len(w)
    out = np.empty((n, 3))
    if n < 3:  # two samples: one difference
        out[:] = (w[-1] - w[0]) / ((n - 1) * dt)
        return out[lo_pad : n - hi_pad]
    if n >= 5:
        out[2 : n - 2] = (w[:-4] - 8.0 * w[1:-3] + 8.0 * w[3:-1] - w[4:]) / (12.0 * dt)
        edges = [0, 1, n - 2, n - 1]
    else:
        edges = range(n)
    for r in edges:
        out[r] = _alpha(w, dt, r, n - r - 1)[0]
    return out[lo_pad : n - hi_pad]


class Mounting:
    """The shared part of the mounted-IMU transform on one truth (one per shard).

    Parameters
    ----------
    truth : imugen.sensors.ideal.TruthSource
        Serves the vehicle's ideal IMU in chunks.
    q_nb : (K, 4) ndarray, optional
        The truth's attitude ``C_nv``, for the gravitation-gradient term.
    gradient : (G, 3, 3) ndarray, optional
        Gravitation gradient in n [1/s^2] at samples ``0, step, 2 step, ..`` and ``K - 1``
        (:func:`gradient_grid`), linearly interpolated; None: left out (``flat``).
    step : int
        Spacing of the gradient grid [samples].
    """

    def __init__(self, truth, q_nb=None, gradient=None, step=1):
        self.truth = truth
        self.q_nb = q_nb
        self.gradient = None if gradient is None or q_nb is None else np.asarray(gradient)
        self.step = int(step)

    def _G(self, k0, L):
        """``C_vn Gamma C_nv`` at samples ``k0 .. k0+L-1`` (L, 3, 3)."""
        C = quat_to_dcm(self.q_nb[k0 : k0 + L])
        k = np.arange(k0, k0 + L)
        grid = _grid(self.truth.K, self.step)
        G = np.empty((L, 9))
        flat = self.gradient.reshape(-1, 9)
        for i in range(9):
            G[:, i] = np.interp(k, grid, flat[:, i])
        return np.einsum("kji,kjl,klm->kim", C, G.reshape(L, 3, 3), C)

    def shared(self, k0, L, raw):
        """Quantities shared by every sequence for samples ``k0 .. k0+L-1``: ``(w, w_prev,
        alpha, f, Q, G, G_prev)`` (``Q``, ``G`` empty when unused)."""
        tr, K, dt = self.truth, self.truth.K, self.truth.dt
        lo = max(0, k0 - 3)
        hi = min(K, k0 + L + 2)
        w_ext = tr.chunk(lo, hi - lo)[1]
        a = k0 - lo
        w = w_ext[a : a + L]
        wp = w_ext[a - 1 : a - 1 + L] if k0 > 0 else np.vstack([w[:1], w[: L - 1]])
        alpha = _alpha_fast(w_ext, dt, a, hi - lo - a - L)
        f = tr.chunk(k0, L)[2]
        if raw:
            # Q_k = int [w x]^2 over the interval ending at k: 4-point rule on the samples
            ww = np.einsum("ki,kj->kij", w_ext, w_ext).reshape(-1, 9)
            n2 = np.einsum("ki,ki->k", w_ext, w_ext)
            ww[:, [0, 4, 8]] -= n2[:, None]
            # interval ending at global g: the 4-point rule on samples g-2 .. g+1 (the 4
            # nearest at the two end intervals), as the truth's raw quadrature
            Qe = np.zeros_like(ww)
            c = dt / 24.0
            r = np.arange(a, a + L)
            g = lo + r
            inner = r[(g >= 2) & (g <= K - 2)]
            Qe[inner] = c * (
                -ww[inner - 2] + 13.0 * ww[inner - 1] + 13.0 * ww[inner] - ww[inner + 1]
            )
            for rr in r[(g == 1) | (g == K - 1)]:
                if K < 4:  # trapezoid, as interval_integrals
                    Qe[rr] = 0.5 * dt * (ww[rr - 1] + ww[rr])
                else:
                    Qe[rr] = _edge_integral(ww, rr, lo + rr == 1, dt)
            Q = np.ascontiguousarray(Qe[a : a + L].reshape(L, 3, 3))
        else:
            Q = _EMPTY33
        if self.gradient is not None:
            G = self._G(k0, L)
            Gp = self._G(k0 - 1, L) if k0 > 0 else np.concatenate([G[:1], G[: L - 1]])
        else:
            G = Gp = _EMPTY33
        return w, wp, alpha, f, Q, G, Gp

    def apply(self, k0, shared, angles, lever, dth, dv, raw=False):
        """One sequence's mounted IMU for a chunk: ``(omega_b, f_b, dtheta_b, dv_b)`` (L, 3)
        new arrays; ``dth``, ``dv`` the vehicle's increments (compensated or ``raw``)."""
        w, wp, alpha, f, Q, G, Gp = shared
        L = len(w)
        Cbv = np.ascontiguousarray(C_vb(angles).T)
        out = [np.empty((L, 3)) for _ in range(4)]
        _apply_kernel(
            int(k0), float(self.truth.dt), Cbv, np.asarray(lever, dtype=np.float64),
            *(np.ascontiguousarray(x, dtype=np.float64) for x in (w, wp, alpha, f, dth, dv)),
            Q, G, Gp, bool(raw), self.gradient is not None, *out,
        )  # fmt: skip
        return tuple(out)


_EMPTY33 = np.zeros((0, 3, 3))


def _edge_integral(x, r, first, dt):
    """4-point rule of the first (``first``) or last interval, ending at row ``r`` of ``x``."""
    c = dt / 24.0
    if first:
        return c * (9.0 * x[r - 1] + 19.0 * x[r] - 5.0 * x[r + 1] + x[r + 2])
    return c * (9.0 * x[r] + 19.0 * x[r - 1] - 5.0 * x[r - 2] + x[r - 3])


def _grid(K, step):
    return np.unique(np.append(np.arange(0, K, step), K - 1))


def gravitation_gradient(p_n, frame, h=10.0) -> np.ndarray:
    """Gravitation gradient ``d G_n / d p_n`` at positions ``p_n`` (m, 3) -> (m, 3, 3)
    [1/s^2], central differences with step ``h`` m (exact to ``(h / R)^2``)."""
    from imugen.core.earth import gravitation_n

    p = np.atleast_2d(np.asarray(p_n, dtype=float))
    out = np.empty((len(p), 3, 3))
    for j in range(3):
        d = np.zeros(3)
        d[j] = h
        out[:, :, j] = (gravitation_n(p + d, frame) - gravitation_n(p - d, frame)) / (2.0 * h)
    return out


def setup(truth, spec: MountingSpec | None, source=None) -> Mounting | None:
    """The shard's :class:`Mounting` (None when ``spec`` is None). ``source``: the truth file,
    read for its position and attitude when its Earth model is ``wgs84`` (gravitation
    gradient at 1 s spacing along the route, where it changes by ``speed / R`` per second)."""
    if spec is None:
        return None
    if source is None or truth.meta.get("earth") != "wgs84":
        return Mounting(truth)
    from imugen.tables import truth as ttruth

    tr = ttruth.read(source, columns=[*ttruth.POS, *ttruth.QUAT], arrow=True)
    step = max(1, round(1.0 / truth.dt))
    grad = gravitation_gradient(tr.p_n[_grid(tr.K, step)], tr.origin_frame())
    return Mounting(truth, tr.q_nb, grad, step)


def forward_axis_angles(angles) -> np.ndarray:
    """What a non-holonomic constraint can observe of a mounting: the direction of the
    vehicle's forward axis in IMU axes, ``e = C_bv (1, 0, 0)``, as the pitch and yaw
    ``(atan2(-e_z, e_x), asin(-e_y))`` that map it back to x through ``Rz(yaw) Ry(-pitch)``
    (rad; (..., 3) roll/pitch/yaw -> (..., 2)). Equal to the Euler pitch and yaw when the roll
    is zero; otherwise they differ by about ``roll x yaw``."""
    e = C_vb(angles)[..., 0, :]
    return np.stack([np.arctan2(-e[..., 2], e[..., 0]), np.arcsin(-e[..., 1])], axis=-1)


# --- the IMU's truth --------------------------------------------------------------------------------
def imu_states(p_n, v_n, q_nb, omega_ib_b, omega_n, angles, lever):
    """The mounted IMU's truth from the vehicle's, for ``S`` sequences.

    Parameters
    ----------
    p_n, v_n : (K, 3)        vehicle reference point position [m], velocity [m/s] in n
    q_nb : (K, 4)            vehicle attitude ``C_nv``
    omega_ib_b : (K, 3) or None  vehicle inertial rate [rad/s] (None: velocity not returned)
    omega_n : (3,)           Earth rate in n [rad/s]
    angles, lever : (S, 3)   mounting angles [rad] and lever arms [m]

    Returns
    -------
    p_imu (S, K, 3), v_imu (S, K, 3) or None, q_imu (S, K, 4)
    """
    angles = np.atleast_2d(np.asarray(angles, float))
    lever = np.atleast_2d(np.asarray(lever, float))
    C = quat_to_dcm(np.asarray(q_nb, float))  # (K, 3, 3)
    p = np.asarray(p_n, float)[None] + np.einsum("kij,sj->ski", C, lever)
    q = quat_mul(np.asarray(q_nb, float)[None], dcm_to_quat(C_vb(angles))[:, None])
    v = None
    if omega_ib_b is not None:
        w_nv = np.asarray(omega_ib_b, float) - np.einsum("kji,j->ki", C, np.asarray(omega_n))
        v = np.asarray(v_n, float)[None] + np.einsum(
            "kij,skj->ski", C, np.cross(w_nv[None], lever[:, None])
        )
    return p, v, q
