"""The sensor model on torch (CPU here): closed forms and Allan figures, and the NumPy path's."""

import math

import numpy as np
import pytest

from imugen.sensors.grades import gm_avar
from imugen.sensors.model import SensorModel, SensorParams

torch = pytest.importorskip("torch")

from imugen.sensors.torch_model import TorchSensor, imu  # noqa: E402

DT = 0.01


def params(S, *, b_on=0.0, sigma=0.0, tau=1.0, white=0.0, rrw=0.0, sf=0.0, cc=0.0, gs=0.0,
           lsb=0.0, full_scale=math.inf, seed=0):  # fmt: skip
    rng = np.random.default_rng(seed)
    off = 1 - np.eye(3)
    return SensorParams(
        b_on=b_on * rng.standard_normal((S, 3)), bi_level=np.zeros((S, 3)),
        bi_floor=np.zeros((S, 3)), bi_sigma=np.full((S, 3, 1), sigma),
        bi_tau=np.full((S, 1), tau), white=np.full((S, 3), white), rrw=np.full((S, 3), rrw),
        sf=sf * rng.standard_normal((S, 3)), cc=cc * rng.standard_normal((S, 3, 3)) * off,
        gs=gs * rng.standard_normal((S, 3, 3)), tb=np.zeros((S, 3)), ts=np.zeros((S, 3)),
        lsb=lsb, full_scale=full_scale,
    )  # fmt: skip


def avar(y, m):
    """Overlapping Allan variance of rate samples ``y (S, L)`` at ``tau = m DT``."""
    th = np.cumsum(y, axis=1) * DT
    d = th[:, 2 * m :] - 2 * th[:, m:-m] + th[:, : -2 * m]
    return np.mean(d**2) / (2 * (m * DT) ** 2)


def torch_rates(p, L, seed=1):
    ts = TorchSensor(p, DT, dtype=torch.float64)
    g = torch.Generator().manual_seed(seed)
    return ts.apply(torch.zeros(L, 3), torch.zeros(L, 3), generator=g, outputs=("rate",))[
        "rate"
    ].numpy()


def numpy_rates(p, L, seed=2):
    m = SensorModel(p, DT)
    S = len(p.b_on)
    rng = np.random.default_rng(seed)
    out = np.empty((S, L, 3))
    zw = rng.standard_normal((S, L, 3)) if m.use_w else None
    zr = rng.standard_normal((S, L, 3)) if m.use_r else None
    zb = rng.standard_normal((S, L, 3)) if m.use_b else None
    z3 = np.zeros((L, 3))
    m.step(0, z3, z3, None, None, None, zw, zr, zb, out_rate=out)
    return out


def test_deterministic_terms_are_the_closed_form():
    S, L = 5, 50
    p = params(S, b_on=1e-3, sf=1e-2, cc=1e-3, gs=1e-4)
    rng = np.random.default_rng(3)
    u, du, a, da = (rng.standard_normal((S, L, 3)) for _ in range(4))
    ts = TorchSensor(p, DT, dtype=torch.float64)
    T = [torch.from_numpy(v) for v in (u, du, a, da)]
    o = ts.apply(*T, outputs=("rate", "inc", "err_rate", "err_inc", "bias"))
    E = p.cc + np.stack([np.diag(v) for v in p.sf])
    rate = (
        u + np.einsum("sij,slj->sli", E, u) + np.einsum("sij,slj->sli", p.gs, a) + p.b_on[:, None]
    )
    inc = du + np.einsum("sij,slj->sli", E, du) + np.einsum("sij,slj->sli", p.gs, da)
    inc += p.b_on[:, None] * DT
    np.testing.assert_allclose(o["rate"].numpy(), rate, rtol=0, atol=1e-15)
    np.testing.assert_allclose(o["inc"].numpy(), inc, rtol=0, atol=1e-15)
    np.testing.assert_allclose(o["err_inc"].numpy(), inc - du, rtol=0, atol=1e-15)
    np.testing.assert_allclose(o["bias"].numpy(), np.broadcast_to(p.b_on[:, None], (S, L, 3)))


