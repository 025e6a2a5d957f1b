"""The truth table: route -> motion -> attitude -> ideal IMU and increments -> metadata."""

from __future__ import annotations

import math
import sys
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import pandas as pd

from imugen import __version__
from imugen.core import earth as ea
from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.tables import enu as tenu
from imugen.tables import truth as col
from imugen.truth import multirotor
from imugen.truth.attitude import SLIP_GAP_RAD, EarthField, GroundAttitude, attitude_pass
from imugen.truth.budget import budget_meta, earth_budget
from imugen.truth.fit import (
    CURVATURE_RESIDUAL_RADII,
    LIMIT_RESIDUAL_NOISE,
    TimedMotion,
    fit_path,
    fit_timed,
    floor_heights,
)
from imugen.truth.flight import flight_corner, flight_geometry
from imugen.truth.gate import findings
from imugen.truth.increments import imu_pass
from imugen.truth.pose import PoseSettings, fit_poses, motion_figures, pose_pass
from imugen.truth.profile import PathMotion, speed_profile
from imugen.truth.report import plausibility, report_lines
from imugen.truth.reversals import TURN_REST_S, find_reversals, legs_motion
from imugen.truth.road import motion_on_road, path_on_road
from imugen.truth.timed_bends import TURN_RATE_RADPS, bound_timed_bends, slow_turns
from imugen.truth.vehicles import VehicleParams, vehicle_params

CHUNK = 1 << 16  # samples per evaluation chunk


@dataclass
class BuildOptions:
    """Options of :func:`build_truth` beyond rate, Earth model and vehicle (None: defaults)."""

    grade: object = None  # name, FILE.yaml:NAME, Grade, GradeFigures, or a list of them
    fit_tol_m: float | None = None
    stops: bool = True
    corner_m: float | None = None
    cruise_mps: float | None = None
    accel_mps2: float | None = None
    lat_accel_mps2: float | None = None
    jerk_mps3: float | None = None
    hold_speed_mps: tuple | None = None
    vehicle_params: dict | None = None  # VehicleParams fields to override
    auto_fraction: float = 0.1
    pose: PoseSettings | None = None  # frames, time offset, smoothing of a pose truth
    extra: dict = field(default_factory=dict)


def enu_table(enu_m, time_s=None, origin=(0.0, 0.0, 0.0)) -> tuple[pd.DataFrame, dict]:
    """Build an ENU table and its metadata from arrays (synthetic routes, tests).

    Parameters
    ----------
    enu_m : array_like, shape (N, 3)
        East, North, Up relative to the origin [m].
    time_s : array_like, shape (N,), optional
        Times [s]; None for an untimed path.
    origin : (lat_deg, lon_deg, alt_m)

    Returns
    -------
    (DataFrame, dict)
        Columns like ingestion's output and the metadata (``origin``, ``timed``).
    """
    enu_m = np.asarray(enu_m, dtype=float).reshape(-1, 3)
    frame = ea.OriginFrame.from_deg(*origin)
    lat, lon, h = frame.geodetic_from_n(enu_m)
    data = {}
    if time_s is not None:
        data[col.TIME] = np.asarray(time_s, dtype=float)
    data[tenu.LAT] = np.degrees(lat)
    data[tenu.LON] = np.degrees(lon)
    data[tenu.ALT] = h
    data[tenu.E], data[tenu.N], data[tenu.U] = enu_m.T
    meta = {
        "origin": {
            "lat_deg": float(origin[0]),
            "lon_deg": float(origin[1]),
            "alt_m": float(origin[2]),
        },
        "timed": time_s is not None,
        "source": "arrays",
    }
    return pd.DataFrame(data), meta


def is_pose(enu: pd.DataFrame) -> bool:
    """Whether the ENU table is a pose trajectory's (attitude columns)."""
    return all(c in enu.columns for c in tenu.ATTITUDE)


