"""Aid stage (imugen aid): files consistent with their contracts and with the array API.

Oracles: the GNSS table against the truth at each fix's time of validity; the draw of a
sequence independent of the batch; ideal IMU + noiseless GNSS through the files stays on the
truth; the outage-end error of the file equals the filter run in memory on the same inputs
(receiver, scenario and filter called directly); evaluation figures recomputed by hand; the
workflow schedules the aid jobs only when ``gnss.enabled``.
"""

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from imugen import truth as T
from imugen.aid import filter as A
from imugen.aid import gnss as G
from imugen.aid import scenarios as SC
from imugen.aid import stage as AID
from imugen.core.errors import InputError
from imugen.evaluate import stage as EV
from imugen.tables import aided as taided
from imugen.tables import gnss as tgnss
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth

from helpers import simulate_shard

OUTAGE = {"kind": "outage", "start_s": 80.0, "duration_s": 30.0}
SEED = 5


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 180 s car truth (flat), a consumer shard of 3 sequences, the stage run on it."""
    d = tmp_path_factory.mktemp("aid")
    pts = np.array(
        [[0, 0, 0], [400, 0, 0], [400, 200, 0], [0, 200, 0], [0, 0, 0], [400, 0, 0], [400, 200, 0]],
        float,
    )
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": {"lat_deg": 45.0, "lon_deg": 7.0, "alt_m": 200.0}, "timed": False}
    # a rigid car (no dive and squat on a suspension): the subject is the stage's plumbing and
    # the stage's ideal-IMU exactness (attitude < 2e-3 rad; 2.8e-3 on the car's
    # suspension, whose dive NHC's vertical row covers; tests/aid/test_filter.py checks that case)
    df, tm = T.build_truth(
        enu, meta, rate_hz=100.0, earth="flat", vehicle="car", verbose=False,
        vehicle_params={"suspension": "rigid"},
    )  # fmt: skip
    ttruth.write(df, tm, d / "truth.parquet")
    simulate_shard(d / "truth.parquet", d / "imu.parquet", "consumer", sequences=3, seed=SEED, shard=1,
          shard_size=3, route="car", dtype="float64")  # fmt: skip
    params = AID.AidOptions(intervals=(OUTAGE,))
    AID.run(d / "truth.parquet", d / "imu.parquet", d / "g.parquet", d / "a.parquet", params)
    return d


def test_gnss_file_matches_truth_and_labels(scene):
    truth = ttruth.read(scene / "truth.parquet")
    g = tgnss.read(scene / "g.parquet")
    lab = tgnss.read_labels(scene / "g.parquet")
    ivs = tgnss.read_intervals(scene / "g.parquet")
    ids = tshard.read_labels(scene / "imu.parquet")["sequence"].to_numpy()
    assert list(g.columns) == list(tgnss.COLUMNS)
    np.testing.assert_array_equal(lab["sequence"].to_numpy(), ids)
    np.testing.assert_array_equal(np.unique(g["sequence"]), ids)
    assert list(ivs["kind"]) == ["outage"] * 3 and np.allclose(ivs["end_s"], 110.0)
    t = g["time_s"].to_numpy()
    inside = (t >= 80.0 - 1e-9) & (t < 110.0 - 1e-9)
    assert np.all(g["state"].to_numpy()[inside] == 1) and np.all(
        g["state"].to_numpy()[~inside] == 0
    )
    assert (
        np.all(g["fix"].to_numpy()[inside] == 0)
        and np.isnan(g.loc[inside, list(tgnss.P)].to_numpy()).all()
    )
    # measured - true error = true antenna (zero lever arm: the IMU) at the time of validity
    for sid, rows in g[~inside & (g["fix"] > 0)].groupby("sequence"):
        lat = lab.set_index("sequence").loc[sid, "gnss_latency_s"]
        ant = rows[list(tgnss.P)].to_numpy() - rows[list(tgnss.OFFSET_P)].to_numpy()
        tv = rows["time_s"].to_numpy() - lat
        ref = np.stack([np.interp(tv, truth.time_s, truth.p_n[:, i]) for i in range(3)], -1)
        assert np.max(np.abs(ant - ref)) < 2e-3  # linear vs Hermite interpolation, 10 m/s car
        sd = rows[list(tgnss.SIGMA_P)].to_numpy()[0]
        exp = np.hypot(lab.set_index("sequence").loc[sid, "gnss_position_white_h_m"],
                       lab.set_index("sequence").loc[sid, "gnss_position_bias_h_m"])  # fmt: skip
        assert sd[0] == pytest.approx(exp)


def test_draw_does_not_depend_on_batch(scene, tmp_path):
    params = AID.AidOptions(intervals=(OUTAGE,))
    AID.run(scene / "truth.parquet", scene / "imu.parquet", tmp_path / "g.parquet",
            tmp_path / "a.parquet", params, batch=1)  # fmt: skip
    pd.testing.assert_frame_equal(
        tgnss.read(tmp_path / "g.parquet"), tgnss.read(scene / "g.parquet")
    )
    pd.testing.assert_frame_equal(
        taided.read(tmp_path / "a.parquet"), taided.read(scene / "a.parquet")
    )
    # streamed: one row group per batch of one sequence (a shard's table never sits whole)
    assert pq.ParquetFile(tmp_path / "a.parquet").num_row_groups == 3


def test_outage_end_equals_filter_in_memory(scene):
    """The file's outage-end error = the array API run by hand on the same inputs."""
    truth = ttruth.read(scene / "truth.parquet")
    shard = tshard.read(scene / "imu.parquet").to_pandas()
    ids = shard["sequence"].unique()
    K = truth.K
    dth = shard[list(tshard.INCREMENTS[:3])].to_numpy().reshape(len(ids), K, 3)
    dv = shard[list(tshard.INCREMENTS[3:])].to_numpy().reshape(len(ids), K, 3)
    rid, idx = tshard.split_ids(ids)
    gs = []
    for j in range(len(ids)):
        ent = [SEED, int(rid[j]), int(idx[j])]
        g = G.simulate_gnss(truth.time_s, truth.p_n, truth.v_n, truth.q_nb, truth.omega_ib_b,
                            "standalone", 1, ent, 0)  # fmt: skip
        gs.append(SC.apply(g, [OUTAGE], ent, 0))
    from imugen.aid.stage import _stack

    scen = _stack(gs)
    tun = A.Tuning.from_grade("consumer", "law")
    Tm = A.tuning_matrix(tun, len(ids), gnss_receiver=scen.gnss.receiver, gnss_level="law")
    # the stage's NHC noise: the truth's own slip (its plausibility report)
    slip = AID.truth_slip_sd(truth.meta.get("plausibility"))
    damped = (truth.meta.get("vehicle_params") or {}).get("suspension") == "damped"
    assert not damped  # the scene's car is rigid: no dive and squat for NHC to cover
    opts = A.Options(
        nhc=True, zupt=True, nhc_sd_mps=slip,
        nhc_pitch_sd_rad=AID.suspension_pitch_sd("car", damped=damped),
    )  # fmt: skip
    res = A.run(dth, dv, truth.dt, truth.origin_frame(), scen.gnss, tun, opts, tuning_T=Tm)
    last = np.flatnonzero(scen.gnss.time_s < 110.0 - 1e-9)[-1]  # last epoch without a fix
    err = res.p_n[:, last] - truth.p_n[res.index[last]]
    a = taided.read(scene / "a.parquet")
    ends = a[np.isclose(a["time_s"], scen.gnss.time_s[last])].set_index("sequence").loc[ids]
    np.testing.assert_allclose(ends[list(taided.ERR_POS)].to_numpy(), err, rtol=0, atol=1e-9)
    assert np.allclose(ends["since_fix_s"], 30.0, atol=0.11) and np.all(ends["gnss_used"] == 0)
    # evaluation: outage_30s_end_m is the horizontal error at that epoch
    m = EV.aided_metrics(a)
    np.testing.assert_allclose(m.loc[ids, "outage_30s_end_m"], np.hypot(err[:, 0], err[:, 1]))
    # with GNSS: RMSE over the used, nominal epochs, recomputed
    on = a[(a["gnss_used"] == 1) & (a["state"] == 0)]
    r = np.sqrt((on[list(taided.ERR_POS)] ** 2).groupby(on["sequence"]).mean().sum(axis=1))
    np.testing.assert_allclose(m["aided_total_m"], r.loc[m.index])
    # the filter's sigma is in the file: errors normalized by it are of order 1
    assert 0.1 < m["aided_nees_pos"].median() < 10
    # full state: every row equals the filter's output at its epoch, sigmas its covariance
    assert list(a.columns) == list(taided.COLUMNS)
    j = np.searchsorted(scen.gnss.time_s, a["time_s"].to_numpy())
    s = np.searchsorted(ids, a["sequence"].to_numpy())
    for cols, arr in (
        (ttruth.POS, res.p_n), (ttruth.VEL, res.v_n), (ttruth.QUAT, res.q_nb),
        (taided.GYRO_BIAS, res.gyro_bias), (taided.ACCEL_BIAS, res.accel_bias),
        (taided.SD_VEL, res.sd[..., 3:6]), (taided.SD_ATT, res.sd[..., 6:9]),
        (taided.SD_GYRO_BIAS, res.sd[..., 9:12]), (taided.SD_ACCEL_BIAS, res.sd[..., 12:15]),
    ):  # fmt: skip
        np.testing.assert_array_equal(a[list(cols)].to_numpy(), arr[s, j])
    # closure with the truth: position minus truth is the error column; attitude error angle
    ti = res.index[j]
    np.testing.assert_allclose(
        a[list(ttruth.POS)].to_numpy() - truth.p_n[ti], a[list(taided.ERR_POS)], atol=1e-9
    )
    q = a[list(ttruth.QUAT)].to_numpy()
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-9)
    ang = np.linalg.norm(A.attitude_error(q, truth.q_nb[ti]), axis=-1)
    np.testing.assert_allclose(ang, a["err_att_rad"], atol=1e-12)


