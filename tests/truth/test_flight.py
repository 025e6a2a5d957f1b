"""Flight phases of untimed airliner routes (imugen.truth.flight): plan oracles and the
plausibility of whole truths on a 429 km and a 7,600 km (antimeridian) route, built in the
model `earth: auto` picks for them (geodetic)."""

import math
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from pyproj import Geod

from imugen.core import earth as ea
from imugen.core.frames import LocalFrame, Origin
from imugen.core.geodesic import densify
from imugen.tables import truth as col
from imugen.truth import build_truth
from imugen.truth.flight import FlightPlan
from imugen.truth.report import _warnings
from imugen.truth.vehicles import VEHICLES, vehicle_params

GEOD = Geod(ellps="WGS84")
VP = VEHICLES["airliner"]


def _route(lat, lon, h=0.0):
    """Untimed route without heights as ingestion writes it (geodesics densified)."""
    la, lo, al, _ = densify(np.asarray(lat), np.asarray(lon), np.full(len(lat), h))
    o = Origin(float(la[0]), float(lo[0]), float(al[0]))
    enu = LocalFrame(o).to_enu(la, lo, al)
    df = pd.DataFrame(
        dict(lat_deg=la, lon_deg=lo, alt_m=al, e_m=enu[:, 0], n_m=enu[:, 1], u_m=enu[:, 2])
    )
    return df, {"origin": o.as_dict(), "timed": False, "source": "test"}


def _legs(lat0, lon0, legs):
    lat, lon = [lat0], [lon0]
    for az, d in legs:
        x, y, _ = GEOD.fwd(lon[-1], lat[-1], az, d)
        lat.append(y)
        lon.append(x)
    return lat, lon


def _slope(plan):
    return np.gradient(plan.h, plan.d), np.gradient(np.gradient(plan.h, plan.d), plan.d)


def test_plan_of_a_long_flight_follows_its_phases():
    D = 7_600e3
    plan = FlightPlan(D, 20.0, 5.0, VP)
    r = plan.report
    d, h = plan.d, plan.h
    assert r["top_m"] == VP.cruise_alt_m and h.max() == pytest.approx(VP.cruise_alt_m)
    roll = (VP.rotate_mps**2 - VP.taxi_mps**2) / (2 * VP.accel_mps2)
    assert r["lift_off_m"] == pytest.approx(VP.taxi_m + roll)
    # on the runway until lift-off and after touchdown, never below it
    assert np.all(h[d <= r["lift_off_m"]] == 20.0) and np.all(h[d >= r["touchdown_m"]] == 5.0)
    assert h.min() >= 5.0
    g, g2 = _slope(plan)
    w = r["transitions_m"]
    # climb at climb_rate_mps at the capped speed, descent on the 3 deg path, level cruise
    climb = (d > r["lift_off_m"] + w[0]) & (d < r["top_of_climb_m"] - w[1] / 2)
    np.testing.assert_allclose(g[climb] * plan.v_cap[climb], VP.climb_rate_mps, rtol=2e-3)
    desc = (d > r["top_of_descent_m"] + w[2] / 2) & (d < r["touchdown_m"] - w[3] - 100.0)
    np.testing.assert_allclose(g[desc], -math.tan(VP.descent_angle_rad), rtol=1e-6)
    cruise = (d > r["top_of_climb_m"] + w[1] / 2) & (d < r["top_of_descent_m"] - w[2] / 2)
    assert np.abs(g[cruise]).max() < 1e-8
    # vertical acceleration of the path flown at the cap within the bound
    inner = slice(2, -2)
    assert np.max(np.abs(g2 * plan.v_cap**2)[inner]) <= 1.02 * VP.vertical_accel_mps2
    # speeds: taxi at the ends, cruise in the middle, a continuous cap in flight
    assert plan.v_cap[0] == VP.taxi_mps and plan.v_cap[-1] == VP.taxi_mps
    assert plan.cap(D / 2) == pytest.approx(VP.cruise_mps)
    air = (d > r["lift_off_m"] + 100) & (d < r["touchdown_m"])
    assert np.abs(np.diff(plan.v_cap[air])).max() < 0.1


def test_short_flight_levels_off_below_cruise_and_a_hop_is_taxied():
    plan = FlightPlan(150e3, 0.0, 0.0, VP)
    r = plan.report
    assert 1000.0 < r["top_m"] < VP.cruise_alt_m
    # the highest level that fits: 1 % higher would not
    higher = FlightPlan(150e3, 0.0, 0.0, vehicle_params("airliner", {"cruise_alt_m": 1e5}))
    assert higher.report["top_m"] == pytest.approx(r["top_m"], rel=0.01)
    assert r["top_of_climb_m"] <= r["top_of_descent_m"]
    for D in (15e3, 20e3, 40e3):  # short hops: the transitions never overlap nor undershoot
        p = FlightPlan(D, 0.0, 0.0, VP)
        assert p.report["top_m"] > VP.airborne_height_m and p.h.min() >= 0.0
        assert p.h.max() == pytest.approx(p.report["top_m"], abs=1e-6)
    hop = FlightPlan(6e3, 0.0, 0.0, VP)
    assert hop.report["top_m"] is None and np.all(hop.v_cap == VP.taxi_mps)