def pose_motion(enu: pd.DataFrame, meta: dict, settings: PoseSettings | None):
    """The IMU's motion of a pose trajectory (:func:`imugen.truth.pose.fit_poses`) in the
    origin's ENU: attitudes turned from the local ENU at each pose to the origin's axes."""
    if tenu.TIME not in enu.columns:
        raise InputError(None, "a pose trajectory needs its times (time_s)")
    y = enu[list(tenu.ENU)].to_numpy(dtype=float)
    q_l = enu[list(tenu.ATTITUDE)].to_numpy(dtype=float)
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(q_l))):
        raise InputError(None, "ENU table holds non-finite poses")
    frame = ea.OriginFrame.from_deg(*_origin(meta), "wgs84")
    q_n = rot.quat_mul(rot.dcm_to_quat(np.swapaxes(frame.C_ln(y), -1, -2)), q_l)
    return fit_poses(enu[tenu.TIME].to_numpy(float), y, q_n, settings)


def _virtual(t: np.ndarray, meta: dict) -> np.ndarray | None:
    """Coordinates of a timed route that ingestion placed, (n, 3) bool, or None: the virtual
    fixes of bridged gaps (``segments.virtual_s`` spans, s like ``time_s``) and the heights
    held while an aircraft stands still (``cleaning.still_runs_s``), and the fixes of GPS
    jitter at rest placed at their centroid (``cleaning.at_rest.runs_s``)."""
    out = np.zeros((len(t), 3), bool)
    for a, b in (meta.get("segments") or {}).get("virtual_s") or []:
        out[(t > a + 1e-6) & (t < b - 1e-6)] = True
    for a, b in ((meta.get("cleaning") or {}).get("at_rest") or {}).get("runs_s") or []:
        out[(t >= a - 1e-6) & (t <= b + 1e-6)] = True
    for a, b in (meta.get("cleaning") or {}).get("still_runs_s") or []:
        out[(t >= a - 1e-6) & (t <= b + 1e-6), 2] = True
    return out if out.any() else None


FLOOR_RISE_M = 50.0
"""Height deficit [m] whose correction by :func:`imugen.truth.fit.floor_heights` stays within
the class's ``vertical_accel_mps2`` at cruise speed (:func:`_floor_taper`)."""


def _floor_taper(vp: VehicleParams) -> float:
    """Taper [m] of the height floor's ramps: ``v sqrt(8 FLOOR_RISE_M / vertical_accel)`` at
    ``cruise_mps`` (the distance over which a quadratic ramp rises that much at that
    acceleration)."""
    return vp.cruise_mps * math.sqrt(8.0 * FLOOR_RISE_M / vp.vertical_accel_mps2)


def _limits(vp: VehicleParams, opts: BuildOptions) -> dict:
    """The speed profile's limits of an untimed route: the options' or the class's."""
    return {
        "cruise_mps": opts.cruise_mps or vp.cruise_mps,
        "accel_mps2": opts.accel_mps2 or vp.accel_mps2,
        "lat_accel_mps2": opts.lat_accel_mps2 or vp.lat_accel_mps2,
        "jerk_mps3": opts.jerk_mps3 or vp.jerk_mps3,
    }