def test_ideal_imu_and_gnss_stay_on_truth(scene, tmp_path):
    simulate_shard(scene / "truth.parquet", tmp_path / "ideal.parquet", "consumer", sequences=1, seed=1,
          route="car", terms=[], dtype="float64")  # fmt: skip
    cfg = {"id": 902, "rate_hz": 10, "latency_s": 0.0, "position_bias_tau_s": 60.0}
    cfg.update({k: 0.0 for k in G.FIGURES if k not in cfg})
    cfg["position_white_h_m"] = cfg["position_white_v_m"] = 1e-3  # 1 mm: R > 0
    rec = G.receiver_from_config("quiet", cfg)
    # no NHC: the truth's car may slip sideways by up to a degree in corners (the ground-vehicle
    # attitude model), so the constraint is not exact for it
    params = AID.AidOptions(
        receiver=rec, draw="nominal", gnss_bias_states=False, zupt=False, nhc=False
    )
    AID.run(scene / "truth.parquet", tmp_path / "ideal.parquet", tmp_path / "g.parquet",
            tmp_path / "a.parquet", params)  # fmt: skip
    a = taided.read(tmp_path / "a.parquet")
    assert len(a) > 150
    assert np.abs(a[list(taided.ERR_POS)].to_numpy()).max() < 5e-3
    # the alignment's heading transient, inside the filter's own 3 sigma (1.2e-3 rad at 28 s
    # with the accelerometer cross-coupling states: their prior slows it, r26 study)
    sd_att = np.linalg.norm(a[list(taided.SD_ATT)].to_numpy(), axis=1)
    assert np.all(a["err_att_rad"].to_numpy() < 3 * sd_att)
    assert a["err_att_rad"].max() < 2e-3
    truth = ttruth.read(scene / "truth.parquet")
    k = np.searchsorted(truth.time_s, a["time_s"].to_numpy() - 1e-9)
    np.testing.assert_allclose(a[list(ttruth.VEL)].to_numpy(), truth.v_n[k], atol=5e-3)
    dq = np.abs(np.sum(a[list(ttruth.QUAT)].to_numpy() * truth.q_nb[k], axis=1))
    assert np.all(dq > np.cos(1e-3))  # same rotation (angle < 2e-3), scalar first (sign free)
    # nothing to estimate: the biases stay inside their reported 3-sigma
    b = a[[*taided.GYRO_BIAS, *taided.ACCEL_BIAS]].to_numpy()
    sd = a[[*taided.SD_GYRO_BIAS, *taided.SD_ACCEL_BIAS]].to_numpy()
    assert np.all(np.abs(b) < 3 * sd)


