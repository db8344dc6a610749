"""Order statistics (k-th smallest values) of arrays that repeat many values, compiled.

Quantised depths and their differences take few distinct values; numba's sort slows down on
such arrays and a call of ``np.partition`` costs tens of microseconds from a compiled loop's
point of view. An order statistic does not depend on how it is found, so these give the values
``np.partition`` gives.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["kth_pair", "kth_smallest", "median_inplace", "next_smallest", "percentile32"]


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


#: Widest span of doubled values :func:`kth_pair` counts instead of partitioning.
_MAX_COUNT_SPAN = 1 << 14


@njit(cache=True, nogil=True)
def kth_pair(a: NDArray[np.float64], k: int) -> tuple[float, float]:
    """Return the ``k``-th and ``(k + 1)``-th smallest values of ``a`` (0-based).

    The second is the first again when ``k`` is the last index.
    ``np.partition(a, k)[k]`` and the next value, as :func:`kth_smallest` and
    :func:`next_smallest` give them (``a`` may be reordered). Whole and half numbers within a
    span of 8192 (quantised depths, their differences and the deviations from a median of
    them) are counted in one pass instead: an order statistic is a value of ``a`` whatever
    finds it, and each counted value is checked to come back exactly.
    """
    n = a.size
    lo = a[0]
    hi = a[0]
    for i in range(1, n):
        v = a[i]
        lo = min(lo, v)
        hi = max(hi, v)
    if (hi - lo) * 2.0 < _MAX_COUNT_SPAN:
        m = int((hi - lo) * 2.0) + 1
        count = np.zeros(m, np.int64)
        exact = True
        for i in range(n):
            t = (a[i] - lo) * 2.0
            j = int(t)
            if j != t or lo + j / 2.0 != a[i]:
                exact = False
                break
            count[j] += 1
        if exact:
            j = 0
            seen = count[0]
            while seen <= k:
                j += 1
                seen += count[j]
            first = lo + j / 2.0
            if seen > k + 1 or k + 1 >= n:
                return first, first
            j += 1
            while count[j] == 0:
                j += 1
            return first, lo + j / 2.0
    first = kth_smallest(a, k)
    if k + 1 >= n:
        return first, first
    return first, next_smallest(a, k)


@njit(cache=True, nogil=True)
def percentile32(a: NDArray[np.float32], q: float, weak: bool) -> float:
    """Return ``np.percentile(a, q)`` (method ``linear``) of float32 values, ``a`` reordered in place.

    numpy interpolates between the two order statistics around ``(n - 1) q / 100`` in float32
    when ``q`` is a Python number (``weak``) and in float64 when it is one of a sequence of
    percentiles; both are reproduced here operation by operation, so the result is numpy's to
    the last bit (a test compares them). ``a`` must not be empty.
    """
    n = a.size
    vi = (n - 1) * (q / 100)
    if vi >= n - 1:
        top = a[0]
        for i in range(1, n):
            top = max(top, a[i])
        return float(top)
    j = math.floor(vi)
    lo = np.float32(kth_smallest(a, j))
    hi = np.float32(next_smallest(a, j))
    diff = hi - lo  # float32, as numpy takes the difference of the two values
    t = vi - j
    if weak:
        if t >= 0.5:
            return float(hi - diff * np.float32(1.0 - t))
        return float(lo + diff * np.float32(t))
    if t >= 0.5:
        return np.float64(hi) - np.float64(diff) * (1.0 - t)
    return np.float64(lo) + np.float64(diff) * t


@njit(cache=True, nogil=True)
def median_inplace(a: NDArray[np.float64]) -> float:
    """Return ``np.median`` of a 1-D float64 array, reordering it in place."""
    n = a.size
    h = n // 2
    if n % 2:
        return kth_pair(a, h)[0]
    lo, hi = kth_pair(a, h - 1)
    return (lo + hi) / 2.0