def build_motion(enu: pd.DataFrame, meta: dict, vp: VehicleParams, opts: BuildOptions, E=None):
    """Fit the route: returns (motion, fit report, timing report).

    With ``E`` (the :class:`EarthField` of the truth), an untimed ground route's geometry
    takes the vertical of its road profile before its speed profile (:func:`_path_on_road`);
    the motion's ``profile`` holds it. A pose trajectory's motion carries its attitude
    (:func:`pose_motion`). An untimed ground route that doubles back is timed leg by leg with
    a stop and a turn at each reversal (:mod:`imugen.truth.reversals`)."""
    for c in tenu.ENU:
        if c not in enu.columns:
            raise InputError(None, f"ENU table lacks column {c!r}")
    if is_pose(enu):
        motion, fit = pose_motion(enu, meta, opts.pose)
        return motion, fit, {"timed": True, "source": "pose clock", "attitude": "given"}
    y = enu[list(tenu.ENU)].to_numpy(dtype=float)
    if not np.all(np.isfinite(y)):
        raise InputError(None, "ENU table holds non-finite coordinates")
    timed = bool(meta.get("timed", col.TIME in enu.columns)) and col.TIME in enu.columns
    if timed:
        t = enu[col.TIME].to_numpy(float)
        motion, fit = fit_timed(t, y, vp, opts.fit_tol_m, opts.stops, _virtual(t, meta))
        motion, fit = _bounded_bends(motion, fit, t, y, vp)
        timing = {"timed": True, "source": "input clock"}
        if vp.attitude == "ground":  # it pulls away from a stop facing its velocity
            timing["turns_at_rest_s"] = _union(
                _stop_turns(motion.spline, fit["stops"], t, vp)
                + slow_turns(motion.spline, motion.t0, motion.t1, vp, fit["stops"])
            )
    elif vp.attitude == "ground" and (cuts := find_reversals(y, vp)):
        motion, fit, timing = legs_motion(y, cuts, vp, opts.corner_m, _limits(vp, opts))
    else:
        corner, kmax = opts.corner_m, None
        if vp.phases:  # a flight: rounded at the input's spacing, turns at the bank limit
            alt = enu[tenu.ALT].to_numpy(float) if tenu.ALT in enu.columns else y[:, 2]
            corner, kmax = flight_corner(y, alt, vp, opts.corner_m)
        G, L, fit, s_v = fit_path(y, vp, corner, vertices=True, max_curvature=kmax)
        if vp.phases:  # never below the input's heights (the terrain, the runway)
            G, L, fit["height_floor"] = floor_heights(
                G, L, s_v, y[:, 2], corner, _floor_taper(vp), fit["densify_step_m"] / 4.0
            )
        profile = None
        if E is not None and vp.attitude == "ground":
            G, L, profile = _path_on_road(G, L, E, vp, enu, fit, s_v)
        vmax, plan = None, None
        if vp.phases:
            alt = enu[tenu.ALT].to_numpy(float) if tenu.ALT in enu.columns else y[:, 2]
            G, L, vmax, plan = flight_geometry(G, L, _origin(meta), alt, vp)
        s_pp, rep = speed_profile(G, L, **_limits(vp, opts), vmax_mps=vmax)
        motion = PathMotion(G, s_pp, L, profile)
        timing = {"timed": False, "source": "speed profile", **rep}
        if plan is not None:
            timing["flight"] = plan
    return motion, fit, timing


class EcefMotion:
    """A motion fitted in the route origin's ENU coordinates, expressed in ECEF.

    The origin's ENU is an exact Cartesian frame (a rigid transform of ECEF, at any
    distance), so the fitted motion is a physical motion however long the route; this adapter
    rotates it into the ``geodetic`` model's navigation coordinates:
    ``r_e = r0_e + C_ne p``, derivatives rotated by ``C_ne``.

    Parameters
    ----------
    motion : TimedMotion or PathMotion
        Positions in the ENU of ``origin`` [m].
    origin : imugen.core.earth.OriginFrame
        The route origin (any model: only its ``r0_e`` and ``C_en`` of the ENU axes are used).
    """

    def __init__(self, motion, origin: ea.OriginFrame):
        self.inner = motion
        self.kind = motion.kind
        self.t0, self.t1 = motion.t0, motion.t1
        enu = origin.with_model("wgs84")
        self.C_en = enu.C_en
        self.r0_e = enu.r0_e

    def _rotate(self, x):
        return np.einsum("mi,ij->mj", x, self.C_en)  # C_ne x per row (einsum: no BLAS call)

    def position(self, t):
        return self.r0_e + self._rotate(self.inner.position(t))

    def velocity(self, t):
        return self._rotate(self.inner.velocity(t))

    def eval(self, t):
        """(r, v, a, j) in ECEF, each shape (m, 3), at times ``t`` (m,)."""
        p, v, a, j = self.inner.eval(t)
        return self.r0_e + self._rotate(p), self._rotate(v), self._rotate(a), self._rotate(j)


def _heights(E, enu):
    """Heights [m] of the input points: n's Up in ``flat``, else ellipsoidal (the input ENU
    is the origin's)."""
    y = enu[list(tenu.ENU)].to_numpy(dtype=float)
    return y[:, 2] if E.flat else E.frame.with_model("wgs84").geodetic_from_n(y)[2]