def test_bad_inputs_are_one_line_errors(scene, tmp_path, cli):
    with pytest.raises(InputError, match="kind must be one of"):
        SC.parse_scenarios(["tunnel:30"])
    with pytest.raises(InputError, match="only outage"):
        SC.parse_scenarios(["jamming:30"])
    assert SC.parse_scenarios(["outage:60", "outage:30", "jamming"]) == {
        "intervals": [],
        "draw_kinds": ["outage", "jamming"],
        "outage_durations_s": [30.0, 60.0],
    }
    r = cli("aid", str(scene / "truth.parquet"), str(scene / "imu.parquet"), "--gnss-out",
            str(tmp_path / "g.parquet"), "-o", str(tmp_path / "a.parquet"), "--receiver", "nope")  # fmt: skip
    assert r.returncode == 2 and "unknown receiver" in r.stderr
    assert not (tmp_path / "g.parquet").exists() and not (tmp_path / "a.parquet").exists()


def test_meaningless_free_inertial_flag():
    assert EV.meaningless(0.2 * EV.EARTH_RADIUS_M, None)
    assert not EV.meaningless(1e3, None)
    assert EV.meaningless(5e4 + 1, 500.0) and not EV.meaningless(5e4 - 1, 500.0)


def test_workflow_schedules_aid_only_when_enabled(tmp_path):
    """Dry runs (the subprocess keeps this worktree's PYTHONPATH): no aid job by default; one
    per route, grade and shard with ``gnss.enabled`` (and one outage figure per route); a bad
    receiver refused by the schema."""

    import helpers as W

    cfg = {k: v for k, v in W.TINY.items() if k != "grades"}
    cfg["grades"] = {"consumer": {}, "tactical": {}}
    W.write_config(tmp_path, cfg)
    jobs = W.planned_jobs(tmp_path)
    assert "aid" not in jobs and "outage_figure" not in jobs and "outage_drift" not in jobs
    W.write_config(tmp_path, {**cfg, "gnss": {"enabled": True}, "scenarios": {"outages_s": [60]}})
    jobs = W.planned_jobs(tmp_path)
    shards = cfg["simulate"]["sequences"] // cfg["simulate"]["sequences_per_shard"]
    assert jobs["aid"] == len(cfg["routes"]) * len(cfg["grades"]) * shards
    assert jobs["outage_figure"] == len(cfg["routes"])  # the outage figure of each route
    assert jobs["outage_drift"] == len(cfg["routes"])  # and its outage-drift table and figure
    W.write_config(tmp_path, {**cfg, "gnss": {"enabled": True, "receiver": "galileo"}})
    proc = W.snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0 and "galileo" in proc.stdout + proc.stderr


