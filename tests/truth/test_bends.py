"""Untimed ground paths take their bends within the vehicle's least turning radius (issue 27):
the fit widens a bend tighter than ``1 / max_curvature_1pm`` (:func:`imugen.truth.fit.fit_path`),
the speed profile slows the vehicle for it, and the body follows the path without sliding
sideways; the gate refuses the slip of a bend no car can take (legs closer than its turning
diameter)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from imugen import truth
from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.truth import fit as tfit
from imugen.truth import stage
from imugen.truth.options import TruthOptions
from imugen.truth.profile import curvature

ORIGIN = (46.5, 7.5, 800.0)
CAR = truth.VEHICLES["car"]
R_MIN = 1.0 / CAR.max_curvature_1pm  # 5 m


def _corner(turn_deg, leg=200.0):
    """Two legs meeting at one vertex, the direction turning by ``turn_deg``."""
    a = np.radians(turn_deg)
    return np.array([[0, 0, 0], [leg, 0, 0], [leg + leg * np.cos(a), leg * np.sin(a), 0]], float)


def _hairpin(gap=20.0, leg=200.0):
    """A mountain road's hairpin: out and back on legs ``gap`` apart, the bend drawn with one
    apex vertex (two 135 deg corners)."""
    return np.array(
        [[0, 0, 0], [leg, 0, 0], [leg + gap / 2, gap / 2, 0], [leg, gap, 0], [0, gap, 0]], float
    )


def _off_polyline(P, y):
    """Distance [m] of each point P (M, 2+) to the polyline y (N, 2+), horizontally."""
    P, y = P[:, :2], y[:, :2]
    best = np.full(len(P), np.inf)
    for a, b in itertools.pairwise(y):
        d = b - a
        w = np.clip((P - a) @ d / (d @ d), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(P - (a + w[:, None] * d), axis=1))
    return best


def _truth(y, vehicle="car"):
    df, meta = truth.enu_table(y, None, ORIGIN)
    return truth.build_truth(df, meta, rate_hz=10, vehicle=vehicle, earth="wgs84", verbose=False)


@pytest.mark.parametrize(
    ("name", "y", "within"),
    [
        ("right angle", _corner(90.0), 1.0 * R_MIN),
        ("hairpin", _hairpin(20.0), 1.0 * R_MIN),
        ("140 deg corner", _corner(140.0), 2.0 * R_MIN),
    ],
)
def test_bends_are_taken_within_the_turning_radius_without_slip(name, y, within):
    G, L, _ = tfit.fit_path(y, CAR)
    s = np.linspace(0.0, L, 40_001)
    # the geometry turns no tighter than the car can (with the fit's margin) ...
    assert curvature(G, s).max() <= CAR.max_curvature_1pm, name
    # ... and stays within the stated distance of the input polyline
    assert _off_polyline(G(s), y).max() <= within, name
    _, meta = _truth(y)
    p = meta["plausibility"]
    assert meta["gate"] == [], (name, meta["gate"])  # slip gated on untimed ground paths
    assert p["max_body_lateral_speed_mps"] < 0.05 * CAR.max_slip_mps, name
    assert p["max_yaw_rate_excess_dps"] < 1e-6


def test_without_the_bound_the_acute_corner_slides(monkeypatch):
    """The same 140 deg corner with the curvature bound off: the corner rounding alone leaves a
    bend of ~1 m radius, the heading cannot follow it, and the body slides (the gate says so)."""
    monkeypatch.setattr(tfit, "CURVATURE_ITERATIONS", 0)
    monkeypatch.setattr(tfit, "CORNER_ROUNDS", 0)  # no constructed corner either
    _, meta = _truth(_corner(140.0))
    assert meta["plausibility"]["max_body_lateral_speed_mps"] > CAR.max_slip_mps
    assert "slip (body lateral speed)" in [g["limit"] for g in meta["gate"]]


def test_hairpin_left_tight_is_refused(tmp_path, monkeypatch):
    """Legs 8 m apart without the constructed corners (:mod:`imugen.truth.corners`, which
    swing out there, ``tests/truth/test_corners.py``): the curvature bound alone cannot widen
    the bend within its cap; it is left as drawn and the gate refuses the slide in one line."""
    monkeypatch.setattr(tfit, "CORNER_ROUNDS", 0)
    y = _hairpin(8.0)
    rep = tfit.fit_path(y, CAR)[2]
    assert rep["curvature_bound"]["bends_left"] >= 1
    df, meta = truth.enu_table(y, None, ORIGIN)
    src = tmp_path / "hairpin_enu.parquet"
    write_parquet(df, meta, src)
    out = tmp_path / "truth.parquet"
    with pytest.raises(InputError) as exc:
        stage.run(src, out, TruthOptions(rate_hz=10, earth="wgs84", vehicle="car"))
    msg = str(exc.value)
    assert not out.exists() and "\n" not in msg
    assert "slip (body lateral speed)" in msg and "beyond the car limit 0.5 m/s" in msg
