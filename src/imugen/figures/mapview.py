"""Map coordinates for route figures: the tangent plane for short routes, a map projection else.

A route whose extent (diagonal of its bounding box in the ENU of its origin) is at most
:data:`LONG_ROUTE_M` is drawn as today: East/North of the origin's tangent plane, metres
(``kind = "tangent"``). A longer one -- where the tangent plane bends a 264 km road by hundreds
of metres and a 7,600 km flight beyond recognition -- is drawn in the azimuthal equidistant
projection of the WGS-84 ellipsoid centred on the route (``kind = "aeqd"``, pyproj/PROJ):
distances and azimuths from the centre are true, the scale across them grows as
``(d/R) / sin(d/R)`` (+0.4 % at 300 km from the centre, +6 % at 3,800 km), it is continuous
across the antimeridian (no wrap-around streak, unlike longitude) and across the poles. The
vertical coordinate is then the ellipsoidal height (the ENU Up of a far origin would dive by
``d^2 / 2R``). The centre is the normalized mean of the route's ECEF unit vectors, so a route
on either side of 180 deg is centred on it.

Navigated positions are rebuilt from the stored errors, which are East/North/Up at the true
position (:mod:`imugen.navigate.local_errors`): ``p_nav_n = p_true_n + C_ln^T err_l``.

:func:`add_scale_bar` draws a scale bar in kilometres whose length in data units is the stated
distance at the bar's own place (the projection's scale factor along x measured there), so it
is true to well under 1 % wherever the bar sits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from imugen.core import earth as E

LONG_ROUTE_M = 100_000.0
"""Routes with a larger extent are drawn in a map projection (m)."""


def extent_enu_m(frame: E.OriginFrame, p_n: np.ndarray) -> float:
    """Diagonal of the bounding box of positions ``p_n`` (K, 3) in the ENU of the origin [m]."""
    p = np.asarray(p_n, dtype=float).reshape(-1, 3)
    if frame.model == "geodetic":
        p = frame.with_model("wgs84").n_from_ecef(p)
    return float(np.sqrt(np.sum(np.ptp(p, axis=0) ** 2))) if len(p) else 0.0


def route_centre(r_e: np.ndarray) -> tuple[float, float]:
    """Geodetic (lat, lon) in degrees of the normalized mean of the ECEF unit vectors."""
    r = np.asarray(r_e, dtype=float).reshape(-1, 3)
    u = r / np.linalg.norm(r, axis=1, keepdims=True)
    m = u.mean(axis=0)
    lat, lon, _ = E.geodetic_from_ecef(m / np.linalg.norm(m) * E.A_WGS84)
    return math.degrees(float(lat)), math.degrees(float(lon))


@dataclass
class RouteMap:
    """Plot coordinates of one route's figures (module docstring).

    Attributes
    ----------
    frame : OriginFrame
        Navigation frame and Earth model of the truth.
    kind : str
        ``"tangent"`` (East/North/Up of the origin, m) or ``"aeqd"`` (azimuthal equidistant
        about ``centre_deg``, m, and ellipsoidal height).
    centre_deg : (lat, lon)
        Centre of the projection (``aeqd``), degrees.
    """

    frame: E.OriginFrame
    kind: str = "tangent"
    centre_deg: tuple[float, float] = (0.0, 0.0)
    _proj: object = field(default=None, repr=False)

    @classmethod
    def for_route(cls, frame: E.OriginFrame, p_n: np.ndarray, long_m: float = LONG_ROUTE_M):
        """The map of a route from (a decimation of) its true positions ``p_n`` (K, 3)."""
        if extent_enu_m(frame, p_n) <= long_m:
            return cls(frame, "tangent")
        return cls(frame, "aeqd", route_centre(frame.ecef_from_n(p_n)))

    @property
    def projected(self) -> bool:
        """True when the route is drawn in a map projection (long route)."""
        return self.kind == "aeqd"

    def _transformer(self):
        if self._proj is None:
            from pyproj import Transformer

            lat, lon = self.centre_deg
            self._proj = Transformer.from_crs(
                "EPSG:4326",
                f"+proj=aeqd +lat_0={lat!r} +lon_0={lon!r} +datum=WGS84 +units=m +no_defs",
                always_xy=True,
            )
        return self._proj

    def xyz(self, p_n) -> np.ndarray:
        """Plot coordinates (..., 3) [m] of positions ``p_n`` (..., 3) in n."""
        p = np.asarray(p_n, dtype=float)
        if self.kind == "tangent":
            if self.frame.model == "geodetic":
                return self.frame.with_model("wgs84").n_from_ecef(p)
            return p.copy()
        lat, lon, h = self.frame.geodetic_from_n(p)
        x, y = self._transformer().transform(np.degrees(lon), np.degrees(lat))
        return np.stack([np.asarray(x, float), np.asarray(y, float), h], axis=-1)

    def xy_from_lonlat(self, lon_deg, lat_deg) -> tuple[np.ndarray, np.ndarray]:
        """Projected x, y [m] of geodetic points (``aeqd`` only)."""
        x, y = self._transformer().transform(np.asarray(lon_deg), np.asarray(lat_deg))
        return np.asarray(x, float), np.asarray(y, float)

    def lonlat(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Inverse projection: (lon, lat) in degrees of projected x, y [m] (``aeqd`` only)."""
        from pyproj.enums import TransformDirection

        lon, lat = self._transformer().transform(
            np.asarray(x, float), np.asarray(y, float), direction=TransformDirection.INVERSE
        )
        return np.asarray(lon, float), np.asarray(lat, float)

    def navigated_n(self, p_true_n, err_l) -> np.ndarray:
        """Navigated positions in n from the true ones and the local-level errors, (..., 3)."""
        p = np.asarray(p_true_n, dtype=float)
        C = self.frame.C_ln(p)
        return p + np.einsum("...ki,...k->...i", C, np.asarray(err_l, dtype=float))

    def scale_x(self, x: float, y: float, step_m: float = 1000.0) -> float:
        """Scale factor along x at ``(x, y)``: geodesic metres per projected metre (1 in the
        tangent plane)."""
        if self.kind == "tangent":
            return 1.0
        from pyproj import Geod

        lon, lat = self.lonlat([x - step_m / 2, x + step_m / 2], [y, y])
        _, _, d = Geod(ellps="WGS84").inv(lon[0], lat[0], lon[1], lat[1])
        return float(d) / step_m

    def labels(self) -> tuple[str, str, str]:
        """Axis labels (x, y, z)."""
        if self.kind == "tangent":
            return "East [m]", "North [m]", "Up [m]"
        lat, lon = self.centre_deg
        where = (
            f"{abs(lat):.2f}°{'N' if lat >= 0 else 'S'} {abs(lon):.2f}°{'E' if lon >= 0 else 'W'}"
        )
        return (
            f"x [km], azimuthal equidistant about {where}",
            "y [km]",
            "ellipsoidal height [m]",
        )