def _aid_scenarios(tmp_path, scenarios):
    """The ``--scenario`` specs of the dry run's first ``imugen aid`` command."""
    import shlex

    import helpers as W

    cfg = {"routes": {"example": {"file": str(W.ROUTE)}}, "grades": {"consumer": {}},
           "simulate": {"sequences": 2, "sequences_per_shard": 2, "seed": 7},
           "gnss": {"enabled": True}}  # fmt: skip
    if scenarios is not None:
        cfg["scenarios"] = scenarios
    W.write_config(tmp_path, cfg)
    proc = W.snakemake(tmp_path, "-n", "-p", "-j1")
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = (proc.stdout + proc.stderr).splitlines()
    line = next(x for x in lines if x.startswith("Shell command: imugen aid "))
    return [w.split("=", 1)[1] for w in shlex.split(line) if w.startswith("--scenario=")]


def test_declared_outages_are_the_outages_drawn_ones_only_where_asked(tmp_path):
    """Declared outages without ``scenarios.outages_s``: those, nothing drawn (the schema's
    presets used to be drawn beside them); with ``outages_s`` given: drawn beside them; with
    none declared: the presets drawn, as before."""
    declared = [{"kind": "outage", "start_s": 90, "duration_s": 30}]
    assert _aid_scenarios(tmp_path, {"intervals": declared}) == ["outage:30.0@90.0"]
    both = _aid_scenarios(tmp_path, {"intervals": declared, "outages_s": [60]})
    assert both == ["outage:60.0", "outage:30.0@90.0"]
    assert _aid_scenarios(tmp_path, None) == [f"outage:{d!r}" for d in SC.OUTAGE_PRESETS_S]
    jamming = [{"kind": "jamming", "start_s": 90, "duration_s": 30}]  # no declared outage
    assert _aid_scenarios(tmp_path, {"intervals": jamming})[:4] == [
        f"outage:{d!r}" for d in SC.OUTAGE_PRESETS_S
    ]