def _gate_heights(E, enu):
    """Heights [m] of the input points as the gate takes the truth's
    (``E.frame.geodetic_from_n``: absolute in every model)."""
    if not E.flat:
        return _heights(E, enu)
    return E.frame.geodetic_from_n(enu[list(tenu.ENU)].to_numpy(dtype=float))[2]


def _input_heights(E, enu):
    """Times [s] and heights [m] of a timed route's input points (:func:`_heights`)."""
    return enu[col.TIME].to_numpy(float), _heights(E, enu)


def _enu_field(E):
    """The field of the origin's ENU where routes are fitted: ``E`` itself, or its ``wgs84``
    field in ``geodetic``."""
    return EarthField(E.frame.with_model("wgs84")) if E.ecef else E


def _path_on_road(G, L, E, vp, enu, fit, s_v):
    """An untimed ground path with the vertical of its road profile
    (:func:`imugen.truth.road.path_on_road`, in the origin's ENU; sampled at the fine grid of
    :func:`fit_path`, ``densify_step_m / 4``), its length and ``(H, grade report)`` (None when
    too short for a profile); the fit report gets the profile's report and the distances of
    the path on the road profile to the input."""
    y = enu[list(tenu.ENU)].to_numpy(float)
    G2, L2, H, rep = path_on_road(
        G, L, _enu_field(E), vp, (s_v, _heights(E, enu)), y, fit["densify_step_m"] / 4.0
    )
    fit["vertical"] = rep
    if H is None:
        return G, L, None
    fit["length_m"] = L2
    fit["rms_distance_m"] = rep["rms_distance_m"]
    fit["max_distance_m"] = rep["max_distance_m"]
    fit["rms_vertical_distance_m"] = rep["rms_vertical_distance_m"]
    return G2, L2, (H, rep["grade"])


def _on_road(motion, E, vp, enu, fit):
    """A timed ground route's motion with the vertical of its road profile
    (:func:`imugen.truth.road.motion_on_road`, in the origin's ENU) and that profile; the fit
    report gets the profile's report and the distances of the motion on the road profile to the input."""
    E_enu = _enu_field(E)
    t_in, h = _input_heights(E, enu)
    noise_up = float(fit["noise_estimate_m"][2])
    on_road, H, rep = motion_on_road(motion, E_enu, vp, (t_in, h), noise_up, fit.get("stops", []))
    fit["vertical"] = rep
    if H is None:
        return motion, None
    d = on_road.position(t_in) - enu[list(tenu.ENU)].to_numpy(float)
    dist = np.linalg.norm(d, axis=1)
    fit["rms_distance_m"] = float(np.sqrt(np.mean(dist**2)))
    fit["max_distance_m"] = float(dist.max())
    fit["rms_horizontal_distance_m"] = float(np.sqrt(np.mean(np.sum(d[:, :2] ** 2, axis=1))))
    fit["rms_vertical_distance_m"] = float(np.sqrt(np.mean(d[:, 2] ** 2)))
    return on_road, (H, rep["grade"])


def _ground(motion, E, vp, enu, fit, profile=None, turns=()) -> GroundAttitude:
    """The ground-vehicle attitude of the motion: on a motion on the road profile or path its road profile;
    heights from the input points of other timed routes (their own noise), else from the
    smoothed path; ``turns``: the intervals [s] of its turns at rest (reversals' stops)."""
    if profile is not None:
        return GroundAttitude(motion, E, vp, profile=profile, turns=turns)
    if motion.kind != "timed":
        return GroundAttitude(motion, E, vp, turns=turns)
    noise_up = float(fit["noise_estimate_m"][2])
    return GroundAttitude(motion, E, vp, _input_heights(E, enu), noise_up, turns=turns)


