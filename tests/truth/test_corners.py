"""Constructed corners of untimed ground paths (issue 27, :mod:`imugen.truth.corners`).

Oracles: the fillet's closed forms (its tangent length and its largest distance from the legs,
``(R + p) - R cos(delta / 2)``, the middle of its arc), the curvature bound and the clothoids'
rate of curvature, the distance of the fitted path from the drawn polyline, and a truth whose
body does not slide sideways (heading along the velocity) and that passes the gate.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from imugen import truth
from imugen.truth import corners as cn
from imugen.truth import fit as tfit
from imugen.truth.profile import curvature

from .test_bends import _corner, _hairpin, _off_polyline, _truth

CAR = truth.VEHICLES["car"]
R = cn.fillet_radius_m(CAR.max_curvature_1pm)  # 6.25 m
#: steepest rate of curvature [1/m^2] of a constructed corner, its clothoids' (one radius
#: long), with half as much again for the spline joining the smoothed legs to it
DKDS_MAX = 1.5 / (cn.SPIRAL_RADII * R * R)
RALLY = (
    Path(__file__).resolve().parents[2]
    / ".."
    / "shared"
    / "data"
    / "trajectories"
    / "a_sparkfun_rally_course_ge_pro.kml"
)


@pytest.mark.parametrize("turn_deg", [30.0, 90.0, 140.0])
def test_fillet_is_tangent_to_both_legs_with_continuous_bounded_curvature(turn_deg):
    delta = math.radians(turn_deg)
    v = np.array([10.0, -3.0])
    P, k = cn.fillet(v, 0.3, delta, R, 0.001 * R)
    T, p, E, d_leg = cn.fillet_offsets(delta, R)
    d_in = np.array([math.cos(0.3), math.sin(0.3)])
    d_out = np.array([math.cos(0.3 + delta), math.sin(0.3 + delta)])
    # ends on the legs, a tangent length from the vertex, heading along them
    assert np.linalg.norm(P[0] - (v - T * d_in)) < 1e-6 * R
    assert np.linalg.norm(P[-1] - (v + T * d_out)) < 1e-6 * R
    h = np.diff(P, axis=0)
    h /= np.linalg.norm(h, axis=1)[:, None]
    assert abs(h[0] @ d_in - 1.0) < 1e-4 and abs(h[-1] @ d_out - 1.0) < 1e-4
    # curvature: at most 1/R, zero at both ends, changing by the clothoid's rate at most
    ds = np.linalg.norm(np.diff(P, axis=0), axis=1)
    assert np.abs(k).max() <= 1.0 / R + 1e-12 and k[0] == 0.0 and k[-1] == 0.0
    ls = cn.SPIRAL_RADII * R
    assert np.max(np.abs(np.diff(k)) / ds) <= 1.0 / (R * ls) * (1.0 + 1e-3)  # ds: chords
    # closed forms: the points within E of the vertex, the arc's middle farthest from the legs
    assert np.linalg.norm(P - v, axis=1).min() == pytest.approx(E, abs=1e-3 * R)
    legs = np.array([v - 100.0 * d_in, v, v + 100.0 * d_out])
    assert _off_polyline(P, legs).max() == pytest.approx(d_leg, abs=1e-3 * R)
    r_peak = 1.0 / np.abs(k).max()  # R, or R / delta below 1 rad
    assert p == pytest.approx(ls * ls / (24.0 * r_peak), rel=0.02)


def _bounds(name, y):
    """The stated largest distance [m] of the fitted path from the polyline ``y``."""
    if name == "right angle":  # the corner rounding follows it (no construction): 1 radius
        return 1.0 / CAR.max_curvature_1pm
    if name == "140 deg corner":  # a fillet: the middle of its arc from the legs
        return cn.fillet_offsets(math.radians(140.0), R)[3] + 0.02 * R
    gap = float(y[-1, 1])
    if name.startswith("hairpin"):  # inside the box of the legs' ends and the apex
        return gap / (2.0 * math.sqrt(2.0)) + 0.02 * R
    return R - 0.5 * gap + 0.02 * R  # a bulb swings out by R - gap / 2 beyond the legs


CASES = [
    ("right angle", _corner(90.0)),
    ("140 deg corner", _corner(140.0)),
    ("hairpin 16 m", _hairpin(16.0)),
    ("hairpin 60 m", _hairpin(60.0)),
    ("bulb 8 m", _hairpin(8.0)),
]


@pytest.mark.parametrize(("name", "y"), CASES, ids=[c[0] for c in CASES])
def test_tight_bends_are_built_within_the_turning_radius(name, y):
    G, L, rep = tfit.fit_path(y, CAR)
    s = np.linspace(0.0, L, 40_001)
    k = curvature(G, s)
    # within the class limit (the construction's margin, and the fit's bound over it) ...
    assert k.max() <= tfit.CURVATURE_MARGIN * CAR.max_curvature_1pm, name
    # ... continuous: changing no faster than the steepest clothoid allows
    assert np.max(np.abs(np.diff(k)) / np.diff(s)) <= DKDS_MAX, name
    # ... within the stated distance of the drawn polyline, and as long as it (or the bulb's
    # swing out longer)
    P = G(s)
    assert _off_polyline(P, y).max() <= _bounds(name, y), name
    assert 0.9 < L / np.linalg.norm(np.diff(y, axis=0), axis=1).sum() < 1.05, name
    built = rep.get("corners", {})
    if name.startswith("hairpin 16"):
        assert built["hairpin"] == 1
        assert P[:, 0].max() >= y[:, 0].max() - 0.02 * R  # reaches the drawn apex
    if name.startswith("bulb"):
        assert built["bulb"] == 1
        assert P[:, 1].min() < -0.5  # swings out beyond the entry leg
    if name == "140 deg corner":
        assert built["fillet"] == 1
    assert "curvature_bound" not in rep or rep["curvature_bound"]["bends_left"] == 0
    _, meta = _truth(y)
    p = meta["plausibility"]
    assert meta["gate"] == [], (name, meta["gate"])
    assert p["max_body_lateral_speed_mps"] < 0.01, name


@pytest.mark.skipif(not RALLY.is_file(), reason="needs ../shared")
def test_rally_hairpin_is_rounded_not_cut():
    """The shared rally course's 16 m hairpin (legs 16 m apart, ~180 deg): built as a hairpin,
    the path as long as the course (it was half of it when the curvature bound alone smoothed
    the hairpin away) and no slide."""
    from imugen.ingest.stage import ingest

    ing = ingest(RALLY)
    y = ing.table[["e_m", "n_m", "u_m"]].to_numpy()
    _, L, rep = tfit.fit_path(y, CAR)
    assert rep["corners"]["hairpin"] >= 1
    assert L / np.linalg.norm(np.diff(y, axis=0), axis=1).sum() > 0.9
    assert rep["max_distance_m"] < 2.0 * R
    _, meta = truth.build_truth(
        ing.table, ing.meta, rate_hz=10, earth="wgs84", vehicle="car", verbose=False
    )
    assert meta["gate"] == []
    assert meta["plausibility"]["max_body_lateral_speed_mps"] < 0.05 * CAR.max_slip_mps
