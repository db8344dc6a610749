"""Percentiles and medians of small samples: numpy's values, callable from compiled code.

An order statistic does not depend on how it is found, so the selections are numpy's own
(``np.partition``, which numba also compiles); what is kept here is numpy's interpolation
arithmetic between the two order statistics, in numpy's precision, so that a compiled caller
gets ``np.percentile``'s value.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["median_inplace", "percentile32"]


@njit(cache=True, nogil=True)
def percentile32(a: NDArray[np.float32], q: float, weak: bool) -> float:
    """Return ``np.percentile(a, q)`` (method ``linear``) of float32 values.

    numpy interpolates between the two order statistics around ``(n - 1) q / 100`` in float32
    when ``q`` is a Python number (``weak``) and in float64 when it is one of a sequence of
    percentiles; both are reproduced here (a test compares them with numpy). Compiled because
    the caller is (surfaces' far limit, the plane search's depth spread). ``a`` must not be
    empty.
    """
    n = a.size
    vi = (n - 1) * (q / 100)
    if vi >= n - 1:
        return float(a.max())
    j = math.floor(vi)
    part = np.partition(a, j)
    lo = part[j]
    hi = part[j + 1 :].min()
    diff = hi - lo  # float32, as numpy takes the difference of the two values
    t = vi - j
    if weak:
        if t >= 0.5:
            return float(hi - diff * np.float32(1.0 - t))
        return float(lo + diff * np.float32(t))
    if t >= 0.5:
        return np.float64(hi) - np.float64(diff) * (1.0 - t)
    return np.float64(lo) + np.float64(diff) * t


def median_inplace(a: NDArray[np.float64]) -> float:
    """Return ``np.median`` of a 1-D float64 array (which is sorted in place).

    The middle value, or the mean of the two middle ones, of the sorted array: np.median's
    value (a test compares them) without its 50 us of argument handling around a few values.
    """
    a.sort()
    h = a.size // 2
    return float(a[h]) if a.size % 2 else float((a[h - 1] + a[h]) / 2.0)
