"""RMSE statistics against hand-computable cases."""

import numpy as np
import pandas as pd
import pytest

from imugen.evaluate import grade_row, grade_table, sequence_metrics, write_tables


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
