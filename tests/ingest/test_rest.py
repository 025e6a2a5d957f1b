"""GPS jitter at rest (a parked airliner at the gate) is merged at ingestion (issue 27)."""

from __future__ import annotations

from datetime import datetime

import numpy as np
import pytest

from imugen import truth
from imugen.core.frames import LocalFrame, Origin
from imugen.ingest.clean import K_SIGMA, UNTIMED_NOISE_M, rest_runs
from imugen.ingest.stage import ingest
from imugen.tables import truth as col

ORIGIN = Origin(48.35, 11.78, 450.0)


def _gate_taxi_takeoff(rng, n_park, sigma, taxi_leg, run_leg):
    """ENU (m) of a logger at the gate (``n_park`` fixes of ``sigma`` m horizontal jitter,
    heights jittered by 3 m), then a taxi of 1.2 km north and 0.8 km east (legs of ``taxi_leg``
    m) and a take-off run of 3 km east climbing to 300 m (legs of ``run_leg`` m); returns the
    fixes and the length of the path moved."""
    park = np.column_stack([rng.normal(0, sigma, (n_park, 2)), rng.normal(0, 3.0, n_park)])
    north = np.arange(1, int(1200 / taxi_leg) + 1) * taxi_leg
    east = np.arange(1, int(800 / taxi_leg) + 1) * taxi_leg
    run = np.arange(1, int(3000 / run_leg) + 1) * run_leg
    moved = np.vstack(
        [
            np.column_stack([np.zeros_like(north), north, np.zeros_like(north)]),
            np.column_stack([east, np.full_like(east, 1200.0), np.zeros_like(east)]),
            np.column_stack([800.0 + run, np.full_like(run, 1200.0), 300.0 * (run / 3000) ** 2]),
        ]
    )
    return np.vstack([park, moved]), 1200.0 + 800.0 + 3000.0


def _kml(tmp_path, enu):
    lat, lon, alt = LocalFrame(ORIGIN).to_geodetic(enu)
    coords = " ".join(
        f"{float(b)!r},{float(a)!r},{float(h)!r}" for a, b, h in zip(lat, lon, alt, strict=True)
    )
    f = tmp_path / "flight.kml"
    f.write_text(
        '<kml xmlns="http://www.opengis.net/kml/2.2"><Placemark><name>Flight</name><LineString>'
        f"<altitudeMode>absolute</altitudeMode><coordinates>{coords}</coordinates></LineString>"
        "</Placemark></kml>"
    )
    return f


def test_gate_jitter_after_a_stale_first_fix(tmp_path):
    """A logger's stale first fix (at the path's end) is removed before the jitter is merged;
    the merge works in the frame of the points kept (it once used the removed point's, which
    put the centroid hundreds of kilometres off: 429 -> 1,276 km)."""
    rng = np.random.default_rng(6)
    enu, moved = _gate_taxi_takeoff(rng, 120, 3.0, 40.0, 100.0)
    ing = ingest(_kml(tmp_path, np.vstack([enu[-1:], enu])), vehicle="airliner")
    assert ing.meta["cleaning"]["stale_first_removed"]
    assert ing.meta["cleaning"]["at_rest"]["count"] == 1
    assert moved - 10.0 < ing.meta["length_horizontal_m"] < moved + 30.0


def test_untimed_gate_jitter_is_one_point_and_the_truth_does_not_crawl(tmp_path):
    """Issue 27: the 429 km logger flight's gate jitter (120 fixes within ~10 m) made the
    untimed speed profile crawl at 0.8 m/s for ~1,250 s. The cluster is one point now; the path
    is not lengthened by the jitter and the truth moves purposefully from the gate (before: this
    shape's truth wandered 175 m through the jitter in 47 s to get 100 m from the gate, 10.4 s
    below 1 m/s, and its path was 613 m long; now 101 m, 19 s, 6.6 s: the start from rest)."""
    rng = np.random.default_rng(1)
    enu, moved = _gate_taxi_takeoff(rng, 120, 3.0, 40.0, 100.0)
    f = _kml(tmp_path, enu)
    jitter = float(np.linalg.norm(np.diff(enu[:120, :2], axis=0), axis=1).sum())
    assert jitter > 400.0  # what the raw path adds

    ing = ingest(f, vehicle="airliner")
    rest = ing.meta["cleaning"]["at_rest"]
    assert rest["count"] == 1 and rest["merged_to_one_point"]
    a, b = rest["runs"][0]
    assert a == 1 and 110 <= b <= 121 and rest["radius_m"] == K_SIGMA * UNTIMED_NOISE_M
    assert any("clusters of GPS jitter at rest" in w for w in ing.warnings)
    e, n = ing.table["e_m"].to_numpy(), ing.table["n_m"].to_numpy()
    start = LocalFrame(ORIGIN).to_enu(
        *(ing.table[c].to_numpy()[:1] for c in ("lat_deg", "lon_deg", "alt_m"))
    )
    assert np.hypot(*start[0, :2]) < 1.5  # the gate: the jitter's centroid (3 m / sqrt(120))
    length = float(np.hypot(np.diff(e), np.diff(n)).sum())
    assert moved <= length < moved + 30.0, length  # not inflated by ~400 m of jitter

    tr, _ = truth.build_truth(ing.table, ing.meta, rate_hz=10.0, vehicle="airliner", verbose=False)
    v = np.hypot(tr[col.VEL[0]].to_numpy(), tr[col.VEL[1]].to_numpy())
    crawl_s = float(((v > 1e-3) & (v < 1.0)).sum()) / 10.0
    assert crawl_s < 8.0, crawl_s  # the ramp from rest only
    p, t = tr[list(col.POS)].to_numpy(), tr[col.TIME].to_numpy()
    out = int(np.argmax(np.hypot(*(p[:, :2] - p[0, :2]).T) > 100.0))
    wander = float(np.hypot(*np.diff(p[: out + 1, :2], axis=0).T).sum())
    assert wander < 110.0 and t[out] < 30.0, (wander, t[out])


