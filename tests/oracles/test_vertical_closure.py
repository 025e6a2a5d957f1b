"""Zero-error closure over hours with the damped vertical channel (issue 27): the 264 km road
stand-in of tests/oracles/test_long_routes.py (10,560 s, ``geodetic``), whole route from one
initial state. Free, the vertical channel grows as exp(t / 570 s) to kilometres; damped by the
true height it closes to the truth's consistency."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imugen.closure import closure_of_truth
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
