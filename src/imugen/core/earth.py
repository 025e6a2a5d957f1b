"""Earth models: WGS-84 constants, the exact normal gravity field, navigation frames, Earth rate.

Three fidelities. In ``flat`` and ``wgs84`` the navigation frame ``n`` is Earth-fixed with the
East-North-Up axes of the route origin ``(lat0, lon0, h0)``; a position ``p_n`` is the ENU
coordinate (metres) of a point relative to the origin. In ``geodetic`` the navigation
coordinates are ECEF (``C_en = I``, origin at the Earth's centre): valid at any distance,
across the antimeridian and over the poles; :func:`local_level` reports position, velocity and
attitude in the East-North-Up frame at the vehicle.

``flat``
    ``n`` is taken as inertial; gravity is the constant ``g_n = (0, 0, -g0)`` with ``g0`` the
    WGS-84 normal gravity at the origin; Earth rate 0.
``wgs84``, ``geodetic``
    ``n`` rotates with the Earth at ``omega_ie_n = Omega C_en e_z``. Gravity is the exact
    normal field of the WGS-84 level ellipsoid (gradient of the closed-form normal potential
    in ellipsoidal harmonic coordinates, NIMA TR8350.2 ch. 4; no series in height, north
    component of the curved plumb line included; no deflection of the vertical of the real
    Earth). The gravitation (mass attraction only) is ``G_n = g_n + Omega x (Omega x r_n)``
    with ``r_n = r0_n + p_n``; it is symmetric about the Earth's axis, so it is the same
    function of position in any frame sharing that axis (the inertial frame of the
    mechanization included).

The scalar numba field (``gravitation_at_nb``, used inside kernels) is also what the array
functions (``gravity_n``, ``gravitation_n``, ``gravity_e``) evaluate, so truth generation and
mechanization see the same field bit for bit.

``choose_earth_model`` implements ``--earth auto``: it estimates the position effect of every
term ``flat`` drops and of the chosen sensor grade over the scene, picks ``flat`` when all
dropped terms stay below a fraction (default 10 %) of the grade effect, else ``wgs84``, and
``geodetic`` whenever the scene reaches so far from its origin that the origin's ENU axes
no longer describe East, North and Up at the vehicle (:data:`GEODETIC_TILT_RAD`); it returns
the budget as printable lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imugen.core.jit import njit

# --- WGS-84 defining and derived constants (NIMA TR8350.2, 3rd ed., tables 3.1-3.4) ---------
A_WGS84 = 6378137.0
"""Semi-major axis a [m]."""
F_WGS84 = 1.0 / 298.257223563
"""Flattening f."""
B_WGS84 = A_WGS84 * (1.0 - F_WGS84)
"""Semi-minor axis b [m]."""
E2_WGS84 = F_WGS84 * (2.0 - F_WGS84)
"""First eccentricity squared e^2."""
EP2_WGS84 = E2_WGS84 / (1.0 - E2_WGS84)
"""Second eccentricity squared e'^2."""
GM_WGS84 = 3.986004418e14
"""Earth's gravitational constant GM [m^3/s^2]."""
OMEGA_IE = 7.292115e-5
"""Earth rotation rate Omega [rad/s]."""
GAMMA_E = 9.7803253359
"""Normal gravity at the equator [m/s^2]."""
GAMMA_P = 9.8321849378
"""Normal gravity at the poles [m/s^2]."""
K_SOMIGLIANA = (B_WGS84 * GAMMA_P) / (A_WGS84 * GAMMA_E) - 1.0
"""Somigliana constant k = b*gamma_p / (a*gamma_e) - 1."""
M_WGS84 = OMEGA_IE**2 * A_WGS84**2 * B_WGS84 / GM_WGS84
"""m = Omega^2 a^2 b / GM."""
R_MEAN = math.sqrt(A_WGS84 * B_WGS84)
"""A mean Earth radius for budgets [m] (not used by the physics)."""

MODELS = ("flat", "wgs84", "geodetic")

# Layout of the parameter vector handed to numba kernels (``OriginFrame.params``).
P_MODEL = 0  # 0.0 flat, 1.0 wgs84, 2.0 geodetic
P_G0 = 1  # normal gravity at the origin [m/s^2]
P_OMEGA = 2  # omega_ie_n, 3 values (zeros in flat)
P_CEN = 5  # C_en (ECEF -> n), 9 values row-major
P_R0E = 14  # r0_e, origin in ECEF [m], 3 values
P_R0N = 17  # r0_n = C_en r0_e [m], 3 values
N_PARAMS = 20


# --- normal gravity: the exact field of the level ellipsoid ---------------------------------
E_LIN = math.sqrt(A_WGS84**2 - B_WGS84**2)
"""Linear eccentricity E = sqrt(a^2 - b^2) [m] (focal distance of the ellipsoidal coordinates)."""

