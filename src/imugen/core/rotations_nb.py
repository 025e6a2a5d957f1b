"""Compiled scalar quaternion helpers for numba kernels (``inline="always"``).

The array versions are :mod:`imugen.core.rotations`; these work on scalars held in registers
inside the navigation and filter kernels. Quaternions are scalar first.
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

from imugen.core.jit import njit


@intrinsic
def fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (the CPU's fused multiply-add; float64 only).

    Explicit, so results do not depend on where a compiler chooses to contract (numba's
    ``fastmath`` would also reach every callee, e.g. the shared gravitation).
    """
    if not all(isinstance(x, types.Float) for x in (a, b, c)):
        return None
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(d, [d, d, d]), "llvm.fma.f64"
        )
        return builder.call(
            fn,
            [
                context.cast(builder, v, t, types.float64)
                for v, t in zip(args, signature.args, strict=True)
            ],
        )

    return sig, codegen


@njit(cache=True, inline="always")
def qexpm1(x, y, z):
    """Exp of a rotation vector as a quaternion minus identity: (cos(t/2) - 1, sin(t/2)/t v).

    Series for |t| < 0.1 (exact in float64), closed form otherwise; no cancellation in the
    scalar part.
    """
    t2 = fma(x, x, fma(y, y, z * z))
    if t2 < 1e-2:
        a2 = 0.25 * t2
        c = fma(a2, -1.0 / 40320.0, 1.0 / 720.0)
        c = fma(a2, -c, 1.0 / 24.0)
        c = fma(a2, -c, 0.5)
        cm1 = -a2 * c
        s = fma(a2, -1.0 / 362880.0, 1.0 / 5040.0)
        s = fma(a2, -s, 1.0 / 120.0)
        s = fma(a2, -s, 1.0 / 6.0)
        s = fma(-0.5 * a2, s, 0.5)
    else:
        t = math.sqrt(t2)
        sq = math.sin(0.25 * t)
        cm1 = -2.0 * sq * sq
        s = math.sin(0.5 * t) / t
    return cm1, s * x, s * y, s * z


@njit(cache=True, inline="always")
def qmul(aw, ax, ay, az, bw, bx, by, bz):
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )
