"""The labels name apart the static terms a still sensor reads (issue 24)."""

import numpy as np
import pytest

from imugen.simulate.stage import simulate

STATIC = ["turn_on_bias", "scale_factor", "cross_coupling", "g_sensitivity"]


@pytest.mark.parametrize("grade", ["consumer", "consumer_calibrated", "phone"])
def test_bias_at_rest_is_what_a_still_level_sensor_reads(grade):
    sh = simulate(None, grade, sequences=6, seed=2, static_s=1.0, rate_hz=10.0,
                  outputs="rates", terms=STATIC)  # fmt: skip
    ideal = simulate(None, grade, sequences=1, seed=2, static_s=1.0, rate_hz=10.0,
                     outputs="rates", terms=[])  # fmt: skip
    L = sh.labels
    for s, u in (("gyro", "radps"), ("accel", "mps2")):
        read = sh.data[s].mean(axis=1) - ideal.data[s][0].mean(axis=0)  # (S, 3)
        rest = L[[f"{s}_bias_at_rest_{a}_{u}" for a in "xyz"]].to_numpy()
        on = L[[f"{s}_turn_on_bias_{a}_{u}" for a in "xyz"]].to_numpy()
        grav = "gyro_g_sensitivity_gravity" if s == "gyro" else "accel_scale_factor_gravity"
        g = L[[f"{grav}_{a}_{u}" for a in "xyz"]].to_numpy()
        assert np.allclose(rest, on + g)
        # left out of the labels: the errors on the Earth rate (gyro, E omega_ie ~ 5 % x
        # 7.3e-5 rad/s) and on local gravity's difference from g0 (accel, ~ 5 % x 0.01 m/s^2)
        other = 4e-6 if s == "gyro" else 5e-4
        assert np.allclose(read, rest, rtol=3e-3, atol=other), (s, read, rest)
    if grade == "consumer_calibrated":  # the residual of a calibration at rest is small
        r = L[[f"gyro_bias_at_rest_{a}_radps" for a in "xyz"]].to_numpy()
        o = L[[f"gyro_turn_on_bias_{a}_radps" for a in "xyz"]].to_numpy()
        assert np.sqrt(np.mean(r**2)) < 0.1 * np.sqrt(np.mean(o**2))
