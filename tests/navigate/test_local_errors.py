"""Errors in the local level at the true position, along/cross track (imugen.navigate.local_errors).

Oracles: an error injected in ECEF along a known local direction comes out in that East/North/Up
component and in the along/cross component its angle to the velocity gives; a displacement
along the velocity is pure along-track; the three Earth models describe the same physical error
identically; ``flat`` equals the n-frame errors bit for bit; an absurd navigated position keeps
a finite error of the same norm; the navigation stage and ``evaluate`` carry the columns.
"""

import math
import warnings

import numpy as np
import pandas as pd
import pytest
from pyproj import Geod

from imugen import truth as T
from imugen.core import earth as E
from imugen.evaluate import stage as EV
from imugen.evaluate.options import EvaluateOptions
from imugen.navigate import local_errors as L
from imugen.navigate import stage as NV
from imugen.navigate.navigator import Navigator
from imugen.tables import nav as tnav
from imugen.tables import truth as ttruth

LAT, LON, H = math.radians(52.0), math.radians(179.95), 300.0  # next to the antimeridian


def _vehicle(lat, lon, h, heading_rad, speed=250.0):
    """ECEF position, local ENU basis (rows E, N, U in ECEF) and ECEF velocity of a vehicle
    heading ``heading_rad`` (from North towards East)."""
    r = E.ecef_from_geodetic(lat, lon, h)
    C_le = E.C_en_from_geodetic(lat, lon)
    v_l = speed * np.array([math.sin(heading_rad), math.cos(heading_rad), 0.0])
    return r, C_le, v_l @ C_le


@pytest.mark.parametrize("heading_deg", [0.0, 37.0, 90.0, 200.0])
def test_injected_ecef_error_lands_in_its_local_component(heading_deg):
    psi = math.radians(heading_deg)
    r, C_le, v_e = _vehicle(LAT, LON, H, psi)
    frame = E.OriginFrame(0.3, -1.0, 0.0, "geodetic")  # origin irrelevant: p_n is ECEF
    e_hat, n_hat, u_hat = C_le
    a, b, c = 12.5, -7.0, 3.25
    err = a * e_hat + b * n_hat + c * u_hat
    got = L.local_errors(frame, r[None], v_e[None], err[None])[0]
    np.testing.assert_allclose(got[:3], [a, b, c], atol=1e-9)
    # track unit (sin psi, cos psi); left of it (-cos psi, sin psi)
    along = a * math.sin(psi) + b * math.cos(psi)
    cross = -a * math.cos(psi) + b * math.sin(psi)
    np.testing.assert_allclose(got[3:], [along, cross], atol=1e-9)
    # along the velocity: pure along-track; to its left: pure positive cross-track
    t_e = v_e / np.linalg.norm(v_e)
    got = L.local_errors(frame, r[None], v_e[None], 40.0 * t_e[None])[0]
    np.testing.assert_allclose(got[3:], [40.0, 0.0], atol=1e-9)
    left = np.cross(u_hat, t_e)
    got = L.local_errors(frame, r[None], v_e[None], 9.0 * left[None])[0]
    np.testing.assert_allclose(got[3:], [0.0, 9.0], atol=1e-9)


def test_models_agree_on_one_physical_error():
    """The same true and navigated points in wgs84 (ENU of an origin 300 km away) and in
    geodetic (ECEF) coordinates give the same local errors; both equal earth.errors_local_level
    (the ECEF form, an independent route to the same numbers)."""
    rng = np.random.default_rng(3)
    lat = LAT + rng.normal(0, 0.01, 20)
    lon = LON + rng.normal(0, 0.01, 20)
    r_true = E.ecef_from_geodetic(lat, lon, H + rng.normal(0, 100, 20))
    r_nav = r_true + rng.normal(0, 500.0, (20, 3))
    v_e = rng.normal(0, 30.0, (20, 3))
    ref = E.errors_local_level(r_true, r_nav, v_e)
    geo = E.OriginFrame(LAT, LON, H, "geodetic")
    got_geo = L.local_errors(geo, r_true, v_e, r_nav - r_true, min_speed_mps=0.0)
    np.testing.assert_allclose(got_geo, ref, atol=1e-8)
    w = E.OriginFrame(LAT - 0.047, LON + 0.02, 0.0, "wgs84")  # ~ 300 km away
    p_true, p_nav = w.n_from_ecef(r_true), w.n_from_ecef(r_nav)
    got_w = L.local_errors(w, p_true, v_e @ w.C_en.T, p_nav - p_true, min_speed_mps=0.0)
    np.testing.assert_allclose(got_w, ref, atol=1e-6)
    # the origin's ENU differs from the vehicle's by the route's angle: not a no-op
    assert np.abs((p_nav - p_true) - got_w[:, :3]).max() > 1.0


