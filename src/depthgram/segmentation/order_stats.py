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
    """Return ``np.percentile(a, q)`` (method ``linear``) of float32 values, ``a`` reordered in place.

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
    a[:] = np.partition(a, j)
    lo = a[j]
    hi = a[j + 1 :].min()
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
    """Return ``np.median`` of a 1-D float64 array (which may be reordered)."""
    return float(np.median(a, overwrite_input=True))