def test_aided_metrics_on_a_constructed_table():
    """Closed-form table: a no-fix run at the start (not an outage), then GNSS, then a 30 s
    outage whose East error grows as 0.5 t (crosses 10 m at 20 s), then GNSS again."""
    t = np.arange(0.0, 80.0)
    since = np.where(t < 3, np.nan, 0.0)
    out = (t >= 40) & (t < 70)
    since[out] = t[out] - 39.0  # last fix at 39 s
    e = np.where(out, 0.5 * since, 1.0)
    e[t < 3] = 100.0  # before the first fix: ignored by every figure
    used = (~out & (t >= 3)).astype(np.int8)
    rows = []
    for sid, k in ((7, 1.0), (9, 2.0)):
        rows.append(pd.DataFrame({
            "sequence": sid, "time_s": t, "err_e_m": k * e, "err_n_m": 0.0, "err_u_m": 0.0,
            "err_att_rad": 0.0, "sd_e_m": 1.0, "sd_n_m": 1.0, "sd_u_m": 1.0,
            "gnss_used": used, "state": out.astype(np.int8), "since_fix_s": since,
        }))  # fmt: skip
    m = EV.aided_metrics(pd.concat(rows, ignore_index=True))
    np.testing.assert_allclose(m.loc[[7, 9], "aided_total_m"], [1.0, 2.0])
    np.testing.assert_allclose(m.loc[[7, 9], "aided_nees_pos"], [1 / 3, 4 / 3])
    np.testing.assert_allclose(m.loc[[7, 9], "outage_30s_end_m"], [15.0, 30.0])
    np.testing.assert_allclose(m.loc[[7, 9], "time_to_10m_s"], [21.0, 11.0])  # first > 10 m
    assert [c for c in m.columns if c.startswith("outage_")] == ["outage_30s_end_m"]


def test_correction_out_and_in_follow_their_contract(scene, tmp_path):
    """``--correction-out`` streams what the filter removed from each increment (every sample
    of every sequence) without changing the aided table; a learner's zero correction through
    ``--correction-in`` changes nothing; a table missing a sequence is refused in one line."""
    from imugen.tables import imu_correction as tcorr

    d = scene
    params = AID.AidOptions(intervals=(OUTAGE,))
    AID.run(d / "truth.parquet", d / "imu.parquet", tmp_path / "g.parquet",
            tmp_path / "a.parquet", params, out_correction=tmp_path / "c.parquet")  # fmt: skip
    ref = taided.read(d / "a.parquet")
    pd.testing.assert_frame_equal(taided.read(tmp_path / "a.parquet"), ref)
    c = tcorr.read(tmp_path / "c.parquet")
    ids = tshard.read_labels(d / "imu.parquet")["sequence"].to_numpy()
    K = ttruth.read(d / "truth.parquet").K
    assert list(c.columns) == list(tcorr.COLUMNS) and len(c) == len(ids) * K
    dth, dv = tcorr.arrays(tmp_path / "c.parquet", ids, K)
    # the filter's gyro-bias estimate times dt dominates the angle correction (consumer grade;
    # the cross-coupling's share depends on the rate)
    late = ref.groupby("sequence")[list(taided.GYRO_BIAS)].last()
    np.testing.assert_allclose(dth[:, -1], late.loc[ids].to_numpy() * 0.01, rtol=0.3, atol=2e-7)
    assert np.isfinite(dv).all() and np.abs(dv[:, -1]).max() > 0.0
    assert np.all(dth[:, 0] == 0.0)  # row 0 unused
    zeros = tcorr.frame(ids, np.zeros((len(ids), K, 6)))
    tcorr.write(zeros, {"what": "zeros"}, tmp_path / "z.parquet")
    AID.run(d / "truth.parquet", d / "imu.parquet", tmp_path / "g2.parquet",
            tmp_path / "a2.parquet", params, correction_in=tmp_path / "z.parquet")  # fmt: skip
    pd.testing.assert_frame_equal(taided.read(tmp_path / "a2.parquet"), ref)
    part = tcorr.frame(ids[:2], np.zeros((2, K, 6)))
    tcorr.write(part, {}, tmp_path / "p.parquet")
    with pytest.raises(InputError, match=f"sequence {ids[2]} has 0 samples"):
        tcorr.arrays(tmp_path / "p.parquet", ids, K)


