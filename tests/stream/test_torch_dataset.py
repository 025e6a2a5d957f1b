"""The stream's PyTorch IterableDataset (skipped without torch, the optional extra)."""

import numpy as np
import pytest

from imugen.stream import Stream

torch = pytest.importorskip("torch")

from imugen.stream.torch import StreamDataset  # noqa: E402


def truth(K=300, dt=0.01):
    t = np.arange(K) * dt
    w = np.column_stack([0.1 * np.sin(t), 0 * t, 0.2 + 0 * t])
    f = np.column_stack([0 * t, 0.3 * np.cos(t), 9.8 + 0 * t])
    inc = np.vstack([np.zeros((1, 3)), 0.5 * (w[1:] + w[:-1]) * dt])
    dv = np.vstack([np.zeros((1, 3)), 0.5 * (f[1:] + f[:-1]) * dt])
    return {"time_s": t, "omega_ib_b": w, "f_b": f, "dtheta": inc, "dv": dv}


def test_batches_as_tensors_and_workers_share_the_numbers():
    s = Stream({"r": truth()}, "consumer", window=40, batch_size=8, windows_per_sequence=4,
               targets=["effective_error"], seed=3)  # fmt: skip
    ds = StreamDataset(s, batches=4)
    got = list(torch.utils.data.DataLoader(ds, batch_size=None, num_workers=0))
    assert len(got) == 4
    assert got[0]["x"].shape == (8, 40, 6) and got[0]["x"].dtype == torch.float32
    assert got[0]["keys"].shape == (8, 5)
    for n, b in enumerate(got):
        np.testing.assert_array_equal(b["x"].numpy(), s.batch(n)["x"])
    two = list(torch.utils.data.DataLoader(ds, batch_size=None, num_workers=2))
    firsts = sorted(int(b["keys"][0, 2]) for b in two)
    assert firsts == sorted(int(b["keys"][0, 2]) for b in got)
    by_shard = {int(b["keys"][0, 2]): b["x"] for b in two}
    for b in got:
        torch.testing.assert_close(by_shard[int(b["keys"][0, 2])], b["x"], rtol=0, atol=0)
