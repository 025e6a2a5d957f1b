"""KF-GINS export: the config read the way KF-GINS' ``loadConfig``/``main`` read it (yaml-cpp
types, required keys, time checks, files), its ``imunoise`` converted back equal to the
sequence's labels, up-front refusal of rate-only shards, once-per-export warnings, and (when a
KF-GINS binary is available) KF-GINS itself run on the export."""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess

import numpy as np
import pytest
import yaml

from imugen.aid import stage as aid
from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.export.source import iter_sequences, read_truth
from imugen.export.stage import export
from imugen.sensors.grades import get_grade
from imugen.tables.truth import origin_frame
from imugen.truth import build_truth, enu_table

from helpers import simulate_shard

RATE = 50.0
D2R = math.pi / 180.0

# --- yaml-cpp, as KF-GINS uses it (YAML::Node::as<T>: the scalar's text must convert whole) ---
_INT = re.compile(r"[+-]?(0|[1-9][0-9]*)")  # decimal (yaml-cpp reads a leading 0 as octal)
_DOUBLE = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")


def _scalar(node, key, pattern=None):
    assert isinstance(node, yaml.ScalarNode), f"{key}: not a scalar"
    assert pattern is None or pattern.fullmatch(node.value), f"{key}: {node.value!r}"
    return node.value


def _as_int(node, key):
    return int(_scalar(node, key, _INT))


def _as_double(node, key):
    return float(_scalar(node, key, _DOUBLE))


def _as_vec3(node, key):
    # as<std::vector<double>>, then indexed [0..2]
    assert isinstance(node, yaml.SequenceNode) and len(node.value) == 3, f"{key}: not 3 numbers"
    return np.array([_as_double(n, key) for n in node.value])


def _mapping(node):
    assert isinstance(node, yaml.MappingNode)
    return {k.value: v for k, v in node.value}


VECTORS = (
    *("initpos", "initvel", "initatt", "initgyrbias", "initaccbias", "initgyrscale"),
    *("initaccscale", "initposstd", "initvelstd", "initattstd", "antlever"),
)
OPTIONAL_VECTORS = ("initbgstd", "initbastd", "initsgstd", "initsastd")
NOISE = ("arw", "vrw", "gbstd", "abstd", "gsstd", "asstd")


def load_like_kfgins(folder):
    """The configuration of ``folder/kf-gins.yaml`` as KF-GINS reads it, with its checks."""
    root = _mapping(yaml.compose((folder / "kf-gins.yaml").read_text()))
    cfg = {k: _as_vec3(root[k], k) for k in VECTORS}
    cfg |= {k: _as_vec3(root[k], k) for k in OPTIONAL_VECTORS if k in root}
    noise = _mapping(root["imunoise"])
    cfg["imunoise"] = {k: _as_vec3(noise[k], k) for k in NOISE}
    cfg["imunoise"]["corrtime"] = _as_double(noise["corrtime"], "corrtime")
    for k in ("imupath", "gnsspath", "outputpath"):
        cfg[k] = _scalar(root[k], k)
    cfg["imudatalen"] = _as_int(root["imudatalen"], "imudatalen")
    cfg["imudatarate"] = _as_int(root["imudatarate"], "imudatarate")
    cfg["starttime"] = _as_double(root["starttime"], "starttime")
    cfg["endtime"] = _as_double(root["endtime"], "endtime")
    # main(): files open (paths relative to the folder KF-GINS runs in), process time checks
    imu = np.loadtxt(folder / cfg["imupath"])
    gnss = np.loadtxt(folder / cfg["gnsspath"], ndmin=2)
    assert (folder / cfg["outputpath"]).is_dir()
    assert imu.shape[1] >= cfg["imudatalen"] == 7 and gnss.shape[1] == 7
    end = imu[-1, 0] if cfg["endtime"] < 0 else cfg["endtime"]
    assert imu[0, 0] <= cfg["starttime"] <= end <= 604800.0
    assert np.any(gnss[:, 0] > cfg["starttime"])  # else its alignment loop never ends
    assert np.all(np.diff(imu[:, 0]) > 0) and np.all(np.diff(gnss[:, 0]) > 0)
    return cfg, imu, gnss


