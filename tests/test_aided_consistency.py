"""Aided filter tuned from the grade's full error model: Monte-Carlo NEES inside chi-square
bounds with every configured error term on (scale factor, cross-coupling, g-sensitivity,
quantization beside the biases and noises), car scene with four turns and a 30 s GNSS outage.

Oracle: the mean over runs and epochs of NEES / dof of position, attitude and the bias states
(truth: the labelled slow bias plus the static error on gravity ``(G + E) (0, 0, g0)``) lies
between 0.5 (not grossly conservative) and the 99.5 % chi-square quantile of ``d M`` dof / ``d M``
(the bound of one epoch's Monte-Carlo mean; the time average is tighter).
"""

import sys
from pathlib import Path

import pytest
from scipy.stats import chi2

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_aided_nees as B

M = 20


@pytest.fixture(scope="module")
def scene():
    return B.scene()


_TILT = pytest.mark.xfail(
    strict=True,
    reason="gyro cross-coupling across a turn: a body-fixed tilt the filter takes for an "
    "accelerometer bias (tilt and bias NEES 5-11; README, aided baseline)",
)


@pytest.fixture(scope="module")
def results(scene):
    return {}


def _run(scene, results, grade):
    if grade not in results:
        results[grade] = B.run_grade(scene, grade, M)
    return results[grade]


@pytest.mark.parametrize("grade", ["consumer", "industrial", "tactical"])
def test_position_nees_all_terms(scene, results, grade):
    r = _run(scene, results, grade)
    hi = chi2.ppf(0.995, 3 * M) / (3 * M)
    assert 0.5 < r["nees_pos"] < hi, r


@pytest.mark.parametrize(
    "grade", [pytest.param("consumer", marks=_TILT), pytest.param("industrial", marks=_TILT),
              "tactical"],
)  # fmt: skip
def test_attitude_and_bias_nees_all_terms(scene, results, grade):
    r = _run(scene, results, grade)
    for name, d in (("att", 3), ("bias", 6)):
        hi = chi2.ppf(0.995, d * M) / (d * M)
        assert 0.5 < r[f"nees_{name}"] < hi, (name, r)
