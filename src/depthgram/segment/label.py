"""Connected components of a keyed image in one pass, bridging small holes of invalid pixels.

OpenCV's ``connectedComponentsWithStats`` labels binary images only, and labelling each depth
band by masking would cost (bands x pixels). This union-find labeller joins 4-neighbours whose
keys agree within a tolerance, so one pass labels every band at once (key = band index,
tolerance 0) and also serves region growing (key = depth, tolerance in mm). It skips over short
runs of pixels without a reading, so a surface seen through a sieve of dropouts stays one
component, while a valid pixel of another key always blocks the join. No library kernel does
this (scipy's csgraph needs an explicit edge list, measured slower in
``benchmarks/bench_segmentation.py``), hence numba.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["ACTIVE", "BLOCK", "HOLE", "label_keyed"]

#: Pixel states for :func:`label_keyed`: a hole may be bridged, an active pixel is labelled,
#: a blocking pixel (valid, but not part of any component) stops a bridge.
HOLE, ACTIVE, BLOCK = 0, 1, 2


@njit(cache=True, inline="always")
def _find(parent: NDArray[np.int32], i: int) -> int:
    root = i
    while parent[root] != root:
        root = parent[root]
    while parent[i] != root:  # path compression keeps later finds short
        nxt = parent[i]
        parent[i] = root
        i = nxt
    return root


@njit(cache=True)
def _label(
    key: NDArray[np.float32],
    state: NDArray[np.int8],
    tol: float,
    rel: float,
    bridge: int,
) -> tuple[NDArray[np.int32], int]:
    h, w = key.shape
    parent = np.arange(h * w, dtype=np.int32)
    for y in range(h):
        for x in range(w):
            if state[y, x] != ACTIVE:
                continue
            p = y * w + x
            kp = key[y, x]
            lim = tol + rel * abs(kp)
            # nearest active pixel to the left, across at most `bridge` holes
            for d in range(1, bridge + 2):
                xx = x - d
                if xx < 0:
                    break
                s = state[y, xx]
                if s == HOLE:
                    continue
                if s == ACTIVE and abs(key[y, xx] - kp) <= lim:
                    a = _find(parent, p)
                    b = _find(parent, y * w + xx)
                    if a != b:
                        if a < b:
                            parent[b] = a
                        else:
                            parent[a] = b
                break
            for d in range(1, bridge + 2):
                yy = y - d
                if yy < 0:
                    break
                s = state[yy, x]
                if s == HOLE:
                    continue
                if s == ACTIVE and abs(key[yy, x] - kp) <= lim:
                    a = _find(parent, p)
                    b = _find(parent, yy * w + x)
                    if a != b:
                        if a < b:
                            parent[b] = a
                        else:
                            parent[a] = b
                break
    labels = np.zeros((h, w), dtype=np.int32)
    # roots are the smallest index of each set, so a raster scan meets each root first
    ids = np.zeros(h * w, dtype=np.int32)
    n = 0
    for y in range(h):
        for x in range(w):
            if state[y, x] != ACTIVE:
                continue
            p = y * w + x
            r = _find(parent, p)
            if r == p:
                n += 1
                ids[p] = n
            labels[y, x] = ids[r]
    return labels, n


def label_keyed(
    key: NDArray[Any],
    state: NDArray[np.int8],
    *,
    tol: float = 0.0,
    rel: float = 0.0,
    bridge: int = 0,
) -> tuple[NDArray[np.int32], int]:
    """Label 4-connected components of active pixels whose keys agree.

    Parameters
    ----------
    key : ndarray, shape (H, W)
        Value compared between neighbours (band index, or depth in mm).
    state : ndarray of int8, shape (H, W)
        :data:`HOLE`, :data:`ACTIVE` or :data:`BLOCK` per pixel.
    tol : float
        Neighbours join when ``|key_a - key_b| <= tol + rel * |key_a|``.
    rel : float
        Relative part of the tolerance (per unit of key).
    bridge : int
        Longest run of holes (px) crossed along a row or a column.

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
        Component id per active pixel, 1..n in raster order of first pixel; 0 elsewhere.
    n : int
        Number of components.
    """
    k = np.ascontiguousarray(key, dtype=np.float32)
    s = np.ascontiguousarray(state, dtype=np.int8)
    labels, n = _label(k, s, float(tol), float(rel), int(bridge))
    return labels, int(n)