# --- fixtures ----------------------------------------------------------------------------------
def _truth(tmp):
    t = np.arange(0.0, 61.0, 1.0)
    enu = np.column_stack([400 * np.sin(t / 50.0), 250 * (1 - np.cos(t / 35.0)), 0.1 * t])
    df, meta = enu_table(enu, t, origin=(45.2, 7.6, 300.0))
    tdf, tmeta = build_truth(df, meta, rate_hz=RATE, earth="wgs84", verbose=False)
    return write_parquet(tdf, tmeta, tmp / "drive" / "truth.parquet")


@pytest.fixture(scope="module")
def route(tmp_path_factory):
    """A 60 s drive at 50 Hz (wgs84), two consumer sequences of raw increments, their GNSS."""
    tmp = tmp_path_factory.mktemp("kfgins")
    truth = _truth(tmp)
    shard = tmp / "drive" / "imu" / "consumer" / "shard-000.parquet"
    simulate_shard(truth, shard, "consumer", sequences=2, seed=3, increments="raw")
    g, a = tmp / "g.parquet", tmp / "a.parquet"
    aid.run(truth, shard, g, a, aid.AidOptions(lever_arm_b_m=(0.4, -0.2, 1.1)))
    out = tmp / "export"
    export(["kfgins"], truth, [shard], out, gnss_paths=[g], log=lambda m: None)
    return truth, shard, g, out


def _folders(out):
    return sorted(p for p in (out / "kfgins").iterdir() if p.is_dir())


# --- tests -------------------------------------------------------------------------------------
def test_config_reads_as_kfgins_reads_it(route):
    truth, _, _, out = route
    tr = read_truth(truth)
    folders = _folders(out)
    assert len(folders) == 2
    for folder in folders:
        cfg, imu, _ = load_like_kfgins(folder)
        assert cfg["imudatarate"] == round(RATE) and cfg["endtime"] == -1
        assert cfg["starttime"] == imu[0, 0] == pytest.approx(tr.time_s[1], abs=1e-9)
        # the initial state is the truth at starttime, in KF-GINS' units (deg, m, m/s, deg)
        nav = np.loadtxt(folder / "truth.nav")
        assert nav.shape == (tr.K, 11) and np.all(nav[:, 0] == 0)  # week 0, as KF-GINS writes
        k = int(np.argmin(np.abs(nav[:, 1] - cfg["starttime"])))
        assert k == 1
        lat, lon, h = origin_frame(tr.meta).geodetic_from_n(tr.p_n[1])
        assert np.allclose(cfg["initpos"], [math.degrees(lat), math.degrees(lon), h], atol=1e-11)
        assert np.allclose(cfg["initpos"], nav[1, 2:5], rtol=0, atol=1e-4)  # truth.nav: 0.1 mm
        assert np.allclose(cfg["initvel"], nav[1, 5:8], atol=1e-6)
        assert np.allclose(cfg["initatt"], nav[1, 8:11], atol=1e-7)
        assert np.all(cfg["initposstd"] > 0) and np.all(cfg["initattstd"] > 0)
        # GNSS antenna lever arm: the receiver's labels (FLU) in FRD
        assert np.allclose(cfg["antlever"], [0.4, 0.2, -1.1])


