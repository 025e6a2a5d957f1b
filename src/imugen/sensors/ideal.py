"""The ideal IMU a sensor measures: the truth's signals served in time chunks.

A :class:`TruthSource` gives, for samples ``k0 .. k0+L-1``, the time, the ideal rates
``omega_ib_b``, ``f_b`` and the exact (compensated) increments of the intervals ending there,
and on demand the raw increments (plain integrals of rate and specific force). The sensor
model, the mounting and the vibration (:mod:`imugen.sensors`) read their input through it;
:class:`ArrayTruth` holds a truth in memory (a truth table's columns, or arrays). The still
IMU of ``imugen simulate --static`` is :class:`imugen.simulate.sources.StaticTruth`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.tables import truth as ttruth
from imugen.tables.truth import ACCEL, DTHETA, DV, GYRO, TIME, VEL

CHUNK = 8192
"""Samples per sequence served and processed per step (a constant; results do not depend on it)."""


class TruthSource(ABC):
    """Ideal IMU signals on a uniform time grid, served in chunks (abstract base).

    Attributes
    ----------
    K : int
        Number of samples.
    dt : float
        Sample interval [s].
    meta : dict
        Provenance for the shard metadata.
    """

    K: int
    dt: float
    meta: dict

    @abstractmethod
    def chunk(self, k0: int, L: int):
        """``(time_s (L,), omega_ib_b (L,3), f_b (L,3), dtheta (L,3), dv (L,3))``, float64."""

    def times(self) -> np.ndarray:
        """``time_s`` of every sample (K,), float64: the chunks' times, joined."""
        return np.concatenate(
            [self.chunk(k, min(CHUNK, self.K - k))[0] for k in range(0, self.K, CHUNK)]
        )

    @abstractmethod
    def raw_chunk(self, k0: int, L: int):
        """Raw increments ``(int omega_ib_b dt (L,3), int f_b dt (L,3))`` of the intervals
        ending at samples ``k0 .. k0+L-1`` (row 0 zero), float64."""


