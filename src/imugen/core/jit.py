"""numba ``njit`` with an on-disk cache that follows the whole package's code.

numba's ``cache=True`` revalidates a compiled kernel against the source file of that
function only; a kernel that calls jitted helpers from another module (the mechanization
calls :mod:`imugen.core.earth`'s gravity) would keep stale machine code after that other module
changes. Before the first kernel is defined, this module hashes every ``*.py`` file of the
package and, when the hash differs from the one stamped in the package's ``__pycache__``,
deletes the numba cache files of every ``__pycache__`` folder of the package. Kernels then recompile once (a few
seconds) and are cached across processes again.

Start-up: numba's array-math registry (loaded with the typing context on a kernel's first call,
even from the cache) probes for BLAS at import by importing ``scipy.linalg`` (0.2-0.3 CPU-s per
process). scipy is a dependency of imugen, so the probe's answer is known; this module imports
that registry once with the probe answered, and scipy loads only where a stage uses it (or
where a kernel using BLAS compiles: numba's linear algebra calls the real probe then).

The cache is an optimisation, never a requirement: a kernel whose cache file cannot be written
(read-only install, full disk, quota or ``RLIMIT_FSIZE``: ``OSError``) runs from memory and the
stage goes on; numba itself lets such errors fail the call that compiled the kernel.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

from numba import njit as _njit
from numba.core.caching import FunctionCache
from numba.core.dispatcher import Dispatcher

_PACKAGE = Path(__file__).resolve().parents[1]
"""The ``imugen`` package folder (this module is ``imugen/core/jit.py``)."""
_STAMP = "imugen-numba-source.sha256"


def _source_digest() -> str:
    h = hashlib.sha256()
    for path in sorted(_PACKAGE.rglob("*.py")):
        h.update(str(path.relative_to(_PACKAGE)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def _refresh_cache() -> None:
    cache = _PACKAGE / "__pycache__"
    if not cache.is_dir():
        return
    digest = _source_digest()
    stamp = cache / _STAMP
    try:
        if stamp.is_file() and stamp.read_text() == digest:
            return
        for folder in _PACKAGE.rglob("__pycache__"):
            for f in (*folder.glob("*.nbi"), *folder.glob("*.nbc")):
                f.unlink(missing_ok=True)
        fd, tmp = tempfile.mkstemp(dir=cache, prefix=".stamp.")
        with os.fdopen(fd, "w") as fh:
            fh.write(digest)
        os.replace(tmp, stamp)
    except OSError:
        pass  # read-only install: numba then caches elsewhere or not at all


_refresh_cache()


def _import_arraymath_without_scipy() -> None:
    """Import ``numba.np.arraymath`` with its BLAS probe answered (see the module docstring)."""
    if "numba.np.arraymath" in sys.modules:
        return
    import numba.np.linalg as nplinalg

    probe = nplinalg.ensure_blas
    nplinalg.ensure_blas = lambda: None  # scipy (hence its BLAS) is an imugen dependency
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        nplinalg.ensure_blas = probe


_import_arraymath_without_scipy()


class _TolerantCache(FunctionCache):
    """numba's per-function cache whose failed saves are ignored (the kernel stays in memory)."""

    def save_overload(self, sig, data):
        try:
            super().save_overload(sig, data)
        except OSError:
            pass


def _tolerant(dispatcher):
    if isinstance(dispatcher, Dispatcher) and isinstance(dispatcher._cache, FunctionCache):
        dispatcher._cache = _TolerantCache(dispatcher.py_func)
    return dispatcher


def njit(*args, **kwargs):
    """``numba.njit`` (same arguments); see the module docstring for the cache policy."""
    out = _njit(*args, **kwargs)
    if isinstance(out, Dispatcher):
        return _tolerant(out)
    return lambda func: _tolerant(out(func))


def njit_borrowing(*args, **kwargs):
    """:func:`njit` for a function that allocates nothing and only borrows its arrays: no
    reference counting is compiled into it (numba's ``_nrt=False``).

    Passing a named tuple of arrays to a compiled function costs two atomic reference-count
    operations per array per call; the aided filter's time loop passes its inputs, outputs
    and scratch arrays to one function per measurement at every epoch, which made it 6x
    slower than the same arithmetic in one function (benchmarks/bench_aided.py). Its arrays
    live, owned by the Python caller, for the whole call, so the counts are not needed. A
    function compiled this way that allocates fails to compile (numba needs the runtime).
    """
    return njit(*args, _nrt=False, **kwargs)