# Series in eps^2 = (E/u)^2 of the Legendre functions of the second kind used by the normal
# potential (Heiskanen & Moritz 1967, ch. 2; NIMA TR8350.2, 3rd ed., ch. 4):
#   q(u)  = 1/2 [(1 + 3 u^2/E^2) atan(E/u) - 3 u/E] = eps^3 sum_m c_m eps^(2m-2),
#   q'(u) = 3 (1 + u^2/E^2) (1 - u/E atan(E/u)) - 1  = eps^2 sum_m d_m eps^(2m-2),
# c_m = (-1)^(m+1) 2m / ((2m+1)(2m+3)), d_m = (-1)^(m+1) 6 / ((2m+1)(2m+3)). The closed forms
# cancel catastrophically (q ~ 7e-5 from terms ~ 36); 9 terms reach float64 precision for
# eps^2 <= 0.012, i.e. u >= 4,700 km: every point within 1,500 km of the surface.
_NSER = 9
_C_Q = tuple((-1.0) ** (m + 1) * 2.0 * m / ((2 * m + 1) * (2 * m + 3)) for m in range(1, _NSER + 1))
_D_Q = tuple((-1.0) ** (m + 1) * 6.0 / ((2 * m + 1) * (2 * m + 3)) for m in range(1, _NSER + 1))


def _q_series(eps2):
    """(q / eps^3, q' / eps^2) of the series above (Python floats; for the constants)."""
    a = 0.0
    b = 0.0
    for c, d in zip(reversed(_C_Q), reversed(_D_Q), strict=True):
        a = a * eps2 + c
        b = b * eps2 + d
    return a, b


_EP = E_LIN / B_WGS84  # second eccentricity e' = E / b
Q0_WGS84 = _EP**3 * _q_series(_EP**2)[0]
"""q0 = q(u = b), the normal potential's constant (TR8350.2: 7.334625e-5)."""
_OMA2_Q0 = OMEGA_IE**2 * A_WGS84**2 / Q0_WGS84  # Omega^2 a^2 / q0
_C0, _C1, _C2, _C3, _C4, _C5, _C6, _C7, _C8 = _C_Q
_D0, _D1, _D2, _D3, _D4, _D5, _D6, _D7, _D8 = _D_Q
_E2L = E_LIN * E_LIN


@njit(cache=True, inline="always")
def gravitation_at_nb(rx, ry, rz, zx, zy, zz):
    """Gravitation (mass attraction only) of the WGS-84 level ellipsoid, exact.

    The gradient of the normal gravitational potential in ellipsoidal harmonic coordinates
    ``(u, beta)``, ``V = GM/E atan(E/u) + 1/2 Omega^2 a^2 q/q0 (sin^2 beta - 1/3)``, written
    in Cartesian form. The field is symmetric about the Earth's axis, so it needs only the
    geocentric position ``r`` and the axis' unit vector ``zax`` in any common frame (ECEF,
    the route-origin ENU frame, or an inertial frame whose z is the Earth's axis): with
    ``z = zax . r``, ``p^2 = |r|^2 - z^2`` the result is ``a r + (c - a) z zax``.

    Returns ``(Gx, Gy, Gz)`` [m/s^2] in the frame of ``r``.
    """
    r2 = rx * rx + ry * ry + rz * rz
    z = zx * rx + zy * ry + zz * rz
    z2 = z * z
    p2 = r2 - z2
    s = r2 - _E2L
    u2 = 0.5 * (s + math.sqrt(s * s + 4.0 * _E2L * z2))  # u^2 of the point
    iu = 1.0 / math.sqrt(u2)
    iu2 = iu * iu
    u = u2 * iu
    e2 = _E2L * iu2  # eps^2
    # 9 terms, Estrin's scheme (short dependency chain)
    e4 = e2 * e2
    e8 = e4 * e4
    qs = (
        (_C0 + _C1 * e2)
        + e4 * (_C2 + _C3 * e2)
        + e8 * ((_C4 + _C5 * e2) + e4 * (_C6 + _C7 * e2) + e8 * _C8)
    )
    ds = (
        (_D0 + _D1 * e2)
        + e4 * (_D2 + _D3 * e2)
        + e8 * ((_D4 + _D5 * e2) + e4 * (_D6 + _D7 * e2) + e8 * _D8)
    )
    sb2 = z2 * iu2  # sin^2 beta
    w2 = u2 + _E2L
    dd = u2 + _E2L * sb2  # u^2 + E^2 sin^2 beta
    iwd = 1.0 / (w2 * dd)
    iw2 = dd * iwd
    idd = w2 * iwd
    # dV/du = -(GM + 1/2 Omega^2 a^2 E q'/q0 (sin^2 beta - 1/3)) / (u^2 + E^2),
    # q' = eps^2 ds, E eps^2 = E^3/u^2
    vu = -(GM_WGS84 + 0.5 * _OMA2_Q0 * _E2L * E_LIN * iu2 * ds * (sb2 - 1.0 / 3.0)) * iw2
    # dV/dbeta = sin(beta) cos(beta) bt, bt = Omega^2 a^2 q/q0, q = eps^3 qs
    bt = _OMA2_Q0 * _E2L * E_LIN * iu2 * iu * qs
    ca = (vu * u - z2 * bt * iu2) * idd  # along r - z zax (equatorial part)
    cz = (vu * w2 * iu + p2 * bt * iw2) * idd  # along z zax
    cd = (cz - ca) * z
    return ca * rx + cd * zx, ca * ry + cd * zy, ca * rz + cd * zz


