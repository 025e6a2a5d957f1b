"""Compiled kernels of the strapdown mechanization (:mod:`imugen.navigate.mechanize` is
their face): the state layout, the time recursion of a batch of sequences (:func:`kernel`)
and the two-sample coning/sculling correction of raw increments (:func:`compensate`).
The formulation is that of the face's docstring; no I/O, no allocation per step.
"""

from __future__ import annotations

import math

import numpy as np

from imugen.core import earth
from imugen.core.jit import njit
from imugen.core.rotations_nb import fma as _fma
from imugen.core.rotations_nb import qexpm1 as _qexpm1
from imugen.core.rotations_nb import qmul as _qmul

# --- state layout (one row per sequence) --------------------------------------------------------
# flat: n-frame quantities; wgs84/geodetic: inertial ones (module docstring)
S_P = 0  # position p_n, or r_I - r0_n (3)
S_PC = 3  # Kahan compensation of p (3)
S_V = 6  # velocity v_n, or v_I (3)
S_VC = 9  # Kahan compensation of v (3)
S_Q = 12  # quaternion q_nb, or q_Ib (4), scalar first
S_VP = 16  # velocity at the previous sample (3)
S_G = 19  # gravitation at sample k (3)
S_GP = 22  # gravitation at sample k-1 (3)
S_K = 25  # steps done
S_QC = 26  # Kahan compensation of q (4)
S_N = 30  # gravitation at the last four nodes k = j m, (j-1) m .. (j-3) m (12), newest first
S_FB = 42  # blocks integrated with the exact gravitation every step (error check failed)
S_D4 = 43  # 4th difference of the nodes at the previous node (3; inf until 5 nodes exist)
S_B = 46  # height loop: vertical acceleration correction b (third order) [m/s^2]
S_KL = 47  # height loop: sample k of its last update
S_NL = 48  # height loop: updates done
S_DH = 49  # height loop: last height error h - h_ref [m]
N_STATE = 50

# --- kernel parameter vector: frame params (earth.N_PARAMS) then these ------------------------
K_DT = earth.N_PARAMS  # dt
K_MB = K_DT + 1  # steps per gravitation node interval m (1: exact gravitation every step)
K_D4 = K_MB + 1  # limit on |4th difference of the nodes| (24 x the error allowed, / margin)
N_KPARAMS = K_D4 + 1

K3 = earth.GM_WGS84 / earth.R_MEAN**3  # point-mass gravity gradient scale [1/s^2]
IG2 = (earth.R_MEAN**2 / earth.GM_WGS84) ** 2  # 1 / |G|^2 at the mean radius


# --- numba kernel --------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _qmul_f(aw, ax, ay, az, bw, bx, by, bz):
    """``_qmul`` with fused multiply-adds, in two balanced halves (short dependency chain)."""
    return (
        _fma(aw, bw, -ax * bx) - _fma(ay, by, az * bz),
        _fma(aw, bx, ax * bw) + _fma(ay, bz, -az * by),
        _fma(aw, by, -ax * bz) + _fma(ay, bw, az * bx),
        _fma(aw, bz, ax * by) + _fma(-ay, bx, az * bw),
    )


@njit(cache=True, inline="always")
def _qrot(qw, qx, qy, qz, vx, vy, vz):
    """Rotate v by q (C(q) v): v + w t + q_vec x t with t = 2 q_vec x v."""
    tx = 2.0 * _fma(qy, vz, -qz * vy)
    ty = 2.0 * _fma(qz, vx, -qx * vz)
    tz = 2.0 * _fma(qx, vy, -qy * vx)
    return (
        _fma(qw, tx, vx) + _fma(qy, tz, -qz * ty),
        _fma(qw, ty, vy) + _fma(qz, tx, -qx * tz),
        _fma(qw, tz, vz) + _fma(qx, ty, -qy * tx),
    )


@njit(cache=True)
def _rot_axis(zx, zy, zz, c, s, omc, x, y, z):
    """Rotate (x, y, z) about the unit axis zax by the angle (cos c, sin s, 1 - cos omc)."""
    d = omc * (zx * x + zy * y + zz * z)
    return (
        c * x + s * (zy * z - zz * y) + d * zx,
        c * y + s * (zz * x - zx * z) + d * zy,
        c * z + s * (zx * y - zy * x) + d * zz,
    )


