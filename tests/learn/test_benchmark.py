"""The GNSS-denied benchmark: its config, the table's columns, the network's correction, and a
tiny variant of its workflow end to end (src/imugen/learn, workflow/rules/learn.smk)."""

import importlib.util

import numpy as np
import pandas as pd
import pytest
import yaml

from imugen import preflight
from imugen.learn import table as T
from imugen.learn.options import TableOptions
from imugen.learn.stage import main_table
from imugen.tables import metrics as tmetrics

from helpers import PAPER, REPO, ROUTE, SHARED, snakemake, write_config

HAS_TORCH = importlib.util.find_spec("torch") is not None
needs_torch = pytest.mark.skipif(not HAS_TORCH, reason="the optional torch extra")
SCHEMA = yaml.safe_load((REPO / "workflow/schemas/config.schema.yaml").read_text())


def _benchmark_config():
    return yaml.safe_load((REPO / "config/benchmark.yaml").read_text())


def test_benchmark_config_validates_and_its_splits_are_disjoint_shared_routes():
    cfg = _benchmark_config()
    assert preflight.schema_problems(cfg, SCHEMA) == []
    b = cfg["benchmark"]
    splits = [*b["train"], *b["validation"], *b["test"]]
    assert len(splits) == len(set(splits)) and set(splits) == set(cfg["routes"])
    vehicles = {s: {cfg["routes"][r]["vehicle"] for r in b[s]} for s in ("train", "test")}
    assert vehicles == {"train": {"car", "pedestrian"}, "test": {"car", "pedestrian"}}
    assert all(cfg["routes"][r]["file"].startswith("../shared/data/trajectories/") for r in splits)
    assert {"consumer", "phone"} <= set(cfg["grades"])
    assert b["outages_s"] == [30, 60, 120, 180]
    declared = sorted(iv["duration_s"] for iv in cfg["scenarios"]["intervals"])
    assert declared == b["outages_s"] and cfg["gnss"]["enabled"]


def test_schema_refuses_a_benchmark_without_test_routes():
    cfg = _benchmark_config()
    del cfg["benchmark"]["test"]
    assert any("test" in p for p in preflight.schema_problems(cfg, SCHEMA))


def _metrics(path, seed, scale):
    rng = np.random.default_rng(seed)
    n = 20
    df = pd.DataFrame({"sequence": np.arange(n), "rmse_total_m": rng.random(n)})
    for D in (30, 60):
        df[f"drift_{D}s_m"] = scale * D * (1 + rng.random(n))
        df[f"outage_{D}s_end_m"] = scale * (1 + rng.random(n))
    df.loc[0, "outage_60s_end_m"] = np.nan  # a sequence without that outage
    tmetrics.write(df, {"stage": "evaluate", "grade": "consumer"}, path)
    return df


def test_table_columns_and_figures(tmp_path):
    a = _metrics(tmp_path / "a.parquet", 0, 1.0)
    b = _metrics(tmp_path / "b.parquet", 1, 0.5)
    opts = TableOptions(durations_s=(30.0, 60.0), formats=("png",))
    main_table(
        opts, output=str(tmp_path / "table"), figure=str(tmp_path / "fig"),
        aided=[f"park,consumer={tmp_path / 'a.parquet'}"],
        learned=[f"park,consumer={tmp_path / 'b.parquet'}"], split=["park=test"],
    )  # fmt: skip
    df = pd.read_csv(tmp_path / "table.csv")
    assert tuple(df.columns) == T.COLUMNS
    assert list(df["baseline"].unique()) == list(T.BASELINES)
    assert (df["split"] == "test").all() and len(df) == 6
    row = df[(df.baseline == "aided") & (df.outage_s == 60)].iloc[0]
    v = a["outage_60s_end_m"].dropna()
    assert row.sequences == 19
    assert row.median_m == pytest.approx(np.median(v))
    assert row.p95_m == pytest.approx(np.percentile(v, 95))
    free = df[(df.baseline == "free_inertial") & (df.outage_s == 30)].iloc[0]
    assert free.median_m == pytest.approx(np.median(a["drift_30s_m"]))
    learned = df[(df.baseline == "aided_learned") & (df.outage_s == 30)].iloc[0]
    assert learned.median_m == pytest.approx(np.median(b["outage_30s_end_m"]))
    md = (tmp_path / "table.md").read_text()
    assert "| test | park | consumer | aided_learned |" in md
    assert (tmp_path / "fig.png").stat().st_size > 1000
    from imugen.core.plotting import style

    with style():
        fig = T.draw(df)
    fig.canvas.draw()  # the legend sits below the axes: it hides no curve
    (legend,) = fig.legends
    assert not any(legend.get_window_extent().overlaps(ax.get_window_extent()) for ax in fig.axes)


def test_table_agrees_with_the_outage_drift_table(tmp_path):
    """One statistic: the benchmark's aided and free-inertial rows are the outage-drift table's
    median, 95th percentile and sequence count of the same metrics (imugen.figures.outage_drift
    owns it), and a length the metrics lack is a row of NaN, not an error."""
    from imugen.figures.outage_drift import outage_drift

    a = _metrics(tmp_path / "a.parquet", 0, 1.0)
    df = T.rows({("park", "consumer"): tmp_path / "a.parquet"}, {}, {"park": "test"}, (30, 60, 90))
    ref = outage_drift({"consumer": a}).set_index("outage_s")
    for D in (30.0, 60.0):
        aided = df[(df.baseline == "aided") & (df.outage_s == D)].iloc[0]
        free = df[(df.baseline == "free_inertial") & (df.outage_s == D)].iloc[0]
        r = ref.loc[D]
        assert (aided.median_m, aided.p95_m) == (r.aided_end_m, r.aided_end_p95_m)
        assert aided.sequences == r.sequences and free.sequences == len(a)
        assert (free.median_m, free.p95_m) == (r.free_inertial_drift_m, r.free_inertial_drift_p95_m)
    missing = df[df.outage_s == 90]
    assert len(missing) == 2 and (missing.sequences == 0).all() and missing.median_m.isna().all()


