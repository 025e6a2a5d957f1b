"""NumPy's ``SeedSequence(seed, spawn_key=key).generate_state(n, uint64)`` for many keys at once.

The stream seeds two generators per sequence (its parameters, PCG64; its window draws, SFC64);
building a ``SeedSequence`` object costs more than the hashing itself. :func:`generate_state`
runs NumPy's algorithm (entropy words, the pool mixing of ``mix_entropy``, the output hashing of
``generate_state``, pool size 4) compiled over a batch of keys: the same words, held equal to
NumPy's by the tests. :func:`pcg64_state` turns four words into the state a ``PCG64`` seeded
from that sequence has, to set on a reused generator.
"""

from __future__ import annotations

import numpy as np
from numba import uint32

from imugen.core.jit import njit

_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R = 0xCA01F9DD, 0x4973F715
_POOL = 4
_PCG_MULT = (2549297995355413924 << 64) + 4865540595714422341
_M128 = (1 << 128) - 1


def _words(v: int) -> list[int]:
    """NumPy's ``_int_to_uint32_array``: little-endian 32-bit words (one zero word for 0)."""
    v = int(v)
    if v < 0:
        raise ValueError("seed and spawn-key elements must be non-negative")
    out = [0] if v == 0 else []
    while v > 0:
        out.append(v & 0xFFFFFFFF)
        v >>= 32
    return out


@njit(cache=True)
def _hash(ent, starts, n32):
    out = np.empty((len(starts) - 1, n32), np.uint32)
    pool = np.empty(_POOL, np.uint32)
    for k in range(len(starts) - 1):
        e = ent[starts[k] : starts[k + 1]]
        h = uint32(_INIT_A)
        for i in range(_POOL):
            v = e[i] if i < len(e) else uint32(0)
            v ^= h
            h = uint32(h * uint32(_MULT_A))
            v = uint32(v * h)
            v ^= v >> uint32(16)
            pool[i] = v
        for i_src in range(_POOL):
            for i_dst in range(_POOL):
                if i_src != i_dst:
                    v = pool[i_src] ^ h
                    h = uint32(h * uint32(_MULT_A))
                    v = uint32(v * h)
                    v ^= v >> uint32(16)
                    r = uint32(uint32(_MIX_L) * pool[i_dst]) - uint32(uint32(_MIX_R) * v)
                    r = uint32(r)
                    pool[i_dst] = r ^ (r >> uint32(16))
        for i_src in range(_POOL, len(e)):
            for i_dst in range(_POOL):
                v = e[i_src] ^ h
                h = uint32(h * uint32(_MULT_A))
                v = uint32(v * h)
                v ^= v >> uint32(16)
                r = uint32(uint32(_MIX_L) * pool[i_dst]) - uint32(uint32(_MIX_R) * v)
                r = uint32(r)
                pool[i_dst] = r ^ (r >> uint32(16))
        h = uint32(_INIT_B)
        for i in range(n32):
            v = pool[i % _POOL] ^ h
            h = uint32(h * uint32(_MULT_B))
            v = uint32(v * h)
            v ^= v >> uint32(16)
            out[k, i] = v
    return out


def generate_state(seed: int, keys, n_words: int) -> np.ndarray:
    """``SeedSequence(seed, spawn_key=key).generate_state(n_words, np.uint64)`` of each key.

    Parameters
    ----------
    seed : int (>= 0)
    keys : sequence of tuples of int (>= 0)
    n_words : int

    Returns
    -------
    (len(keys), n_words) uint64
    """
    run = _words(seed)
    if len(run) < _POOL:
        run = run + [0] * (_POOL - len(run))
    ent, starts = [], [0]
    for key in keys:
        ent += run
        for v in key:
            ent += _words(v)
        starts.append(len(ent))
    out = _hash(np.array(ent, np.uint32), np.array(starts, np.int64), 2 * n_words)
    return np.ascontiguousarray(out).view("<u8").astype(np.uint64)


def pcg64_state(words) -> dict:
    """The ``state`` dict of ``PCG64`` seeded with these four ``generate_state`` words."""
    w = [int(x) for x in words]
    initstate = (w[0] << 64) | w[1]
    inc = ((((w[2] << 64) | w[3]) << 1) | 1) & _M128
    s = (0 * _PCG_MULT + inc) & _M128
    s = (s + initstate) & _M128
    s = (s * _PCG_MULT + inc) & _M128
    return {
        "bit_generator": "PCG64",
        "state": {"state": s, "inc": inc},
        "has_uint32": 0,
        "uinteger": 0,
    }
