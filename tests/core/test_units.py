"""Datasheet unit conversions (oracles: definitions and the conversions quoted in peers.md §6)."""

import math

import numpy as np
import pytest

from imugen.core import units


def test_angular_rate_units():
    assert units.to_si(1.0, "deg_per_h") == pytest.approx(math.pi / 180 / 3600, rel=1e-15)
    assert units.to_si(1.0, "deg_per_s") == pytest.approx(math.pi / 180, rel=1e-15)


def test_arw_density_equivalence():
    # ARW [deg/sqrt(h)] = density [deg/s/sqrt(Hz)] x 60 (MPU-6050: 0.005 -> 0.30)
    a = units.to_si(0.30, "deg_per_sqrt_h")
    b = units.to_si(0.005, "deg_per_s_per_sqrt_hz")
    assert a == pytest.approx(b, rel=1e-12)


def test_vrw_density_equivalence():
    # VRW [m/s/sqrt(h)] = density [ug/sqrt(Hz)] x 9.80665e-6 x 60
    a = units.to_si(400.0, "ug_per_sqrt_hz")
    assert units.from_si(a, "m_per_s_per_sqrt_h") == pytest.approx(400 * 9.80665e-6 * 60, rel=1e-12)
    # HG1700 0.065 ft/s/sqrt(h) = 0.0198 m/s/sqrt(h)
    assert units.from_si(
        units.to_si(0.065, "ft_per_s_per_sqrt_h"), "m_per_s_per_sqrt_h"
    ) == pytest.approx(0.065 * 0.3048, rel=1e-12)


def test_acceleration_and_misc_units():
    assert units.to_si(1.0, "ug") == pytest.approx(9.80665e-6, rel=1e-15)
    assert units.to_si(2.0, "mg") == pytest.approx(2 * 9.80665e-3, rel=1e-15)
    assert units.to_si(500.0, "ppm") == pytest.approx(5e-4, rel=1e-15)
    assert units.to_si(1.0, "mrad") == pytest.approx(1e-3, rel=1e-15)
    assert units.to_si(2.0, "percent") == pytest.approx(0.02, rel=1e-15)
    # g-sensitivity: 0.1 deg/s/g == 360 deg/h/g, and both in rad/s per m/s^2
    assert units.to_si(0.1, "deg_per_s_per_g") == pytest.approx(
        units.to_si(360.0, "deg_per_h_per_g")
    )
    assert units.to_si(1.0, "deg_per_h_per_g") == pytest.approx(math.pi / 180 / 3600 / 9.80665)
    # RRW: 1 deg/h/sqrt(h) = pi/180/3600/60 rad/s/sqrt(s)
    assert units.to_si(1.0, "deg_per_h_per_sqrt_h") == pytest.approx(math.pi / 180 / 3600 / 60)


def test_round_trip_arrays():
    v = np.array([0.1, 2.0, 30.0])
    for name in units.UNITS:
        np.testing.assert_allclose(units.from_si(units.to_si(v, name), name), v, rtol=1e-14)


def test_dimension_checks():
    with pytest.raises(ValueError, match="measures angular_rate"):
        units.unit("deg_per_h", "angular_rate_density")
    with pytest.raises(KeyError, match="unknown unit"):
        units.unit("deg_per_hour")
    assert "deg_per_sqrt_h" in units.units_of("angular_rate_density")
    for u in units.UNITS.values():
        assert u.dimension in units.SI_UNIT
