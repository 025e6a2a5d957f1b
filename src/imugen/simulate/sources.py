"""Truth sources of a shard: the truth file, a table or arrays in memory, or a still IMU.

:func:`resolve_truth` turns what :func:`imugen.simulate.stage.simulate` was given into a
:class:`imugen.sensors.ideal.TruthSource`; :class:`StaticTruth` is the still, level IMU of
``imugen simulate --static``; :func:`route_name` names the route a shard belongs to (its id
enters every spawn key).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.sensors.ideal import CHUNK, ArrayTruth, TruthSource
from imugen.tables.truth import TIME

DEFAULT_STATIC_ORIGIN = (45.0, 0.0, 0.0)
"""Origin (lat_deg, lon_deg, alt_m) of a still IMU built with ``--static``."""


class StaticTruth(TruthSource):
    """A still, level IMU (body axes = ENU axes of the origin), built chunk by chunk.

    ``flat``: ``f_b = (0, 0, g0)``, ``omega_ib_b = 0``. ``wgs84``: the body turns with the Earth,
    ``omega_ib_b = Omega (0, cos lat, sin lat)``, and the exact increments are
    ``dtheta = omega dt`` and ``dv = int_0^dt Exp([omega x] tau) f_b dtau`` (closed form).

    Parameters
    ----------
    duration_s : float
        Length [s]; samples at ``k dt`` for ``k = 0 .. floor(duration/dt)``.
    rate_hz : float
    earth : {"flat", "wgs84"}
    origin : (lat_deg, lon_deg, alt_m)
    """

    def __init__(self, duration_s, rate_hz=100.0, earth="flat", origin=DEFAULT_STATIC_ORIGIN):
        from imugen.core.earth import OriginFrame, earth_rate_n, gravity_n

        if not (duration_s > 0 and math.isfinite(duration_s)):
            raise InputError("--static", f"duration must be > 0 s, got {duration_s!r}")
        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise InputError("--rate-hz", f"rate must be > 0 Hz, got {rate_hz!r}")
        if earth not in ("flat", "wgs84"):
            raise InputError("--earth", f"static earth model must be flat or wgs84, got {earth!r}")
        self.dt = 1.0 / float(rate_hz)
        self.K = math.floor(duration_s * rate_hz + 1e-9) + 1
        frame = OriginFrame.from_deg(*origin, model=earth)
        if earth == "flat":
            g = np.array([0.0, 0.0, -frame.g0])
        else:
            g = np.asarray(gravity_n(np.zeros((1, 3)), frame), float).reshape(3)
        self.omega = np.asarray(earth_rate_n(frame), float).reshape(3)
        self.f_b = -g
        self.dth_c = self.omega * self.dt
        W = np.array(
            [
                [0.0, -self.omega[2], self.omega[1]],
                [self.omega[2], 0.0, -self.omega[0]],
                [-self.omega[1], self.omega[0], 0.0],
            ]
        )
        wn = float(np.linalg.norm(self.omega))
        if wn > 0:
            th = wn * self.dt
            # (th - sin th) / wn^3 by its series when th is small (cancellation)
            c3 = (
                (th - math.sin(th)) / wn**3
                if th > 1e-2
                else self.dt**3 / 6.0 * (1.0 - th**2 / 20.0 + th**4 / 840.0)
            )
            A = self.dt * np.eye(3) + (2.0 * math.sin(th / 2) ** 2 / wn**2) * W + c3 * (W @ W)
        else:
            A = self.dt * np.eye(3)
        self.dv_c = A @ self.f_b
        self._cache = None
        self.meta = {
            "static": {
                "duration_s": float(duration_s),
                "earth": earth,
                "origin": {"lat_deg": origin[0], "lon_deg": origin[1], "alt_m": origin[2]},
                "f_b_mps2": self.f_b.tolist(),
                "omega_ib_b_radps": self.omega.tolist(),
            },
            "rate_hz": float(rate_hz),
            "earth": earth,
        }

    def chunk(self, k0, L):
        if self._cache is None or len(self._cache[0]) < L:
            n = max(L, CHUNK)
            self._cache = (
                np.tile(self.omega, (n, 1)),
                np.tile(self.f_b, (n, 1)),
                np.tile(self.dth_c, (n, 1)),
                np.tile(self.dv_c, (n, 1)),
            )
        w, f, dth, dv = (c[:L] for c in self._cache)
        if k0 == 0:
            dth = dth.copy()
            dv = dv.copy()
            dth[0] = 0.0
            dv[0] = 0.0
        t = np.arange(k0, k0 + L, dtype=np.float64) * self.dt
        return t, w, f, dth, dv

    def raw_chunk(self, k0, L):
        """Constant rates: the plain integrals are exactly ``omega dt`` and ``f_b dt``."""
        a = np.tile(self.omega * self.dt, (L, 1))
        b = np.tile(self.f_b * self.dt, (L, 1))
        if k0 == 0:
            a[0] = 0.0
            b[0] = 0.0
        return a, b


def route_name(truth, tr: TruthSource, route=None) -> str:
    """The route a shard belongs to: ``route``; else the truth metadata's ``route``; else the
    truth file's folder name (``results/<route>/truth.parquet``); else ``"static"`` for a
    still IMU and ``""`` for in-memory arrays."""
    if route is not None:
        if not isinstance(route, str):
            raise InputError("--route", f"must be a string, got {route!r}")
        return route
    if tr.meta.get("route"):
        return str(tr.meta["route"])
    if isinstance(tr, StaticTruth):
        return "static"
    if isinstance(truth, str | Path):
        return Path(truth).resolve().parent.name
    return ""


def resolve_truth(truth, static_s, rate_hz, static_earth) -> TruthSource:
    """The truth source of ``truth`` (or of a still IMU of ``static_s`` seconds)."""
    if isinstance(truth, TruthSource):
        return truth
    if truth is None:
        if static_s is None:
            raise InputError("simulate", "give a truth table or --static SECONDS")
        return StaticTruth(float(static_s), rate_hz, static_earth)
    if static_s is not None:
        raise InputError("--static", "give either a truth table or --static, not both")
    pd = sys.modules.get("pandas")  # a DataFrame can only exist once pandas is imported
    if pd is not None and isinstance(truth, pd.DataFrame):
        return ArrayTruth.from_frame(truth)
    if isinstance(truth, dict):
        return ArrayTruth(
            truth[TIME],
            truth["omega_ib_b"],
            truth["f_b"],
            truth["dtheta"],
            truth["dv"],
            truth.get("meta"),
        )
    return ArrayTruth.read(truth)
