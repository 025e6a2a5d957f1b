"""Geodetic WGS-84 <-> local East-North-Up, and optional UTM, through PROJ.

The local frame is the topocentric frame of an origin point: geodetic coordinates go to
ECEF (``cart``) and are rotated into East-North-Up about the origin (``topocentric``),
one :class:`pyproj.Transformer` per origin, built once and reused. The conversion is
exact at any distance and across the antimeridian (it is a rigid transform of ECEF), but
the *meaning* of the axes is local: ``u_m`` is height above the origin's tangent plane, not
above the ground. At a horizontal distance ``d`` from the origin the tangent plane lies
``d^2 / (2 R)`` above the ellipsoid and the local vertical is tilted by ``d / R`` from the
frame's up axis. So the coordinates of a long route are exact Cartesian coordinates the
truth can fit, not East/North/Up at the vehicle: the truth's ``geodetic`` model (chosen by
``--earth auto`` beyond 64 km) expresses them in ECEF and reports everything in the local
level at the vehicle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pyproj import CRS, Transformer


@dataclass(frozen=True)
class Origin:
    """Geodetic WGS-84 origin of a local ENU frame (degrees, metres)."""

    lat_deg: float
    lon_deg: float
    alt_m: float

    def as_dict(self) -> dict:
        return {"lat_deg": self.lat_deg, "lon_deg": self.lon_deg, "alt_m": self.alt_m}


class LocalFrame:
    """Transforms between geodetic WGS-84 and the ENU frame of ``origin``.

    Parameters
    ----------
    origin : Origin
        Frame origin; its ENU coordinates are (0, 0, 0).
    """

    method = "PROJ pipeline: unitconvert deg->rad, cart (WGS-84 ECEF), topocentric (ENU)"

    def __init__(self, origin: Origin):
        self.origin = origin
        self._tf = Transformer.from_pipeline(
            "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
            "+step +proj=cart +ellps=WGS84 "
            f"+step +proj=topocentric +ellps=WGS84 +lat_0={origin.lat_deg!r} "
            f"+lon_0={origin.lon_deg!r} +h_0={origin.alt_m!r}"
        )

    def to_enu(self, lat_deg, lon_deg, alt_m) -> np.ndarray:
        """Geodetic (deg, deg, m), shape (n,) each -> ENU metres, shape (n, 3)."""
        e, n, u = self._tf.transform(
            np.asarray(lon_deg, float), np.asarray(lat_deg, float), np.asarray(alt_m, float)
        )
        return np.column_stack([e, n, u])

    def to_geodetic(self, enu_m) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """ENU metres, shape (n, 3) -> latitude (deg), longitude (deg), height (m)."""
        enu_m = np.asarray(enu_m, float)
        lon, lat, h = self._tf.transform(enu_m[:, 0], enu_m[:, 1], enu_m[:, 2], direction="INVERSE")
        lon = (np.asarray(lon) + 180.0) % 360.0 - 180.0
        return np.asarray(lat), lon, np.asarray(h)


def utm_crs(origin: Origin) -> CRS:
    """The WGS-84 UTM zone CRS containing ``origin`` (EPSG 326zz north, 327zz south)."""
    if not -80.0 <= origin.lat_deg <= 84.0:
        raise ValueError(f"UTM is not defined at latitude {origin.lat_deg:.4f} deg")
    zone = int((origin.lon_deg + 180.0) // 6.0) % 60 + 1
    return CRS.from_epsg((32600 if origin.lat_deg >= 0 else 32700) + zone)


def to_utm(lat_deg, lon_deg, crs: CRS) -> tuple[np.ndarray, np.ndarray]:
    """Geodetic degrees -> UTM easting, northing (m) in ``crs``."""
    tf = Transformer.from_crs("EPSG:4326", crs, always_xy=True)
    e, n = tf.transform(np.asarray(lon_deg, float), np.asarray(lat_deg, float))
    return np.asarray(e), np.asarray(n)