@njit(cache=True)
def _gravity_e_batch_nb(r_e, out, centrifugal):
    w2 = OMEGA_IE * OMEGA_IE if centrifugal else 0.0
    for i in range(r_e.shape[0]):
        x = r_e[i, 0]
        y = r_e[i, 1]
        gx, gy, gz = gravitation_at_nb(x, y, r_e[i, 2], 0.0, 0.0, 1.0)
        out[i, 0] = gx + w2 * x
        out[i, 1] = gy + w2 * y
        out[i, 2] = gz


def gravitation_e(r_e) -> np.ndarray:
    """Exact gravitation (mass attraction) of the WGS-84 level ellipsoid in ECEF.

    Parameters
    ----------
    r_e : ndarray, shape (..., 3)
        ECEF position [m], valid for points within 1,500 km of the surface.

    Returns
    -------
    ndarray, shape (..., 3)
        ``G_e`` [m/s^2].
    """
    return _batch_e(r_e, False)


def gravity_e(r_e) -> np.ndarray:
    """Exact normal gravity (gravitation + centrifugal ``Omega^2 (x, y, 0)``) in ECEF, (..., 3)."""
    return _batch_e(r_e, True)


def _batch_e(r_e, centrifugal):
    r = np.asarray(r_e, dtype=float)
    flat = np.ascontiguousarray(r.reshape(-1, 3))
    out = np.empty_like(flat)
    _gravity_e_batch_nb(flat, out, centrifugal)
    return out.reshape(r.shape)


def normal_gravity(lat_rad, h_m):
    """Magnitude of WGS-84 normal gravity at geodetic latitude and height, exact.

    On the ellipsoid it equals Somigliana's ``gamma_e (1 + k sin^2 lat) / sqrt(1 - e^2 sin^2
    lat)``; off it, the norm of :func:`gravity_e` (no series in the height).

    Parameters
    ----------
    lat_rad : float or ndarray
        Geodetic latitude [rad].
    h_m : float or ndarray
        Height above the ellipsoid [m] (broadcast against ``lat_rad``).

    Returns
    -------
    float or ndarray
        Normal gravity [m/s^2].
    """
    lat, h = np.broadcast_arrays(np.asarray(lat_rad, dtype=float), np.asarray(h_m, dtype=float))
    g = np.linalg.norm(gravity_e(ecef_from_geodetic(lat, np.zeros_like(lat), h)), axis=-1)
    return g if g.ndim else float(g)


# --- geodetic <-> ECEF --------------------------------------------------------------------------
def ecef_from_geodetic(lat_rad, lon_rad, h_m):
    """Geodetic (WGS-84) -> ECEF.

    Parameters
    ----------
    lat_rad, lon_rad : float or ndarray, shape (N,)
        Geodetic latitude and longitude [rad].
    h_m : float or ndarray, shape (N,)
        Ellipsoidal height [m].

    Returns
    -------
    ndarray, shape (..., 3)
        ECEF position [m].
    """
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_rad, dtype=float)
    h = np.asarray(h_m, dtype=float)
    sl = np.sin(lat)
    n_rad = A_WGS84 / np.sqrt(1.0 - E2_WGS84 * sl * sl)
    cl = np.cos(lat)
    x = (n_rad + h) * cl * np.cos(lon)
    y = (n_rad + h) * cl * np.sin(lon)
    z = (n_rad * (1.0 - E2_WGS84) + h) * sl
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1)