def _stop_turns(spline, stops, t, vp):
    """Turns at rest [s] of a timed ground route: the middle of each group of stops
    (:func:`_stop_groups`; in its longest stop) inside the route (but
    :data:`imugen.truth.reversals.TURN_REST_S` at either end, at most a quarter of the stop;
    at least :data:`imugen.truth.timed_bends.TURN_RATE_RADPS`'s time) whose direction of departure differs from that of arrival by more than
    :data:`imugen.truth.attitude.SLIP_GAP_RAD` (each the velocity's the last and first moment
    faster than twice ``stop_speed_mps``, within 10 s): the vehicle turns from the one to the
    other at rest (:class:`imugen.truth.attitude.GroundAttitude`), standing in for the
    turn of its pulling away that the fixes' jitter at rest hides; a heading turning with the
    distance after the stop slid sideways as the vehicle pulled away (0.6 m/s on the
    mountain-pass drive)."""
    out = []
    for group in _stop_groups(spline, stops, vp):
        a, b = group[0][0], group[-1][1]
        if not (a > t[0] and b < t[-1]):
            continue
        dirs = []
        for tq in (np.arange(a - 10.0, a, 0.1)[::-1], np.arange(b, b + 10.0, 0.1)):
            v = spline(tq, 1)
            fast = np.flatnonzero(np.hypot(v[:, 0], v[:, 1]) > 2.0 * vp.stop_speed_mps)
            if len(fast):
                dirs.append(math.atan2(v[fast[0], 1], v[fast[0], 0]))
        turn = abs(math.remainder(dirs[1] - dirs[0], math.tau)) if len(dirs) == 2 else 0.0
        a, b = max(group, key=lambda ab: ab[1] - ab[0])  # turned in the group's longest
        m = min(TURN_REST_S, 0.25 * (b - a))
        # at least TURN_RATE_RADPS's time (a quicker one would spin the body on the spot)
        if turn > SLIP_GAP_RAD and b - a - 2.0 * m >= turn / TURN_RATE_RADPS:
            out.append([float(a + m), float(b - m)])
    return out


def _stop_groups(spline, stops, vp):
    """The stops [s] in groups between which the vehicle never moves faster than twice
    ``stop_speed_mps`` (a creep of a fix or two between two stops, which the stop join of
    :func:`imugen.truth.fit.fit_timed` holds still at both ends): one arrival and one
    departure each."""
    groups = []
    for a, b in stops:
        if groups:
            pa = groups[-1][-1][1]
            v = spline(np.linspace(pa, a, max(3, math.ceil((a - pa) / 0.1) + 1)), 1)
            if a - pa < 10.0 and np.all(np.hypot(v[:, 0], v[:, 1]) <= 2.0 * vp.stop_speed_mps):
                groups[-1].append((a, b))
                continue
        groups.append([(a, b)])
    return groups


def _union(intervals):
    """Overlapping intervals merged (sorted)."""
    out = []
    for a, b in sorted(intervals):
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return out


def _bounded_bends(motion, fit, t, y, vp):
    """A timed ground fit with its bends tighter than the vehicle turns refitted
    (:func:`imugen.truth.timed_bends.bound_timed_bends`; no fix farther from the curve than
    the fit's cap on local smoothing), its report in ``fit["curvature_bound"]``."""
    if vp.attitude != "ground":
        return motion, fit
    cap = max(  # the fit's cap on local smoothing, and the untimed paths' on a bend
        LIMIT_RESIDUAL_NOISE * float(np.linalg.norm(fit["noise_estimate_m"])),
        vp.fit_tol_max_m,
        fit["max_distance_m"],
        CURVATURE_RESIDUAL_RADII / vp.max_curvature_1pm,
    )
    spline, bends = bound_timed_bends(motion.spline, t, y, vp, fit["stops"], cap)
    if bends is None:
        return motion, fit
    fit = {**fit, "curvature_bound": bends}
    if bends["refitted"]:
        motion = TimedMotion(spline, motion.t0, motion.t1)
        dist = np.linalg.norm(spline(t) - y, axis=1)
        fit["rms_distance_m"] = float(np.sqrt(np.mean(dist**2)))
        fit["max_distance_m"] = float(dist.max())
    return motion, fit


def _column_slices() -> dict:
    """Slices of the truth table's column groups (each group is contiguous)."""
    ci = {c: i for i, c in enumerate(col.COLUMNS)}
    groups = {
        "pos": col.POS,
        "vel": col.VEL,
        "quat": col.QUAT,
        "gyro": col.GYRO,
        "accel": col.ACCEL,
        "euler": col.EULER,
        "dtheta": col.DTHETA,
        "dv": col.DV,
    }
    out = {}
    for name, cols in groups.items():
        idx = [ci[c] for c in cols]
        assert idx == list(range(idx[0], idx[0] + len(idx))), name
        out[name] = slice(idx[0], idx[-1] + 1)
    return out


