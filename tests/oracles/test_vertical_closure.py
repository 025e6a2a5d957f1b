"""Zero-error closure over hours with the damped vertical channel (issue 27): the 264 km road
stand-in of tests/oracles/test_long_routes.py (10,560 s, ``geodetic``), whole route from one
initial state. Free, the vertical channel grows as exp(t / 570 s) to kilometres; damped by the
true height it closes to the truth's consistency. And a truth synthesized by the truth stage
(a 70 km untimed drive, 5,051 s): within 1e-6 m at 10 Hz, and its start from rest (snap
steps every 0.02 s) mechanized with the gravitation nodes as with the exact gravitation every
step (the full routes' figures: docs/explanation/vertical-channel.md)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from imugen.closure import closure_of_truth
from imugen.core import earth
from imugen.navigate import mechanize as M
from imugen.tables import truth as col

from oracles.strapdown import exact_increments
from oracles.test_long_routes import GEO, road_264km, truth

RATE_HZ = 10.0


@pytest.fixture(scope="module")
def road_truth():
    rt = road_264km()
    dt = 1.0 / RATE_HZ
    t, r, v, q = truth(rt, dt)
    dth, dv = exact_increments(t, rt.position, rt.velocity, rt.attitude, GEO)
    df = pd.DataFrame({col.TIME: t})
    for names, x in ((col.POS, r), (col.VEL, v), (col.QUAT, q)):
        for j, c in enumerate(names):
            df[c] = x[:, j]
    for names, x in ((col.DTHETA, dth), (col.DV, dv)):
        for j, c in enumerate(names):
            df[c] = np.concatenate([[0.0], x[:, j]])
    meta = {"origin": {"lat_deg": 0.0, "lon_deg": 0.0, "alt_m": 0.0}, "earth": "geodetic",
            "rate_hz": RATE_HZ}  # fmt: skip
    return df, meta


def test_damped_closure_of_a_long_road(road_truth):
    df, meta = road_truth
    res = closure_of_truth(df, meta)  # auto: damped (10,560 s > 3 x 570 s)
    vc, free = res["vertical_channel"], res["free"]
    print(f"damped: H {res['horizontal_final_m']:.2e} (max {res['horizontal_max_m']:.2e}) m, "
          f"V {res['vertical_final_m']:.2e} (max {res['vertical_max_m']:.2e}) m; free expected "
          f"V {free['expected_vertical_m']:.3g} m, H {free['expected_horizontal_m']:.3g} m "
          f"(seed {free['seed_vertical_m']:.2e} m at {free['seed_time_s']:.0f} s)")  # fmt: skip
    assert vc["mode"] == "damped" and vc["requested"] == "auto"
    assert vc["growth_time_s"] == pytest.approx(569.5, abs=1.5)
    assert res["horizontal_max_m"] <= 1e-6
    assert res["vertical_max_m"] <= 1e-6
    assert res["max_attitude_error_rad"] <= 1e-9
    assert res["final_position_error_m"] == pytest.approx(
        np.hypot(res["horizontal_final_m"], res["vertical_final_m"]), rel=1e-6
    )
    # free, the same seed grows x1e6 by the end (0.17 m here: this truth is consistent to
    # 3e-8 m; a fitted route's seed of 1e-7 m reaches 1e10 m over 5 h)
    assert free["expected_vertical_m"] > 1e6 * res["vertical_final_m"]


def test_free_channel_expected_growth_matches_a_free_run(road_truth):
    """The linearized growth from the 1,710 s seed predicts the free run at 6,000 s (x2,000,
    still linear) within 10 %."""
    df, meta = road_truth
    n = round(6000.0 * RATE_HZ) + 1
    res = closure_of_truth(df.iloc[:n], meta, vertical="free")
    free = res["free"]
    print(f"free at 6,000 s: V {res['vertical_final_m']:.3e} m, expected "
          f"{free['expected_vertical_m']:.3e} m; H {res['horizontal_final_m']:.3e} m, expected "
          f"{free['expected_horizontal_m']:.3e} m")  # fmt: skip
    assert res["vertical_channel"]["mode"] == "free"
    assert res["vertical_final_m"] == pytest.approx(free["expected_vertical_m"], rel=0.1)
    assert res["vertical_final_m"] > 30 * free["seed_vertical_m"]


def _drive(legs):
    """An untimed car route without time stamps (geodesic legs ``(azimuth deg, metres)`` from
    44.9 N 9.6 E at 60 m), as ingestion writes it, and its truth builder."""
    from pyproj import Geod

    from imugen.core.frames import LocalFrame, Origin
    from imugen.core.geodesic import densify

    geod = Geod(ellps="WGS84")
    lat, lon = [44.9], [9.6]
    for az, d in legs:
        x, y, _ = geod.fwd(lon[-1], lat[-1], az, d)
        lat.append(y)
        lon.append(x)
    la, lo, al, _ = densify(np.asarray(lat), np.asarray(lon), np.full(len(lat), 60.0))
    o = Origin(float(la[0]), float(lo[0]), float(al[0]))
    enu = LocalFrame(o).to_enu(la, lo, al)
    df = pd.DataFrame(
        dict(lat_deg=la, lon_deg=lo, alt_m=al, e_m=enu[:, 0], n_m=enu[:, 1], u_m=enu[:, 2])
    )
    return df, {"origin": o.as_dict(), "timed": False, "source": "test"}


def test_synthesized_long_drive_closes_within_a_micrometre_at_10_hz():
    """A 70 km drive through the truth stage (5,051 s, four bends, ``geodetic``) at 10 Hz:
    ``auto`` damps it; horizontal closure 8.3e-7 m (the 10 Hz position rule's residue of the
    start from rest), vertical 1.5e-9 m."""
    from imugen.truth import build_truth

    df, meta = _drive([(110, 15e3), (95, 20e3), (120, 15e3), (100, 20e3)])
    tr, tm = build_truth(df, meta, rate_hz=10.0, earth="geodetic", vehicle="car", verbose=False)
    res = closure_of_truth(tr, tm)
    print(f"70 km drive at 10 Hz: H {res['horizontal_final_m']:.2e} m, "
          f"V {res['vertical_final_m']:.2e} m over {tm['duration_s']:.0f} s")  # fmt: skip
    assert tm["duration_s"] > 2.5 * 1708.0
    assert res["vertical_channel"]["mode"] == "damped"
    assert res["horizontal_final_m"] <= 1e-6
    assert res["vertical_final_m"] <= 1e-6
    assert res["max_attitude_error_rad"] <= 1e-9


def test_start_from_rest_with_nodes_as_with_exact_gravitation():
    """A synthesized car's start from rest at 50 Hz, 300 s free: the kernel with its
    gravitation nodes leaves a velocity within 2e-11 m/s of the exact gravitation every step
    (a Schuler swing of 1.6e-8 m, 1.6 % of the closure bound; nodes every 0.4 s left 1.6e-10
    here and 3.3e-9 m/s on the 264 km road: a 2e-6 m swing)."""
    from imugen.truth import build_truth

    df, meta = _drive([(110, 6e3)])
    rate = 50.0
    tr, tm = build_truth(df, meta, rate_hz=rate, earth="geodetic", vehicle="car", verbose=False)
    frame = col.origin_frame(tm)
    K = int(300.0 * rate) + 1
    P, V, Q = (tr[list(c)].to_numpy()[:K] for c in (col.POS, col.VEL, col.QUAT))
    dth, dv = (tr[list(c)].to_numpy()[1:K] for c in (col.DTHETA, col.DV))
    vel = {}
    for node_s in (M.GRAVITY_NODE_S, 0.0):
        mech = M.Mechanizer(frame, 1.0 / rate, P[0], V[0], Q[0])
        mech.prm = M.kernel_params(frame, 1.0 / rate, node_s)
        mech.run(dth[None], dv[None])
        vel[node_s] = mech.v_n[0]
    dv_end = float(np.linalg.norm(vel[M.GRAVITY_NODE_S] - vel[0.0]))
    swing = dv_end * math.sqrt(earth.R_MEAN / 9.81)
    print(f"start from rest: |v_nodes - v_exact| {dv_end:.2e} m/s (Schuler swing {swing:.1e} m)")
    assert dv_end <= 2e-11
