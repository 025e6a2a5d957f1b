"""Timed ground routes keep within the vehicle's least turning radius (issue 27,
:mod:`imugen.truth.timed_bends`): the body follows its velocity, so the gate holds their slip.

Oracles: a car's hairpin logged every 5 s (the fit, slowing at the apex between fixes, turns
1.6 times as tight as a car can) is driven within the radius with no sideways slide and moved by
less than 3 noise sigmas, while without the refit the gate refuses its slip; a corner of
5 m radius at 15 m/s is refused in one line naming the place and the limit.
"""

from __future__ import annotations

import numpy as np
import pytest

from imugen import truth
from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.tables import truth as col
from imugen.truth import build as tbuild
from imugen.truth import stage
from imugen.truth.fit import fit_timed
from imugen.truth.options import TruthOptions
from imugen.truth.timed_bends import _curvature

ORIGIN = (39.6, -105.8, 3000.0)
NOISE_M = 0.5


def _route(bends, v_leg, v_bend, dt_fix, noise=NOISE_M, seed=27, leg=80.0, ramp=30.0):
    """A timed car route: ``leg`` m straight legs joined by left bends ``(radius, deg)``,
    driven at ``v_leg`` slowing to ``v_bend`` through each bend (cosine ramps over ``ramp`` m),
    from rest to rest at 1.5 m/s^2; fixes every ``dt_fix`` s with Gaussian noise (seeded).
    Returns (times, noisy ENU fixes, true ENU, bend intervals [s])."""
    ds = 0.01
    pts, th, x = [], 0.0, np.zeros(2)
    marks = []
    s_at = 0.0
    for R, deg in [*bends, (None, 0.0)]:
        n = int(leg / ds)
        pts.append(x + np.outer(np.arange(n) * ds, [np.cos(th), np.sin(th)]))
        x = x + leg * np.array([np.cos(th), np.sin(th)])
        s_at += leg
        if R is None:
            break
        a = np.radians(deg)
        u = np.arange(int(R * a / ds)) * ds / R
        c = x + R * np.array([-np.sin(th), np.cos(th)])
        pts.append(c + R * np.column_stack([np.sin(th + u), -np.cos(th + u)]))
        marks.append((s_at, s_at + R * a))
        s_at += R * a
        x = c + R * np.array([np.sin(th + a), -np.cos(th + a)])
        th += a
    xy = np.vstack(pts)
    s = np.arange(len(xy)) * ds
    v = np.full(len(s), v_leg)
    for s0, s1 in marks:
        d = np.clip((np.maximum(s0 - s, s - s1)) / ramp, 0.0, 1.0)
        v = np.minimum(v, v_bend + (v_leg - v_bend) * 0.5 * (1.0 - np.cos(np.pi * d)))
    v = np.minimum(v, np.sqrt(3.0 * s) + 1e-3)
    v = np.minimum(v, np.sqrt(3.0 * (s[-1] - s)) + 1e-3)
    t = np.r_[0.0, np.cumsum(ds / (0.5 * (v[1:] + v[:-1])))]
    tf = np.arange(0.0, t[-1], dt_fix)
    true = np.column_stack([np.interp(tf, t, xy[:, 0]), np.interp(tf, t, xy[:, 1]), 0 * tf])
    rng = np.random.default_rng(seed)
    enu = true + rng.normal(0.0, 1.0, true.shape) * [noise, noise, 0.3]
    return tf, enu, true, [(np.interp(a, s, t), np.interp(b, s, t)) for a, b in marks]


def _lateral(tr):
    C = rot.quat_to_dcm(tr[list(col.QUAT)].to_numpy())
    return np.einsum("kji,kj->ki", C, tr[list(col.VEL)].to_numpy())[:, 1]


def _hairpin():
    return _route([(7.0, 160.0)], v_leg=8.0, v_bend=2.0, dt_fix=5.0)


def test_sparse_hairpin_is_driven_within_the_turning_radius():
    t, enu, _, _ = _hairpin()
    vp = truth.VEHICLES["car"]
    motion, _ = fit_timed(t, enu, vp)
    tq = np.linspace(t[0], t[-1], 4000)
    k, vh2 = _curvature(motion.spline(tq, 1), motion.spline(tq, 2))
    moving = vh2 > (2.0 * vp.stop_speed_mps) ** 2
    assert k[moving].max() > 1.4 * vp.max_curvature_1pm  # the fit slows and turns tight
    df, meta = truth.enu_table(enu, t, ORIGIN)
    tr, m = truth.build_truth(df, meta, rate_hz=20, earth="flat", vehicle="car", verbose=False)
    bends = m["fit"]["curvature_bound"]
    assert bends["refitted"] == 1 and bends["left"] == 0
    assert bends["max_curvature_ratio"] <= 1.0
    assert bends["max_moved_m"] < 3.0 * NOISE_M  # within the fixes' noise
    assert m["gate"] == []
    assert np.abs(_lateral(tr)).max() < 1e-6  # the body follows its velocity
    # the truth's path within the radius wherever it moves
    v = tr[list(col.VEL)].to_numpy()
    a = np.gradient(v, tr[col.TIME].to_numpy(), axis=0)
    kt, vt2 = _curvature(v, a)
    assert kt[vt2 > 1.0].max() < 1.05 * vp.max_curvature_1pm


def test_without_the_refit_the_hairpin_slides_and_is_refused(monkeypatch):
    t, enu, _, _ = _hairpin()
    monkeypatch.setattr(tbuild, "_bounded_bends", lambda motion, fit, *a: (motion, fit))
    df, meta = truth.enu_table(enu, t, ORIGIN)
    _, m = truth.build_truth(df, meta, rate_hz=20, earth="flat", vehicle="car", verbose=False)
    assert [g["limit"] for g in m["gate"]] == ["slip (body lateral speed)"]
    assert m["gate"][0]["value"] > 0.5


def test_corner_beyond_the_car_is_refused_in_one_line(tmp_path):
    """A 90 deg corner of 5 m radius at 15 m/s (10 Hz fixes): 45 m/s^2 of lateral
    acceleration, beyond what local smoothing within the fixes' noise or the bend's refit
    (its acceleration bound) can take: refused in one line naming the place and the limit."""
    t, enu, _, marks = _route(
        [(5.0, 90.0)], v_leg=15.0, v_bend=15.0, dt_fix=0.1, noise=0.3, leg=120.0, ramp=1.0
    )
    df, meta = truth.enu_table(enu, t, ORIGIN)
    src = tmp_path / "corner_enu.parquet"
    write_parquet(df, meta, src)
    out = tmp_path / "truth.parquet"
    with pytest.raises(InputError) as exc:
        stage.run(src, out, TruthOptions(rate_hz=10, earth="wgs84", vehicle="car"))
    assert not out.exists()
    msg = str(exc.value)
    assert msg.startswith(str(src)) and "\n" not in msg
    assert "not a motion a car makes" in msg and "acceleration" in msg
    assert " N, " in msg and " W, " in msg and "km along the route" in msg
    _, m = truth.build_truth(df, meta, rate_hz=10, earth="wgs84", vehicle="car", verbose=False)
    acc = [g for g in m["gate"] if g["limit"] == "acceleration"]
    ((c0, c1),) = marks
    assert acc and c0 - 1.0 <= acc[0]["t_s"] <= c1 + 1.0  # at the corner
    assert acc[0]["value"] > 1.3 * acc[0]["bound"]
