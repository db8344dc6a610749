"""Union-find over provisional labels, and the second pass every two-pass labeller shares.

A labeller's first pass gives each pixel a provisional label and joins labels found to meet
(:func:`union`); :func:`resolve` then numbers the sets in raster order of their first pixel,
adds up their statistics (the table of :mod:`depthgram.segmentation.label.stats`), drops
small ones and rewrites the label map, all in one pass over the image.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label.stats import COUNT, KEY, N_COLUMNS, N_SUMS

__all__ = ["find", "fold_tables", "resolve", "resolve_tables", "union"]


@njit(cache=True, inline="always")
def find(parent: NDArray[np.int32], i: int) -> int:
    """Root of ``i``'s set, compressing the path on the way."""
    root = i
    while parent[root] != root:
        root = parent[root]
    while parent[i] != root:  # path compression keeps later finds short
        nxt = parent[i]
        parent[i] = root
        i = nxt
    return root


@njit(cache=True, inline="always")
def fold_tables(
    final: NDArray[np.int32],
    nxt: int,
    n: int,
    psums: NDArray[np.float64],
    pboxes: NDArray[np.int32],
    h: int,
    w: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Return the statistics table and inclusive boxes of labels 1..n from the provisional ones.

    Provisional label ``i`` (1..nxt-1) goes to final label ``final[i]``; its rows are added in
    provisional order, so every labeller that folds this way gets the same numbers.
    """
    sums = np.zeros((n + 1, N_COLUMNS), np.float64)
    boxes = np.empty((n + 1, 4), np.int64)
    boxes[:, 0] = w
    boxes[:, 1] = h
    boxes[:, 2] = -1
    boxes[:, 3] = -1
    for i in range(1, nxt):
        f = final[i]
        for k in range(N_SUMS):
            sums[f, k] += psums[i, k]
        sums[f, KEY] = psums[i, KEY]
        boxes[f, 0] = min(boxes[f, 0], pboxes[i, 0])
        boxes[f, 1] = min(boxes[f, 1], pboxes[i, 1])
        boxes[f, 2] = max(boxes[f, 2], pboxes[i, 2])
        boxes[f, 3] = max(boxes[f, 3], pboxes[i, 3])
    return sums, boxes


@njit(cache=True, nogil=True)
def union(parent: NDArray[np.int32], a: int, b: int) -> int:
    """Join the sets of ``a`` and ``b``; the smaller root becomes the root. Returns it."""
    ra = find(parent, a)
    rb = find(parent, b)
    if ra < rb:
        parent[rb] = ra
        return ra
    parent[ra] = rb
    return rb


@njit(cache=True, nogil=True)
def resolve(
    lab: NDArray[np.int32],
    parent: NDArray[np.int32],
    nxt: int,
    psums: NDArray[np.float64],
    pboxes: NDArray[np.int32],
    min_px: int,
    stats: bool,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    """Second pass of a two-pass labeller: provisional labels ``1..nxt - 1`` to final ones.

    Sets are numbered 1..n in raster order of their first pixel (the root of a set is its
    smallest provisional label). With ``stats``, the provisional sums and boxes are added up
    per set, sets under ``min_px`` pixels dropped and the rest renumbered, all before the one
    relabelling pass over ``lab`` (rewritten in place and returned). Without ``stats`` the
    returned sums are zeros and the boxes are unset.
    """
    final, n, sums, boxes = resolve_tables(lab, parent, nxt, psums, pboxes, min_px, stats)
    h, w = lab.shape
    # final[0] is 0: one branch-free gather per pixel, with unsigned indices so that it
    # vectorises (a test-and-branch version does not)
    uw = np.uint64(w)
    for y in range(h):
        row = lab[y]
        for x in range(uw):
            row[x] = final[np.uint64(row[x])]
    return lab, n, sums, boxes


@njit(cache=True, nogil=True)
def resolve_tables(
    lab: NDArray[np.int32],
    parent: NDArray[np.int32],
    nxt: int,
    psums: NDArray[np.float64],
    pboxes: NDArray[np.int32],
    min_px: int,
    stats: bool,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    """:func:`resolve` without its relabelling pass.

    The final label of each provisional one (``final[0]`` is 0), n, and the sums and boxes per final
    label, for a caller that rewrites ``lab`` itself (gathering more per run on the way).
    """
    final = np.zeros(nxt, np.int32)
    n = 0
    for i in range(1, nxt):
        r = find(parent, i)
        if r == i:
            n += 1
            final[i] = n
        else:
            final[i] = final[r]
    if stats:
        sums, boxes = fold_tables(final, nxt, n, psums, pboxes, lab.shape[0], lab.shape[1])
        newid = np.zeros(n + 1, np.int32)
        k = 0
        for j in range(1, n + 1):
            if sums[j, COUNT] >= min_px:
                k += 1
                newid[j] = k
                if k != j:
                    sums[k] = sums[j]
                    boxes[k] = boxes[j]
        for i in range(1, nxt):
            final[i] = newid[final[i]]
        n = k
        sums = sums[: n + 1].copy()
        boxes = boxes[: n + 1].copy()
    else:
        sums = np.zeros((n + 1, N_COLUMNS), np.float64)
        boxes = np.empty((n + 1, 4), np.int64)
    sums[0] = 0.0
    h, w = lab.shape
    boxes[0, 0] = w
    boxes[0, 1] = h
    boxes[0, 2] = -1
    boxes[0, 3] = -1
    return final, n, sums, boxes