def geodetic_parts(x, y, z):
    """ECEF -> (sin lat, cos lat, cos lon, sin lon, h), Bowring's method (one iteration).

    Latitude within 3e-5 m and height within 1e-8 m for -1 km < h < 50 km (tested against
    pyproj); a fixed formula (no data-dependent iteration count), so it is smooth in the
    position. The numba twin performs the same operations in the same order.
    """
    p = np.sqrt(x * x + y * y)
    # Bowring (1976): parametric latitude from tan u = a z / (b p), then one update
    su = z * A_WGS84
    cu = p * B_WGS84
    ir = 1.0 / np.sqrt(su * su + cu * cu)
    su = su * ir
    cu = cu * ir
    num = z + EP2_WGS84 * B_WGS84 * su * su * su
    den = p - E2_WGS84 * A_WGS84 * cu * cu * cu
    ir = 1.0 / np.sqrt(num * num + den * den)
    sl = num * ir
    cl = den * ir
    h = p * cl + z * sl - A_WGS84 * np.sqrt(1.0 - E2_WGS84 * sl * sl)
    with np.errstate(invalid="ignore", divide="ignore"):
        ip = 1.0 / p
        clon = np.where(p > 0.0, x * ip, 1.0)
        slon = np.where(p > 0.0, y * ip, 0.0)
    return sl, cl, clon, slon, h


def geodetic_from_ecef(r_e):
    """ECEF -> geodetic (WGS-84), Bowring's method.

    Parameters
    ----------
    r_e : ndarray, shape (..., 3)
        ECEF position [m].

    Returns
    -------
    lat_rad, lon_rad, h_m : ndarray, shape (...)
    """
    r_e = np.asarray(r_e, dtype=float)
    sl, cl, _, _, h = geodetic_parts(r_e[..., 0], r_e[..., 1], r_e[..., 2])
    return np.arctan2(sl, cl), np.arctan2(r_e[..., 1], r_e[..., 0]), h