def _check_truth(tr, meta, vp, origin):
    rep = meta["plausibility"]
    assert rep["warnings"] == []
    t = tr[col.TIME].to_numpy()
    v = tr[list(col.VEL)].to_numpy()
    speed = np.linalg.norm(v, axis=1)
    assert speed.max() <= vp.cruise_mps * (1 + 1e-3)
    frame = ea.OriginFrame.from_deg(*origin, model=meta["earth"])
    p = tr[list(col.POS)].to_numpy()
    lat, lon, h = frame.geodetic_from_n(p)
    # heights from the plan: cruise level reached, climb rate and bank within the class
    plan = meta["timing"]["flight"]
    assert plan["heights"] == "flight plan"
    assert h.max() == pytest.approx(plan["top_m"], abs=1.0)
    rate = np.diff(h) / np.diff(t)
    assert rate.max() <= vp.climb_rate_mps * 1.01
    assert rate.min() >= -speed.max() * math.sin(vp.descent_angle_rad) * 1.01
    assert rep["max_abs_roll_airborne_deg"] <= math.degrees(math.atan(vp.lat_accel_mps2 / 9.78))
    # coordinated flight: pitch is the flight-path angle, steepest just after rotation
    assert rep["max_abs_pitch_airborne_deg"] <= math.degrees(
        math.atan(vp.climb_rate_mps / vp.rotate_mps)
    ) * (1 + 1e-3)
    assert rep["max_abs_roll_deg"] == 0.0 or rep["max_abs_roll_deg"] < 1e-6
    assert rep["max_accel_mps2"] <= math.hypot(vp.accel_mps2, vp.lat_accel_mps2) * 1.02
    assert rep["time_airborne_s"] > 0.8 * (t[-1] - t[0])
    # taxiing (at most taxi speed, on the runway's height) the airliner is level: the rotation
    # and the flare belong to the take-off and the landing (a 5 deg nose-up on the final taxi
    # of the 7,600 km route: the height profile lost the ends' level, GRADE_BIN_RATIO)
    taxi = (speed <= vp.taxi_mps * (1 + 1e-3)) & (
        np.minimum(np.abs(h - h[0]), np.abs(h - h[-1])) < 1.0
    )
    assert taxi[:5].all() and taxi[-5:].all()
    assert np.abs(tr[col.EULER[1]].to_numpy()[taxi]).max() < 1e-3
    return lat, lon, h


def test_height_profile_keeps_a_long_flights_taxi_level():
    """Oracle: a level taxi at both ends of a 400 km flight (0.1 s samples: 0.5 m apart
    taxiing, 24 m at cruise) keeps its level and zero grade in the height profile (the
    penalty's conditioning at bins 48x denser than the median lost it: 0.8 m, grade 0.03)."""
    from imugen.truth.fit import fit_height_profile

    taxi = np.arange(0.0, 2000.0, 0.5)
    s = np.r_[taxi, np.arange(2000.0, 402000.0, 24.0), 402000.0 + taxi]
    x = np.clip(np.minimum(s - 2000.0, 402000.0 - s) / 150e3, 0.0, 1.0)
    h = 10000.0 * x**3 * (10.0 - 15.0 * x + 6.0 * x * x)
    H, _ = fit_height_profile(s, h, 0.0, 0.5, 50.0, 1e-3)
    ends = np.r_[np.linspace(0.0, 1500.0, 301), np.linspace(s[-1] - 1500.0, s[-1], 301)]
    assert np.abs(H(ends)).max() < 0.01
    assert np.abs(H.derivative()(ends)).max() < 1e-4