def _samples(motion, rate_hz):
    """Number of IMU samples ``t0 + k / rate_hz`` over the motion (at least 2)."""
    duration = motion.t1 - motion.t0
    K = math.floor(duration * rate_hz + 1e-9) + 1
    if K < 2:
        raise InputError(None, f"route lasts {duration:.3g} s: shorter than one IMU interval")
    return K


def _origin(meta):
    try:
        origin = meta["origin"]
        return tuple(float(origin[k]) for k in ("lat_deg", "lon_deg", "alt_m"))
    except (KeyError, TypeError, ValueError):
        raise InputError(None, "ENU metadata lacks the origin (lat_deg, lon_deg, alt_m)") from None


def build_truth(
    enu: pd.DataFrame,
    meta: dict,
    *,
    rate_hz: float = 100.0,
    earth: str = "flat",
    vehicle: str = "car",
    grade=None,
    chunk: int = CHUNK,
    verbose: bool = True,
    **options,
) -> tuple[pd.DataFrame, dict]:
    """ENU route -> truth table at the IMU rate (columns :data:`imugen.tables.truth.COLUMNS`).

    Parameters
    ----------
    enu : DataFrame
        Ingestion's table: ``e_m, n_m, u_m`` and ``time_s`` for timed routes.
    meta : dict
        Ingestion's metadata: ``origin`` {lat_deg, lon_deg, alt_m}, ``timed``.
    rate_hz : float
        IMU rate; samples at ``t0 + k / rate_hz`` over the route.
    earth : {"flat", "wgs84", "geodetic", "auto"}
        Earth model (``auto``: budget stored in the metadata). In ``geodetic`` the route is
        fitted in its origin's ENU (exact Cartesian) and the truth is expressed in ECEF
        (:class:`EcefMotion`), with ``lat_deg, lon_deg, alt_m`` columns; the attitude is
        relative to the local level at the vehicle in every model.
    vehicle : str
        A key of :data:`imugen.truth.VEHICLES`.
    grade : str, Grade, GradeFigures or a list of them, optional
        Sensor grade(s) for the ``auto`` budget (default ``consumer``): preset names,
        ``FILE.yaml:NAME`` custom grades, grade objects or budget figures; with several, the
        most demanding model any grade's budget needs decides (``geodetic`` > ``wgs84`` >
        ``flat``; ``geodetic`` depends on the scene's extent only).
    verbose : bool
        Print the ``auto`` budget and the plausibility report to stderr.
    **options
        Fields of :class:`BuildOptions` (``fit_tol_m``, ``stops``, ``corner_m``,
        ``cruise_mps``, ``accel_mps2``, ``lat_accel_mps2``, ``jerk_mps3``, ``hold_speed_mps``).

    Returns
    -------
    (DataFrame, dict)
        Truth table (float64) and its metadata.
    """
    if earth not in (*ea.MODELS, "auto"):
        raise InputError("--earth", f"unknown Earth model {earth!r}; flat, wgs84, geodetic or auto")
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise InputError("--rate-hz", f"IMU rate must be a positive number, got {rate_hz}")
    unknown = set(options) - set(BuildOptions.__dataclass_fields__)
    if unknown:
        raise TypeError(f"unknown options {sorted(unknown)}")
    opts = BuildOptions(grade=grade, **options)
    vp = vehicle_params(vehicle, opts.vehicle_params)
    if opts.hold_speed_mps is not None:
        vp = replace(vp, hold_speed_mps=tuple(opts.hold_speed_mps))
    lat0, lon0, h0 = _origin(meta)

    dt = 1.0 / rate_hz
    budget = None
    model = earth
    E = None if earth == "auto" else EarthField(ea.OriginFrame.from_deg(lat0, lon0, h0, model))
    motion, fit, timing = build_motion(enu, meta, vp, opts, E)
    if "vertex_times_s" in timing:  # timed leg by leg: the input points' times
        enu = enu.assign(**{col.TIME: timing.pop("vertex_times_s")})
    K = _samples(motion, rate_hz)
    if earth == "auto":
        budget = earth_budget(motion, K, math.radians(lat0), opts.grade, opts.auto_fraction)
        model = budget.model
        E = EarthField(ea.OriginFrame.from_deg(lat0, lon0, h0, model))
        if (
            motion.kind == "untimed" and vp.attitude == "ground"
        ):  # on the road profile of E's heights
            motion, fit, timing = build_motion(enu, meta, vp, opts, E)
            K = _samples(motion, rate_hz)
    times = motion.t0 + np.arange(K) * dt
    pose = is_pose(enu)
    profile = None
    if not pose and motion.kind == "timed" and vp.attitude == "ground":
        motion, profile = _on_road(motion, E, vp, enu, fit)
    elif motion.kind == "untimed":
        profile = motion.profile
    if E.ecef and pose:  # the fit in the origin's ENU, expressed in ECEF (as EcefMotion)
        enu_frame = E.frame.with_model("wgs84")
        motion = motion.rigid(enu_frame.C_en.T, enu_frame.r0_e)
    elif E.ecef:
        motion = EcefMotion(motion, E.frame)
    thrust = vp.attitude == "thrust"
    turns = timing.get("turns_at_rest_s", [])
    ground = None if pose or thrust else _ground(motion, E, vp, enu, fit, profile, turns)

    ci = _column_slices()
    out = np.zeros((K, len(col.COLUMNS)))
    out[:, col.COLUMNS.index(col.TIME)] = times
    if pose:
        f_n, stats = pose_pass(out, ci, motion, times, E, chunk)
    elif thrust:
        f_n, stats = multirotor.thrust_pass(out, ci, motion, times, E, vp, chunk)
    else:
        f_n, stats = attitude_pass(out, ci, motion, times, E, vp, chunk, ground)
    imu_pass(out, ci, f_n, E, motion, times, dt, chunk)
    del f_n
    if not np.all(np.isfinite(out)):
        raise InputError(None, "truth generation produced non-finite values (report this route)")

    df = pd.DataFrame(out, columns=list(col.COLUMNS), copy=False)
    columns = list(col.COLUMNS)
    if E.ecef:
        lat, lon, h = E.frame.geodetic_from_n(out[:, ci["pos"]])
        df[col.LAT], df[col.LON], df[col.ALT] = np.degrees(lat), np.degrees(lon), h
        columns += col.GEODETIC
    airborne = stats.pop("airborne")
    c_thrust = stats.pop("thrust_mps2", None)
    rotors = None
    if c_thrust is not None:
        rpm, rotors = multirotor.rotor_speeds(times, out[:, ci["gyro"]], c_thrust, vp)
        for i, c in enumerate(col.ROTORS[:4]):
            df[c] = rpm[:, i]
        df[col.ROTORS[4]] = vp.mass_kg * c_thrust
        columns += col.ROTORS
    stats["speed_max_mps"] = float(np.linalg.norm(out[:, ci["vel"]], axis=1).max())
    y_in = enu[list(tenu.ENU)].to_numpy(dtype=float)  # its length is frame-independent
    t_in = enu[col.TIME].to_numpy(float) if motion.kind == "timed" else None
    if pose:  # the fit report gives the distances to the poses; dense poses: no arcs
        t_in = None
    plaus = plausibility(
        df,
        vp,
        input_enu=y_in,
        input_time=t_in,
        fit=fit,
        airborne=airborne,
        frame=E.frame,
        turns_at_rest=turns,
        suspension_pitch_rad=(
            None if ground is None or ground.suspension is None else ground.suspension(times)[2]
        ),
    )
    # the pre-write gate (imugen.truth.gate); a pose truth is the given motion, not gated
    gate = (
        None
        if pose
        else findings(
            df,
            vp,
            frame=E.frame,
            airborne=airborne,
            input_heights=_gate_heights(E, enu),
            slip=True,
            turns_at_rest=turns,
        )
    )
    if pose or thrust:
        plaus.update(
            motion_figures(times, out[:, ci["vel"]], out[:, ci["gyro"]], out[:, ci["accel"]])
        )
    if rotors is not None:
        e = out[:, ci["euler"]]
        tilt = np.arccos(np.clip(np.cos(e[:, 0]) * np.cos(e[:, 1]), -1.0, 1.0))
        mr = multirotor.plausibility(tilt, out[:, ci["gyro"]], c_thrust, rotors, vp)
        plaus["warnings"] = plaus.get("warnings", []) + mr.pop("warnings")
        plaus["multirotor"] = mr
    tmeta = {
        "stage": "truth",
        "imugen_version": __version__,
        "source": meta.get("source"),
        "origin": {"lat_deg": lat0, "lon_deg": lon0, "alt_m": h0},
        "earth": model,
        "nav_frame": col.NAV_FRAMES[model],
        "earth_requested": earth,
        "earth_budget": None if budget is None else budget_meta(budget, opts.grade),
        "rate_hz": float(rate_hz),
        "samples": K,
        "duration_s": float(times[-1] - times[0]),
        "vehicle": vehicle,
        "vehicle_params": asdict(vp),
        "fit": fit,
        "timing": timing,
        "motion": stats,
        "ground_attitude": None if ground is None else ground.report,
        "plausibility": plaus,
        "gate": gate,
        "conventions": f"n = {col.NAV_FRAMES[model]}, b = FLU; l = ENU at the vehicle; "
        "C_lb = C_ln C_nb = Rz(yaw) Ry(-pitch) Rx(roll); quaternion scalar first; increments on "
        "the row ending their interval (row 0 zeros)",
        "units": {c: col.UNITS[c] for c in columns},
    }
    if verbose:
        for line in messages(tmeta):
            print(line, file=sys.stderr)
    return df, tmeta


