"""RMSE statistics against hand-computable cases."""

import numpy as np
import pandas as pd
import pytest

from imugen.evaluate.stage import (
    grade_row,
    grade_table,
    segment_drift,
    segment_starts,
    sequence_metrics,
    write_tables,
)
from imugen.tables import truth as col


def nav_table(errors: dict[int, np.ndarray]) -> pd.DataFrame:
    frames = []
    for seq, err in errors.items():
        n = len(err)
        frames.append(
            pd.DataFrame(
                {
                    "sequence": seq,
                    "time_s": np.arange(n, dtype=float),
                    "err_e_m": err[:, 0],
                    "err_n_m": err[:, 1],
                    "err_u_m": err[:, 2],
                }
            )
        )
    return pd.concat(frames, ignore_index=True).sample(frac=1.0, random_state=1)


def test_sequence_metrics_closed_form():
    # errors growing linearly: e = a t, RMSE over t = 0..n-1 is a sqrt(sum t^2 / n)
    n = 11
    t = np.arange(n, dtype=float)
    err = np.column_stack([1.0 * t, -2.0 * t, 0.5 * np.ones(n)])
    m = sequence_metrics(nav_table({7: err}), distance_m=1000.0).loc[7]
    rms_t = np.sqrt(np.mean(t**2))
    assert m.rmse_east_m == pytest.approx(rms_t)
    assert m.rmse_north_m == pytest.approx(2 * rms_t)
    assert m.rmse_up_m == pytest.approx(0.5)
    assert m.rmse_total_m == pytest.approx(np.sqrt(5 * rms_t**2 + 0.25))
    assert m.final_east_m == 10 and m.final_north_m == -20
    assert m.final_3d_m == pytest.approx(np.sqrt(100 + 400 + 0.25))
    assert m.final_pct_distance == pytest.approx(100 * np.hypot(10, 20) / 1000)
    assert m.epochs == n


def test_grade_row_percentiles_and_paper_total():
    rng = np.random.default_rng(0)
    errs = {k: rng.normal(0, 1 + k, size=(50, 3)) for k in range(101)}
    m = sequence_metrics(nav_table(errs), 500.0)
    row = grade_row("tactical", m)
    assert row["sequences"] == 101
    assert row["total_m"] == pytest.approx(np.median(m.rmse_total_m))
    assert row["total_p05_m"] == pytest.approx(np.percentile(m.rmse_total_m, 5))
    assert row["east_p95_m"] == pytest.approx(np.percentile(m.rmse_east_m, 95))
    assert row["total_p05_m"] < row["total_m"] < row["total_p95_m"]


def test_tables_written(tmp_path):
    rows = []
    for g, s in (("consumer", 10.0), ("tactical", 0.1)):
        errs = {k: np.full((5, 3), s * (k + 1)) for k in range(20)}
        rows.append(grade_row(g, sequence_metrics(nav_table(errs), 100.0)))
    table = grade_table(rows)
    assert list(table.columns[:7]) == [
        "grade",
        "east_m",
        "north_m",
        "up_m",
        "total_m",
        "total_p05_m",
        "total_p95_m",
    ]
    paths = write_tables(table, tmp_path / "rmse.csv")
    back = pd.read_csv(paths["csv"])
    assert list(back.grade) == ["consumer", "tactical"]
    np.testing.assert_allclose(
        back.total_m, [np.sqrt(3) * 10 * 10.5, np.sqrt(3) * 0.1 * 10.5], rtol=1e-5
    )
    assert "| consumer |" in paths["md"].read_text()
    assert r"\begin{tabular}" in paths["tex"].read_text() and "<table" in paths["html"].read_text()


# --- relative drift ----------------------------------------------------------------------------
RATE, DURATION_S = 10.0, 300.0
BIASES = {0: (0.0, 0.0, 0.0), 1: (3e-3, -2e-3, 1e-3), 2: (6e-3, -4e-3, 2e-3), 3: (0.0, 0.01, 0.0)}


def static_scene(tmp_path):
    """A level IMU at rest (flat Earth, 10 Hz, 300 s); sequence s has accel bias BIASES[s]."""
    from imugen.core.earth import OriginFrame
    from imugen.core.io import write_parquet

    origin = {"lat_deg": 45.0, "lon_deg": 7.0, "alt_m": 200.0}
    g0 = OriginFrame.from_deg(*origin.values(), model="flat").g0
    K = int(DURATION_S * RATE) + 1
    t = np.arange(K) / RATE
    truth = pd.DataFrame({c: np.zeros(K) for c in col.COLUMNS})
    truth[col.TIME] = t
    truth["q_w"] = 1.0
    meta = {"rate_hz": RATE, "origin": origin, "earth": "flat"}
    write_parquet(truth, meta, tmp_path / "truth.parquet")
    frames = []
    for s, b in BIASES.items():
        df = pd.DataFrame({"sequence": np.full(K, s, np.int32), col.TIME: t})
        for c in col.DTHETA:
            df[c] = 0.0
        for i, c in enumerate(col.DV):
            df[c] = (b[i] + (g0 if i == 2 else 0.0)) / RATE
        df.loc[0, [*col.DTHETA, *col.DV]] = 0.0
        frames.append(df)
    shard = pd.concat(frames, ignore_index=True)
    write_parquet(shard, {"grade": {"name": "test"}}, tmp_path / "shard-000.parquet")
    return tmp_path / "truth.parquet", tmp_path / "shard-000.parquet"