def test_imunoise_is_the_sequences_figures(route):
    """Converted back from KF-GINS units, ``imunoise`` equals the shard's labels: white noise per
    axis, the Gauss-Markov driving noise ``2 gbstd^2 / corrtime`` equal to the labels' in-run
    ``2 sigma^2 / tau + K^2``, and the grade's scale-factor sigma; ``imugen grade import`` reads
    the block back."""
    from imugen.sensors.grade_io import import_grade

    truth, shard, _, out = route
    tr = read_truth(truth)
    grade = get_grade("consumer")
    seqs = {s.id: s.labels for s in iter_sequences([shard], tr.K)}
    for folder in _folders(out):
        lab = seqs[int(folder.name.rsplit("_", 1)[1])]
        n = load_like_kfgins(folder)[0]["imunoise"]

        def axes(stem, lab=lab):
            return np.array([lab[stem.format(a=a)] for a in "xyz"])

        w = axes("gyro_white_noise_{a}_rad_per_sqrt_s")
        assert np.allclose(n["arw"] * D2R / 60.0, w, rtol=1e-12)
        vw = axes("accel_white_noise_{a}_m_per_s_per_sqrt_s")
        assert np.allclose(n["vrw"] / 60.0, vw, rtol=1e-12)
        T = n["corrtime"] * 3600.0
        assert T == pytest.approx(lab["gyro_bias_instability_tau0_s"], rel=1e-12)
        for key, s, unit, rw, scale in (
            ("gbstd", "gyro", "radps", "radps_per_sqrt_s", D2R / 3600.0),
            ("abstd", "accel", "mps2", "mps2_per_sqrt_s", 1e-5),
        ):
            sig = axes(f"{s}_bias_instability_sigma0_{{a}}_{unit}")
            q = 2 * sig**2 / lab[f"{s}_bias_instability_tau0_s"]
            q = q + axes(f"{s}_rate_random_walk_{{a}}_{rw}") ** 2
            assert np.all(q > 0)
            assert np.allclose(2 * (n[key] * scale) ** 2 / T, q, rtol=1e-12)
        # consumer gyro: one GM, no rate random walk: gbstd is its sigma exactly
        sig = axes("gyro_bias_instability_sigma0_{a}_radps")
        assert np.allclose(n["gbstd"] * D2R / 3600.0, sig, rtol=1e-12)
        assert np.allclose(n["gsstd"] * 1e-6, grade.gyro.scale_factor.hi, rtol=1e-12)
        assert np.allclose(n["asstd"] * 1e-6, grade.accel.scale_factor.hi, rtol=1e-12)
        _, cfg = import_grade(folder / "kf-gins.yaml")
        assert cfg["gyro"]["white_noise"]["value"] == pytest.approx(np.mean(n["arw"]))
        assert cfg["gyro"]["white_noise"]["unit"] == "deg_per_sqrt_h"


def test_rate_only_shards_refused_before_anything_is_written(route, tmp_path, cli):
    truth = route[0]
    shard = tmp_path / "rates" / "shard-000.parquet"
    simulate_shard(truth, shard, "consumer", sequences=1, seed=1, outputs="rates")
    out = tmp_path / "out"
    with pytest.raises(InputError, match="no increment columns"):
        export(["euroc", "kfgins"], truth, [shard], out, log=lambda m: None)
    assert not out.exists() and not list(tmp_path.glob(".out.*"))
    r = cli("export", truth, shard, "-o", out, "--format", "euroc,kfgins")
    assert r.returncode == 2 and not out.exists()
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("imugen: error: ")


def test_warnings_once_per_export_and_no_config_without_gnss(route, tmp_path):
    truth = route[0]
    shard = tmp_path / "comp" / "shard-000.parquet"
    simulate_shard(truth, shard, "consumer", sequences=3, seed=2)  # compensated increments
    msgs = []
    export(["kfgins"], truth, [shard], tmp_path / "out", log=msgs.append)
    warns = [m for m in msgs if m.startswith("imugen: warning: ")]
    assert sum("compensated" in m for m in warns) == 1
    assert sum("no GNSS" in m for m in warns) == 1 and len(warns) == 2
    for folder in _folders(tmp_path / "out"):
        assert (folder / "imu.txt").is_file() and (folder / "truth.nav").is_file()
        assert not (folder / "kf-gins.yaml").exists()
    assert len(_folders(tmp_path / "out")) == 3


