"""Datasheet units -> SI, converted once when a grade configuration is read.

Every unit has an explicit name (``deg_per_h``, ``deg_per_sqrt_h``, ``ug_per_sqrt_hz``...) and a
*dimension* (what kind of quantity it measures). A grade field declares the dimension it
expects, so a figure given in a unit of the wrong kind (a noise density where a bias is
expected, ``mg`` where ``deg_per_h`` is expected) is rejected instead of being silently
misread -- the most common datasheet confusion (``deg/h`` vs ``deg/sqrt(h)``, ``mg`` vs
``ug/sqrt(Hz)``, single- vs double-sided PSDs).

Conventions
-----------
* ``G0 = 9.80665 m/s^2`` (standard gravity, CGPM 1901) converts ``g``, ``mg`` and ``ug``.
* A noise density is the white noise's continuous-time sigma (the square root of its two-sided
  power spectral density; Kalibr's ``*_noise_density``, IEEE 952's ``N``); a one-sided amplitude
  density, as Welch's method gives, is sqrt(2) times larger (see ``imugen.sensors.grade_io``). A white
  rate noise of density ``N`` [rad/s/sqrt(Hz)] is the same number as an angle random walk ``N``
  [rad/sqrt(s)]:
  ``deg_per_sqrt_h = deg_per_s_per_sqrt_hz / 60`` [IEEE Std 952-1997, annex C]; likewise
  ``m_per_s_per_sqrt_h`` (VRW) and ``ug_per_sqrt_hz``.
* Rate random walk ``K`` is the density of the *derivative* of the bias: SI rad/s/sqrt(s)
  (gyro) and m/s^2/sqrt(s) (accelerometer); ``deg_per_h_per_sqrt_h`` = ``(pi/180/3600)/60``.
* Scale factors and cross-couplings are dimensionless (``ppm``, ``percent``, ``fraction``);
  misalignment angles (``mrad``, ``deg``, ``arcsec``) are converted to radians and used as
  small-angle cross-coupling terms.

SI dimension names and their SI units (``SI_UNIT``)::

    angular_rate            rad/s          (gyro biases, bias instability, range, LSB)
    angular_rate_density    rad/s/sqrt(Hz) = rad/sqrt(s)   (ARW)
    angular_rate_rw         rad/s/sqrt(s)  (gyro RRW)
    acceleration            m/s^2          (accelerometer biases, range, LSB)
    acceleration_density    m/s^2/sqrt(Hz) = m/s/sqrt(s)   (VRW)
    acceleration_rw         m/s^2/sqrt(s)  (accelerometer RRW)
    dimensionless           1              (scale factor, cross-coupling)
    angle                   rad            (misalignment)
    time                    s              (correlation times)
    temperature             K              (temperature differences)
    g_sensitivity           rad/s per m/s^2 = rad s/m
    angular_rate_per_K      rad/s/K
    acceleration_per_K      m/s^2/K
    dimensionless_per_K     1/K
    frequency               Hz             (internal sample rate, filter cut-off)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

G0 = 9.80665
"""Standard gravity [m/s^2] (CGPM 1901), converts g, mg, ug."""
DEG = math.pi / 180.0
"""One degree [rad]."""
HOUR = 3600.0
"""One hour [s]."""
SQRT_HOUR = 60.0
"""sqrt(1 h) [sqrt(s)]."""
FT = 0.3048
"""One international foot [m]."""

SI_UNIT = {
    "angular_rate": "rad/s",
    "angular_rate_density": "rad/s/sqrt(Hz)",
    "angular_rate_rw": "rad/s/sqrt(s)",
    "acceleration": "m/s^2",
    "acceleration_density": "m/s^2/sqrt(Hz)",
    "acceleration_rw": "m/s^2/sqrt(s)",
    "dimensionless": "1",
    "angle": "rad",
    "time": "s",
    "temperature": "K",
    "g_sensitivity": "rad/s/(m/s^2)",
    "angular_rate_per_K": "rad/s/K",
    "acceleration_per_K": "m/s^2/K",
    "dimensionless_per_K": "1/K",
    "frequency": "Hz",
}
"""SI unit of each dimension."""


@dataclass(frozen=True)
class Unit:
    """A named unit: ``value_si = value * factor``.

    Attributes
    ----------
    name : str
        Explicit unit name used in configuration files (e.g. ``"deg_per_sqrt_h"``).
    dimension : str
        Kind of quantity (a key of :data:`SI_UNIT`).
    factor : float
        Multiplier to SI.
    label : str
        Human-readable symbol for reports and plots.
    """

    name: str
    dimension: str
    factor: float
    label: str


def _u(name, dimension, factor, label):
    return Unit(name, dimension, float(factor), label)


_UNITS = [
    # angular rate (bias, bias instability, range, LSB)
    _u("rad_per_s", "angular_rate", 1.0, "rad/s"),
    _u("deg_per_s", "angular_rate", DEG, "deg/s"),
    _u("deg_per_h", "angular_rate", DEG / HOUR, "deg/h"),
    _u("mdeg_per_s", "angular_rate", 1e-3 * DEG, "mdeg/s"),
    # angular rate density / angle random walk
    _u("rad_per_sqrt_s", "angular_rate_density", 1.0, "rad/sqrt(s)"),
    _u("rad_per_s_per_sqrt_hz", "angular_rate_density", 1.0, "rad/s/sqrt(Hz)"),
    _u("deg_per_sqrt_h", "angular_rate_density", DEG / SQRT_HOUR, "deg/sqrt(h)"),
    _u("deg_per_s_per_sqrt_hz", "angular_rate_density", DEG, "deg/s/sqrt(Hz)"),
    _u("mdeg_per_s_per_sqrt_hz", "angular_rate_density", 1e-3 * DEG, "mdeg/s/sqrt(Hz)"),
    _u("deg_per_h_per_sqrt_hz", "angular_rate_density", DEG / HOUR, "deg/h/sqrt(Hz)"),
    # gyro rate random walk
    _u("rad_per_s_per_sqrt_s", "angular_rate_rw", 1.0, "rad/s/sqrt(s)"),
    _u("deg_per_h_per_sqrt_h", "angular_rate_rw", DEG / HOUR / SQRT_HOUR, "deg/h/sqrt(h)"),
    _u("deg_per_s_per_sqrt_s", "angular_rate_rw", DEG, "deg/s/sqrt(s)"),
    # acceleration (bias, bias instability, range, LSB)
    _u("m_per_s2", "acceleration", 1.0, "m/s^2"),
    _u("g", "acceleration", G0, "g"),
    _u("mg", "acceleration", 1e-3 * G0, "mg"),
    _u("mgal", "acceleration", 1e-5, "mGal"),
    _u("ug", "acceleration", 1e-6 * G0, "ug"),
    # acceleration density / velocity random walk
    _u("m_per_s_per_sqrt_s", "acceleration_density", 1.0, "m/s/sqrt(s)"),
    _u("m_per_s2_per_sqrt_hz", "acceleration_density", 1.0, "m/s^2/sqrt(Hz)"),
    _u("m_per_s_per_sqrt_h", "acceleration_density", 1.0 / SQRT_HOUR, "m/s/sqrt(h)"),
    _u("ft_per_s_per_sqrt_h", "acceleration_density", FT / SQRT_HOUR, "ft/s/sqrt(h)"),
    _u("ug_per_sqrt_hz", "acceleration_density", 1e-6 * G0, "ug/sqrt(Hz)"),
    _u("mg_per_sqrt_hz", "acceleration_density", 1e-3 * G0, "mg/sqrt(Hz)"),
    # accelerometer rate random walk
    _u("m_per_s2_per_sqrt_s", "acceleration_rw", 1.0, "m/s^2/sqrt(s)"),
    _u("m_per_s_per_h_per_sqrt_h", "acceleration_rw", 1.0 / HOUR / SQRT_HOUR, "m/s/h/sqrt(h)"),
    _u("ug_per_sqrt_h", "acceleration_rw", 1e-6 * G0 / SQRT_HOUR, "ug/sqrt(h)"),
    _u("ug_per_sqrt_s", "acceleration_rw", 1e-6 * G0, "ug/sqrt(s)"),
    # dimensionless (scale factor, cross-coupling)
    _u("fraction", "dimensionless", 1.0, "1"),
    _u("percent", "dimensionless", 1e-2, "%"),
    _u("ppm", "dimensionless", 1e-6, "ppm"),
    # angles (misalignment)
    _u("rad", "angle", 1.0, "rad"),
    _u("mrad", "angle", 1e-3, "mrad"),
    _u("urad", "angle", 1e-6, "urad"),
    _u("deg", "angle", DEG, "deg"),
    _u("arcsec", "angle", DEG / 3600.0, "arcsec"),
    # time
    _u("s", "time", 1.0, "s"),
    _u("min", "time", 60.0, "min"),
    _u("h", "time", HOUR, "h"),
    # temperature differences
    _u("K", "temperature", 1.0, "K"),
    _u("degC", "temperature", 1.0, "degC (difference)"),
    # gyro g-sensitivity
    _u("rad_per_s_per_m_per_s2", "g_sensitivity", 1.0, "rad/s/(m/s^2)"),
    _u("deg_per_h_per_g", "g_sensitivity", DEG / HOUR / G0, "deg/h/g"),
    _u("deg_per_s_per_g", "g_sensitivity", DEG / G0, "deg/s/g"),
    # temperature coefficients
    _u("rad_per_s_per_K", "angular_rate_per_K", 1.0, "rad/s/K"),
    _u("deg_per_h_per_K", "angular_rate_per_K", DEG / HOUR, "deg/h/K"),
    _u("deg_per_s_per_K", "angular_rate_per_K", DEG, "deg/s/K"),
    _u("m_per_s2_per_K", "acceleration_per_K", 1.0, "m/s^2/K"),
    _u("ug_per_K", "acceleration_per_K", 1e-6 * G0, "ug/K"),
    _u("mg_per_K", "acceleration_per_K", 1e-3 * G0, "mg/K"),
    _u("ppm_per_K", "dimensionless_per_K", 1e-6, "ppm/K"),
    _u("percent_per_K", "dimensionless_per_K", 1e-2, "%/K"),
    _u("per_K", "dimensionless_per_K", 1.0, "1/K"),
    # frequency (sensor internal rate, filter cut-off)
    _u("hz", "frequency", 1.0, "Hz"),
    _u("khz", "frequency", 1e3, "kHz"),
]

UNITS: dict[str, Unit] = {u.name: u for u in _UNITS}
"""All known units by name."""


def unit(name: str, dimension: str | None = None) -> Unit:
    """Look up a unit by name, optionally requiring a dimension.

    Raises
    ------
    KeyError
        Unknown unit name (the message lists the units of the requested dimension).
    ValueError
        The unit measures another kind of quantity than ``dimension``.
    """
    u = UNITS.get(name)
    if u is None:
        choices = units_of(dimension) if dimension else sorted(UNITS)
        raise KeyError(f"unknown unit {name!r}; expected one of {', '.join(choices)}")
    if dimension is not None and u.dimension != dimension:
        raise ValueError(
            f"unit {name!r} measures {u.dimension}, expected {dimension} "
            f"(one of {', '.join(units_of(dimension))})"
        )
    return u


def units_of(dimension: str) -> list[str]:
    """Names of the units of a dimension."""
    return [u.name for u in _UNITS if u.dimension == dimension]


def to_si(value, name: str, dimension: str | None = None):
    """Convert ``value`` (scalar or array) from the named unit to SI."""
    f = unit(name, dimension).factor
    if np.isscalar(value):
        return float(value) * f
    return np.asarray(value, dtype=float) * f


def from_si(value, name: str, dimension: str | None = None):
    """Convert ``value`` from SI to the named unit."""
    f = unit(name, dimension).factor
    if np.isscalar(value):
        return float(value) / f
    return np.asarray(value, dtype=float) / f
