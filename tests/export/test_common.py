"""The exports' shared label arithmetic (src/imugen/export/common.py)."""

import math

import pytest


def test_noise_figures_count_every_gauss_markov_the_slow_bias_too():
    """Kalibr's random walk from a sequence's labels: sqrt(RRW^2 + sum 2 sigma^2 / T) over the
    bias instability's components and the grade's second, slow one."""
    from imugen.export.common import gm_components, noise_figures

    lab = {"gyro_rate_random_walk_{a}_radps_per_sqrt_s": 1e-5,
           "gyro_bias_instability_tau0_s": 10.0, "gyro_bias_instability_sigma0_{a}_radps": 1e-4,
           "gyro_slow_bias_tau_s": 150.0, "gyro_slow_bias_sigma_{a}_radps": 2e-4}  # fmt: skip
    labels = {k.format(a=a): v for k, v in lab.items() for a in "xyz"}
    assert gm_components(labels, "gyro") == [
        ("bias_instability_tau0_s", "bias_instability_sigma0"),
        ("slow_bias_tau_s", "slow_bias_sigma"),
    ]
    want = math.sqrt(1e-10 + 2 * 1e-8 / 10.0 + 2 * 4e-8 / 150.0)
    assert noise_figures(labels)["gyroscope_random_walk"] == pytest.approx(want, rel=1e-12)
    assert gm_components(labels, "accel") == []