def test_flat_equals_n_errors_exactly():
    rng = np.random.default_rng(1)
    f = E.OriginFrame(LAT, 0.2, 0.0, "flat")
    p = rng.normal(0, 5e4, (30, 3))
    v = rng.normal(0, 20.0, (30, 3))
    err = rng.normal(0, 100.0, (4, 30, 3))
    got = L.local_errors(f, p, v, err)
    assert np.array_equal(got[..., :3], err)
    t = v[:, :2] / np.hypot(v[:, 0], v[:, 1])[:, None]
    np.testing.assert_allclose(got[..., 3], (err[..., :2] * t).sum(-1), atol=1e-9)
    # |along, cross| = horizontal error
    np.testing.assert_allclose(np.hypot(got[..., 3], got[..., 4]), np.hypot(*err[..., :2].T).T)


@pytest.mark.parametrize("size_m", [1e7, 1e12, 1e18])
def test_absurd_navigated_position_stays_finite(size_m):
    """A free-inertial solution thousands of Earth radii away: finite errors, same norm."""
    r, _, v_e = _vehicle(LAT, LON, H, 0.4)
    frame = E.OriginFrame(LAT, LON, H, "geodetic")
    err = size_m * np.array([[0.6, -0.48, 0.64]])
    got = L.local_errors(frame, r[None], v_e[None], err)[0]
    assert np.isfinite(got).all()
    assert np.linalg.norm(got[:3]) == pytest.approx(size_m, rel=1e-12)
    assert np.hypot(*got[3:]) == pytest.approx(np.hypot(*got[:2]), rel=1e-12)
    nan = L.local_errors(frame, np.stack([r, r]), np.stack([v_e, v_e]), [[np.nan] * 3, err[0]])
    assert np.isnan(nan[0]).all() and np.isfinite(nan[1]).all()


def test_track_direction_held_when_stopped():
    v = np.array([[0, 0, 0], [0, 5, 0], [0, 0.01, 0], [3, 0, 1], [0, 0, 0]], float)
    t = L.track_direction(v)
    np.testing.assert_array_equal(t, [[0, 1], [0, 1], [0, 1], [1, 0], [1, 0]])
    assert np.isnan(L.track_direction(np.zeros((3, 3)))).all()


