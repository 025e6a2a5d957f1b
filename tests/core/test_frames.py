"""Geodetic <-> ENU: round trip (property test) and an independent closed-form implementation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imugen.core.frames import LocalFrame, Origin, to_utm, utm_crs

A = 6378137.0
F = 1 / 298.257223563
E2 = F * (2 - F)


def ecef(lat_deg, lon_deg, h):
    """Textbook geodetic -> ECEF (independent of PROJ)."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = A / np.sqrt(1 - E2 * np.sin(lat) ** 2)
    return np.stack(
        [
            (n + h) * np.cos(lat) * np.cos(lon),
            (n + h) * np.cos(lat) * np.sin(lon),
            (n * (1 - E2) + h) * np.sin(lat),
        ],
        axis=-1,
    )


def enu_reference(origin, lat, lon, h):
    lat0, lon0 = np.radians(origin.lat_deg), np.radians(origin.lon_deg)
    r = np.array(
        [
            [-np.sin(lon0), np.cos(lon0), 0],
            [-np.sin(lat0) * np.cos(lon0), -np.sin(lat0) * np.sin(lon0), np.cos(lat0)],
            [np.cos(lat0) * np.cos(lon0), np.cos(lat0) * np.sin(lon0), np.sin(lat0)],
        ]
    )
    d = ecef(lat, lon, h) - ecef(origin.lat_deg, origin.lon_deg, origin.alt_m)
    return d @ r.T


lat_s = st.floats(-89.0, 89.0)
lon_s = st.floats(-180.0, 180.0)
h_s = st.floats(-400.0, 9000.0)


@settings(max_examples=200, deadline=None)
@given(lat_s, lon_s, h_s, st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(-500, 500))
def test_round_trip_within_1mm(lat0, lon0, h0, dlat, dlon, dh):
    origin = Origin(lat0, lon0, h0)
    frame = LocalFrame(origin)
    lat = np.clip(lat0 + dlat, -89.9, 89.9)
    lon = (lon0 + dlon + 180) % 360 - 180
    enu = frame.to_enu([lat], [lon], [h0 + dh])
    lat2, lon2, h2 = frame.to_geodetic(enu)
    back = LocalFrame(origin).to_enu(lat2, lon2, h2)
    assert np.linalg.norm(back - enu) < 1e-3
    # the geodetic values themselves: 1 mm is ~9e-9 deg of latitude
    assert abs(lat2[0] - lat) < 1e-8
    dlon_wrapped = (lon2[0] - lon + 180) % 360 - 180
    assert abs(dlon_wrapped) * np.cos(np.radians(lat)) < 1e-8
    assert abs(h2[0] - (h0 + dh)) < 1e-3


@settings(max_examples=100, deadline=None)
@given(lat_s, lon_s, h_s, st.floats(-0.8, 0.8), st.floats(-0.8, 0.8), st.floats(-1000, 3000))
def test_matches_independent_implementation(lat0, lon0, h0, dlat, dlon, h):
    origin = Origin(lat0, lon0, h0)
    lat = np.clip(lat0 + dlat, -89.9, 89.9)
    lon = (lon0 + dlon + 180) % 360 - 180
    ours = LocalFrame(origin).to_enu([lat], [lon], [h])
    ref = enu_reference(origin, np.array([lat]), np.array([lon]), np.array([h]))
    assert np.max(np.abs(ours - ref)) < 1e-6


def test_origin_is_zero_and_axes():
    o = Origin(31.63, -7.99, 450.0)
    f = LocalFrame(o)
    np.testing.assert_allclose(f.to_enu([31.63], [-7.99], [450.0]), [[0, 0, 0]], atol=1e-9)
    e, n, u = f.to_enu([31.63, 31.64, 31.63], [-7.98, -7.99, -7.99], [450, 450, 460]).T
    assert e[0] > 900 and abs(n[0]) < 1 and n[1] > 1100 and abs(e[1]) < 1e-6
    assert u[2] == pytest.approx(10.0, abs=1e-9)


def test_antimeridian_continuous():
    o = Origin(-16.8, 179.99, 0.0)
    f = LocalFrame(o)
    enu = f.to_enu([-16.8, -16.8], [179.99, -179.99], [0, 0])
    # 0.02 deg of longitude at 16.8 deg S is about 2.13 km, eastwards
    assert enu[1, 0] == pytest.approx(
        0.02 * np.pi / 180 * 6378137 * np.cos(np.radians(16.8)), rel=2e-3
    )


def test_utm_zone_and_value():
    o = Origin(31.63, -7.99, 0.0)
    crs = utm_crs(o)
    assert crs.to_epsg() == 32629
    e, n = to_utm([31.63], [-9.0], crs)  # on the central meridian of zone 29: easting 500 km
    assert e[0] == pytest.approx(500000.0, abs=1e-6)
    # northing on the central meridian = 0.9996 * meridian arc length (independent series)
    lat = np.radians(31.63)
    n_ = F / (2 - F)
    a_hat = A / (1 + n_) * (1 + n_**2 / 4 + n_**4 / 64)
    arc = a_hat * (
        lat
        - (3 * n_ / 2 - 9 * n_**3 / 16) * np.sin(2 * lat)
        + (15 * n_**2 / 16 - 15 * n_**4 / 32) * np.sin(4 * lat)
        - (35 * n_**3 / 48) * np.sin(6 * lat)
    )
    assert n[0] == pytest.approx(0.9996 * arc, abs=1e-3)
    assert utm_crs(Origin(-7.96, 110.0, 0)).to_epsg() == 32749
    with pytest.raises(ValueError):
        utm_crs(Origin(85.0, 0.0, 0.0))