@njit(cache=True)
def _write(out_p, out_v, out_q, s, slot, prm, k, px, py, pz, vx, vy, vz, q0, q1, q2, q3, wq):
    """Store sample ``k`` (kernel quantities, compensations already applied) in n."""
    if prm[earth.P_MODEL] != 0.0:
        iw = 1.0 / earth.OMEGA_IE
        zx = prm[earth.P_OMEGA] * iw
        zy = prm[earth.P_OMEGA + 1] * iw
        zz = prm[earth.P_OMEGA + 2] * iw
        th = -earth.OMEGA_IE * prm[K_DT] * k  # A(t_k)^T, from its half angle
        h = math.sin(0.5 * th)
        ch = math.cos(0.5 * th)
        omc = 2.0 * h * h
        c = 1.0 - omc
        sn = 2.0 * h * ch
        r0x = prm[earth.P_R0N]
        r0y = prm[earth.P_R0N + 1]
        r0z = prm[earth.P_R0N + 2]
        # p_n = A^T d + (A^T - I) r0_n (no cancellation against r0_n)
        ax, ay, az = _rot_axis(zx, zy, zz, c, sn, omc, px, py, pz)
        bx, by, bz = _rot_axis(zx, zy, zz, 0.0, sn, omc, r0x, r0y, r0z)
        px = ax + (bx - omc * r0x)
        py = ay + (by - omc * r0y)
        pz = az + (bz - omc * r0z)
        # v_n = A^T v_I - Omega x r_n
        ax, ay, az = _rot_axis(zx, zy, zz, c, sn, omc, vx, vy, vz)
        rx = r0x + px
        ry = r0y + py
        rz = r0z + pz
        w = earth.OMEGA_IE
        vx = ax - w * (zy * rz - zz * ry)
        vy = ay - w * (zz * rx - zx * rz)
        vz = az - w * (zx * ry - zy * rx)
        if wq:
            q0, q1, q2, q3 = _qmul(ch, h * zx, h * zy, h * zz, q0, q1, q2, q3)
    if 0 <= slot < out_p.shape[1]:
        out_p[s, slot, 0] = px
        out_p[s, slot, 1] = py
        out_p[s, slot, 2] = pz
    if 0 <= slot < out_v.shape[1]:
        out_v[s, slot, 0] = vx
        out_v[s, slot, 1] = vy
        out_v[s, slot, 2] = vz
    if wq and 0 <= slot < out_q.shape[1]:
        out_q[s, slot, 0] = q0
        out_q[s, slot, 1] = q1
        out_q[s, slot, 2] = q2
        out_q[s, slot, 3] = q3


# --- height loop (damped vertical channel, imugen.navigate.vertical) -----------------------
@njit(cache=True, inline="always")
def _geodetic_h_up(x, y, z):
    """ECEF -> (height, up_e): Bowring, one iteration (scalar twin of earth.geodetic_parts)."""
    sl, cl, clon, slon, h = earth.geodetic_parts_nb(x, y, z)
    return h, cl * clon, cl * slon, sl


@njit(cache=True)
def height_of(prm, k, px, py, pz):
    """Height [m] above the ellipsoid and local up (unit, kernel frame I) at the kernel
    displacement ``d = (px, py, pz)`` of sample ``k``; ``flat``: the Up of n and n's Up."""
    if prm[earth.P_MODEL] == 0.0:
        return pz, 0.0, 0.0, 1.0
    iw = 1.0 / earth.OMEGA_IE
    zx = prm[earth.P_OMEGA] * iw
    zy = prm[earth.P_OMEGA + 1] * iw
    zz = prm[earth.P_OMEGA + 2] * iw
    th = earth.OMEGA_IE * prm[K_DT] * k  # A(t_k): I <- n
    h = math.sin(-0.5 * th)
    ch = math.cos(0.5 * th)
    omc = 2.0 * h * h
    c = 1.0 - omc
    sn = 2.0 * h * ch  # sin(-th): A^T
    r0x = prm[earth.P_R0N]
    r0y = prm[earth.P_R0N + 1]
    r0z = prm[earth.P_R0N + 2]
    ax, ay, az = _rot_axis(zx, zy, zz, c, sn, omc, px, py, pz)
    bx, by, bz = _rot_axis(zx, zy, zz, 0.0, sn, omc, r0x, r0y, r0z)
    pnx = ax + (bx - omc * r0x)
    pny = ay + (by - omc * r0y)
    pnz = az + (bz - omc * r0z)
    # r_e = r0_e + C_en^T p_n
    C = prm[earth.P_CEN : earth.P_CEN + 9]
    rex = prm[earth.P_R0E] + C[0] * pnx + C[3] * pny + C[6] * pnz
    rey = prm[earth.P_R0E + 1] + C[1] * pnx + C[4] * pny + C[7] * pnz
    rez = prm[earth.P_R0E + 2] + C[2] * pnx + C[5] * pny + C[8] * pnz
    hh, uex, uey, uez = _geodetic_h_up(rex, rey, rez)
    # up_n = C_en up_e, up_I = A up_n
    unx = C[0] * uex + C[1] * uey + C[2] * uez
    uny = C[3] * uex + C[4] * uey + C[5] * uez
    unz = C[6] * uex + C[7] * uey + C[8] * uez
    ux, uy, uz = _rot_axis(zx, zy, zz, c, -sn, omc, unx, uny, unz)
    return hh, ux, uy, uz


@njit(cache=True)
def heights_n(prm, p_n, h_out, up_out):
    """Heights [m] and local up (unit, in n) of n-frame positions ``p_n`` (K, 3), by the loop's
    own conversion (:func:`height_of` at ``k = 0``, where the kernel frame is n)."""
    for j in range(p_n.shape[0]):
        d0 = p_n[j, 0]
        d1 = p_n[j, 1]
        d2 = p_n[j, 2]
        h, ux, uy, uz = height_of(prm, 0, d0, d1, d2)
        h_out[j] = h
        up_out[j, 0] = ux
        up_out[j, 1] = uy
        up_out[j, 2] = uz