def test_filter_options_cover_the_suspension_the_truth_was_built_with():
    """A truth built on its suspension (metadata ``vehicle_params.suspension: damped``) gets
    NHC's pitch sigma (the class's pitch gradient x tyre limit); a rigid one none; without the
    record, the class's default."""
    from imugen.aid.options import AidOptions

    p = AidOptions()
    damped = AID.filter_options(p, "car", vehicle_params={"suspension": "damped"})
    rigid = AID.filter_options(p, "car", vehicle_params={"suspension": "rigid"})
    assert damped.nhc_pitch_sd_rad == pytest.approx(AID.suspension_pitch_sd("car", damped=True))
    assert damped.nhc_pitch_sd_rad > 0.02 and rigid.nhc_pitch_sd_rad == 0.0
    assert AID.filter_options(p, "car").nhc_pitch_sd_rad == AID.suspension_pitch_sd("car")


def test_nhc_vertical_slip_sigma_does_not_count_the_dive_twice():
    """On a car on its suspension the body's vertical speed holds the dive and squat
    (``-u sin theta_s``), which NHC covers with its own ``nhc_pitch_sd_rad``: the vertical
    slip sigma comes from the vehicle's speed under that pitch (the path's own, the same as
    the rigid car's on the same road), the lateral from the body's lateral speed."""
    t = np.arange(0.0, 40.0, 0.1)  # accelerate at 2 m/s^2 to 20 m/s, brake at 4 m/s^2 to 8
    v = np.clip(np.minimum(np.minimum(2.0 * t, 20.0), 20.0 - 4.0 * (t - 25.0)), 8.0, None)
    x = np.r_[0.0, np.cumsum(0.5 * (v[1:] + v[:-1]) * 0.1)]
    y = 5.0 * np.sin(x / 80.0)  # a gentle weave: some lateral acceleration
    df, meta = T.enu_table(np.column_stack([x, y, 0.01 * x]), t, (31.63, -7.99, 480.6))
    reps = {}
    for susp in ("rigid", "damped"):
        _, m = T.build_truth(
            df, meta, rate_hz=50, earth="flat", vehicle="car", verbose=False,
            vehicle_params={"suspension": susp},
        )  # fmt: skip
        reps[susp] = m["plausibility"]
    rigid, damped = reps["rigid"], reps["damped"]
    # the dive is in the body's vertical speed, not in the vehicle's under it
    assert damped["rms_body_vertical_speed_mps"] > 20.0 * damped["rms_vehicle_vertical_speed_mps"]
    assert damped["rms_vehicle_vertical_speed_mps"] == pytest.approx(
        rigid["rms_body_vertical_speed_mps"], rel=0.05, abs=1e-5
    )
    assert rigid["rms_vehicle_vertical_speed_mps"] == rigid["rms_body_vertical_speed_mps"]
    opts = AID.filter_options(AID.AidOptions(), "car", None, damped, {"suspension": "damped"})
    assert opts.nhc_pitch_sd_rad > 0.0  # the dive: its own sigma
    lat, vert = opts.nhc_sd_mps
    assert (
        vert
        == AID.truth_slip_sd(rigid)[1]
        == max(rigid["rms_body_vertical_speed_mps"], AID.SLIP_FLOOR_MPS)
    )
    assert vert < damped["rms_body_vertical_speed_mps"]
    assert lat == max(damped["rms_body_lateral_speed_mps"], AID.SLIP_FLOOR_MPS)
    # an older report without the vehicle's figure: the body's, as before
    old = {k: v for k, v in damped.items() if "vehicle_vertical" not in k}
    assert AID.truth_slip_sd(old)[1] == damped["rms_body_vertical_speed_mps"]
