"""imugen.core.seedseq: NumPy's SeedSequence words and PCG64 state for many keys at once."""

import numpy as np
import pytest

from imugen.core import seedseq

KEYS = [(1, 2, 3, 4, 5), (0,), (2**40 + 7, 3, 2**31 + 9, 0, 11), (123456789, 77, 5, 2**33, 0, 1, 2)]


@pytest.mark.parametrize("seed", [0, 7, 2**70 + 3])
def test_words_and_pcg64_state_are_numpys(seed):
    for n in (3, 4):
        got = seedseq.generate_state(seed, KEYS, n)
        assert got.shape == (len(KEYS), n) and got.dtype == np.uint64
        for k, g in zip(KEYS, got, strict=True):
            want = np.random.SeedSequence(seed, spawn_key=k).generate_state(n, np.uint64)
            np.testing.assert_array_equal(g, want)
    words = seedseq.generate_state(seed, KEYS, 4)
    rng = np.random.Generator(np.random.PCG64(0))
    for k, w in zip(KEYS, words, strict=True):
        ref = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=k)))
        rng.bit_generator.state = seedseq.pcg64_state(w)
        assert rng.bit_generator.state == ref.bit_generator.state
        np.testing.assert_array_equal(rng.standard_normal(50), ref.standard_normal(50))


def test_negative_entropy_is_refused():
    with pytest.raises(ValueError):
        seedseq.generate_state(-1, [(1,)], 2)
