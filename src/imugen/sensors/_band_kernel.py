"""Compiled kernels of the output bandwidth over many independent windows (no I/O).

Used by :func:`imugen.sensors.bandwidth.filter_windows` and
:func:`~imugen.sensors.bandwidth.noise_windows` (the stream's window mode). Filters are in
the transposed direct form II of ``scipy.signal.lfilter`` (``b``, ``a`` normalized by
``a[0]``); an FIR (``len(a) == 1``) is evaluated at the read indices only.
"""

from __future__ import annotations

import math

import numpy as np

from imugen.core.jit import njit


@njit(cache=True)
def _read(k, D, Di, ph):
    """Internal index read for output ``k``."""
    if Di > 0:
        return k * Di
    return math.floor(k * D + ph)


@njit(cache=True)
def _interp(Y, w, c, j, ph, D, L):
    """Row ``j`` of the internal grid: ``Y`` (rows = outputs ``0 .. L``) linear at
    ``(j - ph) / D``, held at the ends."""
    pos = (j - ph) / D
    if pos < 0.0:
        pos = 0.0
    elif pos > L:
        pos = float(L)
    i0 = math.floor(pos)
    if i0 > L:
        i0 = L
    i1 = i0 + 1 if i0 < L else L
    fr = pos - i0
    return Y[w, i0, c] * (1.0 - fr) + Y[w, i1, c] * fr


@njit(cache=True)
def motion_reads(b, a, zi0, Y, phase, D, Di, out):
    """Each window's signal ``Y`` ``(B, L + 1, C)`` (row 0 the first value repeated) on the
    internal grid, filtered from steady state and read: ``out`` ``(B, L, C)``."""
    B, L1, C = Y.shape
    L = L1 - 1
    nb, na = len(b), len(a)
    n = max(nb, na) - 1
    z = zi0.copy()
    for w in range(B):
        ph = phase[w]
        for c in range(C):
            if na == 1:
                for k in range(1, L + 1):
                    j = _read(k, D, Di, ph)
                    acc = 0.0
                    for m in range(nb):
                        acc += b[m] * _interp(Y, w, c, j - m, ph, D, L)
                    out[w, k - 1, c] = acc
                continue
            j = _read(1, D, Di, ph)
            x0 = _interp(Y, w, c, j, ph, D, L)
            for i in range(n):
                z[i] = zi0[i] * x0
            k = 1
            jk = j
            while k <= L:
                x = _interp(Y, w, c, j, ph, D, L)
                y = (b[0] if nb > 0 else 0.0) * x + z[0]
                for i in range(n - 1):
                    bi = b[i + 1] if i + 1 < nb else 0.0
                    ai = a[i + 1] if i + 1 < na else 0.0
                    z[i] = bi * x + z[i + 1] - ai * y
                bi = b[n] if n < nb else 0.0
                ai = a[n] if n < na else 0.0
                z[n - 1] = bi * x - ai * y
                if j == jk:
                    out[w, k - 1, c] = y
                    k += 1
                    if k <= L:
                        jk = _read(k, D, Di, ph)
                j += 1


@njit(cache=True)
def noise_reads(b, a, zn, scale, phase, D, Di, warm, out):
    """Filtered white noise of each window: ``zn`` ``(B, n, 3)`` standard normals on the
    internal grid (the first ``warm`` warm the filter up from rest), scaled by ``scale``
    ``(B, 3)``, filtered and read: ``out`` ``(B, L, 3)``."""
    B, L = out.shape[0], out.shape[1]
    nb, na = len(b), len(a)
    n = max(nb, na) - 1
    z = np.zeros(max(n, 1))
    for w in range(B):
        ph = phase[w]
        j1 = _read(1, D, Di, ph)
        for c in range(3):
            s = scale[w, c]
            if na == 1:
                for k in range(1, L + 1):
                    r = warm + _read(k, D, Di, ph) - j1
                    acc = 0.0
                    for m in range(nb):
                        acc += b[m] * zn[w, r - m, c]
                    out[w, k - 1, c] = acc * s
                continue
            for i in range(n):
                z[i] = 0.0
            k = 1
            rk = warm
            r = 0
            while k <= L:
                x = zn[w, r, c]
                y = b[0] * x + z[0]
                for i in range(n - 1):
                    bi = b[i + 1] if i + 1 < nb else 0.0
                    ai = a[i + 1] if i + 1 < na else 0.0
                    z[i] = bi * x + z[i + 1] - ai * y
                bi = b[n] if n < nb else 0.0
                ai = a[n] if n < na else 0.0
                z[n - 1] = bi * x - ai * y
                if r == rk:
                    out[w, k - 1, c] = y * s
                    k += 1
                    if k <= L:
                        rk = warm + _read(k, D, Di, ph) - j1
                r += 1