@njit(cache=True, inline="always")
def _grad(gx, gy, gz, dx, dy, dz):
    """Gravitation moved by d (point-mass gradient, as the kernel's node correction)."""
    gd = IG2 * (gx * dx + gy * dy + gz * dz)
    return (
        gx + K3 * (3.0 * gd * gx - dx),
        gy + K3 * (3.0 * gd * gy - dy),
        gz + K3 * (3.0 * gd * gz - dz),
    )


@njit(cache=True)
def kernel(dth, dvb, st, prm, every, out_p, out_v, out_q, out_start, href, gains):
    """Advance every sequence by ``dth.shape[1]`` steps (sequences outside, time inside).

    dth, dvb : (S, N, 3) increments; st : (S, N_STATE) state, updated in place;
    prm : kernel_params; out_* : (S, M, 3|4), M == 0 to skip; sample j (global index) is
    written to slot ``j // every - out_start`` when ``j % every == 0``;
    href : (1 or S, N + 1) reference heights [m] of samples ``k .. k + N`` (NaN: none; row 0
    serves every sequence when it has one row); gains : (k1, k2, k3) of the height loop, all
    zero for the free channel (:mod:`imugen.navigate.vertical`; href is not read then).
    """
    S = dth.shape[0]
    N = dth.shape[1]
    rot = prm[earth.P_MODEL] != 0.0
    dt = prm[K_DT]
    m = int(prm[K_MB]) if rot else 1
    d4lim = prm[K_D4]
    wq = out_q.shape[1] > 0  # attitude stored (else not converted)
    c12 = dt / 12.0
    hdt = 0.5 * dt
    iw = 1.0 / earth.OMEGA_IE
    zx = prm[earth.P_OMEGA] * iw
    zy = prm[earth.P_OMEGA + 1] * iw
    zz = prm[earth.P_OMEGA + 2] * iw
    r0x = prm[earth.P_R0N]
    r0y = prm[earth.P_R0N + 1]
    r0z = prm[earth.P_R0N + 2]
    g0dt = prm[earth.P_G0] * dt
    # block tables for a cubic gravitation g(tau) = sum_n c_n tau^n, tau = (t - t_k0) / T:
    # WC[j, n] = int_0^(j dt) tau^n dt = T (j/m)^(n+1) / (n+1), its velocity change after j
    # steps; QC[j, n], the matching position change by the 3-point rule (module docstring)
    T = m * dt
    WC = np.zeros((m + 1, 4))
    QC = np.zeros((m + 1, 4))
    for j in range(1, m + 1):
        x = j / m
        for n in range(4):
            WC[j, n] = T * x ** (n + 1) / (n + 1)
            wm = WC[j - 2, n] if j >= 2 else 0.0
            QC[j, n] = QC[j - 1, n] + c12 * (5.0 * WC[j, n] + 8.0 * WC[j - 1, n] - wm)
    abuf = np.empty((m + 1, 3))  # A_j: sums of the resolved specific-force increments
    pbuf = np.empty((m + 1, 3))  # QA_j: their position effect
    qbuf = np.empty((m + 1, 4))
    fbuf = np.empty((m, 3))  # a_j = C_Ib dv_j of the block's steps
    abuf[0] = 0.0
    pbuf[0] = 0.0
    k1, k2, k3 = gains[0], gains[1], gains[2]
    damp = k1 != 0.0 or k2 != 0.0 or k3 != 0.0
    Tl = m * dt  # height-loop update interval (every gravitation node)
    for s in range(S):
        # fmt: off
        (px, py, pz, pcx, pcy, pcz, vx, vy, vz, vcx, vcy, vcz,
         q0, q1, q2, q3, vpx, vpy, vpz, Gx, Gy, Gz, Gpx, Gpy, Gpz) = st[s, :25]
        (n0x, n0y, n0z, n1x, n1y, n1z, n2x, n2y, n2z,
         n3x, n3y, n3z) = st[s, S_N:S_N + 12]
        # fmt: on
        nfb = st[s, S_FB]
        dpx, dpy, dpz = st[s, S_D4], st[s, S_D4 + 1], st[s, S_D4 + 2]
        qc0, qc1, qc2, qc3 = st[s, S_QC], st[s, S_QC + 1], st[s, S_QC + 2], st[s, S_QC + 3]
        k = int(st[s, S_K])
        km = k % m  # phases of k (no integer division per step)
        kw = k % every
        k_start = k
        hs = s if href.shape[0] > 1 else 0
        bz_ = st[s, S_B]
        kl = int(st[s, S_KL])  # 0 at the start: no update at sample 0 (the initial state)
        nl = st[s, S_NL]
        dhl = st[s, S_DH]
        i = 0
        while i < N:
            # height loop at every node (km == 0), once per sample, from the sample's
            # reference height; impulses on p, v (and v_k-1: the 3-point rule sees no kink),
            # gravitation history moved with the position
            if damp and km == 0 and k > kl:
                kl = k
                hr = href[hs, k - k_start]
                if hr == hr:
                    hh, ux, uy, uz = height_of(prm, k, px - pcx, py - pcy, pz - pcz)
                    dh = hh - hr
                    dhl = dh
                    bz_ += k3 * dh * Tl
                    a1 = -k1 * dh * Tl
                    a2 = -(k2 * dh + bz_) * Tl
                    ddx = a1 * ux
                    ddy = a1 * uy
                    ddz = a1 * uz
                    px, pcx = _kahan(px, pcx, ddx)
                    py, pcy = _kahan(py, pcy, ddy)
                    pz, pcz = _kahan(pz, pcz, ddz)
                    wx = a2 * ux
                    wy = a2 * uy
                    wz = a2 * uz
                    if rot:  # Omega x delta d (the velocity of a displaced Earth-fixed point)
                        w = earth.OMEGA_IE
                        wx += w * (zy * ddz - zz * ddy)
                        wy += w * (zz * ddx - zx * ddz)
                        wz += w * (zx * ddy - zy * ddx)
                        Gx, Gy, Gz = _grad(Gx, Gy, Gz, ddx, ddy, ddz)
                        Gpx, Gpy, Gpz = _grad(Gpx, Gpy, Gpz, ddx, ddy, ddz)
                        n0x, n0y, n0z = _grad(n0x, n0y, n0z, ddx, ddy, ddz)
                        n1x, n1y, n1z = _grad(n1x, n1y, n1z, ddx, ddy, ddz)
                        n2x, n2y, n2z = _grad(n2x, n2y, n2z, ddx, ddy, ddz)
                        n3x, n3y, n3z = _grad(n3x, n3y, n3z, ddx, ddy, ddz)
                    vx, vcx = _kahan(vx, vcx, wx)
                    vy, vcy = _kahan(vy, vcy, wy)
                    vz, vcz = _kahan(vz, vcz, wz)
                    vpx += wx
                    vpy += wy
                    vpz += wz
                    nl += 1.0
            if km == 0 and m > 1 and k >= 4 * m and i + m <= N:
                # ---- a block of m steps: attitude first (it does not depend on gravity),
                # then the exact gravitation once at the block's predicted end, a cubic in
                # time through it and the three previous nodes, and velocity/position
                # specific force: running sums A_j and their 3-point position effect QA_j
                # (relative to the block start; v_k-1 - v_k enters the first step)
                inner = every - kw < m  # samples to store inside the block (buffers needed)
                # two short loops (few live values each, no register spills): attitude and
                # resolved increments a_j, then A_j and the 3-point position effect
                # QA_J = dt/12 (12 sum_(j<J) A_j + 5 A_J + A_(J-1) - A_(-1)), A_0 = 0
                for j in range(m):
                    ax, ay, az = _qrot(
                        q0, q1, q2, q3, dvb[s, i + j, 0], dvb[s, i + j, 1], dvb[s, i + j, 2]
                    )
                    fbuf[j, 0] = ax
                    fbuf[j, 1] = ay
                    fbuf[j, 2] = az
                    q0, q1, q2, q3, qc0, qc1, qc2, qc3 = _att_step(
                        q0, q1, q2, q3, qc0, qc1, qc2, qc3,
                        dth[s, i + j, 0], dth[s, i + j, 1], dth[s, i + j, 2],
                    )  # fmt: skip
                    if inner and wq:
                        qbuf[j + 1, 0] = q0 - qc0
                        qbuf[j + 1, 1] = q1 - qc1
                        qbuf[j + 1, 2] = q2 - qc2
                        qbuf[j + 1, 3] = q3 - qc3
                b0x = vpx - vx  # A_(-1) = v_(k-1) - v_k
                b0y = vpy - vy
                b0z = vpz - vz
                bx = b0x  # A_(j-1)
                by = b0y
                bz = b0z
                Ax = 0.0
                Ay = 0.0
                Az = 0.0
                Sx = 0.0  # sum_(j' < j) A_j'
                Sy = 0.0
                Sz = 0.0
                for j in range(m):
                    Sx += Ax
                    Sy += Ay
                    Sz += Az
                    bx = Ax
                    by = Ay
                    bz = Az
                    Ax += fbuf[j, 0]
                    Ay += fbuf[j, 1]
                    Az += fbuf[j, 2]
                    if inner:
                        abuf[j + 1, 0] = Ax
                        abuf[j + 1, 1] = Ay
                        abuf[j + 1, 2] = Az
                        pbuf[j + 1, 0] = c12 * (_fma(12.0, Sx, _fma(5.0, Ax, bx)) - b0x)
                        pbuf[j + 1, 1] = c12 * (_fma(12.0, Sy, _fma(5.0, Ay, by)) - b0y)
                        pbuf[j + 1, 2] = c12 * (_fma(12.0, Sz, _fma(5.0, Az, bz)) - b0z)
                Px = c12 * (_fma(12.0, Sx, _fma(5.0, Ax, bx)) - b0x)
                Py = c12 * (_fma(12.0, Sy, _fma(5.0, Ay, by)) - b0y)
                Pz = c12 * (_fma(12.0, Sz, _fma(5.0, Az, bz)) - b0z)
                # predicted end position: gravitation extrapolated linearly from the nodes
                e0 = QC[m, 0] + QC[m, 1]
                e1 = QC[m, 1]
                ppx = px + T * vx + Px + e0 * n0x - e1 * n1x
                ppy = py + T * vy + Py + e0 * n0y - e1 * n1y
                ppz = pz + T * vz + Pz + e0 * n0z - e1 * n1z
                gex, gey, gez = earth.gravitation_at_nb(r0x + ppx, r0y + ppy, r0z + ppz, zx, zy, zz)
                # error check (module docstring): 4th differences of the nodes, this one and
                # the previous one, and their extrapolation to the block; beyond the limit the
                # block takes the exact gravitation every step (the per-step rule, bit for bit)
                d4x = gex - 4.0 * n0x + 6.0 * n1x - 4.0 * n2x + n3x
                d4y = gey - 4.0 * n0y + 6.0 * n1y - 4.0 * n2y + n3y
                d4z = gez - 4.0 * n0z + 6.0 * n1z - 4.0 * n2z + n3z
                est = max(
                    max(abs(d4x), abs(d4y), abs(d4z)),
                    max(abs(dpx), abs(dpy), abs(dpz)),
                    max(abs(2.5 * d4x - 1.5 * dpx), abs(2.5 * d4y - 1.5 * dpy),
                        abs(2.5 * d4z - 1.5 * dpz)),
                )  # fmt: skip
                dpx = d4x
                dpy = d4y
                dpz = d4z
                if not est <= d4lim:
                    nfb += 1.0
                    for j in range(m):
                        ax = fbuf[j, 0]
                        ay = fbuf[j, 1]
                        az = fbuf[j, 2]
                        sx = vx + ax + dt * Gx
                        sy = vy + ay + dt * Gy
                        sz = vz + az + dt * Gz
                        ppx = px + c12 * (5.0 * sx + 8.0 * vx - vpx)
                        ppy = py + c12 * (5.0 * sy + 8.0 * vy - vpy)
                        ppz = pz + c12 * (5.0 * sz + 8.0 * vz - vpz)
                        Gnx, Gny, Gnz = earth.gravitation_at_nb(
                            r0x + ppx, r0y + ppy, r0z + ppz, zx, zy, zz
                        )
                        dvx = ax + c12 * (5.0 * Gnx + 8.0 * Gx - Gpx)
                        dvy = ay + c12 * (5.0 * Gny + 8.0 * Gy - Gpy)
                        dvz = az + c12 * (5.0 * Gnz + 8.0 * Gz - Gpz)
                        Gpx = Gx
                        Gpy = Gy
                        Gpz = Gz
                        Gx = Gnx
                        Gy = Gny
                        Gz = Gnz
                        ovx = vx
                        ovy = vy
                        ovz = vz
                        vx, vcx = _kahan(vx, vcx, dvx)
                        vy, vcy = _kahan(vy, vcy, dvy)
                        vz, vcz = _kahan(vz, vcz, dvz)
                        px, pcx = _kahan(px, pcx, c12 * _fma(5.0, vx, _fma(8.0, ovx, -vpx)))
                        py, pcy = _kahan(py, pcy, c12 * _fma(5.0, vy, _fma(8.0, ovy, -vpy)))
                        pz, pcz = _kahan(pz, pcz, c12 * _fma(5.0, vz, _fma(8.0, ovz, -vpz)))
                        vpx = ovx
                        vpy = ovy
                        vpz = ovz
                        kw += 1
                        if kw == every:
                            kw = 0
                            if j + 1 < m:
                                w0, w1 = qbuf[j + 1, 0], qbuf[j + 1, 1]
                                w2, w3 = qbuf[j + 1, 2], qbuf[j + 1, 3]
                            else:
                                w0, w1, w2, w3 = q0 - qc0, q1 - qc1, q2 - qc2, q3 - qc3
                            _write(out_p, out_v, out_q, s, (k + j + 1) // every - out_start, prm,
                                   k + j + 1, px - pcx, py - pcy, pz - pcz, vx - vcx, vy - vcy,
                                   vz - vcz, w0, w1, w2, w3, wq)  # fmt: skip
                    k += m
                    i += m
                    n3x, n3y, n3z = n2x, n2y, n2z
                    n2x, n2y, n2z = n1x, n1y, n1z
                    n1x, n1y, n1z = n0x, n0y, n0z
                    n0x, n0y, n0z = Gx, Gy, Gz
                    continue
                # cubic g(tau) = n0 + c1 tau + c2 tau^2 + c3 tau^3 through tau = -2, -1, 0, 1
                c2x = 0.5 * (gex + n1x) - n0x
                c2y = 0.5 * (gey + n1y) - n0y
                c2z = 0.5 * (gez + n1z) - n0z
                sx = 0.5 * (gex - n1x)
                sy = 0.5 * (gey - n1y)
                sz = 0.5 * (gez - n1z)
                c3x = (n0x - n2x + 4.0 * c2x - 2.0 * sx) / 6.0
                c3y = (n0y - n2y + 4.0 * c2y - 2.0 * sy) / 6.0
                c3z = (n0z - n2z + 4.0 * c2z - 2.0 * sz) / 6.0
                c1x = sx - c3x
                c1y = sy - c3y
                c1z = sz - c3z
                # samples inside the block that are stored
                jw = every - kw
                while jw < m:
                    tj = jw * dt
                    _write(out_p, out_v, out_q, s, (k + jw) // every - out_start, prm, k + jw,
                           (px - pcx) + (tj * vx + pbuf[jw, 0]
                                         + (QC[jw, 0] * n0x + QC[jw, 1] * c1x
                                            + QC[jw, 2] * c2x + QC[jw, 3] * c3x)),
                           (py - pcy) + (tj * vy + pbuf[jw, 1]
                                         + (QC[jw, 0] * n0y + QC[jw, 1] * c1y
                                            + QC[jw, 2] * c2y + QC[jw, 3] * c3y)),
                           (pz - pcz) + (tj * vz + pbuf[jw, 2]
                                         + (QC[jw, 0] * n0z + QC[jw, 1] * c1z
                                            + QC[jw, 2] * c2z + QC[jw, 3] * c3z)),
                           (vx - vcx) + (abuf[jw, 0] + (WC[jw, 0] * n0x + WC[jw, 1] * c1x
                                                        + WC[jw, 2] * c2x + WC[jw, 3] * c3x)),
                           (vy - vcy) + (abuf[jw, 1] + (WC[jw, 0] * n0y + WC[jw, 1] * c1y
                                                        + WC[jw, 2] * c2y + WC[jw, 3] * c3y)),
                           (vz - vcz) + (abuf[jw, 2] + (WC[jw, 0] * n0z + WC[jw, 1] * c1z
                                                        + WC[jw, 2] * c2z + WC[jw, 3] * c3z)),
                           qbuf[jw, 0], qbuf[jw, 1], qbuf[jw, 2], qbuf[jw, 3], wq)  # fmt: skip
                    jw += every
                kw += m
                while kw >= every:
                    kw -= every
                # end of the block: one compensated sum each for position and velocity
                j = m - 1
                vpx = vx + (
                    bx + (WC[j, 0] * n0x + WC[j, 1] * c1x + WC[j, 2] * c2x + WC[j, 3] * c3x)
                )
                vpy = vy + (
                    by + (WC[j, 0] * n0y + WC[j, 1] * c1y + WC[j, 2] * c2y + WC[j, 3] * c3y)
                )
                vpz = vz + (bz + (WC[j, 0] * n0z + WC[j, 1] * c1z + WC[j, 2] * c2z
                                          + WC[j, 3] * c3z))  # fmt: skip
                px, pcx = _kahan(
                    px,
                    pcx,
                    T * vx
                    + (Px + (QC[m, 0] * n0x + QC[m, 1] * c1x + QC[m, 2] * c2x + QC[m, 3] * c3x)),
                )
                py, pcy = _kahan(
                    py,
                    pcy,
                    T * vy
                    + (Py + (QC[m, 0] * n0y + QC[m, 1] * c1y + QC[m, 2] * c2y + QC[m, 3] * c3y)),
                )
                pz, pcz = _kahan(
                    pz,
                    pcz,
                    T * vz
                    + (Pz + (QC[m, 0] * n0z + QC[m, 1] * c1z + QC[m, 2] * c2z + QC[m, 3] * c3z)),
                )
                vx, vcx = _kahan(
                    vx,
                    vcx,
                    Ax + (WC[m, 0] * n0x + WC[m, 1] * c1x + WC[m, 2] * c2x + WC[m, 3] * c3x),
                )
                vy, vcy = _kahan(
                    vy,
                    vcy,
                    Ay + (WC[m, 0] * n0y + WC[m, 1] * c1y + WC[m, 2] * c2y + WC[m, 3] * c3y),
                )
                vz, vcz = _kahan(vz, vcz, Az + (WC[m, 0] * n0z + WC[m, 1] * c1z + WC[m, 2] * c2z
                                                + WC[m, 3] * c3z))  # fmt: skip
                k += m
                if kw == 0:
                    _write(out_p, out_v, out_q, s, k // every - out_start, prm, k,
                           px - pcx, py - pcy, pz - pcz, vx - vcx, vy - vcy, vz - vcz,
                           q0 - qc0, q1 - qc1, q2 - qc2, q3 - qc3, wq)  # fmt: skip
                # node at the actual end: point-mass gradient across the prediction error
                dx = (px - pcx) - ppx
                dy = (py - pcy) - ppy
                dz = (pz - pcz) - ppz
                # Gamma d ~ GM/R^3 (3 G (G.d) / |G|^2 - d): radial direction from G itself,
                # radius and |G| at their means (a few 1e-3 of a correction of ~1e-12 m/s^2)
                gd = IG2 * (gex * dx + gey * dy + gez * dz)
                gex += K3 * (3.0 * gd * gex - dx)
                gey += K3 * (3.0 * gd * gey - dy)
                gez += K3 * (3.0 * gd * gez - dz)
                # the per-step rule continues from the cubic's last two samples
                x = 1.0 - 1.0 / m
                Gpx = n0x + x * (c1x + x * (c2x + x * c3x))
                Gpy = n0y + x * (c1y + x * (c2y + x * c3y))
                Gpz = n0z + x * (c1z + x * (c2z + x * c3z))
                Gx = gex
                Gy = gey
                Gz = gez
                n3x, n3y, n3z = n2x, n2y, n2z
                n2x, n2y, n2z = n1x, n1y, n1z
                n1x, n1y, n1z = n0x, n0y, n0z
                n0x, n0y, n0z = gex, gey, gez
                i += m
                continue
            # ---- one step with the exact gravitation at the predicted end of the step
            if k == 1:
                v0x = vpx
                v0y = vpy
                v0z = vpz
                p1x = px - pcx
                p1y = py - pcy
                p1z = pz - pcz
            # specific-force increment resolved at t_k: a = C_k dv
            ax, ay, az = _qrot(q0, q1, q2, q3, dvb[s, i, 0], dvb[s, i, 1], dvb[s, i, 2])
            if rot:
                # predictor of v_{k+1}, r_{k+1}; gravitation there; 3-point rule for its integral
                sx = vx + ax + dt * Gx
                sy = vy + ay + dt * Gy
                sz = vz + az + dt * Gz
                if k == 0:
                    ppx = px + hdt * (sx + vx)
                    ppy = py + hdt * (sy + vy)
                    ppz = pz + hdt * (sz + vz)
                else:
                    ppx = px + c12 * (5.0 * sx + 8.0 * vx - vpx)
                    ppy = py + c12 * (5.0 * sy + 8.0 * vy - vpy)
                    ppz = pz + c12 * (5.0 * sz + 8.0 * vz - vpz)
                Gnx, Gny, Gnz = earth.gravitation_at_nb(r0x + ppx, r0y + ppy, r0z + ppz, zx, zy, zz)
                if k == 0:
                    dvx = ax + hdt * (Gnx + Gx)
                    dvy = ay + hdt * (Gny + Gy)
                    dvz = az + hdt * (Gnz + Gz)
                else:
                    dvx = ax + c12 * (5.0 * Gnx + 8.0 * Gx - Gpx)
                    dvy = ay + c12 * (5.0 * Gny + 8.0 * Gy - Gpy)
                    dvz = az + c12 * (5.0 * Gnz + 8.0 * Gz - Gpz)
                Gpx = Gx
                Gpy = Gy
                Gpz = Gz
                Gx = Gnx
                Gy = Gny
                Gz = Gnz
            else:
                dvx = ax
                dvy = ay
                dvz = az - g0dt
            ovx = vx
            ovy = vy
            ovz = vz
            vx, vcx = _kahan(vx, vcx, dvx)
            vy, vcy = _kahan(vy, vcy, dvy)
            vz, vcz = _kahan(vz, vcz, dvz)
            if k == 0:
                px, pcx = _kahan(px, pcx, hdt * (vx + ovx))
                py, pcy = _kahan(py, pcy, hdt * (vy + ovy))
                pz, pcz = _kahan(pz, pcz, hdt * (vz + ovz))
            else:
                px, pcx = _kahan(px, pcx, c12 * _fma(5.0, vx, _fma(8.0, ovx, -vpx)))
                py, pcy = _kahan(py, pcy, c12 * _fma(5.0, vy, _fma(8.0, ovy, -vpy)))
                pz, pcz = _kahan(pz, pcz, c12 * _fma(5.0, vz, _fma(8.0, ovz, -vpz)))
            q0, q1, q2, q3, qc0, qc1, qc2, qc3 = _att_step(
                q0, q1, q2, q3, qc0, qc1, qc2, qc3, dth[s, i, 0], dth[s, i, 1], dth[s, i, 2]
            )
            vpx = ovx
            vpy = ovy
            vpz = ovz
            if k == 1:
                # first interval: dt/12 (5 v0 + 8 v1 - v2) instead of the trapezoid
                dx = c12 * (-v0x + 2.0 * vpx - vx)
                dy = c12 * (-v0y + 2.0 * vpy - vy)
                dz = c12 * (-v0z + 2.0 * vpz - vz)
                px += dx
                py += dy
                pz += dz
                if every == 1:
                    _write(out_p, out_v, out_q, s, 1 - out_start, prm, 1,
                           p1x + dx, p1y + dy, p1z + dz, vpx, vpy, vpz,
                           0.0, 0.0, 0.0, 0.0, False)  # fmt: skip
            k += 1
            i += 1
            km += 1
            if km == m:
                km = 0
            kw += 1
            if kw == every:
                kw = 0
            if rot and km == 0:
                if k >= 4 * m:  # five real nodes: k, k - m, .., k - 4m
                    dpx = Gx - 4.0 * n0x + 6.0 * n1x - 4.0 * n2x + n3x
                    dpy = Gy - 4.0 * n0y + 6.0 * n1y - 4.0 * n2y + n3y
                    dpz = Gz - 4.0 * n0z + 6.0 * n1z - 4.0 * n2z + n3z
                n3x, n3y, n3z = n2x, n2y, n2z
                n2x, n2y, n2z = n1x, n1y, n1z
                n1x, n1y, n1z = n0x, n0y, n0z
                n0x, n0y, n0z = Gx, Gy, Gz
            if kw == 0:
                _write(out_p, out_v, out_q, s, k // every - out_start, prm, k,
                       px - pcx, py - pcy, pz - pcz, vx - vcx, vy - vcy, vz - vcz,
                       q0 - qc0, q1 - qc1, q2 - qc2, q3 - qc3, wq)  # fmt: skip
        # fmt: off
        st[s, :25] = (px, py, pz, pcx, pcy, pcz, vx, vy, vz, vcx, vcy, vcz,
                      q0, q1, q2, q3, vpx, vpy, vpz, Gx, Gy, Gz, Gpx, Gpy, Gpz)
        st[s, S_N:S_N + 12] = (n0x, n0y, n0z, n1x, n1y, n1z, n2x, n2y, n2z,
                               n3x, n3y, n3z)
        # fmt: on
        st[s, S_FB] = nfb
        st[s, S_D4], st[s, S_D4 + 1], st[s, S_D4 + 2] = dpx, dpy, dpz
        st[s, S_QC], st[s, S_QC + 1], st[s, S_QC + 2], st[s, S_QC + 3] = qc0, qc1, qc2, qc3
        st[s, S_K] = k
        st[s, S_B] = bz_
        st[s, S_KL] = kl
        st[s, S_NL] = nl
        st[s, S_DH] = dhl


