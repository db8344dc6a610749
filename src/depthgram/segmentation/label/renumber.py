"""Renumbering a label map through a lookup table in one compiled pass."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["relabel"]


@njit(cache=True, nogil=True)
def _relabel(labels: NDArray[np.int32], lut: NDArray[np.int32]) -> NDArray[np.int32]:
    h, w = labels.shape
    out = np.empty((h, w), np.int32)
    uw = np.uint64(w)
    for y in range(h):
        src = labels[y]
        dst = out[y]
        for x in range(uw):
            dst[x] = lut[np.uint64(src[x])]
    return out


def relabel(labels: NDArray[np.int32], lut: NDArray[np.integer]) -> NDArray[np.int32]:
    """``lut[labels]`` as int32, in one compiled pass.

    numpy's fancy indexing with an int32 index image is several times slower, and the slicing
    method renumbers full label maps several times per frame. ``labels`` must hold indices
    into ``lut`` (0 .. lut.size - 1).
    """
    return _relabel(np.ascontiguousarray(labels, np.int32), np.ascontiguousarray(lut, np.int32))
