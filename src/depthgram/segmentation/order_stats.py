"""Order statistics (k-th smallest values) of arrays that repeat many values, compiled.

Quantised depths and their differences take few distinct values; numba's sort slows down on
such arrays and a call of ``np.partition`` costs tens of microseconds from a compiled loop's
point of view. An order statistic does not depend on how it is found, so these give the values
``np.partition`` gives.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["kth_smallest", "next_smallest"]


@njit(cache=True, nogil=True)
def kth_smallest(a: NDArray[np.floating], k: int) -> float:
    """Return the ``k``-th smallest value of ``a`` (0-based), reordering ``a`` in place so that ``a[k + 1:] >= a[k]``.

    ``np.partition(a, k)[k]``.

    Three-way partitions (below, equal to, above a median-of-three pivot), so repeated
    values cost one pass.
    """
    lo, hi = 0, a.size - 1
    while lo < hi:
        mid = (lo + hi) // 2
        p0, p1, p2 = a[lo], a[mid], a[hi]
        pivot = max(min(p0, p1), min(max(p0, p1), p2))
        # values below the pivot to the front, then values equal to it: two branchless passes
        # (a swap every step, the write index moved by the comparison), since which way a
        # value goes cannot be predicted and a mispredicted branch costs more than a swap
        j = lo
        for i in range(lo, hi + 1):
            v = a[i]
            a[i] = a[j]
            a[j] = v
            j += v < pivot
        if k < j:
            hi = j - 1
            continue
        e = j
        for i in range(j, hi + 1):
            v = a[i]
            a[i] = a[e]
            a[e] = v
            e += v == pivot
        if k < e:
            return float(pivot)
        lo = e
    return float(a[k])


@njit(cache=True, nogil=True)
def next_smallest(a: NDArray[np.floating], k: int) -> float:
    """Return the ``(k + 1)``-th smallest value of ``a``.

    Valid after :func:`kth_smallest` (``a``, ``k``) left the larger values right of ``k``.
    """
    return float(a[k + 1 :].min())