def _timed_gpx(tmp_path, enu, t):
    lat, lon, alt = LocalFrame(ORIGIN).to_geodetic(enu)
    pts = "".join(
        f'<trkpt lat="{a:.9f}" lon="{b:.9f}"><ele>{h:.2f}</ele>'
        f"<time>{datetime.fromtimestamp(1.7e9 + s).isoformat()}Z</time></trkpt>"
        for a, b, h, s in zip(lat, lon, alt, t, strict=True)
    )
    f = tmp_path / "gate.gpx"
    f.write_text(f"<gpx><trk><name>flight</name><trkseg>{pts}</trkseg></trk></gpx>")
    return f


def test_timed_gate_jitter_is_exactly_at_rest(tmp_path):
    """The timed shape (``e_airliner_parked_drift.gpx``): 600 s at the gate with 1.5 m of
    jitter, then a taxi accelerating to 8 m/s. The fixes at rest are kept, at their centroid,
    so the path length is the taxi's, and the truth stands exactly still until it moves off."""
    rng = np.random.default_rng(7)
    n_park, n_taxi = 600, 240
    k = np.arange(1, n_taxi + 1)
    north = np.r_[np.zeros(n_park), np.cumsum(np.minimum(8.0, 0.4 * k))]
    true = np.column_stack([np.zeros(north.size), north, np.zeros(north.size)])
    enu = true + np.column_stack(
        [rng.normal(0, 1.5, (north.size, 2)), rng.normal(0, 2, north.size)]
    )
    t = np.arange(north.size, dtype=float)
    ing = ingest(_timed_gpx(tmp_path, enu, t), vehicle="airliner")
    rest = ing.meta["cleaning"]["at_rest"]
    assert rest["count"] == 1 and not rest["merged_to_one_point"]
    ((t0, t1),) = rest["runs_s"]
    assert t0 == 0.0 and 590.0 <= t1 <= 605.0
    assert len(ing.table) == north.size  # every fix kept
    e, n = ing.table["e_m"].to_numpy(), ing.table["n_m"].to_numpy()
    at = ing.table["time_s"].to_numpy() <= t1
    assert np.ptp(e[at]) == pytest.approx(0.0, abs=1e-6) and np.ptp(n[at]) < 1e-6
    raw = float(np.hypot(*np.diff(enu[:, :2], axis=0).T).sum())
    length = float(np.hypot(np.diff(e), np.diff(n)).sum())
    assert raw > north[-1] + 1000.0  # 600 s of jitter add ~1.6 km to the raw path
    assert length < north[-1] + 500.0  # the taxi's own noise is left to the fit

    tr, m = truth.build_truth(ing.table, ing.meta, rate_hz=10.0, vehicle="airliner", verbose=False)
    assert m["plausibility"]["warnings"] == []
    v = np.hypot(tr[col.VEL[0]].to_numpy(), tr[col.VEL[1]].to_numpy())
    tt = tr[col.TIME].to_numpy()
    assert v[tt < t1 - 5.0].max() < 1e-6
    assert float(((v > 1e-3) & (v < 1.0)).sum()) / 10.0 < 10.0


@pytest.mark.parametrize(
    "case",
    ["noisy slow walk", "creeping car", "tight circles", "dense untimed walk"],
)
def test_motion_is_never_taken_for_rest(case):
    """Slow or tight motion within the noise radius is not jitter: it keeps a heading, or
    it progresses beyond the noise of its halves' centroids."""
    rng = np.random.default_rng(3)
    t = np.arange(120, dtype=float)
    if case == "noisy slow walk":  # 1.4 m/s with 3 m of white noise at 1 Hz
        xy = np.column_stack([1.4 * t, np.zeros_like(t)]) + rng.normal(0, 3.0, (t.size, 2))
        noise = 3.0
    elif case == "creeping car":  # a queue at 0.5 m/s, 2 m of noise
        xy = np.column_stack([0.5 * t, np.zeros_like(t)]) + rng.normal(0, 2.0, (t.size, 2))
        noise = 2.0
    elif case == "tight circles":  # a 6 m radius circle walked at 1.2 m/s, noiseless fixes
        ang = 1.2 * t / 6.0
        xy = 6.0 * np.column_stack([np.cos(ang), np.sin(ang)])
        noise = 2.0
    else:  # an untimed walk logged every 1.4 m, judged at the untimed noise (25 m radius)
        s = 1.4 * t
        xy = np.column_stack([s, 5.0 * np.sin(s / 10.0)])
        noise, t = UNTIMED_NOISE_M, None
    assert rest_runs(xy, noise, t) == []


def test_jitter_runs_found_between_motion():
    """Two stops between drives (each drive ends where the stop is): each found, its ends
    inside the stop (the fixes moving away from or towards it are left to the motion)."""
    rng = np.random.default_rng(9)
    drive = np.column_stack([np.arange(1, 61) * 10.0, np.zeros(60)])
    stop = rng.normal(0, 1.5, (90, 2))
    east = np.array([600.0, 0.0])
    xy = np.vstack([drive - east, stop, drive, stop + east, drive + east])
    t = np.arange(len(xy), dtype=float)
    runs = rest_runs(xy, 1.5, t)
    assert len(runs) == 2
    for (a, b), first in zip(runs, (60, 210), strict=True):
        assert first - 1 <= a <= first + 5 and first + 84 <= b <= first + 89