def C_en_from_geodetic(lat_rad, lon_rad):
    """Rotation ECEF -> local ENU at (lat, lon): rows are the East, North, Up unit vectors.

    Parameters
    ----------
    lat_rad, lon_rad : float or ndarray, shape (N,)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_rad, dtype=float)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    zero = np.zeros_like(sl * so)
    rows = [
        [-so + zero, co + zero, zero],
        [-sl * co, -sl * so, cl + zero],
        [cl * co, cl * so, sl + zero],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


# --- the local level at the vehicle ----------------------------------------------------------
def local_level(r_e, v_e=None, q_eb=None):
    """ECEF state -> geodetic position, East-North-Up velocity and attitude at the vehicle.

    Parameters
    ----------
    r_e : ndarray, shape (..., 3)
        ECEF position [m].
    v_e : ndarray, shape (..., 3), optional
        Earth-relative velocity resolved in ECEF [m/s].
    q_eb : ndarray, shape (..., 4), optional
        Attitude body -> ECEF (scalar first).

    Returns
    -------
    lat_rad, lon_rad, h_m : ndarray, shape (...)
    v_l : ndarray, shape (..., 3) or None
        Velocity in the local ENU frame at the vehicle [m/s].
    q_lb : ndarray, shape (..., 4) or None
        Attitude body -> local ENU at the vehicle (``C_lb = C_le C_eb``; roll, pitch and
        yaw relative to the local level, as in the truth's Euler angles).
    """
    from imugen.core.rotations import dcm_to_quat, quat_mul

    lat, lon, h = geodetic_from_ecef(r_e)
    C_le = C_en_from_geodetic(lat, lon)
    v_l = None if v_e is None else np.einsum("...ij,...j->...i", C_le, v_e)
    q_lb = None
    if q_eb is not None:
        q_le = dcm_to_quat(C_le.reshape(-1, 3, 3)).reshape((*C_le.shape[:-2], 4))
        q_lb = quat_mul(q_le, np.asarray(q_eb, dtype=float))
    return lat, lon, h, v_l, q_lb


def errors_local_level(p_true_e, p_nav_e, v_true_e, min_speed_mps=0.1) -> np.ndarray:
    """Position errors in the local level at the true position, plus along/cross track.

    Parameters
    ----------
    p_true_e, p_nav_e : ndarray, shape (..., 3)
        True and navigated ECEF positions [m] (for an origin frame, convert with
        ``OriginFrame.ecef_from_n`` first).
    v_true_e : ndarray, shape (..., 3)
        True Earth-relative velocity in ECEF [m/s] (defines the track direction).
    min_speed_mps : float
        Below this true horizontal speed the track direction is undefined: along and cross
        are NaN there.

    Returns
    -------
    ndarray, shape (..., 5)
        ``east, north, up, along, cross`` [m] of ``p_nav - p_true``: ENU at the true position;
        along the true horizontal velocity, and across it positive to the left.
    """
    p_true = np.asarray(p_true_e, dtype=float)
    lat, lon, _ = geodetic_from_ecef(p_true)
    C = C_en_from_geodetic(lat, lon)
    d = np.einsum("...ij,...j->...i", C, np.asarray(p_nav_e, dtype=float) - p_true)
    v = np.einsum("...ij,...j->...i", C, np.asarray(v_true_e, dtype=float))
    sp = np.hypot(v[..., 0], v[..., 1])
    ok = sp >= min_speed_mps
    with np.errstate(invalid="ignore", divide="ignore"):
        te = np.where(ok, v[..., 0] / sp, np.nan)
        tn = np.where(ok, v[..., 1] / sp, np.nan)
    out = np.empty((*d.shape[:-1], 5))
    out[..., :3] = d
    out[..., 3] = d[..., 0] * te + d[..., 1] * tn
    out[..., 4] = te * d[..., 1] - tn * d[..., 0]
    return out


# --- origin frame --------------------------------------------------------------------------------
@dataclass(frozen=True)
class OriginFrame:
    """The navigation frame ``n`` and the Earth model.

    ENU axes at the route origin (``flat``, ``wgs84``), or ECEF (``geodetic``: ``C_en = I``,
    ``r0_e = 0``; the origin then only names the scene's reference point).

    Attributes
    ----------
    lat0_rad, lon0_rad, h0_m : float
        Geodetic origin (WGS-84).
    model : str
        ``"flat"``, ``"wgs84"`` or ``"geodetic"``.
    """

    lat0_rad: float
    lon0_rad: float
    h0_m: float = 0.0
    model: str = "wgs84"

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"earth model must be one of {MODELS}, got {self.model!r}")

    @classmethod
    def from_deg(cls, lat_deg: float, lon_deg: float, alt_m: float = 0.0, model: str = "wgs84"):
        """Build from degrees (the edge units of route files)."""
        return cls(math.radians(lat_deg), math.radians(lon_deg), float(alt_m), model)

    def with_model(self, model: str) -> OriginFrame:
        """The same origin with another Earth model."""
        return OriginFrame(self.lat0_rad, self.lon0_rad, self.h0_m, model)

    @property
    def C_en(self) -> np.ndarray:
        """Rotation ECEF -> n, shape (3, 3) (the identity in ``geodetic``)."""
        if self.model == "geodetic":
            return np.eye(3)
        return C_en_from_geodetic(self.lat0_rad, self.lon0_rad)

    @property
    def r0_e(self) -> np.ndarray:
        """Origin of the navigation coordinates in ECEF [m], shape (3,) (zero in ``geodetic``)."""
        if self.model == "geodetic":
            return np.zeros(3)
        return ecef_from_geodetic(self.lat0_rad, self.lon0_rad, self.h0_m)

    @property
    def r0_n(self) -> np.ndarray:
        """Origin's geocentric position resolved in n [m], shape (3,)."""
        return self.C_en @ self.r0_e

    @property
    def g0(self) -> float:
        """Normal gravity at the origin [m/s^2] (the constant of the flat model)."""
        return float(normal_gravity(self.lat0_rad, self.h0_m))

    def params(self) -> np.ndarray:
        """Flat float64 parameter vector for numba kernels (layout ``P_*`` in this module)."""
        out = np.zeros(N_PARAMS)
        out[P_MODEL] = float(MODELS.index(self.model))
        out[P_G0] = self.g0
        out[P_OMEGA : P_OMEGA + 3] = earth_rate_n(self)
        out[P_CEN : P_CEN + 9] = self.C_en.ravel()
        out[P_R0E : P_R0E + 3] = self.r0_e
        out[P_R0N : P_R0N + 3] = self.r0_n
        return out

    def ecef_from_n(self, p_n) -> np.ndarray:
        """ENU positions relative to the origin -> ECEF, shape (..., 3) (a copy in ``geodetic``)."""
        if self.model == "geodetic":
            return np.array(p_n, dtype=float)
        return self.r0_e + np.asarray(p_n, dtype=float) @ self.C_en

    def n_from_ecef(self, r_e) -> np.ndarray:
        """ECEF -> ENU positions relative to the origin, shape (..., 3) (a copy in ``geodetic``)."""
        if self.model == "geodetic":
            return np.array(r_e, dtype=float)
        return (np.asarray(r_e, dtype=float) - self.r0_e) @ self.C_en.T

    def geodetic_from_n(self, p_n):
        """ENU positions -> (lat_rad, lon_rad, h_m) arrays."""
        return geodetic_from_ecef(self.ecef_from_n(p_n))

    def n_from_geodetic(self, lat_rad, lon_rad, h_m) -> np.ndarray:
        """Geodetic -> ENU positions relative to the origin, shape (..., 3)."""
        return self.n_from_ecef(ecef_from_geodetic(lat_rad, lon_rad, h_m))

    def C_ln(self, p_n) -> np.ndarray:
        """Rotation n -> local level (ENU at the point itself), shape (..., 3, 3).

        Identity in ``flat`` (local level is n). Attitude relative to the local level at the
        vehicle is ``C_lb = C_ln @ C_nb``.
        """
        p_n = np.asarray(p_n, dtype=float)
        if self.model == "flat":
            return np.broadcast_to(np.eye(3), (*p_n.shape[:-1], 3, 3)).copy()
        lat, lon, _ = self.geodetic_from_n(p_n)
        return C_en_from_geodetic(lat, lon) @ self.C_en.T


def earth_rate_n(frame: OriginFrame) -> np.ndarray:
    """Earth rotation rate resolved in n, shape (3,) [rad/s]; zeros in ``flat``."""
    if frame.model == "flat":
        return np.zeros(3)
    return OMEGA_IE * frame.C_en[:, 2].copy()


def gravity_n(p_n, frame: OriginFrame) -> np.ndarray:
    """Normal gravity (gravitation + centrifugal) at navigation-frame positions, resolved in n.

    Parameters
    ----------
    p_n : ndarray, shape (..., 3)
        Position in the frame's navigation coordinates [m] (ENU relative to the origin, or
        ECEF in ``geodetic``).
    frame : OriginFrame

    Returns
    -------
    ndarray, same shape as ``p_n``
        ``g_n`` [m/s^2], the exact field of the level ellipsoid; ``(0, 0, -g0)`` in ``flat``.
    """
    return _batch_n(p_n, frame, False)


def gravitation_n(p_n, frame: OriginFrame) -> np.ndarray:
    """Gravitation (mass attraction) ``G_n = g_n + Omega x (Omega x r_n)``, shape like ``p_n``.

    Equal to ``gravity_n`` in ``flat`` (no Earth rate).
    """
    return _batch_n(p_n, frame, True)


def _batch_n(p_n, frame, gravitation):
    p = np.asarray(p_n, dtype=float)
    flat = np.ascontiguousarray(p.reshape(-1, 3))
    out = np.empty_like(flat)
    _gravity_batch_nb(frame.params(), flat, out, gravitation)
    return out.reshape(p.shape)


@njit(cache=True, inline="always")
def geodetic_parts_nb(x, y, z):
    """ECEF -> ``(sin lat, cos lat, cos lon, sin lon, h)``: the scalar numba twin of
    :func:`geodetic_parts` (same operations, same order; the aided filter's local level and the
    damped vertical channel's height)."""
    p = math.sqrt(x * x + y * y)
    su = z * A_WGS84
    cu = p * B_WGS84
    ir = 1.0 / math.sqrt(su * su + cu * cu)
    su = su * ir
    cu = cu * ir
    num = z + EP2_WGS84 * B_WGS84 * su * su * su
    den = p - E2_WGS84 * A_WGS84 * cu * cu * cu
    ir = 1.0 / math.sqrt(num * num + den * den)
    sl = num * ir
    cl = den * ir
    h = p * cl + z * sl - A_WGS84 * math.sqrt(1.0 - E2_WGS84 * sl * sl)
    if p > 0.0:
        return sl, cl, x / p, y / p, h
    return sl, cl, 1.0, 0.0, h


@njit(cache=True, inline="always")
def gravitation_nb(prm, px, py, pz):
    """Numba scalar gravitation at navigation position ``p``; ``prm`` from ``OriginFrame.params()``.

    Returns the tuple ``(Gx, Gy, Gz)`` [m/s^2] resolved in n; ``(0, 0, -g0)`` in ``flat``.
    """
    if prm[P_MODEL] == 0.0:
        return 0.0, 0.0, -prm[P_G0]
    iw = 1.0 / OMEGA_IE
    return gravitation_at_nb(
        prm[P_R0N] + px,
        prm[P_R0N + 1] + py,
        prm[P_R0N + 2] + pz,
        prm[P_OMEGA] * iw,
        prm[P_OMEGA + 1] * iw,
        prm[P_OMEGA + 2] * iw,
    )


@njit(cache=True, inline="always")
def gravity_nb(prm, px, py, pz):
    """Numba scalar twin of :func:`gravity_n`; returns ``(gx, gy, gz)`` [m/s^2]."""
    gx, gy, gz = gravitation_nb(prm, px, py, pz)
    if prm[P_MODEL] == 0.0:
        return gx, gy, gz
    # + centrifugal -Omega x (Omega x r) = Omega^2 r - (Omega . r) Omega
    w0 = prm[P_OMEGA]
    w1 = prm[P_OMEGA + 1]
    w2 = prm[P_OMEGA + 2]
    rx = prm[P_R0N] + px
    ry = prm[P_R0N + 1] + py
    rz = prm[P_R0N + 2] + pz
    wr = w0 * rx + w1 * ry + w2 * rz
    ww = OMEGA_IE * OMEGA_IE
    return gx + (ww * rx - wr * w0), gy + (ww * ry - wr * w1), gz + (ww * rz - wr * w2)


@njit(cache=True)
def _gravity_batch_nb(prm, p_n, out, gravitation):
    for i in range(p_n.shape[0]):
        if gravitation:
            a, b, c = gravitation_nb(prm, p_n[i, 0], p_n[i, 1], p_n[i, 2])
        else:
            a, b, c = gravity_nb(prm, p_n[i, 0], p_n[i, 1], p_n[i, 2])
        out[i, 0] = a
        out[i, 1] = b
        out[i, 2] = c


# --- earth model budget (--earth auto) ---------------------------------------------------------
DEG_PER_H = math.pi / 180.0 / 3600.0
MICRO_G = 9.80665e-6
GEODETIC_TILT_RAD = 0.01
"""``auto`` picks ``geodetic`` when the local vertical at the scene's farthest point tilts by
more than this from the origin's (``D / R``: 64 km). Beyond it errors and attitudes resolved
in the origin's ENU mix the vertical into the horizontal by more than 1 %, and the road grade
and distance travelled measured in its East-North plane depart from the local ones."""


@dataclass(frozen=True)
class GradeFigures:
    """Nominal error figures of a grade for the ``auto`` budget (SI; zeros where absent).

    Built from a grade preset by :func:`imugen.sensors.grades.budget_figures`.
    """

    name: str
    gyro_bias_radps: float = 0.0
    accel_bias_mps2: float = 0.0
    gyro_scale_factor: float = 0.0
    arw_rad_per_sqrt_s: float = 0.0
    vrw_mps_per_sqrt_s: float = 0.0


@dataclass(frozen=True)
class EarthBudget:
    """Outcome of :func:`choose_earth_model`.

    Attributes
    ----------
    model : str
        ``"flat"``, ``"wgs84"`` or ``"geodetic"``.
    grade_effect_m : float
        Position effect of the grade's gyro and accelerometer biases over the scene [m].
    terms_m : dict
        Position effect of each term ``flat`` drops [m].
    fraction : float
        Threshold (dropped term / grade effect).
    lines : list of str
        The printable budget.
    """

    model: str
    grade_effect_m: float
    terms_m: dict
    fraction: float
    lines: list
    grade: str = ""


def distance_from_origin_m(p_n, lat0_rad) -> np.ndarray:
    """Geodesic distance [m] on the WGS-84 ellipsoid from the origin to each point's foot.

    A true distance at any range (the horizontal part of the origin's ENU, ``R sin(d / R)``,
    flattens near ``R`` and folds back beyond 90 degrees). The origin is placed at height 0
    (an origin at height ``h0`` moves a point's foot by at most ``h0 sin(d / R)``: 0.016 % of
    ``d`` per km of ``h0``).

    Parameters
    ----------
    p_n : ndarray, shape (N, 3)
        ENU positions relative to the origin [m].
    lat0_rad : float
        Origin latitude [rad].

    Returns
    -------
    ndarray, shape (N,)
    """
    from pyproj import Geod  # imported here: a simulate job loads this module without pyproj

    p = np.asarray(p_n, dtype=float).reshape(-1, 3)
    r_e = ecef_from_geodetic(lat0_rad, 0.0, 0.0) + p @ C_en_from_geodetic(lat0_rad, 0.0)
    lat, lon, _ = geodetic_from_ecef(r_e)
    lat0 = np.full(len(p), math.degrees(lat0_rad))
    _, _, d = Geod(ellps="WGS84").inv(np.zeros(len(p)), lat0, np.degrees(lon), np.degrees(lat))
    return np.asarray(d, dtype=float)


def choose_earth_model(time_s, p_n, lat0_rad, figures: GradeFigures, fraction=0.1) -> EarthBudget:
    """Pick ``flat``, ``wgs84`` or ``geodetic`` for a scene (``--earth auto``).

    ``flat`` or ``wgs84`` from a position-error budget; ``geodetic`` (with the exact Earth of
    ``wgs84``) when the largest distance ``D`` from the origin (the geodesic on the ellipsoid,
    :func:`distance_from_origin_m`) tilts the local vertical by ``D / R > GEODETIC_TILT_RAD``,
    whatever the grade.

    Estimates (order of magnitude, distance from the origin taken to grow linearly in time):

    * grade effect: root sum square of accelerometer bias ``b_a (1 - cos ws T)/ws^2``, gyro
      bias ``R b_g (T - sin(ws T)/ws)`` (Schuler-bounded tilt errors), ``ws = sqrt(g/R)``,
      velocity random walk ``N_a sqrt(T^3/3)`` and angle random walk ``g N_g sqrt(T^5/20)``;
    * Coriolis ``2 Omega x v``: ``Omega L T`` for a path of length ``L`` over ``T``;
    * Earth rate in the gyros: coupling of the attitude error (``g Omega b_g T^4 / 24``) and
      the gyro scale factor acting on Omega (``g s_g Omega T^3 / 6``);
    * Schuler / gravity gradient: ``(ws T)^2 / 12`` of the grade effect (relative change of
      the bias-driven error growth once the gravity gradient restores it);
    * gravity variation over the scene (latitude and height): ``dg T^2 / 6``;
    * tilt of the local vertical ``g d / R``: ``g D T^2 / (6 R)`` for a largest geodesic
      distance ``D`` from the origin.

    Parameters
    ----------
    time_s : ndarray, shape (N,)
        Sample times [s].
    p_n : ndarray, shape (N, 3)
        ENU positions relative to the origin [m].
    lat0_rad : float
        Origin latitude [rad].
    figures : GradeFigures
        Nominal figures of the grade the scene is simulated for.
    fraction : float
        Threshold; ``flat`` when every dropped term < ``fraction`` x grade effect.

    Returns
    -------
    EarthBudget
    """
    t = np.asarray(time_s, dtype=float)
    p = np.asarray(p_n, dtype=float).reshape(-1, 3)
    T = float(t[-1] - t[0]) if t.size > 1 else 0.0
    L = float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))) if len(p) > 1 else 0.0
    D = float(np.max(distance_from_origin_m(p, lat0_rad))) if len(p) else 0.0
    dn = float(np.ptp(p[:, 1])) if len(p) else 0.0
    dh = float(np.ptp(p[:, 2])) if len(p) else 0.0
    g = float(normal_gravity(lat0_rad, 0.0))
    R = R_MEAN
    ws = math.sqrt(g / R)
    bg, ba = figures.gyro_bias_radps, figures.accel_bias_mps2
    sg = figures.gyro_scale_factor
    wT = ws * T
    grade_m = math.sqrt(
        (ba * (1.0 - math.cos(wT)) / ws**2) ** 2
        + (R * bg * (T - math.sin(wT) / ws)) ** 2
        + figures.vrw_mps_per_sqrt_s**2 * T**3 / 3.0
        + (g * figures.arw_rad_per_sqrt_s) ** 2 * T**5 / 20.0
    )
    # gravity change over the scene: d g / d lat * north extent / R + free-air * height range
    dg_dlat = GAMMA_E * (K_SOMIGLIANA + 0.5 * E2_WGS84) * abs(math.sin(2.0 * lat0_rad))
    dg = dg_dlat * dn / R + 3.086e-6 * dh
    terms = {
        "Coriolis 2*Omega x v": OMEGA_IE * L * T,
        "Earth rate in gyros (attitude coupling, scale factor)": g * OMEGA_IE * bg * T**4 / 24.0
        + g * sg * OMEGA_IE * T**3 / 6.0,
        "Schuler / gravity gradient": grade_m * wT**2 / 12.0,
        "gravity variation over the scene": dg * T**2 / 6.0,
        "tilt of the local vertical g*d/R": g * D * T**2 / (6.0 * R),
    }
    limit = fraction * grade_m
    model = "flat" if all(v < limit for v in terms.values()) and T > 0.0 else "wgs84"
    tilt = D / R
    if tilt > GEODETIC_TILT_RAD:
        model = "geodetic"
    lines = [
        f"earth model budget (grade {figures.name}: gyro bias {bg / DEG_PER_H:g} deg/h, accel "
        f"bias {ba / MICRO_G:g} ug, gyro SF {sg * 1e6:g} ppm, ARW "
        f"{figures.arw_rad_per_sqrt_s * 60 * 180 / math.pi:g} deg/sqrt(h), VRW "
        f"{figures.vrw_mps_per_sqrt_s * 60:g} m/s/sqrt(h))",
        f"scene: {T:.1f} s, path {L:.1f} m, max distance {D:.1f} m (geodesic), north extent "
        f"{dn:.1f} m, height range {dh:.1f} m",
        f"grade position effect over the scene: {grade_m:.4g} m; limit "
        f"{fraction:.0%} = {limit:.4g} m",
    ]
    for name, val in terms.items():
        ok = "ok" if val < limit else "EXCEEDS"
        lines.append(
            f"  {name:<55s} {val:11.4g} m  ({val / grade_m:8.2%} of grade) {ok}"
            if grade_m > 0
            else f"  {name:<55s} {val:11.4g} m"
        )
    lines.append(
        f"  tilt of the origin's vertical at the farthest point D/R {tilt:11.4g} rad  (geodetic "
        f"above {GEODETIC_TILT_RAD:g}) {'EXCEEDS' if tilt > GEODETIC_TILT_RAD else 'ok'}"
    )
    lines.append(f"-> earth model: {model}")
    return EarthBudget(model, grade_m, terms, fraction, lines, figures.name)
