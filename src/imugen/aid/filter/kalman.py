"""The Kalman update shared by every measurement model: sequential scalar updates.

A measurement model fills one row at a time: the residual ``r = z_pred - z`` (prediction
from the nominal state minus the measurement), its sensitivity ``h`` to the error state
(``r = h dx + noise``, ``dx`` estimate minus truth) and the noise variance ``var``, then calls
:func:`scalar_update`. ``h`` is sparse: a row sets ``h[i]`` for the indices it lists in
``hz[:m]`` (:func:`put`), in the order the products are summed. Rows with correlated noise
are decorrelated by the model before (the GNSS axes in ``geodetic`` are independent along
the local level; see :mod:`imugen.aid.filter.gnss`).

The update is the standard form ``P <- P - K (P h^T)^T`` on the full rows (contiguous),
symmetric to rounding; :func:`symmetrize` restores exact symmetry once per epoch. (The
Joseph form, ``(I - K h) P (I - K h)^T + K var K^T``, is algebraically the same for the
optimal gain and would change the rounding of every published result.)
"""

from __future__ import annotations

from imugen.core.jit import njit

F_REJECT = 16
"""Epoch flag: a scalar update was rejected by the innovation gate."""


@njit(cache=True, inline="always")
def clear(wk):
    """Zero the measurement row ``wk.h``; returns 0 (the row's count of non-zeros)."""
    for i in range(wk.h.shape[0]):
        wk.h[i] = 0.0
    return 0


@njit(cache=True, inline="always")
def put(wk, m, i, value):
    """Set ``h[i] = value`` as the row's ``m``-th non-zero; returns ``m + 1``."""
    wk.h[i] = value
    wk.hz[m] = i
    return m + 1


@njit(cache=True)
def scalar_update(wk, nnz, r, var, gate):
    """One scalar update of ``wk.P`` and ``wk.dx`` with the row ``wk.h`` (non-zero at
    ``wk.hz[:nnz]``), residual ``r = z_pred - z`` and noise variance ``var``.

    The innovation is ``r - h dx`` (the epoch's earlier updates are in ``dx``); with
    ``gate > 0`` an update whose normalized innovation exceeds ``gate`` is skipped. ``P``
    symmetric: ``P h^T`` is a sum of the rows named in ``hz``. Returns whether it was applied.
    """
    P, dx, h, nz, PHt = wk.P, wk.dx, wk.h, wk.hz, wk.PHt
    n = P.shape[0]
    for i in range(n):
        PHt[i] = 0.0
    for m in range(nnz):
        k = nz[m]
        f = h[k]
        for i in range(n):
            PHt[i] += f * P[k, i]
    s = var
    innov = r
    for m in range(nnz):
        k = nz[m]
        s += h[k] * PHt[k]
        innov -= h[k] * dx[k]
    if gate > 0.0 and innov * innov > gate * gate * s:
        return False
    inv = 1.0 / s
    for i in range(n):
        dx[i] += PHt[i] * inv * innov
    for i in range(n):
        ki = PHt[i] * inv
        for j in range(n):
            P[i, j] -= ki * PHt[j]
    return True


@njit(cache=True)
def fresh_state(P, dx, i, sd):
    """Start state ``i`` afresh: uncorrelated, zero mean error, variance ``sd^2``."""
    for j in range(P.shape[0]):
        P[i, j] = 0.0
        P[j, i] = 0.0
    P[i, i] = sd * sd
    dx[i] = 0.0


@njit(cache=True)
def symmetrize(P):
    """``P <- (P + P^T) / 2`` in place (once per epoch)."""
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            acc = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = acc
            P[j, i] = acc