@njit(cache=True, inline="always")
def _kahan(s, c, d):
    """Compensated s + d; returns the new sum and compensation (true sum = s - c)."""
    y = d - c
    t = s + y
    return t, (t - s) - y


@njit(cache=True, inline="always")
def _att_step(q0, q1, q2, q3, qc0, qc1, qc2, qc3, x, y, z):
    """q <- q (x) Exp(dtheta), as q + dq with dq computed from small quantities, renormalized
    to first order and added with a compensated sum (no systematic rounding drift)."""
    em0, e1, e2, e3 = _qexpm1(x, y, z)
    d0, d1, d2, d3 = _qmul_f(q0, q1, q2, q3, em0, e1, e2, e3)
    # first-order renormalization: scale by 1 - eps/2, eps = |q + dq|^2 - 1
    # = (|q|^2 - 1) + |q|^2 (|1 + e|^2 - 1) (|q (x) x| = |q| |x|): off the q -> dq chain
    ne = _fma(em0, 2.0 + em0, _fma(e1, e1, _fma(e2, e2, e3 * e3)))
    nq = _fma(q0, q0, q1 * q1) + _fma(q2, q2, q3 * q3)
    h = -0.5 * _fma(nq, ne, nq - 1.0)
    d0 = _fma(h, q0 + d0, d0)
    d1 = _fma(h, q1 + d1, d1)
    d2 = _fma(h, q2 + d2, d2)
    d3 = _fma(h, q3 + d3, d3)
    q0, qc0 = _kahan(q0, qc0, d0)
    q1, qc1 = _kahan(q1, qc1, d1)
    q2, qc2 = _kahan(q2, qc2, d2)
    q3, qc3 = _kahan(q3, qc3, d3)
    return q0, q1, q2, q3, qc0, qc1, qc2, qc3