def test_local_sd_rotation():
    """Identity keeps sigmas; a 90 deg turn about Up swaps East and North sigmas."""
    sd = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_allclose(L.local_sd(np.eye(3)[None], sd), sd)
    Rz = np.array([[[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]])
    np.testing.assert_allclose(L.local_sd(Rz, sd), [[2.0, 1.0, 3.0]])


# --- through the navigation stage and evaluate ------------------------------------------------
@pytest.fixture(scope="module")
def truths():
    """The same 60 s drive as a flat and as a wgs84 truth (20 Hz)."""
    pts = np.array([[0, 0, 0], [600, 0, 0], [600, 300, 0], [0, 300, 0]], float)
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": {"lat_deg": 45.0, "lon_deg": 7.0, "alt_m": 200.0}, "timed": False}
    out = {}
    for model in ("flat", "wgs84"):
        df, tm = T.build_truth(enu, meta, rate_hz=20.0, earth=model, verbose=False)
        out[model] = ttruth.Truth(df, tm)
    return out


def _biased(truth, bias_mps2=(0.02, -0.01, 0.005)):
    dv = truth.dv[1:] + np.asarray(bias_mps2) * truth.dt
    return np.stack([truth.dtheta[1:]] * 2), np.stack([dv, dv * 0.5 + truth.dv[1:] * 0.5])


def test_navigator_flat_errors_are_todays(truths):
    """flat: err_e/n/u are navigation minus truth in n, bit for bit (the table before the
    local-level errors), and along/cross split their horizontal part."""
    from imugen.navigate.mechanize import mechanize

    tr = truths["flat"]
    dth, dv = _biased(tr)
    tab = NV.navigate_arrays(tr, (dth, dv), eval_rate_hz=2.0)
    assert list(tab.columns) == list(tnav.COLUMNS)
    nav = Navigator(tr, 2.0)
    m = mechanize(dth, dv, tr.dt, *nav.x0, tr.origin_frame(), every=nav.every, outputs=("p",))
    err = m.p_n - tr.p_n[m.index][None]
    for i, c in enumerate(tnav.ERR_POS):
        assert np.array_equal(tab[c].to_numpy(), err[..., i].ravel())
    h = np.hypot(tab.err_e_m, tab.err_n_m)
    np.testing.assert_allclose(np.hypot(tab.err_along_m, tab.err_cross_m), h, rtol=1e-12)
    assert h.max() > 1.0


def test_navigator_wgs84_local_level(truths):
    """wgs84: the table equals the ECEF form (earth.errors_local_level) applied to the
    mechanized positions, and differs from the origin-ENU difference."""
    from imugen.navigate.mechanize import mechanize

    tr = truths["wgs84"]
    dth, dv = _biased(tr)
    tab = NV.navigate_arrays(tr, (dth, dv), eval_rate_hz=2.0)
    frame = tr.origin_frame()
    nav = Navigator(tr, 2.0)
    m = mechanize(dth, dv, tr.dt, *nav.x0, frame, every=nav.every, outputs=("p",))
    p_true = tr.p_n[m.index]
    ref = E.errors_local_level(
        frame.ecef_from_n(p_true)[None],
        frame.ecef_from_n(m.p_n),
        (tr.v_n[m.index] @ frame.C_en)[None],
    )
    got = tab[list(tnav.ERR_POS)].to_numpy().reshape(ref[..., :3].shape)
    np.testing.assert_allclose(got, ref[..., :3], atol=1e-7)
    moving = np.hypot(*tr.v_n[m.index, :2].T) >= L.MIN_SPEED_MPS
    track = tab[list(tnav.ERR_TRACK)].to_numpy().reshape(ref[..., 3:].shape)
    np.testing.assert_allclose(track[:, moving], ref[:, moving, 3:], atol=1e-7)
    assert np.isfinite(track).all()  # stopped epochs hold the last track direction
    assert np.abs(got - (m.p_n - p_true[None])).max() > 1e-6  # the rotation is not a no-op


def test_navigator_geodetic_equals_wgs84(truths):
    """The same drive re-expressed in ECEF (geodetic: p, v, attitude turned by C_ne), the same
    increments: the same local-level errors, to 1e-8 m (the formulation does not show)."""
    from imugen.core import rotations as R

    tr = truths["wgs84"]
    f = tr.origin_frame()
    df = tr.frame.copy()
    q_ne = R.dcm_to_quat(f.C_en.T[None])[0]
    q_eb = R.quat_mul(np.broadcast_to(q_ne, tr.q_nb.shape), tr.q_nb)
    for cols, x in ((ttruth.POS, f.ecef_from_n(tr.p_n)), (ttruth.VEL, tr.v_n @ f.C_en),
                    (ttruth.QUAT, q_eb)):  # fmt: skip
        for i, c in enumerate(cols):
            df[c] = x[:, i]
    geo = ttruth.Truth(df, {**tr.meta, "earth": "geodetic"})
    assert geo.origin_frame().model == "geodetic"
    dth, dv = _biased(tr)
    a = NV.navigate_arrays(tr, (dth, dv), eval_rate_hz=2.0)
    b = NV.navigate_arrays(geo, (dth, dv), eval_rate_hz=2.0)
    cols = [*tnav.ERR_POS, *tnav.ERR_TRACK]
    assert np.abs(a[cols].to_numpy()).max() > 10.0
    # 2e-7 m: a gravitation block at the check's limit may fall back in one frame only
    # (mechanize.GRAVITY_TOL_MPS2; one fallback moves positions by ~1e-7 m over minutes)
    np.testing.assert_allclose(b[cols].to_numpy(), a[cols].to_numpy(), rtol=0, atol=2e-7)


def test_sequence_metrics_track_columns():
    n = 11
    t = np.arange(n, dtype=float)
    nav = pd.DataFrame(
        {
            "sequence": 3,
            "time_s": t,
            "err_e_m": t,
            "err_n_m": 0.0,
            "err_u_m": 0.0,
            "err_along_m": 2.0 * t,
            "err_cross_m": -1.0,
        }
    )
    m = EV.sequence_metrics(nav, 100.0).loc[3]
    assert m.rmse_along_m == pytest.approx(2.0 * np.sqrt(np.mean(t**2)))
    assert m.rmse_cross_m == pytest.approx(1.0)
    assert m.final_along_m == 20.0 and m.final_cross_m == -1.0
    row = EV.grade_row("g", EV.sequence_metrics(nav, 100.0))
    assert row["along_m"] == pytest.approx(m.rmse_along_m) and row["final_cross_m"] == -1.0
    human = EV.display_table(EV.grade_table([row]))
    assert {"Along (m)", "Cross (m)"} <= set(human.columns)
    # a table without the track columns still evaluates (older navigation files)
    old = EV.sequence_metrics(nav.drop(columns=list(tnav.ERR_TRACK)), 100.0)
    assert "rmse_along_m" not in old.columns and "along_m" not in EV.grade_row("g", old)


def test_meaningless_flag_and_finite_tables(tmp_path):
    """A several-hour consumer run 30 Earth radii off: flagged and warned, numbers finite."""
    big = 30 * EV.EARTH_RADIUS_M
    rows = []
    for g, s in (("consumer", big), ("navigation", 50.0)):
        nav = pd.DataFrame(
            {
                "sequence": np.repeat([0, 1], 5),
                "time_s": np.tile(np.arange(5.0) * 3600, 2),
                "err_e_m": s,
                "err_n_m": s,
                "err_u_m": 0.0,
                "err_along_m": s,
                "err_cross_m": s,
            }
        )
        m = EV.sequence_metrics(nav, 4e6)
        assert np.isfinite(m.to_numpy(float)).all()
        row = EV.grade_row(g, m)
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            row["free_inertial_meaningless"] = EV.warn_meaningless(g, row["final_3d_m"], 5e6, False)
        assert bool(w) == (g == "consumer")
        if w:
            assert "too long for unaided inertial navigation" in str(w[0].message)
        rows.append(row)
    EV.write_tables(EV.grade_table(rows), tmp_path / "rmse.csv")
    csv = pd.read_csv(tmp_path / "rmse.csv")
    assert list(csv.free_inertial_meaningless) == [True, False]
    assert "meaningless" in (tmp_path / "rmse.md").read_text()


def test_distance_and_extent_same_in_wgs84_and_geodetic(tmp_path, monkeypatch):
    """The horizontal distance and extent of a truth do not depend on its coordinates."""
    rng = np.random.default_rng(2)
    lat = np.radians(40.0) + np.cumsum(rng.normal(0, 1e-4, 200))
    lon = np.radians(179.99) + np.cumsum(np.full(200, 2e-5))  # crosses the antimeridian
    h = 100.0 + rng.normal(0, 5, 200)
    r = E.ecef_from_geodetic(lat, lon, h)
    got = {}
    for model in ("wgs84", "geodetic"):
        f = E.OriginFrame(lat[0], lon[0], 0.0, model)
        p = f.n_from_ecef(r)
        df = pd.DataFrame(p, columns=list(ttruth.POS))
        meta = {"origin": {"lat_deg": math.degrees(lat[0]), "lon_deg": math.degrees(lon[0]),
                           "alt_m": 0.0}, "earth": model}  # fmt: skip
        ttruth.write(df, meta, tmp_path / f"{model}.parquet")
        got[model] = (EV.horizontal_distance_m(tmp_path / f"{model}.parquet"),
                      EV.extent_m(tmp_path / f"{model}.parquet"))  # fmt: skip
    assert got["geodetic"][0] == pytest.approx(got["wgs84"][0], rel=1e-9)
    # streamed in blocks: the same figures whatever the block size
    monkeypatch.setattr(EV, "POSITION_BATCH", 7)
    small = (EV.horizontal_distance_m(tmp_path / "geodetic.parquet"),
             EV.extent_m(tmp_path / "geodetic.parquet"))  # fmt: skip
    np.testing.assert_allclose(small, got["geodetic"], rtol=1e-12)
    assert got["geodetic"][1] == pytest.approx(got["wgs84"][1], rel=1e-9)
    # an independent figure: chords between successive ECEF points, heights removed
    chord = np.linalg.norm(np.diff(E.ecef_from_geodetic(lat, lon, 0 * h), axis=0), axis=1).sum()
    assert got["geodetic"][0] == pytest.approx(chord, rel=1e-3)


def test_meaningless_covers_overflow_and_breakdown():
    assert EV.meaningless(np.inf, None) and EV.meaningless(np.nan, 1e6)
    assert EV.meaningless(1.5 * EV.EARTH_RADIUS_M, 7.6e6)  # beyond the radius, any extent


def _six_hour_flight(tmp_path):
    """A 6 h geodetic truth across the antimeridian and navigation errors growing to 3 Earth
    radii; returns (lat, lon) of the truth [rad]."""
    n = 361
    lat = np.radians(np.linspace(40.0, 48.0, n))
    lon = np.radians(np.linspace(175.0, 195.0, n))  # across the antimeridian
    r = E.ecef_from_geodetic(lat, lon, np.full(n, 10_000.0))
    t = np.linspace(0.0, 6 * 3600.0, n)
    df = pd.DataFrame({ttruth.TIME: t, **{c: r[:, i] for i, c in enumerate(ttruth.POS)}})
    meta = {"origin": {"lat_deg": 40.0, "lon_deg": 175.0, "alt_m": 0.0}, "earth": "geodetic"}
    ttruth.write(df, meta, tmp_path / "truth.parquet")
    g = 3 * EV.EARTH_RADIUS_M * (t / t[-1]) ** 2
    nav = pd.DataFrame({"sequence": np.int64(0), "time_s": t, "err_e_m": 0.6 * g,
                        "err_n_m": 0.8 * g, "err_u_m": 0.0, "err_along_m": g,
                        "err_cross_m": 0.0, "err_att_rad": 0.0})  # fmt: skip
    tnav.write(nav, {"stage": "navigate"}, tmp_path / "nav.parquet")
    return lat, lon


def test_evaluate_run_geodetic_truth_several_hours(tmp_path):
    """A 6 h flight in ECEF coordinates, navigation errors of 3 Earth radii at the end: the
    metrics stay finite, evaluate and tables warn, rmse.csv carries the flag."""
    lat, lon = _six_hour_flight(tmp_path)
    with pytest.warns(UserWarning, match="too long for unaided inertial navigation"):
        EV.run(tmp_path / "truth.parquet", [tmp_path / "nav.parquet"], tmp_path / "m.parquet",
               EvaluateOptions(grade="consumer"))  # fmt: skip
    from imugen.tables import metrics as tmetrics

    m = tmetrics.read(tmp_path / "m.parquet")
    assert np.isfinite(m.drop(columns="sequence").to_numpy(float)).all()
    assert m.final_along_m.item() == pytest.approx(3 * EV.EARTH_RADIUS_M)
    dist = tmetrics.read_meta(tmp_path / "m.parquet")["distance_horizontal_m"]
    _, _, steps = Geod(ellps="WGS84").inv(np.degrees(lon[:-1]), np.degrees(lat[:-1]),
                                          np.degrees(lon[1:]), np.degrees(lat[1:]))  # fmt: skip
    assert dist == pytest.approx(steps.sum() * (E.A_WGS84 + 1e4) / E.A_WGS84, rel=2e-3)
    with pytest.warns(UserWarning, match="consumer"):
        EV.run_tables([tmp_path / "m.parquet"], tmp_path / "rmse.csv")
    csv = pd.read_csv(tmp_path / "rmse.csv")
    assert bool(csv.free_inertial_meaningless.item())
    assert {"along_m", "cross_m", "final_along_m", "final_cross_m"} <= set(csv.columns)


def test_meaningless_warning_is_one_log_line(tmp_path, cli):
    """``imugen evaluate`` and ``imugen tables`` print the warning as the one line
    ``imugen: warning: GRADE: ...`` (no Python source location, no code line)."""
    _six_hour_flight(tmp_path)
    m = tmp_path / "m.parquet"
    for args in (
        ("evaluate", tmp_path / "truth.parquet", tmp_path / "nav.parquet", "-o", m),
        ("tables", m, "-o", tmp_path / "rmse.csv"),
    ):
        proc = cli(*args, *(("--grade", "consumer") if args[0] == "evaluate" else ()), check=0)
        lines = [ln for ln in proc.stderr.splitlines() if "warning" in ln.lower()]
        assert len(lines) == 1, proc.stderr
        assert lines[0].startswith("imugen: warning: consumer: median final free-inertial error ")
        assert lines[0].endswith("turn on gnss.enabled and use the aided figures")
        assert "UserWarning" not in proc.stderr and ".py:" not in proc.stderr


def test_other_warning_categories_stay_one_line(capsys):
    """A library's RuntimeWarning keeps its category and origin, on one line."""
    from imugen import cli as C

    C._show_warning(RuntimeWarning("overflow\nin exp"), RuntimeWarning, "/x/y.py", 7)
    err = capsys.readouterr().err
    assert err == "imugen: warning: RuntimeWarning: overflow\\nin exp (/x/y.py:7)\n"


def test_error_vs_time_track_panels(tmp_path):
    """With the track columns: four panels; the along panel's line is the median over
    sequences of |along| at each epoch; without them: the two panels of before."""
    from imugen.core.io import write_parquet
    from imugen.core.plotting import style
    from imugen.figures import stage as fg

    t = np.arange(1.0, 11.0)
    parts = []
    for s in range(5):
        k = 1.0 + s
        parts.append(pd.DataFrame({"sequence": s, "time_s": t, "err_e_m": k * t, "err_n_m": 0.0,
                                   "err_u_m": 1.0, "err_along_m": -2.0 * k * t,
                                   "err_cross_m": 0.5 * k, "err_att_rad": 0.0}))  # fmt: skip
    nav = pd.concat(parts, ignore_index=True)
    p = write_parquet(nav, {}, tmp_path / "nav.parquet")
    with style():
        fig = fg.error_vs_time_figure({"tactical": [p]})
    ax = {a.get_title(): a for a in fig.axes}
    assert set(ax) == {"Horizontal position error", "Vertical position error",
                       "Along-track error", "Cross-track error"}  # fmt: skip
    along = ax["Along-track error"].lines[0]
    np.testing.assert_allclose(along.get_ydata(), 2.0 * 3.0 * t)  # median k = 3
    np.testing.assert_allclose(ax["Cross-track error"].lines[0].get_ydata(), 1.5)
    old = write_parquet(nav.drop(columns=list(tnav.ERR_TRACK)), {}, tmp_path / "old.parquet")
    with style():
        fig = fg.error_vs_time_figure({"tactical": [old]})
    assert len(fig.axes) == 2


def test_apply_bits_independent_of_the_batch():
    """Each sequence's errors carry the same bits alone or among others (batch-independent
    navigation tables)."""
    rng = np.random.default_rng(5)
    f = E.OriginFrame(LAT, LON, H, "geodetic")
    r = E.ecef_from_geodetic(LAT + rng.normal(0, 0.01, 40), LON + rng.normal(0, 0.01, 40), 0.0)
    C = L.rotation_ln(f, r)
    t = L.track_direction(np.einsum("jik,jk->ji", C, rng.normal(0, 9, (40, 3))))
    err = rng.normal(0, 1e3, (7, 40, 3))
    whole = L.apply(C, t, err)
    assert all(np.array_equal(L.apply(C, t, err[s : s + 1])[0], whole[s]) for s in range(7))
    assert np.array_equal(L.apply(C, t, err[3]), whole[3])