@pytest.mark.parametrize(
    ("kw", "closed"),
    [
        ({"white": 2e-3}, lambda t: (2e-3) ** 2 / t),
        ({"sigma": 1e-3, "tau": 1.0}, lambda t: gm_avar(t, 1e-3, 1.0)),
        ({"rrw": 1e-4}, lambda t: (1e-4) ** 2 * t / 3),
    ],
    ids=["white", "gauss_markov", "random_walk"],
)
def test_allan_figures_match_closed_forms_and_the_numpy_path(kw, closed):
    S, L = 24, 12_000  # 120 s at 100 Hz
    p = params(S, **kw)
    yt = torch_rates(p, L)
    yn = numpy_rates(p, L)
    for m in (10, 100, 1000):
        tau = m * DT
        want = float(closed(np.array([tau]))[0])
        vt = np.mean([avar(yt[..., i], m) for i in range(3)])
        vn = np.mean([avar(yn[..., i], m) for i in range(3)])
        tol = 0.06 if m < 1000 else 0.25  # fewer independent spans at 10 s
        assert vt == pytest.approx(want, rel=tol), (m, vt, want)
        assert vt == pytest.approx(vn, rel=1.5 * tol), (m, vt, vn)


def test_window_starts_draw_the_states_law():
    """GM started at zero (in-run wander): state variance sigma^2 (1 - phi^(2 m)) at k0 = m + 1."""
    S, sig, tau = 4000, 1e-3, 2.0
    p = params(S, sigma=sig, tau=tau)
    p.bi_x0 = np.zeros_like(p.bi_sigma)
    ts = TorchSensor(p, DT, dtype=torch.float64)
    for m in (1, 100, 1000):
        s = ts.slow(1, k0=m + 1, generator=torch.Generator().manual_seed(m))[:, 0].numpy()
        want = sig**2 * (1 - math.exp(-2 * m * DT / tau))
        assert np.var(s) == pytest.approx(want, rel=0.1)


def test_quantization_carries_its_residual_and_saturation_clamps():
    S, L, q = 3, 2000, 1e-3
    p = params(S, white=5e-3, lsb=q, full_scale=0.05)
    rng = np.random.default_rng(0)
    u = torch.from_numpy(0.04 * rng.standard_normal((L, 3)))
    ts = TorchSensor(p, DT, dtype=torch.float64)
    o = ts.apply(u, u * DT, generator=torch.Generator().manual_seed(0),
                 outputs=("rate", "inc"))  # fmt: skip
    y = o["rate"].numpy()
    np.testing.assert_allclose(y / q, np.round(y / q), atol=1e-6)
    assert np.abs(y).max() <= 0.05 + q
    dtq = q * DT
    # residual carry: the sum of the quantized output stays within q of the true sum
    c = TorchSensor(params(S, lsb=q), DT, dtype=torch.float64)
    yc = c.apply(torch.full((L, 3), 0.01234), generator=torch.Generator().manual_seed(1),
                 outputs=("rate",))["rate"].numpy()  # fmt: skip
    drift = np.cumsum(yc, axis=1) - 0.01234 * np.arange(1, L + 1)[None, :, None]
    assert np.abs(drift).max() <= q
    assert np.abs(yc - 0.01234).max() <= q  # each sample within one step
    inc = o["inc"].numpy()
    np.testing.assert_allclose(inc / dtq, np.round(inc / dtq), atol=1e-6)


def test_both_triads_in_float32():
    S, L = 2, 10
    g = TorchSensor(params(S, white=1e-3), DT)
    a = TorchSensor(params(S, white=1e-2), DT)
    o = imu(g, a, torch.zeros(L, 3), torch.zeros(L, 3), generator=torch.Generator().manual_seed(0))
    assert o["inc"].shape == (S, L, 6) and o["inc"].dtype == torch.float32


