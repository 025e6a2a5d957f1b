"""A parked aircraft's GPS altitude wander is not flown (issue 27)."""

from __future__ import annotations

from datetime import datetime

import numpy as np

from imugen import truth
from imugen.ingest.stage import ingest
from imugen.tables import truth as col


def _parked_then_taxi(tmp_path):
    """An airliner's logger at the gate for 20 min (1 Hz, 1.5 m horizontal noise), its
    altitude wandering by a random walk plus a 70 m bump (poor geometry at the gate), then
    300 s of taxi accelerating to 8 m/s, the heights as drifted as at the end of the stop."""
    rng = np.random.default_rng(11)
    n_park, n_taxi = 1200, 300
    walk = np.cumsum(rng.normal(0.0, 0.8, n_park))
    walk += 70.0 * np.sin(np.linspace(0.0, np.pi, n_park)) ** 2 - walk[0]
    k = np.arange(1, n_taxi + 1)
    north = np.r_[np.zeros(n_park), 8.0 * k * np.minimum(1.0, k / 20.0)]
    north += rng.normal(0.0, 1.5, north.size)
    east = rng.normal(0.0, 1.5, north.size)
    up = 450.0 + np.r_[walk, np.full(n_taxi, walk[-1])] + rng.normal(0.0, 2.0, north.size)
    pts = "".join(
        f'<trkpt lat="{48.35 + n / 111_200.0:.9f}" lon="{11.78 + e / 74_000.0:.9f}">'
        f"<ele>{u:.2f}</ele><time>{datetime.fromtimestamp(1.7e9 + s).isoformat()}Z</time></trkpt>"
        for s, (n, e, u) in enumerate(zip(north, east, up, strict=True))
    )
    f = tmp_path / "gate.gpx"
    f.write_text(f"<gpx><trk><name>flight</name><trkseg>{pts}</trkseg></trk></gpx>")
    return f, float(np.ptp(walk))


def test_a_parked_airliner_holds_its_height_and_attitude(tmp_path):
    """Issue 27: GPS altitude drift pitched a parked airliner (85 deg on the audit's file, 27
    deg on this shape, flown as 'in flight' at the gate); its still stretch now holds the
    height where it moves off, the truth stays level on the ground."""
    f, wander = _parked_then_taxi(tmp_path)
    ing = ingest(f, vehicle="airliner")
    runs = ing.meta["cleaning"]["still_runs_s"]
    assert len(runs) == 1 and runs[0][0] == 0.0 and runs[0][1] > 1150.0
    assert any("stands still" in w for w in ing.warnings)
    u = ing.table["u_m"].to_numpy()
    t_in = ing.table["time_s"].to_numpy()
    assert np.ptp(u[t_in <= runs[0][1]]) < 1e-6 and wander > 60.0
    tr, m = truth.build_truth(ing.table, ing.meta, rate_hz=10.0, vehicle="airliner", verbose=False)
    assert m["plausibility"]["warnings"] == []
    pitch = tr[col.EULER[1]].to_numpy()
    assert np.degrees(np.abs(pitch)).max() < 5.0
    v_up = tr[col.VEL[2]].to_numpy()
    t = tr[col.TIME].to_numpy()
    parked = t < runs[0][1] - 30.0
    assert np.ptp(tr[col.POS[2]].to_numpy()[parked]) < 0.05
    assert np.abs(v_up[parked]).max() < 0.01 and np.abs(v_up).max() < 1.0