def test_drift_of_a_constant_accel_bias_is_b_t2_over_2(tmp_path):
    truth, shard = static_scene(tmp_path)
    d = segment_drift(truth, shard, [30, 60, 120, 400])
    assert list(d.columns) == ["drift_30s_m", "drift_60s_m", "drift_120s_m", "drift_400s_m"]
    for s, b in BIASES.items():
        for T in (30, 60, 120):
            # every start from the true state drifts by |b| T^2 / 2 (T exact in samples)
            assert d.loc[s, f"drift_{T}s_m"] == pytest.approx(
                np.linalg.norm(b) * T**2 / 2, rel=1e-9, abs=1e-9
            )
        assert np.isnan(d.loc[s, "drift_400s_m"])  # longer than the route
    # starts every T/2 while the segment fits: 0, 60, ..., 180 s for T = 120 s in 300 s
    assert list(segment_starts(3001, 1200)) == [0, 600, 1200, 1800]
    assert list(segment_starts(3001, 3000)) == [0] and len(segment_starts(3001, 3001)) == 0


def test_evaluate_segments_command_and_tables(tmp_path):
    import subprocess
    import sys

    from imugen.navigate.stage import run as navigate

    truth, shard = static_scene(tmp_path)
    nav = navigate(truth, shard, tmp_path / "nav.parquet")
    out = tmp_path / "metrics.parquet"
    cmd = [sys.executable, "-m", "imugen", "evaluate", str(truth), str(nav), "-o", str(out)]
    r = subprocess.run(
        [*cmd, "--grade", "test", "--segments", "30,60", "--imu", str(shard)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    m = pd.read_parquet(out).set_index("sequence")
    np.testing.assert_allclose(
        m["drift_60s_m"], [np.linalg.norm(b) * 1800 for b in BIASES.values()], rtol=1e-9, atol=1e-9
    )
    # the whole-run RMSE is unchanged by the drift columns: bias b gives |b| t^2 / 2
    assert m.loc[1, "final_3d_m"] == pytest.approx(np.linalg.norm(BIASES[1]) * 300**2 / 2)
    row = grade_row("test", m)
    assert row["drift_30s_m"] == pytest.approx(np.median(m["drift_30s_m"]))
    assert row["drift_30s_p95_m"] == pytest.approx(np.percentile(m["drift_30s_m"], 95))
    paths = write_tables(grade_table([row]), tmp_path / "rmse.csv")
    assert {"drift_30s_m", "drift_30s_p05_m", "drift_60s_p95_m"} <= set(
        pd.read_csv(paths["csv"]).columns
    )
    assert "Drift 30 s (m)" in paths["md"].read_text()
    r = subprocess.run(
        [*cmd, "--grade", "test", "--segments", "30"], capture_output=True, text=True
    )
    assert r.returncode == 2 and "needs the IMU shards" in r.stderr
    r = subprocess.run([*cmd, "--grade", "t", "--segments", "0,x"], capture_output=True, text=True)
    assert r.returncode == 2 and "--segments" in r.stderr and not out.with_name("x").exists()


def test_navigation_and_metrics_record_the_vertical_channel(tmp_path):
    """The vertical channel navigation used is recorded in the navigation table's metadata and
    carried into the metrics' (issue 27): ``auto`` on a 300 s flat scene stays free (the rule
    says why), ``damped`` is damped; ``imugen tables`` reads it from there."""
    import warnings

    from imugen.evaluate.options import EvaluateOptions
    from imugen.evaluate.stage import run as evaluate
    from imugen.navigate.options import NavigateOptions
    from imugen.navigate.stage import run as navigate
    from imugen.tables import metrics as tmetrics
    from imugen.tables import nav as tnav

    truth, shard = static_scene(tmp_path)
    for mode, expect in (("auto", "free"), ("damped", "damped")):
        nav = navigate(
            truth, shard, tmp_path / f"nav_{mode}.parquet", NavigateOptions(vertical=mode)
        )
        rec = tnav.read_meta(nav)["vertical_channel"]
        assert rec["requested"] == mode and rec["mode"] == expect
        assert rec["duration_s"] == pytest.approx(DURATION_S)
        assert rec["reference"] == "truth"
        if expect == "damped":
            assert rec["order"] == 3 and rec["time_constant_s"] == 100.0
        assert "damped when duration > 3 x growth time" in rec["rule"]
        assert ("free channel is neutral" in rec["rule"]) and (mode in rec["rule"])
        out = tmp_path / f"metrics_{mode}.parquet"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a static scene has no extent: flagged meaningless
            evaluate(truth, [nav], out, EvaluateOptions(grade="test"))
        assert tmetrics.read_meta(out)["vertical_channel"] == rec