def nice_length_km(target_km: float) -> float:
    """The largest 1, 2 or 5 x 10^n km not above ``target_km`` (> 0)."""
    e = math.floor(math.log10(target_km))
    for m in (5.0, 2.0, 1.0):
        if m * 10.0**e <= target_km:
            return m * 10.0**e
    return 10.0**e


def add_scale_bar(ax, rmap: RouteMap, fraction: float = 0.25) -> dict:
    """Draw a scale bar in km at the lower left of ``ax`` (data units: projected metres).

    Call after the axis limits are final. The bar's length is the largest 1/2/5 x 10^n km
    not above ``fraction`` of the axis width, measured with the projection's scale along x at
    the bar (:meth:`RouteMap.scale_x`).

    Returns
    -------
    dict
        ``x0``, ``x1``, ``y`` (data units) and ``km``; the line artist has gid
        ``"scale_bar"``.
    """
    x_lo, x_hi = ax.get_xlim()
    y_lo, y_hi = ax.get_ylim()
    w, h = x_hi - x_lo, y_hi - y_lo
    x0, y = x_lo + 0.05 * w, y_lo + 0.06 * h
    k = rmap.scale_x(x0 + fraction * w / 2, y)
    km = nice_length_km(fraction * w * k / 1000.0)
    # the scale changes along the bar: refine once at the bar's own midpoint
    k = rmap.scale_x(x0 + km * 500.0 / k, y)
    x1 = x0 + km * 1000.0 / k
    ax.plot([x0, x1], [y, y], color="black", lw=3, solid_capstyle="butt", gid="scale_bar",
            zorder=6)  # fmt: skip
    ax.text((x0 + x1) / 2, y + 0.015 * h, f"{km:g} km", ha="center", va="bottom", zorder=6)
    return {"x0": x0, "x1": x1, "y": y, "km": km}


def km_ticks(ax) -> None:
    """Label both axes of a projected map in kilometres (data stay in metres)."""
    from matplotlib.ticker import FuncFormatter

    fmt = FuncFormatter(lambda v, _: f"{v / 1000.0:,.6g}")
    ax.xaxis.set_major_formatter(fmt)
    ax.yaxis.set_major_formatter(fmt)
