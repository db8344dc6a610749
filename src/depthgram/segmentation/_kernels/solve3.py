"""A 3 x 3 linear solve in compiled code, with numpy's (LAPACK's) operations in numpy's order."""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic
from numpy.typing import NDArray


def _fma_typing(typingctx: object, a: types.Type, b: types.Type, c: types.Type) -> tuple[object, object]:
    # the typing and code of _fma: three float64 in, LLVM's fused multiply-add out
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context: object, builder: ir.IRBuilder, signature: object, args: list[ir.Value]) -> ir.Value:
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


#: ``_fma(a, b, c)``: ``a * b + c`` rounded once (LLVM's ``llvm.fma.f64``), in compiled code only.
_fma = cast(Callable[[float, float, float], float], intrinsic(_fma_typing))


@njit(cache=True, inline="always", error_model="numpy")
def lu_solve3(a: NDArray[np.float64], x: NDArray[np.float64]) -> None:
    """Solve one 3 x 3 system ``a y = x`` in place, to the last bit as ``np.linalg.solve`` does.

    ``a`` is overwritten by its LU factors and ``x`` by the solution. Compiled so that a
    handful of small systems is not a batched numpy call each (about 30 us of calls around
    nanoseconds of arithmetic). numpy's LAPACK (OpenBLAS ``dgesv``) factors column by
    column (left-looking ``getf2``: each column's update a dot product taken with fused
    multiply-adds, then subtracted; the pivot the first largest magnitude; the column below
    it scaled by the pivot's reciprocal), then solves the two triangles by columns
    (``trsv``: fused multiply-adds, a division by each diagonal). The same operations in the
    same order give the same numbers (a test compares them on many systems); a zero pivot,
    where numpy raises, gives inf or nan here.
    """
    # the matrix and the right-hand side in registers: the pivot's row swaps are selects
    # (which row holds the largest magnitude cannot be predicted: a branch on it flushed the
    # pipeline, and with it the overlap of one system's divisions with the next one's); the
    # rows are swapped whole when the pivot is chosen, as getf2's later columns would be
    a00, a01, a02 = a[0, 0], a[0, 1], a[0, 2]
    a10, a11, a12 = a[1, 0], a[1, 1], a[1, 2]
    a20, a21, a22 = a[2, 0], a[2, 1], a[2, 2]
    x0, x1, x2 = x[0], x[1], x[2]
    # column 0 (no update: the column minus an empty product is itself)
    big = abs(a00)
    s1 = abs(a10) > big
    big = max(big, abs(a10)) if s1 else big
    s2 = abs(a20) > big
    s1 = s1 and not s2
    # rows 0 and 1 or 0 and 2 swapped (x too: its swaps come first in the solve)
    t00, t01, t02, tx = a00, a01, a02, x0
    a00 = a20 if s2 else (a10 if s1 else a00)
    a01 = a21 if s2 else (a11 if s1 else a01)
    a02 = a22 if s2 else (a12 if s1 else a02)
    x0 = x2 if s2 else (x1 if s1 else x0)
    a10, a11, a12, x1 = (t00, t01, t02, tx) if s1 else (a10, a11, a12, x1)
    a20, a21, a22, x2 = (t00, t01, t02, tx) if s2 else (a20, a21, a22, x2)
    p = a00
    if p != 0.0:
        if abs(p) >= 2.2250738585072014e-308:
            rp = 1.0 / p
            a10 *= rp
            a20 *= rp
        else:
            a10 /= p
            a20 /= p
    # column 1: minus L times its U part, then its pivot among rows 1 and 2
    a11 = a11 - _fma(a10, a01, 0.0)
    a21 = a21 - _fma(a20, a01, 0.0)
    sw = abs(a21) > abs(a11)
    a10, a20 = (a20, a10) if sw else (a10, a20)
    a11, a21 = (a21, a11) if sw else (a11, a21)
    a12, a22 = (a22, a12) if sw else (a12, a22)
    x1, x2 = (x2, x1) if sw else (x1, x2)
    p = a11
    if p != 0.0:
        if abs(p) >= 2.2250738585072014e-308:
            a21 *= 1.0 / p
        else:
            a21 /= p
    # column 2
    a12 = a12 - _fma(a10, a02, 0.0)
    a22 = a22 - _fma(a21, a12, _fma(a20, a02, 0.0))
    a[0, 0], a[0, 1], a[0, 2] = a00, a01, a02
    a[1, 0], a[1, 1], a[1, 2] = a10, a11, a12
    a[2, 0], a[2, 1], a[2, 2] = a20, a21, a22
    # the right-hand side through L (unit diagonal) and U, by columns
    x1 = _fma(-x0, a10, x1)
    x2 = _fma(-x0, a20, x2)
    x2 = _fma(-x1, a21, x2)
    x2 /= a22
    x0 = _fma(-x2, a02, x0)
    x1 = _fma(-x2, a12, x1)
    x1 /= a11
    x0 = _fma(-x1, a01, x0)
    x0 /= a00
    x[0], x[1], x[2] = x0, x1, x2
