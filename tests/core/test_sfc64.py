"""imugen.core.sfc64: NumPy's SFC64 standard normals, number for number, inside kernels."""

import numpy as np
import pytest

from imugen.core import sfc64


@pytest.mark.parametrize("key", [(1, 2, 3), (5, 9, 2**31 + 4, 0, 11)])
def test_normals_are_numpys_sfc64_normals(key):
    """400,000 draws (about 4,800 through the wedge and tail paths) in three calls: the state
    carries across calls and every value is NumPy's."""
    ref = np.random.Generator(np.random.SFC64(np.random.SeedSequence(3, spawn_key=key)))
    want = ref.standard_normal(400_000)
    s = sfc64.state(3, key)
    out = np.empty(400_000)
    for a, b in ((0, 1), (1, 777), (777, 400_000)):
        sfc64.normals(s, out[a:b], sfc64.KI, sfc64.WI, sfc64.FI)
    np.testing.assert_array_equal(out, want)
    assert np.abs(out).max() > 4.0  # the tail path was taken
    # the state left is NumPy's: the next draw matches too
    nxt = np.empty(5)
    sfc64.normals(s, nxt, sfc64.KI, sfc64.WI, sfc64.FI)
    np.testing.assert_array_equal(nxt, ref.standard_normal(5))