@njit(cache=True)
def compensate(dth, dv):
    S, K = dth.shape[0], dth.shape[1]
    for s in range(S):
        pa0 = pa1 = pa2 = 0.0  # raw dtheta of the previous interval (zero before the first)
        pv0 = pv1 = pv2 = 0.0  # raw dv of the previous interval
        for k in range(K):
            a0, a1, a2 = dth[s, k, 0], dth[s, k, 1], dth[s, k, 2]
            v0, v1, v2 = dv[s, k, 0], dv[s, k, 1], dv[s, k, 2]
            # coning: (a_prev x a) / 12
            c0 = (pa1 * a2 - pa2 * a1) / 12.0
            c1 = (pa2 * a0 - pa0 * a2) / 12.0
            c2 = (pa0 * a1 - pa1 * a0) / 12.0
            # rotation a x v / 2 + a x (a x v) / 6 and sculling (a_prev x v + v_prev x a) / 12
            x0 = a1 * v2 - a2 * v1
            x1 = a2 * v0 - a0 * v2
            x2 = a0 * v1 - a1 * v0
            r0 = 0.5 * x0 + (a1 * x2 - a2 * x1) / 6.0
            r1 = 0.5 * x1 + (a2 * x0 - a0 * x2) / 6.0
            r2 = 0.5 * x2 + (a0 * x1 - a1 * x0) / 6.0
            s0 = (pa1 * v2 - pa2 * v1 + pv1 * a2 - pv2 * a1) / 12.0
            s1 = (pa2 * v0 - pa0 * v2 + pv2 * a0 - pv0 * a2) / 12.0
            s2 = (pa0 * v1 - pa1 * v0 + pv0 * a1 - pv1 * a0) / 12.0
            dth[s, k, 0] = a0 + c0
            dth[s, k, 1] = a1 + c1
            dth[s, k, 2] = a2 + c2
            dv[s, k, 0] = v0 + r0 + s0
            dv[s, k, 1] = v1 + r1 + s1
            dv[s, k, 2] = v2 + r2 + s2
            pa0, pa1, pa2 = a0, a1, a2
            pv0, pv1, pv2 = v0, v1, v2
