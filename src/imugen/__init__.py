"""imugen: route files -> 6-DoF truth -> ideal and erroneous IMU -> strapdown -> RMSE.

Conventions (written once, here; every module names its variables by them)
---------------------------------------------------------------------------
Frames
    ``n``  navigation frame: local East-North-Up (ENU). Its axes are those of the
           topocentric frame at the route origin (a WGS-84 geodetic point).
    ``b``  body frame: x forward, y left, z up (FLU). A level, still IMU reads
           specific force ``f_b = (0, 0, +g)``.
    ``v``  vehicle frame, FLU at the vehicle reference point: the truth's body frame. The IMU's
           ``b`` is ``v`` unless a mounting is simulated (:mod:`imugen.sensors.mounting`: ``C_vb`` and
           the lever arm ``l_v``; the truth of such an IMU is then the vehicle's moved there).
    ``e``  Earth-centred Earth-fixed (ECEF, WGS-84).
    ``C_nb`` rotates a vector from ``b`` to ``n`` (``v_n = C_nb @ v_b``).
    Quaternions are scalar first ``(w, x, y, z)``.
    Suffixes name the frame a vector is resolved in: ``v_n``, ``f_b``, ``omega_ib_b``.
Units
    SI and radians inside. Degrees appear only at the edges (geodetic latitude and
    longitude columns ``lat_deg``/``lon_deg``, figure labels). Datasheet units
    (``deg_per_h``, ``deg_per_sqrt_h``, ``ug``, ``m_per_s_per_sqrt_h``, ``ppm``) are
    converted once, when the configuration is read.
Time
    Seconds from the first sample of the route (``time_s``); absolute start time, when
    known, is kept in file metadata as ISO-8601 UTC.
Errors
    A problem with a user's input raises :class:`imugen.core.errors.InputError`; the CLI prints
    it as one line naming the file and exits with status 2.
"""

__version__ = "0.1.0"

_LAZY = {
    "navigate_arrays": ("imugen.navigate.stage", "navigate_arrays"),
    "write_shard": ("imugen.tables.shard", "write_like"),
}
"""Public functions loaded on first use, so that ``import imugen`` stays cheap."""

__all__ = ["__version__", "navigate_arrays", "write_shard"]


def __getattr__(name):
    """``imugen.navigate_arrays`` (:func:`imugen.navigate.stage.navigate_arrays`) and
    ``imugen.write_shard`` (:func:`imugen.tables.shard.write_like`), imported lazily."""
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'imugen' has no attribute {name!r}")


def __dir__():
    return sorted({*globals(), *_LAZY})