@needs_torch
def test_correction_is_the_causal_running_mean_of_the_window_predictions():
    import torch

    from imugen.learn.correct import predict

    class Mean(torch.nn.Module):  # predicts the window's mean input (normalised units)
        def forward(self, x):
            return x.mean(dim=1)

    W, dt, K = 10, 0.01, 1 + 4 * 10 + 3
    meta = {"window": W, "dt_s": dt, "target_scale": [1.0] * 6}
    x = np.zeros((1, K, 6))
    levels = np.array([1.0, 3.0, 5.0, 7.0]) * dt  # rad per sample: rates 1, 3, 5, 7 rad/s
    for i, v in enumerate(levels):
        x[0, 1 + i * W : 1 + (i + 1) * W, 0] = v
    c = predict(Mean(), meta, x, smooth_s=2 * W * dt)  # running mean of 2 windows
    rate = c[0, :, 0] / dt
    assert rate[0] == 0
    np.testing.assert_allclose(rate[1 : 1 + 4 * W : W], [1.0, 2.0, 4.0, 6.0], rtol=1e-6)
    np.testing.assert_allclose(rate[-3:], 6.0, rtol=1e-6)  # partial window: the last rate


@needs_torch
def test_tiny_benchmark_workflow_end_to_end(tmp_path):
    """Train a few steps on one route, evaluate on another: the table, the figure, the
    correction actually reaching the filter (the learned run differs from the plain one)."""
    cfg = {
        "routes": {
            "train_route": {"file": str(ROUTE)},
            "test_route": {"file": str(PAPER), "origin": [31.63, -7.99, 480.6], "dt_s": 1.0},
        },
        "benchmark": {
            "train": ["train_route"],
            "test": ["test_route"],
            "outages_s": [30, 60],
            "model": {
                "steps": 3,
                "batch_size": 8,
                "windows_per_sequence": 4,
                "window": 20,
                "width": 4,
            },
        },
        "truth": {"rate_hz": 10, "earth": "flat"},
        "grades": {"consumer": {}},
        "simulate": {"sequences": 2, "sequences_per_shard": 2, "seed": 7},
        "evaluate": {"segments_s": [30, 60]},
        "gnss": {"enabled": True, "receiver": "standalone"},
        "scenarios": {
            "intervals": [
                {"kind": "outage", "start_s": 100, "duration_s": 30},
                {"kind": "outage", "start_s": 170, "duration_s": 60},
            ]
        },
        "aided": {"align_speed_mps": 2.0},
        "figures": {"formats": ["png"]},
    }
    write_config(tmp_path, cfg)
    proc = snakemake(tmp_path, "-j2")
    assert proc.returncode == 0, proc.stderr[-4000:]
    df = pd.read_csv(tmp_path / "results/benchmark/table.csv")
    assert tuple(df.columns) == T.COLUMNS
    assert set(df["route"]) == {"test_route"} and set(df["split"]) == {"test"}
    assert len(df) == 3 * 2 and (df["sequences"] == 2).all()
    assert np.isfinite(df[["median_m", "p95_m"]].to_numpy()).all()
    assert (tmp_path / "results/benchmark/figure.png").is_file()
    assert not (tmp_path / "results/train_route/imu").exists()  # training routes: truth only
    plain, learned = (
        df[df.baseline == b].set_index("outage_s")["median_m"] for b in ("aided", "aided_learned")
    )
    assert not np.allclose(plain, learned, rtol=0, atol=1e-9)


def test_benchmark_without_its_route_files_fails_with_one_line(tmp_path):
    cfg = _benchmark_config()
    cfg["routes"]["park"]["file"] = "../no-shared/data/trajectories/missing.gpx"
    write_config(tmp_path, cfg)
    proc = snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0
    out = proc.stdout + proc.stderr
    line = next(x for x in out.splitlines() if "imugen: error" in x)
    assert "route file ../no-shared/data/trajectories/missing.gpx not found" in line
    assert "../shared" in line and "Traceback" not in out


@pytest.mark.skipif(not SHARED.is_dir(), reason="needs ../shared")
def test_benchmark_dry_run_schedules_the_three_baselines(tmp_path):
    (tmp_path / "config").mkdir()
    (tmp_path / "config/config.yaml").write_text(
        (REPO / "config/benchmark.yaml").read_text().replace("../shared", str(SHARED))
    )
    proc = snakemake(tmp_path, "-n", "-j1", "--quiet", "rules")
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout + proc.stderr
    for rule, n in (("learn_train", 2), ("learn_correct", 12), ("aid_learned", 12),
                    ("evaluate_learned", 6), ("benchmark_table", 1)):  # fmt: skip
        assert f"\n{rule} " in out and str(n) in out.split(f"\n{rule} ")[1].split("\n")[0]