@pytest.mark.filterwarnings("ignore::UserWarning")  # an empty gnss.pos read back
def test_no_config_without_a_fix_after_starttime(route, tmp_path):
    """KF-GINS skips GNSS epochs up to starttime and never ends without a later one: such a
    sequence gets its data files and gnss.pos, no kf-gins.yaml, and a warning."""
    from imugen.export import kfgins
    from imugen.export.source import gnss_of

    truth, shard, g, _ = route
    tr = read_truth(truth)
    seq = next(iter_sequences([shard], tr.K, gnss_paths=[g]))
    seq.gnss = gnss_of([g], seq.id)
    seq.gnss.loc[seq.gnss["time_s"] > 0.0, "fix"] = 0
    msgs = []
    files = kfgins.write(seq, tr, tmp_path / "s", warn=msgs.append)
    assert [f.name for f in files] == ["imu.txt", "truth.nav", "gnss.pos"]
    assert np.all(np.loadtxt(tmp_path / "s" / "gnss.pos", ndmin=2)[:, 0] <= tr.time_s[1])
    assert not (tmp_path / "s" / "kf-gins.yaml").exists()
    assert len(msgs) == 1 and "no GNSS fix after" in msgs[0]


def _kfgins_binary():
    exe = os.environ.get("IMUGEN_KFGINS") or shutil.which("KF-GINS")
    if not exe or not os.access(exe, os.X_OK):
        pytest.skip("no KF-GINS binary (set IMUGEN_KFGINS to one built from i2Nav-WHU/KF-GINS)")
    return exe


@pytest.fixture(scope="module")
def navigation_export(tmp_path_factory):
    """KF-GINS binary and an export of three navigation-grade sequences with GNSS."""
    exe = _kfgins_binary()
    tmp = tmp_path_factory.mktemp("kfgins_nav")
    truth = _truth(tmp)
    shard = tmp / "drive" / "imu" / "navigation" / "shard-000.parquet"
    simulate_shard(truth, shard, "navigation", sequences=3, seed=3, increments="raw")
    g, a = tmp / "g.parquet", tmp / "a.parquet"
    aid.run(truth, shard, g, a, aid.AidOptions(lever_arm_b_m=(0.4, -0.2, 1.1)))
    export(["kfgins"], truth, [shard], tmp / "out", gnss_paths=[g], log=lambda m: None)
    return exe, _folders(tmp / "out")


def test_kfgins_runs_on_the_export(navigation_export):
    """KF-GINS itself accepts each folder, and its GNSS/INS solution of a navigation-grade IMU
    (its own ``KF_GINS_Navresult.nav``, the truth.nav layout) keeps the attitude of the truth
    to a fraction of a degree and the position within the GNSS sigmas: a sign, axis, frame or
    unit error in the files or the config would cost degrees within seconds."""
    exe, folders = navigation_export
    for folder in folders:
        r = subprocess.run([exe, "kf-gins.yaml"], cwd=folder, capture_output=True, text=True)
        assert r.returncode == 0 and "Process Finish" in r.stdout, r.stdout
        est = np.loadtxt(folder / "KF_GINS_Navresult.nav")
        nav = np.loadtxt(folder / "truth.nav")
        imu = np.loadtxt(folder / "imu.txt")
        gnss = np.loadtxt(folder / "gnss.pos")
        # one state per record after the first (the initial state)
        assert np.array_equal(est[:, 1], imu[1:, 0])
        k = np.rint(est[:, 1] * RATE).astype(int)
        assert np.allclose(nav[k, 1], est[:, 1], atol=1e-9)
        R = 6378137.0
        dn = np.radians(est[:, 2] - nav[k, 2]) * R
        de = np.radians(est[:, 3] - nav[k, 3]) * R * np.cos(np.radians(nav[k, 2]))
        assert np.max(np.abs(dn)) < 4 * np.max(gnss[:, 4]) + 1.0
        assert np.max(np.abs(de)) < 4 * np.max(gnss[:, 5]) + 1.0
        assert np.max(np.abs(est[:, 4] - nav[k, 4])) < 4 * np.max(gnss[:, 6]) + 1.0
        d_att = np.mod(est[:, 8:11] - nav[k, 8:11] + 180.0, 360.0) - 180.0
        assert np.max(np.abs(d_att)) < 0.3
