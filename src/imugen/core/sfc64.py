"""NumPy's SFC64 generator and standard normals inside compiled kernels, number for number.

:func:`state` seeds the 256-bit state as ``numpy.random.SFC64(SeedSequence(seed,
spawn_key=key))`` does (three words of ``generate_state``, the counter at 1, twelve discarded
outputs); :func:`normals` then fills an array with the values
``numpy.random.Generator(SFC64(...)).standard_normal()`` gives, in the same order (NumPy's
256-layer ziggurat with its own tables, read from numba's copy of them, and its tail and
wedge paths), advancing the state. A kernel draws its normals where it uses them, with the
state in registers: about four times NumPy's own fill on this machine, with no buffer between
the generator and the kernel. The law is NumPy's standard normal exactly (the tests hold the
numbers equal to NumPy's).
"""

from __future__ import annotations

import math

import numpy as np
from numba import uint64

# NumPy's ziggurat tables (numba's copy, the one its np.random.Generator support uses)
from numba.np.random._constants import fi_double as _FI
from numba.np.random._constants import ki_double as _KI
from numba.np.random._constants import wi_double as _WI
from numba.np.random._constants import ziggurat_nor_inv_r as _INV_R
from numba.np.random._constants import ziggurat_nor_r as _R

from imugen.core.jit import njit
from imugen.core.seedseq import generate_state

KI = np.ascontiguousarray(_KI, np.uint64)
WI = np.ascontiguousarray(_WI, np.float64)
FI = np.ascontiguousarray(_FI, np.float64)


@njit(cache=True, inline="always")
def _next(s):
    """One 64-bit output of the state ``s`` (uint64[4]: a, b, c, counter)."""
    tmp = s[0] + s[1] + s[3]
    s[3] += uint64(1)
    s[0] = s[1] ^ (s[1] >> uint64(11))
    s[1] = s[2] + (s[2] << uint64(3))
    s[2] = ((s[2] << uint64(24)) | (s[2] >> uint64(40))) + tmp
    return tmp


@njit(cache=True, inline="always")
def _double(s):
    """A uniform on [0, 1) with 53 bits (NumPy's ``next_double``)."""
    return float(_next(s) >> uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _warm(s):
    s[3] = uint64(1)
    for _ in range(12):
        _next(s)


def state(seed, key) -> np.ndarray:
    """The state of ``SFC64(SeedSequence(seed, spawn_key=key))``: uint64[4]."""
    return states(seed, [tuple(key)])[0]


def states(seed, keys) -> np.ndarray:
    """:func:`state` of each key: ``(len(keys), 4)`` uint64 (the seed sequences hashed at once,
    :func:`imugen.core.seedseq.generate_state`)."""
    s = np.zeros((len(keys), 4), np.uint64)
    if len(keys):
        s[:, :3] = generate_state(seed, keys, 3)
    for row in s:
        _warm(row)
    return s


@njit(cache=True)
def _slow(s, r, rabs, idx, fi):
    """NumPy's ziggurat beyond the rectangle: the tail (layer 0) or the wedge test.
    Returns ``(accepted, x)``."""
    x = float(rabs) * WI[idx]
    if r & uint64(1):
        x = -x
    if idx == 0:
        while True:
            xx = -_INV_R * math.log1p(-_double(s))
            yy = -math.log1p(-_double(s))
            if yy + yy > xx * xx:
                if (rabs >> uint64(8)) & uint64(1):
                    return True, -(_R + xx)
                return True, _R + xx
    if (fi[idx - 1] - fi[idx]) * _double(s) + fi[idx] < math.exp(-0.5 * x * x):
        return True, x
    return False, x


@njit(cache=True)
def normals(s, out, ki, wi, fi):
    """Fill ``out`` (float64, 1-D) with standard normals from the state ``s`` (advanced).

    ``ki, wi, fi``: :data:`KI`, :data:`WI`, :data:`FI` (passed so that the kernel holds them
    as arrays). The rectangle path, 99 % of draws, runs with the state in registers."""
    a, b, c, w = s[0], s[1], s[2], s[3]
    n = out.size
    i = 0
    while i < n:
        tmp = a + b + w
        w += uint64(1)
        a = b ^ (b >> uint64(11))
        b = c + (c << uint64(3))
        c = ((c << uint64(24)) | (c >> uint64(40))) + tmp
        idx = tmp & uint64(0xFF)
        r = tmp >> uint64(8)
        rabs = (r >> uint64(1)) & uint64(0x000FFFFFFFFFFFFF)
        if rabs < ki[idx]:
            x = float(rabs) * wi[idx]
            out[i] = -x if r & uint64(1) else x
            i += 1
            continue
        s[0], s[1], s[2], s[3] = a, b, c, w
        ok, x = _slow(s, r, rabs, idx, fi)
        a, b, c, w = s[0], s[1], s[2], s[3]
        if ok:
            out[i] = x
            i += 1
    s[0], s[1], s[2], s[3] = a, b, c, w