def messages(tmeta: dict) -> list[str]:
    """Lines for stderr of a truth's metadata: its Earth budget and plausibility report."""
    budget = tmeta.get("earth_budget")
    lines = (budget["lines"] if budget else []) + report_lines(tmeta["plausibility"])
    fit = tmeta.get("fit") or {}
    if "attitude_residual_rms_rad" in fit:  # a pose truth (imugen.truth.pose)
        lines.insert(
            len(budget["lines"]) if budget else 0,
            f"pose fit: residual RMS {1e3 * fit['position_residual_rms_m']:.3g} mm, "
            f"{1e3 * fit['attitude_residual_rms_rad']:.3g} mrad (noise "
            f"{1e3 * max(fit['position_noise_m']):.3g} mm, "
            f"{1e3 * fit['attitude_noise_rad']:.3g} mrad per axis, {fit['attitude_noise_source']}); "
            f"cutoffs {', '.join(f'{f:.3g}' for f in fit['position_cutoff_hz'])} Hz, attitude "
            f"{fit['attitude_cutoff_hz']:.3g} Hz; outliers {fit['position_outliers']} + "
            f"{fit['attitude_outliers']}, gaps {fit['gaps']} (max {fit['max_gap_s']:.3g} s)",
        )
    lim = fit.get("limited")
    if lim:
        lines.append(
            f"truth fit: cleaned: smoothed locally at {lim['points_smoothed']} fixes where it "
            "turned tighter than the vehicle's curvature limit or braked/accelerated beyond its "
            f"limit (largest residual there {lim['max_residual_smoothed_m']:.2f} m, cap "
            f"{lim['residual_cap_m']:.2f} m; {lim['places_left']} places still beyond)"
        )
    mr = tmeta["plausibility"].get("multirotor")
    if mr:
        lines.append(
            f"multirotor: tilt <= {math.degrees(mr['max_tilt_rad']):.1f} deg, rotors "
            f"{mr['rotor_rpm_min']:.0f}-{mr['rotor_rpm_max']:.0f} rpm (blade pass "
            f"{mr['blade_pass_hz'][0]:.0f}-{mr['blade_pass_hz'][1]:.0f} Hz), T/W <= "
            f"{mr['thrust_to_weight_max']:.2f}"
        )
    return lines
