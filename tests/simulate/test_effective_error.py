"""Effective error series: measured - true - effective error is exactly the white noise
(plus quantization), regenerated here from the documented random streams."""

import math

import numpy as np
import pytest

from imugen.core.seeding import sensor_rng
from imugen.sensors.grades import TERMS
from imugen.simulate import stage as S
from imugen.tables import shard as tshard

from helpers import simulate_shard

RATE = 100.0
DT = 1.0 / RATE
SEED, SHARD, ROUTE = 12, 2, "oracle"


def moving_truth(K=1500, spin=0.0):
    """A body turning and accelerating (sinusoids); ``spin`` adds a constant z rate (rad/s)."""
    t = np.arange(K) * DT
    w = np.column_stack([0.3 * np.sin(0.7 * t), 0.2 * np.cos(0.5 * t), 0.4 + spin + 0 * t])
    f = np.column_stack([1.5 * np.sin(0.3 * t), 0.8 * np.cos(0.9 * t), 9.8 + 0.5 * np.sin(t)])
    dth = np.vstack([np.zeros(3), 0.5 * (w[1:] + w[:-1]) * DT])
    dv = np.vstack([np.zeros(3), 0.5 * (f[1:] + f[:-1]) * DT])
    return {"time_s": t, "omega_ib_b": w, "f_b": f, "dtheta": dth, "dv": dv}


def white(sh, j, sensor, K):
    """The white-noise term of sequence j, regenerated from its spawn key (rate, increment)."""
    rid = tshard.route_id(ROUTE)
    rng = sensor_rng(SEED, rid, sh.meta["grade"]["id"], SHARD, j, f"{sensor}_white")
    z = rng.standard_normal((K, 3))
    N = getattr(sh, sensor).white[j]
    inc = N * math.sqrt(DT) * z
    inc[0] = 0.0
    return N / math.sqrt(DT) * z, inc


def simulate(truth, terms=None):
    return S.simulate(
        truth, "consumer", sequences=3, seed=SEED, shard=SHARD, route=ROUTE, outputs="both",
        series=True, terms=terms,
    )  # fmt: skip


@pytest.mark.parametrize("spin", [0.0, 50.0])  # 50 rad/s exceeds the 2000 deg/s gyro range
def test_residual_is_exactly_the_white_noise(spin):
    tr = moving_truth(spin=spin)
    terms = [t for t in TERMS if t != "quantization"]  # every term but quantization
    sh = simulate(tr, terms)
    K = len(tr["time_s"])
    if spin:
        assert np.any(np.abs(sh.data["gyro"][..., 2]) >= 2000 * math.pi / 180 - 1e-9)
    for sensor, true_rate, true_inc, inc in (
        ("gyro", tr["omega_ib_b"], tr["dtheta"], "dtheta"),
        ("accel", tr["f_b"], tr["dv"], "dv"),
    ):
        for j in range(3):
            w_rate, w_inc = white(sh, j, sensor, K)
            r_rate = sh.data[sensor][j] - true_rate - sh.data[f"err_{sensor}"][j]
            r_inc = sh.data[inc][j] - true_inc - sh.data[f"err_{inc}"][j]
            scale_r = np.abs(sh.data[sensor][j]).max()
            scale_i = np.abs(sh.data[inc][j]).max()
            np.testing.assert_allclose(r_rate, w_rate, rtol=0, atol=1e-13 * scale_r)
            np.testing.assert_allclose(r_inc, w_inc, rtol=0, atol=1e-13 * scale_i)
            if not spin:
                # re-derived: slow bias + (diag(sf) + C) u + G f (no temperature profile)
                p = getattr(sh, sensor)
                E = np.diag(p.sf[j]) + p.cc[j]
                want = sh.data[f"{sensor}_bias"][j] + true_rate @ E.T
                if sensor == "gyro":
                    want += tr["f_b"] @ p.gs[j].T
                    assert np.abs(p.gs[j]).max() > 0
                np.testing.assert_allclose(
                    sh.data[f"err_{sensor}"][j], want, rtol=0, atol=1e-14 * np.abs(want).max()
                )
                assert np.abs(true_rate @ E.T).max() > 0.1 * np.abs(want).max()


def test_residual_with_quantization_is_white_plus_bounded_carry():
    tr = moving_truth()
    sh = simulate(tr)
    K = len(tr["time_s"])
    for sensor, true_rate, true_inc, inc in (
        ("gyro", tr["omega_ib_b"], tr["dtheta"], "dtheta"),
        ("accel", tr["f_b"], tr["dv"], "dv"),
    ):
        lsb = getattr(sh, sensor).lsb
        assert lsb > 0
        for j in range(3):
            w_rate, w_inc = white(sh, j, sensor, K)
            q_rate = sh.data[sensor][j] - true_rate - sh.data[f"err_{sensor}"][j] - w_rate
            q_inc = sh.data[inc][j] - true_inc - sh.data[f"err_{inc}"][j] - w_inc
            # residual carry: each error is within one LSB and their running sum within half
            for q, step in ((q_rate, lsb), (q_inc, lsb * DT)):
                assert np.abs(q).max() <= step * (1 + 1e-9)
                assert np.abs(np.cumsum(q, axis=0)).max() <= 0.5 * step * (1 + 1e-9)
                # and it is not zero: quantization is really there
                assert np.abs(q).max() > 0.1 * step


def test_series_columns_written_and_typed(tmp_path):
    out = tmp_path / "s.parquet"
    simulate_shard(
        None, out, "industrial", sequences=2, seed=1, static_s=1.0, outputs="both", series=True
    )
    names = tshard.column_names(out)
    for c in (
        *tshard.EFFECTIVE_ERROR["increments"],
        *tshard.EFFECTIVE_ERROR["rates"],
        *tshard.BIAS,
    ):
        assert c in names
    meta = tshard.read_meta(out)
    assert meta["units"]["err_dv_x_mps"] == "m/s" and meta["units"]["err_gyro_z_radps"] == "rad/s"
    # increments only: no rate error columns
    simulate_shard(None, out, "industrial", sequences=1, seed=1, static_s=1.0, series=True)
    names = tshard.column_names(out)
    assert "err_dtheta_x_rad" in names and "err_gyro_x_radps" not in names
