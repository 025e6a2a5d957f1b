"""Compiled kernels of the output bandwidth over many independent windows (no I/O).

Used by :func:`imugen.sensors.bandwidth.filter_windows` and
:func:`~imugen.sensors.bandwidth.noise_windows` (the stream's window mode). Filters are in
the transposed direct form II of ``scipy.signal.lfilter`` (``b``, ``a`` normalized by
``a[0]``); an FIR (``len(a) == 1``) is evaluated at the read indices only. Filtered noise is
drawn from its exact law at the reads (a banded Cholesky factor of their covariance).
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
def noise_law(c, zn, scale, phase, D, Di, out):
    """Filtered white noise of each window read at the output rate, from its exact law: the
    reads are jointly Gaussian with covariance ``c(|j_k - j_l|)`` (``c`` the impulse
    response's autocorrelation, zero beyond its length), drawn as ``Lchol z`` (a banded
    Cholesky factor per window: the reads' spacing depends on the read phase). ``zn``
    ``(B, L, 3)`` standard normals, ``scale`` ``(B, 3)``, ``out`` ``(B, L, 3)``."""
    B, L = out.shape[0], out.shape[1]
    Lc = len(c)
    step = Di if Di > 0 else max(math.floor(D), 1)
    p = min(L - 1, (Lc - 1) // step + 1)
    Lb = np.zeros((L, p + 1))  # Lb[i, m] = Lchol[i, i - m]
    j = np.empty(L, np.int64)
    for w in range(B):
        for k in range(L):
            j[k] = _read(k + 1, D, Di, phase[w])
        for i in range(L):
            for m in range(min(p, i), -1, -1):
                jc = i - m
                lag = j[i] - j[jc]
                s = c[lag] if lag < Lc else 0.0
                for kk in range(max(i - p, 0), jc):
                    s -= Lb[i, i - kk] * Lb[jc, jc - kk]
                if m == 0:
                    Lb[i, 0] = math.sqrt(s) if s > 0.0 else 0.0
                else:
                    Lb[i, m] = s / Lb[jc, 0] if Lb[jc, 0] > 0.0 else 0.0
        for a in range(3):
            sa = scale[w, a]
            for i in range(L):
                acc = 0.0
                for m in range(min(p, i) + 1):
                    acc += Lb[i, m] * zn[w, i - m, a]
                out[w, i, a] = acc * sa
