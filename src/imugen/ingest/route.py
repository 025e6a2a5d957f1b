"""Shared vocabulary of the readers: a candidate path read from a route file."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np

from imugen.ingest import limits


@dataclass
class RoutePath:
    """One candidate path of a route file, as read (no validation yet).

    Attributes
    ----------
    name : str
        Human-readable name (Placemark/track name, or a generated ``"<kind> k"``).
    kind : str
        Geometry it came from: ``LineString``, ``Track``, ``trkseg``, ``rte``, ``csv``, ``enu``.
    lat_deg, lon_deg, alt_m : ndarray, shape (n,)
        Geodetic WGS-84 coordinates; ``alt_m`` is 0 where the file gives none. Empty
        (shape (0,)) for ``enu`` paths.
    enu_m : ndarray, shape (n, 3) or None
        East, North, Up in metres, only for ``enu`` paths (geodetic arrays are then empty).
    time_unix_s : ndarray, shape (n,) or None
        POSIX seconds (UTC), NaN where a point has no time; None when the path is untimed.
    altitude_mode : str or None
        KML altitudeMode as written (None: not given).
    altitude_trusted : bool
        False when the altitudes are not absolute heights (KML clampToGround/default,
        relativeToGround, or 2-D coordinates).
    time_is_absolute : bool
        False when the file gives relative seconds rather than dates.
    notes : list of str
        What the reader did that a user should know (skipped coordinates, etc.).
    carried : dict
        Metadata written by an earlier ``imugen ingest`` (CSV stage), e.g. the origin.
    alt_missing : ndarray of bool, shape (n,), or None
        True where the file gives no height for a point (its ``alt_m`` is then a
        placeholder); None when every point has one or none has. Ingestion interpolates them.
    warnings : list of str
        What the reader did that the user must be told on the command line (printed).
    attitude : ndarray, shape (n, 4), or None
        Pose trajectories only: attitude quaternions (scalar first) of the pose body.
    attitude_frame : str or None
        What ``attitude`` is relative to: ``"world"`` (the file's world axes, put on the Earth
        by ``--pose-world``) or ``"level"`` (the local ENU at each point).
    """

    name: str
    kind: str
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    alt_m: np.ndarray
    enu_m: np.ndarray | None = None
    time_unix_s: np.ndarray | None = None
    altitude_mode: str | None = None
    altitude_trusted: bool = True
    time_is_absolute: bool = True
    notes: list[str] = field(default_factory=list)
    carried: dict = field(default_factory=dict)
    alt_missing: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)
    attitude: np.ndarray | None = None
    attitude_frame: str | None = None

    @property
    def n_points(self) -> int:
        return len(self.enu_m) if self.enu_m is not None else len(self.lat_deg)


# Unambiguous (each character has one way to match), ASCII digits only; applied only to
# tokens no longer than the token bound, so matching is linear and bounded.
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?", re.ASCII)

#: POSIX seconds of 0001-01-02T00:00:00Z and 9999-12-30T23:59:59Z: any UTC offset keeps a time
#: in this span printable as an ISO-8601 date (years 1 to 9999).
TIME_RANGE_S = (-62135510400.0, 253402214399.0)


# Tokens this short pass whatever the token bound (saves reading the bound per value).
_SHORT = 40


def _check_token(s: str, what: str) -> None:
    bound = limits.current().token_chars
    if len(s) > bound:
        raise ValueError(
            f"a {what} longer than {bound} characters ({limits.ENV['token_chars']}): "
            f"{limits.shorten(s, 30)!r}"
        )


def parse_number(text: str) -> float:
    """Parse a finite decimal number as written in route files (``+008.5``, ``-1e-3``).

    Raises ValueError, whose message says why, on anything else: empty strings, ``1_000``,
    hex, non-ASCII digits, NaN, infinities and overflows (``1e999``), and tokens longer than
    the token bound (:mod:`imugen.ingest.limits`).
    """
    s = text.strip()
    if len(s) > _SHORT:
        _check_token(s, "value")
    if not _NUMBER.fullmatch(s):
        if s.lstrip("+-").lower() in ("nan", "inf", "infinity"):
            raise ValueError(f"not a finite number: {s!r}")
        raise ValueError(f"not a number: {limits.shorten(s)!r}")
    value = float(s)
    if not math.isfinite(value):
        raise ValueError(f"not a finite number: {limits.shorten(s)!r}")
    return value


def parse_iso_time(text: str) -> float:
    """ISO-8601 date-time -> POSIX seconds (UTC).

    Accepts ``Z`` and ``+hh:mm`` offsets and fractional seconds; a time without an
    offset is taken as UTC (documented in the README). Raises ValueError when the text
    is not ISO-8601, is longer than the token bound, or falls outside :data:`TIME_RANGE_S`.
    """
    s = text.strip()
    if not s:
        raise ValueError("empty time")
    if len(s) > _SHORT:
        _check_token(s, "time")
    try:
        dt = datetime.fromisoformat(s)
        if dt.tzinfo is None:
            dt = dt.replace(tzinfo=UTC)
        ts = dt.timestamp()
    except (ValueError, OverflowError, OSError):
        raise ValueError(f"not an ISO-8601 date-time: {s!r}") from None
    if not TIME_RANGE_S[0] <= ts <= TIME_RANGE_S[1]:
        raise ValueError(f"time out of range (years 1 to 9999 in UTC): {s!r}")
    return ts


def iso_utc(unix_s: float) -> str:
    """POSIX seconds (within :data:`TIME_RANGE_S`) -> ISO-8601 UTC string with a ``Z`` suffix."""
    return datetime.fromtimestamp(unix_s, tz=UTC).isoformat().replace("+00:00", "Z")
