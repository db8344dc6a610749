"""Window sums of float32 images that are OpenCV's to the last bit, in an order of our choosing.

OpenCV's unnormalised box filter of a float32 image adds in float64 (row sums sliding along the
row, column sums kept running down the rows) and rounds each sum to float32 once, at the end.
When every float64 intermediate is exact, its output is float32 of the exact window sum,
whatever order it adds in, and so is any other order whose intermediates are exact too. Every
float32 value is a whole multiple of ``2**q``, ``q`` the place of the last mantissa bit of the
smallest nonzero magnitude (``e_min - 23``, at least ``-149``), and every intermediate of
either route (a partial sum of an ``k x k`` window, a running column sum plus or minus one
value, one value minus another) is at most ``k * k`` times the largest magnitude ``m`` in the
rows it reads. float64 holds every whole multiple of ``2**q`` up to ``2**(53 + q)``, so all
intermediates are exact when ``k * k * m <= 2**(53 + q)``: about 23 octaves between the
smallest and largest magnitude for a 7 x 7 window, 25 for 3 x 3. :func:`exact_rows` tests it
over each output row's band of source rows (from the per-row ranges :func:`bits_range`
gives); a caller whose image fails it takes OpenCV's own filter.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["bits_range", "exact_rows", "start_columns", "window_row"]

_ABS = 0x7FFFFFFF
_NONE = 0xFFFFFFFF


@njit(cache=True, inline="always")
def bits_range(v: NDArray[np.float32]) -> tuple[np.int64, np.int64]:
    """Return the bit patterns of the largest and the smallest nonzero ``|v|`` (0, 0 if all zero).

    Unsigned 32-bit reductions on the bit patterns (non-negative float32 values order as their
    bits), so that the loop vectorises (a float max reduction does not without fast-math; 64-bit
    integers took a quarter longer); a NaN or an infinity gives a largest pattern of at least
    ``0x7F800000``.
    """
    b = v.view(np.uint32)
    hi = np.uint32(0)
    lo = np.uint32(_NONE)
    mask = np.uint32(_ABS)
    one = np.uint32(1)
    for i in range(b.size):
        a = b[i] & mask
        hi = max(hi, a)
        lo = min(lo, np.uint32(a - one))  # 0 wraps to the largest value: zeros never win
    return np.int64(hi), np.int64(np.uint32(lo + one))


@njit(cache=True, inline="always")
def exact_rows(hi: NDArray[np.int64], lo: NDArray[np.int64], n: int, before: int, after: int) -> bool:
    """Whether every output row's band of source rows sums exactly in float64, ``n`` values at a time.

    ``hi``, ``lo`` (H,): each source row's :func:`bits_range`. Output row ``y`` reads source
    rows ``y - before`` to ``y + after`` (clamped to the image): a running column sum takes the
    row ``r + 1`` above and adds the row ``r`` below. A band of rows instead of the whole image,
    so that a row of tiny values far from the largest ones does not send the frame to OpenCV.

    A band passes when ``n`` times its largest magnitude is a float64 whole multiple of its
    smallest nonzero magnitude's last bit (``n`` at most ``2**30``). Exact integer arithmetic
    on exponents and mantissas: ``n * m * 2**(e_hi - 150) <= 2**(53 + e_lo - 150)`` with ``m``
    the largest value's 24-bit mantissa and ``e`` the biased exponents (1 for subnormals).
    Infinite or NaN values fail; so do sums that could leave float32's range.
    """
    h = hi.size
    for y in range(h):
        a = max(y - before, 0)
        b = min(y + after, h - 1)
        top = 0
        low = _NONE
        for i in range(a, b + 1):
            top = max(top, hi[i])
            if lo[i] != 0:
                low = min(low, lo[i])
        if top == 0:
            continue  # all zeros
        e_hi = top >> 23
        if e_hi >= 240:  # infinities, NaNs and sums near float32's largest value
            return False
        m = top & 0x7FFFFF
        if e_hi == 0:
            e_hi = 1  # subnormal: no hidden bit
        else:
            m += 1 << 23
        s = 53 + max(low >> 23, 1) - e_hi
        if s < 0 or (s < 62 and n * m > (1 << s)):
            return False
    return True


@njit(cache=True, inline="always")
def start_columns(src: NDArray[np.float32], r: int, pad: NDArray[np.floating[Any]]) -> None:
    """Put the column sums of output row 0 (rows ``-r`` to ``r``, replicated) in ``pad[r:r + W]``.

    ``src`` (H, W); ``pad`` (W + 2 r,) of float64, or float32 for whole numbers that stay exact
    in it.
    """
    h, w = src.shape
    mid = pad[r : r + w]
    mid[:] = 0
    for d in range(-r, r + 1):
        row = src[min(max(d, 0), h - 1)]
        for x in range(w):
            mid[x] += row[x]


@njit(cache=True, inline="always")
def window_row(
    pad: NDArray[np.floating[Any]], r: int, pairs: NDArray[np.floating[Any]], out: NDArray[np.float32]
) -> None:
    """Give ``out`` (W,) the sums of ``2 r + 1`` column sums across (replicated border), as float32.

    ``pad`` (W + 2 r,) holds the column sums in its middle; its ends are filled here.
    ``pairs`` (W + 2 r,): scratch of ``pad``'s type. For r = 3 the pairs of neighbours are
    summed once and a window is three pairs and one sum (4 additions for 6).
    """
    w = out.size
    # the first and last column sums repeated over the r places beyond each end
    first = pad[r]
    last = pad[r + w - 1]
    for i in range(r):
        pad[i] = first
        pad[r + w + i] = last
    if r == 3:
        m = w + 5
        a, b = pad[0:m], pad[1 : m + 1]
        for i in range(m):
            pairs[i] = a[i] + b[i]
        p0, p2, p4, s6 = pairs[0:w], pairs[2 : w + 2], pairs[4 : w + 4], pad[6 : w + 6]
        for x in range(w):
            out[x] = np.float32((p0[x] + p2[x]) + (p4[x] + s6[x]))
        return
    acc = pairs[:w]
    for x in range(w):
        acc[x] = pad[x]
    for d in range(1, 2 * r + 1):
        pd = pad[d : d + w]
        for x in range(w):
            acc[x] += pd[x]
    for x in range(w):
        out[x] = np.float32(acc[x])