def test_429_km_flight_at_6800_m_is_plausible():
    lat, lon = _legs(45.63, 8.72, [(120.0, 200e3), (150.0, 229e3)])
    df, meta = _route(lat, lon, 100.0)
    params = {"cruise_alt_m": 6800.0, "cruise_mps": 770 / 3.6}
    tr, tm = build_truth(
        df, meta, rate_hz=2.0, earth="auto", vehicle="airliner", vehicle_params=params,
        verbose=False,
    )  # fmt: skip
    assert tm["earth"] == "geodetic"  # 429 km: what auto simulates it in
    vp = vehicle_params("airliner", params)
    *_, h = _check_truth(tr, tm, vp, (lat[0], lon[0], 100.0))
    assert tm["timing"]["flight"]["top_m"] == 6800.0
    assert h.min() >= 100.0 - 1e-3  # never below the runways
    rep = tm["plausibility"]
    tight = replace(
        vp,
        max_pitch_airborne_rad=math.radians(rep["max_abs_pitch_airborne_deg"] - 0.1),
        max_yaw_rate_airborne_radps=math.radians(rep["max_yaw_rate_airborne_dps"] - 0.01),
    )
    assert [w.split(" reaches")[0] for w in _warnings(rep, tight)] == [
        "|pitch| in flight",
        "turn rate in flight",
    ]
    # flown at the phases' speed caps except while accelerating: the time along the plan at
    # its caps is a lower bound, exceeded by little
    plan = FlightPlan(tm["timing"]["flight"]["length_m"], 100.0, 100.0, vp)
    t_cap = float(np.sum(np.diff(plan.d) / (0.5 * (plan.v_cap[1:] + plan.v_cap[:-1]))))
    assert t_cap <= tm["duration_s"] <= 1.03 * t_cap


def test_7600_km_flight_across_the_antimeridian_is_plausible():
    lat, lon = [35.76, 52.0, 49.19], [140.39, 179.5, -123.18]
    df, meta = _route(lat, lon)
    tr, tm = build_truth(df, meta, rate_hz=1.0, earth="auto", vehicle="airliner", verbose=False)
    assert tm["earth"] == "geodetic"
    la, lo, _ = _check_truth(tr, tm, VP, (lat[0], lon[0], 0.0))
    assert tm["timing"]["flight"]["top_m"] == VP.cruise_alt_m
    # continuous across the antimeridian: steps on the ground no longer than the speed allows
    _, _, step = GEOD.inv(
        np.degrees(lo[:-1]), np.degrees(la[:-1]), np.degrees(lo[1:]), np.degrees(la[1:])
    )
    assert (np.abs(np.diff(np.degrees(lo))) > 180).sum() == 1
    assert step.max() <= VP.cruise_mps * 1.01
    assert tm["duration_s"] == pytest.approx(7_527e3 / VP.cruise_mps, rel=0.1)


def test_route_with_heights_keeps_them_and_other_classes_have_no_phases():
    lat, lon = _legs(45.63, 8.72, [(120.0, 60e3)])
    la, lo, _, _ = densify(np.array(lat), np.array(lon), np.zeros(2))
    from imugen.truth.fit import fit_path
    from imugen.truth.flight import flight_geometry

    o = (lat[0], lon[0], 0.0)
    alt = np.linspace(0.0, 3000.0, len(la))
    y = LocalFrame(Origin(*o)).to_enu(la, lo, alt)
    G, L, _ = fit_path(y, VP)
    G2, L2, cap, rep = flight_geometry(G, L, o, alt, VP)
    assert G2 is G and L2 == L and rep["heights"] == "route's own"
    assert cap(0.0) == VP.taxi_mps
    assert not any(VEHICLES[v].phases for v in ("car", "bicycle", "pedestrian", "aircraft"))


def test_speed_profile_follows_the_phase_caps():
    """Under each cap but for the jerk filter's rounding of the profile's corners: its
    triangular kernel of half-width Tf lifts the end of a braking at ``accel`` by at most
    ``accel Tf / 6`` (the mean of the kernel's positive half); time within 3 % of the time
    at the caps."""
    from scipy.interpolate import make_interp_spline

    from imugen.truth.profile import speed_profile

    D = 150e3
    s = np.linspace(0.0, D, 1001)
    G = make_interp_spline(s, np.column_stack([s, 0 * s, 0 * s]), k=5)
    plan = FlightPlan(D, 0.0, 0.0, VP)
    pp, rep = speed_profile(
        G, D, cruise_mps=VP.cruise_mps, accel_mps2=VP.accel_mps2,
        lat_accel_mps2=VP.lat_accel_mps2, jerk_mps3=VP.jerk_mps3, vmax_mps=plan.cap,
    )  # fmt: skip
    t = np.linspace(0.0, pp.x[-1], 200_001)
    v = pp.derivative()(t)
    excess = v - plan.cap(pp(t))
    bound = VP.accel_mps2 * rep["filter_width_s"] / 6.0
    assert 0.5 * bound < excess.max() <= bound + 1e-6
    assert float(pp(pp.x[-1])) == pytest.approx(D) and abs(v[0]) + abs(v[-1]) < 1e-9
    t_cap = float(np.sum(np.diff(plan.d) / (0.5 * (plan.v_cap[1:] + plan.v_cap[:-1]))))
    assert t_cap <= pp.x[-1] <= 1.03 * t_cap
