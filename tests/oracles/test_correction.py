"""The user's loop end to end: subtract the true effective error from the measured increments,
write the corrected shard, navigate, evaluate --segments; the drift left is the white noise's,
whose growth from a true start has a closed form."""

import math

import numpy as np
import pandas as pd
import pytest

import imugen
from imugen.evaluate import stage as evaluate
from imugen.evaluate.options import EvaluateOptions
from imugen.navigate import stage as navigate
from imugen.tables import shard as tshard

REPO = __import__("pathlib").Path(__file__).resolve().parents[2]
PAPER = REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt"
RATE, S, SEGMENTS = 10, 6, (30.0, 60.0)


@pytest.fixture(scope="module")
def scene(tmp_path_factory, request):
    """The paper's trajectory at 10 Hz (flat Earth); S consumer sequences with their series."""
    from imugen.cli import main

    d = tmp_path_factory.mktemp("loop")
    enu, truth, shard = d / "enu.parquet", d / "truth.parquet", d / "imu" / "shard-000.parquet"
    for args in (
        ["ingest", str(PAPER), "--origin", "31.63,-7.99,480.6", "--dt", "1.0", "-o", str(enu)],
        ["truth", str(enu), "-o", str(truth), "--rate-hz", str(RATE), "--earth", "flat"],
        ["simulate", str(truth), "-o", str(shard), "--grade", "consumer", "--sequences", str(S),
         "--seed", "5", "--shard", "0", "--series", "--dtype", "float64", "--route", "paper"],
    ):  # fmt: skip
        assert main(args) == 0
    return d, truth, shard


def white_noise_drift(labels: pd.DataFrame, T: float, g: float) -> np.ndarray:
    """Expected mean 3-D position error T s after a true start, white noise alone, per sequence.

    Velocity random walk N_a (m/s/sqrt(s)) gives a position variance N_a^2 T^3 / 3 per axis;
    angle random walk N_g (rad/sqrt(s)) tilts the platform and gravity turns the tilt into a
    horizontal position variance g^2 N_g^2 T^5 / 20 per axis. E|e| for the 3-D Gaussian by
    quadrature over 200,000 draws.
    """
    na = labels.filter(like="accel_white_noise_").to_numpy().mean(axis=1)
    ng = labels.filter(like="gyro_white_noise_").to_numpy().mean(axis=1)
    z = np.random.default_rng(0).standard_normal((200_000, 3))
    out = []
    for a, w in zip(na, ng, strict=True):
        h = math.sqrt(a**2 * T**3 / 3 + g**2 * w**2 * T**5 / 20)
        u = math.sqrt(a**2 * T**3 / 3)
        out.append(np.linalg.norm(z * [h, h, u], axis=1).mean())
    return np.array(out)


def test_subtracting_the_effective_error_leaves_the_white_noise_drift(scene):
    d, truth, shard = scene
    cols = [*tshard.INCREMENTS, *tshard.EFFECTIVE_ERROR["increments"]]
    t = tshard.read(shard, cols)
    K = tshard.read_meta(shard)["samples_per_sequence"]
    a = np.column_stack([t.column(c).to_numpy() for c in cols]).reshape(S, K, 12)
    corrected = a[..., :6] - a[..., 6:]  # measured - effective error = true + white + quant.
    fixed = imugen.write_shard(d / "fixed" / "shard-000.parquet", corrected, like=shard)
    assert tshard.read_meta(fixed)["derived"]
    out = {}
    for name, imu in (("measured", shard), ("corrected", fixed)):
        nav = navigate.run(truth, imu, d / f"nav-{name}.parquet")
        opts = EvaluateOptions(grade="consumer", segments_s=SEGMENTS)
        m = evaluate.run(truth, [nav], d / f"metrics-{name}.parquet", opts, imu_paths=[imu])
        out[name] = pd.read_parquet(m).set_index("sequence")
    # the in-memory loop gives the same navigation as the written shard
    mem = imugen.navigate_arrays(truth, (corrected[..., :3], corrected[..., 3:]))
    disk = pd.read_parquet(d / "nav-corrected.parquet")
    np.testing.assert_allclose(mem["err_e_m"], disk["err_e_m"], rtol=1e-5, atol=1e-3)

    labels = tshard.read_labels(shard).set_index("sequence").loc[out["corrected"].index]
    g = navigate.ttruth.read(truth).origin_frame().g0
    for T in SEGMENTS:
        col = evaluate.drift_column(T)
        want = white_noise_drift(labels, T, g)
        got = out["corrected"][col].to_numpy()
        # mean over ~6 x 2(D - T)/T half-overlapping starts: sampling error ~10 %
        assert 0.75 < got.mean() / want.mean() < 1.33, (T, got, want)
        # the bias, scale-factor, g-sensitivity ... drift was far larger
        assert (out["measured"][col].to_numpy() > 5 * got).all()
