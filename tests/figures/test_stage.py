"""Figures: helper oracles (representative, zoom, bands, rates) and reproducible output files."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.evaluate.stage import sequence_metrics
from imugen.figures import stage as fg
from imugen.figures.common import epoch_matrix, error_bands, grade_colours, grade_styles
from imugen.tables import enu as tenu
from imugen.tables import truth as col

RATE = 10.0  # Hz, truth
DUR = 40.0  # s
GRADES = {"paper_low_cost": 20.0, "industrial": 3.0, "tactical": 0.3}  # error scale per grade


# ---------------------------------------------------------------------------------------
# synthetic, well-formed stage files


def _truth_df() -> pd.DataFrame:
    t = np.arange(int(DUR * RATE) + 1) / RATE
    w = 2 * np.pi / DUR  # one circle of radius 100 m
    R = 100.0
    df = pd.DataFrame({col.TIME: t})
    df[tenu.E], df[tenu.N], df[tenu.U] = (
        R * np.cos(w * t),
        R * np.sin(w * t),
        0.5 * np.sin(3 * w * t),
    )
    df[col.VEL[0]], df[col.VEL[1]], df[col.VEL[2]] = (
        -R * w * np.sin(w * t),
        R * w * np.cos(w * t),
        0,
    )
    df[col.GYRO[0]], df[col.GYRO[1]], df[col.GYRO[2]] = 0.01 * np.sin(t), 0.0, w
    df[col.ACCEL[0]], df[col.ACCEL[1]], df[col.ACCEL[2]] = 0.0, R * w * w, 9.81
    return df


def _nav_df(scale: float, first: int, count: int) -> pd.DataFrame:
    t = np.arange(0.0, DUR + 0.5, 1.0)  # 1 Hz epochs
    rows = []
    for s in range(first, first + count):
        k = scale * (1 + 0.37 * ((s * 7) % count))  # distinct growth per sequence
        rows.append(
            pd.DataFrame(
                {
                    "sequence": np.int32(s),
                    col.TIME: t,
                    "err_e_m": k * (t / DUR) ** 2,
                    "err_n_m": -0.5 * k * (t / DUR) ** 2,
                    "err_u_m": 0.2 * k * t / DUR,
                    "err_att_rad": 1e-4 * t,
                }
            )
        )
    return pd.concat(rows, ignore_index=True)


@pytest.fixture(scope="module")
def route(tmp_path_factory):
    root = tmp_path_factory.mktemp("route")
    truth = write_parquet(_truth_df(), {"rate_hz": RATE}, root / "truth.parquet")
    nav, metrics = {}, {}
    for g, scale in GRADES.items():
        parts = [_nav_df(scale, 0, 3), _nav_df(scale, 3, 4)]  # two shards, 7 sequences
        nav[g] = [
            write_parquet(p, {"grade": g}, root / "nav" / g / f"shard-{i:03d}.parquet")
            for i, p in enumerate(parts)
        ]
        m = sequence_metrics(pd.concat(parts), distance_m=2 * np.pi * 100.0).reset_index()
        metrics[g] = write_parquet(m, {"grade": g}, root / "metrics" / f"{g}.parquet")
    # an increments-only shard of 2 sequences for the industrial grade
    tdf = _truth_df()
    K = len(tdf)
    rows = []
    for s in (4, 5):
        d = pd.DataFrame({"sequence": np.full(K, s, np.int32), col.TIME: tdf[col.TIME]})
        for c_inc, c_rate in zip((*col.DTHETA, *col.DV), (*col.GYRO, *col.ACCEL), strict=True):
            inc = (tdf[c_rate].to_numpy() + 0.01 * s) / RATE
            inc[0] = 0.0
            d[c_inc] = inc.astype(np.float32)
        rows.append(d)
    shard = write_parquet(
        pd.concat(rows, ignore_index=True),
        {"grade": {"name": "industrial"}, "sequence_ids": [4, 5], "dt_s": 1 / RATE},
        root / "imu" / "industrial" / "shard-001.parquet",
    )
    return {"root": root, "truth": truth, "nav": nav, "metrics": metrics, "shard": shard}


# ---------------------------------------------------------------------------------------
# helpers


def test_representative_sequence_median_best_worst():
    m = pd.DataFrame({"sequence": [10, 11, 12, 13, 14], "rmse_total_m": [5.0, 1.0, 3.0, 4.0, 2.0]})
    assert fg.representative_sequence(m) == 12  # median of 1..5 is 3
    assert fg.representative_sequence(m, "best") == 11
    assert fg.representative_sequence(m, "worst") == 10
    # index form, even count -> lower median, NaN ignored
    m2 = pd.DataFrame(
        {"rmse_total_m": [4.0, np.nan, 1.0, 3.0, 2.0]},
        index=pd.Index([7, 8, 9, 10, 11], name="sequence"),
    )
    assert fg.representative_sequence(m2) == 11  # sorted 1,2,3,4 -> 2
    # ties go to the smaller id
    m3 = pd.DataFrame({"sequence": [3, 1, 2], "rmse_total_m": [2.0, 2.0, 2.0]})
    assert [fg.representative_sequence(m3, h) for h in fg.REPRESENTATIVE] == [1, 1, 1]
    with pytest.raises(InputError):
        fg.representative_sequence(m, "mean")


def test_representative_on_written_metrics(route):
    # oracle: sequence whose total RMSE equals numpy's median over the 7 (odd) sequences
    for g, path in route["metrics"].items():
        m = pd.read_parquet(path)
        sid = fg.representative_sequence(m)
        assert m.loc[m.sequence == sid, "rmse_total_m"].item() == np.median(m.rmse_total_m), g


def test_zoom_window_and_extent():
    assert fg.zoom_window(0.0, 100.0, 0.2) == pytest.approx((80.0, 100.0))
    assert fg.zoom_window(10.0, 30.0, 1.0) == (10.0, 30.0)
    for bad in (0.0, -0.1, 1.5):
        with pytest.raises(InputError):
            fg.zoom_window(0.0, 1.0, bad)
    t = np.linspace(0.0, 100.0, 101)
    e, n = t.copy(), -2 * t
    lo_e, hi_e, lo_n, hi_n = fg.zoom_extent((80.0, 100.0), [(t, e, n)], pad=0.0)
    assert (lo_e, hi_e, lo_n, hi_n) == (80.0, 100.0, -200.0, -160.0)
    # padding is a fraction of the larger side; a second track widens the box
    box = fg.zoom_extent((80.0, 100.0), [(t, e, n), (t, e + 50, n)], pad=0.1)
    assert box == pytest.approx((80 - 7, 150 + 7, -200 - 7, -160 + 7))
    with pytest.raises(InputError):
        fg.zoom_extent((200.0, 300.0), [(t, e, n)])


def test_clip_box_limits_to_factor_of_reference():
    ref = (0.0, 10.0, 0.0, 4.0)  # centre (5, 2), larger half-side 5
    big = (-1000.0, 20.0, -3.0, 500.0)
    assert fg.clip_box(big, ref, 3.0) == (-10.0, 20.0, -3.0, 17.0)
    assert fg.clip_box(big, ref, None) == big
    inside = (1.0, 9.0, 0.5, 3.0)
    assert fg.clip_box(inside, ref, 1.0) == inside
    with pytest.raises(InputError):
        fg.clip_box(big, ref, 0.5)


def test_error_bands_known_order_statistics():
    rng = np.random.default_rng(3)
    # 101 values 0..100 per epoch (scaled by epoch), shuffled: p05, p50, p95 = 5, 50, 95 exactly
    v = np.stack([rng.permutation(101) * (j + 1.0) for j in range(4)], axis=1)
    p05, p50, p95 = error_bands(v)
    scale = np.arange(1, 5)
    np.testing.assert_array_equal(p05, 5 * scale)
    np.testing.assert_array_equal(p50, 50 * scale)
    np.testing.assert_array_equal(p95, 95 * scale)
    # 21 sequences: ranks 0.05*20 = 1, 10, 19 fall on order statistics
    w = rng.lognormal(size=(21, 6))
    s = np.sort(w, axis=0)
    np.testing.assert_array_equal(np.stack(error_bands(w)), s[[1, 10, 19]])
    # NaN (a failed sequence) is ignored
    w2 = np.vstack([w, np.full((1, 6), np.nan)])
    np.testing.assert_array_equal(np.stack(error_bands(w2)), s[[1, 10, 19]])
    with pytest.raises(ValueError):
        error_bands(np.ones(5))


def test_epoch_matrix_from_shuffled_long_table():
    nav = _nav_df(2.0, 5, 3).sample(frac=1.0, random_state=0)
    ids, t, err = epoch_matrix(nav)
    assert ids.tolist() == [5, 6, 7]
    np.testing.assert_array_equal(t, np.arange(0.0, DUR + 0.5))
    ref = _nav_df(2.0, 5, 3)
    e = ref.err_e_m.to_numpy().reshape(3, -1)
    n = ref.err_n_m.to_numpy().reshape(3, -1)
    np.testing.assert_allclose(err["horizontal"], np.sqrt(e**2 + n**2), rtol=1e-15)
    np.testing.assert_array_equal(err["up"], np.abs(ref.err_u_m.to_numpy().reshape(3, -1)))
    with pytest.raises(InputError):
        epoch_matrix(nav.iloc[1:])  # one sequence short of an epoch


def test_interval_rates_constant_rate():
    t = np.arange(11) * 0.1 + 5.0
    w = np.array([0.2, -1.0, 3.0])
    inc = np.outer(np.r_[0, np.ones(10)] * 0.1, w)
    tm, r = fg.interval_rates(t, inc)
    np.testing.assert_allclose(tm, t[1:] - 0.05, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r, np.tile(w, (10, 1)), rtol=1e-12)


def test_grade_colours_fixed_distinct_stable():
    c = grade_colours(["consumer", "paper_low_cost", "industrial", "paper_tactical", "navigation"])
    assert len(set(c.values())) == 5
    assert c["consumer"] == grade_colours(["consumer"])["consumer"]
    a = grade_colours(["foo", "bar", "tactical"])
    b = grade_colours(["tactical", "bar", "foo"])
    assert a == b and len(set(a.values())) == 3
    assert grade_colours(["my_tactical"])["my_tactical"] == a["tactical"]


# ---------------------------------------------------------------------------------------
# files


def _check_files(paths, stem):
    assert [p.name for p in paths] == [f"{stem.name}.png", f"{stem.name}.svg"]
    png, svg = (p.read_bytes() for p in paths)
    assert png.startswith(b"\x89PNG") and len(png) > 5_000
    assert b"<svg" in svg[:2000] and len(svg) > 5_000
    assert not list(stem.parent.glob(".*.tmp"))  # no temporary files left
    return svg


def test_figure8_files_and_byte_identical(route, tmp_path):
    import matplotlib as mpl

    args = (route["truth"], route["nav"], route["metrics"])
    a = fg.figure8(*args, tmp_path / "a" / "figure8", dpi=60)
    svg = _check_files(a, tmp_path / "a" / "figure8")
    # drawn again, even with a user's rcParams changed: same bytes
    with mpl.rc_context({"lines.linewidth": 4.0, "svg.hashsalt": None, "font.size": 20}):
        b = fg.figure8(*args, tmp_path / "b" / "figure8", dpi=60)
    assert b[1].read_bytes() == svg
    assert b[0].read_bytes() == a[0].read_bytes()
    assert b"<dc:date>" not in svg
    c = fg.figure8(
        *args, tmp_path / "c" / "f8", representative="worst", clip_factor=None, formats=("svg",)
    )
    assert [p.name for p in c] == ["f8.svg"] and c[0].read_bytes() != svg
    with pytest.raises(InputError):
        fg.figure8(*args, tmp_path / "d" / "f8", formats=("docx",))
    with pytest.raises(InputError):
        fg.figure8(route["truth"], route["nav"], {}, tmp_path / "e" / "f8")


def test_trajectories_3d_files(route, tmp_path):
    args = (route["truth"], route["nav"], route["metrics"])
    a = fg.trajectories_3d(*args, tmp_path / "t3d", dpi=50)
    svg = _check_files(a, tmp_path / "t3d")
    b = fg.trajectories_3d(*args, tmp_path / "again" / "t3d", formats=("svg",))
    assert b[0].read_bytes() == svg


def test_error_vs_time_files(route, tmp_path):
    a = fg.error_vs_time(route["nav"], tmp_path / "err", dpi=50)
    svg = _check_files(a, tmp_path / "err")
    b = fg.error_vs_time(route["nav"], tmp_path / "again" / "err", formats=("svg",))
    assert b[0].read_bytes() == svg
    dup = {"x": [*route["nav"]["tactical"], route["nav"]["tactical"][0]]}
    with pytest.raises(InputError, match="also appears"):
        fg.error_vs_time(dup, tmp_path / "dup")


def test_imu_signals_files(route, tmp_path):
    a = fg.imu_signals(route["truth"], route["shard"], tmp_path / "imu", dpi=50)
    _check_files(a, tmp_path / "imu")
    b = fg.imu_signals(
        route["truth"], route["shard"], tmp_path / "imuw", sequence=5, window_s=(10.0, 20.0), dpi=50
    )
    _check_files(b, tmp_path / "imuw")
    with pytest.raises(InputError):
        fg.imu_signals(route["truth"], route["shard"], tmp_path / "x", sequence=99)
    with pytest.raises(InputError):
        fg.imu_signals(route["truth"], route["shard"], tmp_path / "x", window_s=(100.0, 200.0))


# ---------------------------------------------------------------------------------------
# visual properties (not pixels): nothing clipped, every end in the zoom, distinct styles
@pytest.fixture(scope="module")
def drifting(tmp_path_factory):
    """Paired paper/datasheet grades, one drifting 100 km: the case that broke the zoom."""
    root = tmp_path_factory.mktemp("drift")
    truth = write_parquet(_truth_df(), {"rate_hz": RATE}, root / "truth.parquet")
    nav, metrics = {}, {}
    for g, scale in {
        "paper_tactical": 2e3,
        "tactical": 30.0,
        "consumer": 1e5,
        "tactical_calibrated": 0.5,
    }.items():
        part = _nav_df(scale, 0, 3)
        nav[g] = [write_parquet(part, {"grade": g}, root / "nav" / g / "shard-000.parquet")]
        m = sequence_metrics(part, distance_m=2 * np.pi * 100.0).reset_index()
        metrics[g] = write_parquet(m, {"grade": g}, root / "metrics" / f"{g}.parquet")
    return truth, nav, metrics


def test_figure8_properties(drifting):
    import matplotlib.text

    truth, nav, metrics = drifting
    with fg._style():
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        fig = fg.figure8_figure(truth, nav, metrics)
        FigureCanvasAgg(fig).draw()
        r = fig.canvas.get_renderer()
        texts = [t for t in fig.findobj(matplotlib.text.Text) if t.get_visible() and t.get_text()]
        assert any("(b)" in t.get_text() for t in texts)
        # every drawn artist (titles, tick labels, legend) inside the figure
        tight, page = fig.get_tightbbox(r), fig.bbox_inches
        assert page.x0 - 0.01 <= tight.x0 and tight.x1 <= page.x1 + 0.01, (tight, page)
        assert page.y0 - 0.01 <= tight.y0 and tight.y1 <= page.y1 + 0.01, (tight, page)
        for ax in fig.axes:  # titles sit above their axes, below the figure's top edge
            tb = ax.title.get_window_extent(r)
            assert tb.y1 <= fig.bbox.y1 + 1 and tb.x0 >= -1, ax.title.get_text()
        ax_b = fig.axes[1]
        (x0, x1), (y0, y1) = ax_b.get_xlim(), ax_b.get_ylim()
        # the zoom zooms: at most clip_factor (3) times the reference's window (a 100 m
        # circle: its last 20 % spans ~120 m), not the 100 km drift of the consumer grade
        assert x1 - x0 < 1000.0 and y1 - y0 < 1000.0, (x0, x1, y0, y1)
        ref = ax_b.get_lines()[0]
        rx, ry = (np.asarray(v, float) for v in ref.get_data())
        assert x0 <= rx.min() and rx.max() <= x1 and y0 <= ry.min() and ry.max() <= y1
        notes = {t.get_text().split(":")[0]: t.get_text() for t in ax_b.texts}
        colour = {g: st["color"] for g, st in grade_styles(list(nav)).items()}
        for g in nav:  # each end: a dot inside, or an edge mark labelled with its distance
            dots = [
                ln for ln in ax_b.get_lines()
                if ln.get_marker() == "o" and ln.get_color() == colour[g]
            ]  # fmt: skip
            assert bool(dots) != (g in notes), (g, notes)
            for ln in dots:
                x, y = (np.asarray(v, float) for v in ln.get_data())
                assert x0 <= x[-1] <= x1 and y0 <= y[-1] <= y1, g
        assert "consumer" in notes and "km" in notes["consumer"], notes
        assert "tactical_calibrated" not in notes
        styles = {
            (ln.get_color(), ln.get_linestyle()) for ln in fig.axes[0].get_lines()[1 : 1 + len(nav)]
        }
        assert len(styles) == len(nav)  # paper_tactical, tactical, tactical_calibrated differ
        labels = " ".join(t.get_text() for t in texts)
        assert "km" in labels and "e+" not in labels  # 1e5 m reads as kilometres


def test_grade_styles_and_lengths():
    st = grade_styles(["tactical", "paper_tactical", "tactical_calibrated", "consumer"])
    assert len({(v["color"], v["ls"]) for v in st.values()}) == 4
    assert st["paper_tactical"]["ls"] == "--" and st["tactical"]["ls"] == "-"
    assert [fg.format_length(x) for x in (0.4412, 7.4, 172.3, 1726.0, 13439248.0)] == [
        "0.441 m",
        "7.40 m",
        "172 m",
        "1.73 km",
        "13,400 km",
    ]
