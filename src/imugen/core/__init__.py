"""Shared foundations every stage may use; imports no stage.

- :mod:`~imugen.core.units`: datasheet units -> SI, converted once at the config edge;
- :mod:`~imugen.core.rotations`: quaternions, DCMs, Euler angles (the only quaternion helpers);
- :mod:`~imugen.core.earth`: Earth models (flat, wgs84, geodetic), gravity, Earth rate;
- :mod:`~imugen.core.geodesic`: WGS-84 geodesic distances and densification;
- :mod:`~imugen.core.frames`: geodetic <-> local ENU (through PROJ);
- :mod:`~imugen.core.seeding`: the whole spawn-key tree of the random draws;
- :mod:`~imugen.core.jit`: numba ``njit`` with a cache that follows the package's code;
- :mod:`~imugen.core.errors`: :class:`~imugen.core.errors.InputError`;
- :mod:`~imugen.core.io`: atomic writes, Parquet metadata;
- :mod:`~imugen.core.progress`: progress lines of long jobs;
- :mod:`~imugen.core.plotting`: the shared figure style.
"""