class ArrayTruth(TruthSource):
    """Truth held as arrays (rows ``k``: sample at ``t_k``; increments of the interval ending there).

    Parameters
    ----------
    time_s : (K,)
    omega_ib_b, f_b, dtheta, dv : (K, 3)
    meta : dict, optional
    """

    def __init__(self, time_s, omega_ib_b, f_b, dtheta, dv, meta=None, source="<arrays>"):
        self.time = np.ascontiguousarray(time_s, dtype=np.float64)
        self.w = np.ascontiguousarray(omega_ib_b, dtype=np.float64)
        self.f = np.ascontiguousarray(f_b, dtype=np.float64)
        self.dth = np.ascontiguousarray(dtheta, dtype=np.float64)
        self.dv = np.ascontiguousarray(dv, dtype=np.float64)
        self.K = len(self.time)
        if self.K < 2:
            raise InputError(source, "truth needs at least 2 samples")
        for a in (self.w, self.f, self.dth, self.dv):
            if a.shape != (self.K, 3):
                raise InputError(source, f"truth arrays must be ({self.K}, 3), got {a.shape}")
        d = np.diff(self.time)
        self.dt = float((self.time[-1] - self.time[0]) / (self.K - 1))
        if not np.all(np.isfinite(self.time)) or np.max(np.abs(d - self.dt)) > 1e-9 * max(
            1.0, self.dt
        ) + 1e-12 * abs(self.time[-1]):
            raise InputError(source, "time_s is not a uniform grid")
        self.meta = dict(meta or {})
        self._raw = None
        self.speed_mps = None  # vehicle speed per sample when known (vibration model)
        self.rotor_rpm = None  # mean rotor speed per sample of a multirotor (vibration model)

    def chunk(self, k0, L):
        s = slice(k0, k0 + L)
        return self.time[s], self.w[s], self.f[s], self.dth[s], self.dv[s]

    def times(self):
        return self.time

    def raw_chunk(self, k0, L):
        """4-point quadrature of the rate samples (:func:`interval_integrals`: exact for
        cubics, local error ``O(dt^5)``), computed once for the whole truth."""
        if self._raw is None:
            self._raw = (interval_integrals(self.w, self.dt), interval_integrals(self.f, self.dt))
        s = slice(k0, k0 + L)
        return self._raw[0][s], self._raw[1][s]

    @classmethod
    def from_frame(cls, df, meta=None, source="<frame>") -> ArrayTruth:
        need = (TIME, *GYRO, *ACCEL, *DTHETA, *DV)
        miss = [c for c in need if c not in df.columns]
        if miss:
            raise InputError(source, f"not a truth table: missing column(s) {', '.join(miss)}")
        out = cls(
            df[TIME].to_numpy(),
            df[list(GYRO)].to_numpy(),
            df[list(ACCEL)].to_numpy(),
            df[list(DTHETA)].to_numpy(),
            df[list(DV)].to_numpy(),
            meta,
            source,
        )
        if set(VEL) <= set(df.columns):
            out.speed_mps = np.linalg.norm(df[list(VEL)].to_numpy(), axis=1)
        return out

    @classmethod
    def read(cls, path) -> ArrayTruth:
        """Read a truth file; the provenance kept names it by file name and checksum only."""
        names = set(ttruth.column_names(path))
        has_vel = set(VEL) <= names
        rotors = ttruth.ROTORS[:4] if set(ttruth.ROTORS[:4]) <= names else ()
        cols = [TIME, *GYRO, *ACCEL, *DTHETA, *DV, *(VEL if has_vel else ()), *rotors]
        tr = ttruth.read(path, columns=cols, need_meta=False, arrow=True)
        keep = {
            k: tr.meta[k]
            for k in ("origin", "earth", "rate_hz", "vehicle", "route")
            if k in tr.meta
        }
        # no path strings (the truth's own ``source`` is one): a shard's bytes must not depend
        # on how paths were spelled; the checksum names the truth and its provenance
        keep["file"] = Path(path).name
        keep["sha256"] = ttruth.checksum(path)
        out = cls(tr.time_s, tr.omega_ib_b, tr.f_b, tr.dtheta, tr.dv, keep, str(path))
        if has_vel:
            out.speed_mps = np.linalg.norm(tr.v_n, axis=1)
        if rotors:
            out.rotor_rpm = tr._cols(rotors).mean(axis=1)
        return out


def interval_integrals(x, dt):
    """Plain integrals of uniformly sampled signals over each sample interval (4-point rule).

    ``out[k] = int_{t_{k-1}}^{t_k} x dt`` for ``k >= 1`` (row 0 is zero), from the cubic through
    the four nearest samples: ``dt/24 (-x_{k-2} + 13 x_{k-1} + 13 x_k - x_{k+1})`` inside,
    ``dt/24 (9 x_0 + 19 x_1 - 5 x_2 + x_3)`` on the first interval and its mirror on the last.
    Exact for cubics; local error ``11/720 dt^5 x^(4)`` inside (``19/720`` at the ends), so
    the sum over a fixed span converges as ``dt^4``. Fewer than 4 samples: trapezoid.

    Parameters
    ----------
    x : ndarray, shape (K, 3)
        Samples at ``t_k = t_0 + k dt``.
    dt : float

    Returns
    -------
    ndarray, shape (K, 3)
    """
    x = np.asarray(x, dtype=float)
    K = x.shape[0]
    out = np.zeros_like(x)
    if K < 4:
        out[1:] = 0.5 * dt * (x[1:] + x[:-1])
        return out
    c = dt / 24.0
    out[2 : K - 1] = c * (-x[: K - 3] + 13.0 * x[1 : K - 2] + 13.0 * x[2 : K - 1] - x[3:])
    out[1] = c * (9.0 * x[0] + 19.0 * x[1] - 5.0 * x[2] + x[3])
    out[K - 1] = c * (9.0 * x[K - 1] + 19.0 * x[K - 2] - 5.0 * x[K - 3] + x[K - 4])
    return out