@pytest.mark.parametrize(
    "band",
    ["ma_async", "butterworth", "dlpf"],
)
def test_output_bandwidth_noise_has_the_filters_closed_forms(band):
    """White noise through an output bandwidth: variance, lag-1 covariance and Allan variance
    of the torch path's output are those of filtered white noise (OutputFilter's closed forms)
    and the NumPy path's (its Stream on the same parameters)."""
    from imugen.sensors import bandwidth as bw

    f = {
        "ma_async": bw.moving_average(10, 819.2, 1 / DT),
        "butterworth": bw.butterworth(2, 30.0, 1000.0, 1 / DT),
        "dlpf": bw.mpu6050_dlpf(3, "gyro", 1 / DT),
    }[band]
    N, S, L = 0.01, 400, 200
    p = params(S, white=N)
    ts = TorchSensor(p, DT, dtype=torch.float64, band=f)
    g = torch.Generator().manual_seed(3)
    y = ts.apply(torch.zeros(L, 3), torch.zeros(L, 3), generator=g, outputs=("rate",))["rate"]
    y = y.numpy().transpose(0, 2, 1).reshape(-1, L)
    m = SensorModel(p, DT, f, [np.random.default_rng(i) for i in range(S)])
    out = np.empty((S, L, 3))
    z3 = np.zeros((L, 3))
    m.step(1, z3, z3, None, None, None, None, None, None, out_rate=out)
    yn = out.transpose(0, 2, 1).reshape(-1, L)
    r = f.output_autocov(N, 2)
    for x in (y, yn):
        assert np.mean(x**2) == pytest.approx(r[0], rel=0.03)
        assert np.mean(x[:, 1:] * x[:, :-1]) / np.mean(x**2) == pytest.approx(r[1] / r[0],
                                                                              abs=0.02)  # fmt: skip
        for mm in (1, 4, 16):
            assert avar(x, mm) == pytest.approx(float(f.avar(mm, N)), rel=0.08), mm


def test_output_bandwidth_filters_the_motion_as_the_numpy_path():
    """A deterministic scale factor on a ramp through a synchronous Butterworth: the torch
    path's filtered output is the NumPy Stream's (both start in steady state on row 0)."""
    from imugen.sensors import bandwidth as bw

    f = bw.butterworth(2, 20.0, 1000.0, 1 / DT)
    S, L = 3, 120
    p = params(S, sf=0.01)
    t = np.arange(L) * DT
    u = np.column_stack([np.sin(3 * t), 0.5 * t, np.cos(2 * t)])
    ts = TorchSensor(p, DT, dtype=torch.float64, band=f)
    y = ts.apply(torch.as_tensor(u), torch.as_tensor(u) * DT, outputs=("rate",))["rate"].numpy()
    m = SensorModel(p, DT, f, [np.random.default_rng(i) for i in range(S)])
    out = np.empty((S, L, 3))
    m.step(1, u, u * DT, None, None, None, None, None, None, out_rate=out)
    np.testing.assert_allclose(y, out, rtol=0, atol=1e-7)


def test_rounding_quantizes_each_sample():
    p = params(50, white=0.02, lsb=0.003)
    p = SensorParams(**{**p.__dict__, "q_round": True})
    ts = TorchSensor(p, DT, dtype=torch.float64)
    g = torch.Generator().manual_seed(4)
    y = ts.apply(torch.zeros(500, 3), torch.zeros(500, 3), generator=g, outputs=("rate",))
    k = y["rate"].numpy() / 0.003
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    # rounding noise of a white signal well above the step: variance N^2/dt + q^2/12
    assert np.var(y["rate"].numpy()) == pytest.approx(0.02**2 / DT + 0.003**2 / 12, rel=0.03)
