"""The per-label statistics table: its columns, and the one-pass statistics of a label map.

Every labeller of :mod:`depthgram.segmentation.label` and the statistics pass here give the
same two tables per label (row ``i`` is label ``i``, row 0 unused):

``sums``, float64, shape (n + 1, :data:`N_COLUMNS`)
    :data:`COUNT` pixels; :data:`SUM_Z` and :data:`SUM_ZZ` of depth (mm, mm²); :data:`SUM_X`
    and :data:`SUM_Y` of column and row (px); :data:`SUM_XZ` and :data:`SUM_YZ` of column x
    depth and row x depth (px mm); and :data:`KEY`, the key of the label (its band, or what the
    caller passed). The first :data:`N_SUMS` columns are additive: the row of a union of labels
    is the sum of their rows.
``boxes``, int64, shape (n + 1, 4)
    (x0, y0, x1, y1) INCLUSIVE per label (the last column and row it covers); an empty label
    has (W, H, -1, -1). :class:`~depthgram.segmentation.objects.SceneObject` carries half-open
    boxes; :func:`depthgram.segmentation.attributes.make_objects` converts.

This module owns that layout: code reading the table names the column by these constants
(they are plain ints, so compiled kernels index with them at no cost).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "COUNT",
    "KEY",
    "N_COLUMNS",
    "N_SUMS",
    "SUM_X",
    "SUM_XZ",
    "SUM_Y",
    "SUM_YZ",
    "SUM_Z",
    "SUM_ZZ",
    "add_rows",
    "label_stats_fused",
    "relabel_stats",
]

#: Pixel count of the label.
COUNT = 0
#: Sum of depth (mm).
SUM_Z = 1
#: Sum of depth squared (mm²).
SUM_ZZ = 2
#: Sum of the column (px).
SUM_X = 3
#: Sum of the row (px).
SUM_Y = 4
#: Sum of column x depth (px mm).
SUM_XZ = 5
#: Sum of row x depth (px mm).
SUM_YZ = 6
#: Key of the label (band index, or the key image's value at its pixels); not additive.
KEY = 7
#: Number of additive columns (0 .. N_SUMS - 1).
N_SUMS = 7
#: Number of columns of the table.
N_COLUMNS = 8


@njit(cache=True, inline="always")
def flush_run(
    sums: NDArray[np.float64],
    boxes: NDArray[np.int32],
    i: int,
    c: float,
    sz: float,
    szz: float,
    sx: float,
    sxz: float,
    y: int,
    x0: int,
    x1: int,
    k: float | np.float32,
) -> None:
    """Add one run of label ``i`` along row ``y`` (columns ``x0..x1``) to the tables.

    ``c, sz, szz, sx, sxz`` are the run's count and sums of Z, Z², x and xZ; the row terms
    follow from them since ``y`` is constant along the run. The key is overwritten (every
    pixel of a label has the same key).
    """
    sums[i, COUNT] += c
    sums[i, SUM_Z] += sz
    sums[i, SUM_ZZ] += szz
    sums[i, SUM_X] += sx
    sums[i, SUM_Y] += c * y
    sums[i, SUM_XZ] += sxz
    sums[i, SUM_YZ] += sz * y
    sums[i, KEY] = k
    if x0 < boxes[i, 0]:
        boxes[i, 0] = x0
    if x1 > boxes[i, 2]:
        boxes[i, 2] = x1
    boxes[i, 3] = y  # rows are scanned in order: the latest row is the lowest


def add_rows(sums: NDArray[np.float64], boxes: NDArray[np.int64], src: NDArray[np.intp], dst: NDArray[np.intp]) -> None:
    """Add row ``src[k]`` of the table to row ``dst[k]``, and its box to that box, for each k in turn (in place).

    The union of two labels' pixels: the additive columns (the first ``sums.shape[1]``, at most
    :data:`N_SUMS`) summed, the inclusive boxes joined. Row after row, so that a row added to
    carries what was added to it before; a few rows a frame.
    """
    for s, d in zip(src.tolist(), dst.tolist(), strict=True):
        sums[d] += sums[s]
        (a0, a1, a2, a3), (b0, b1, b2, b3) = boxes[d].tolist(), boxes[s].tolist()
        boxes[d] = min(a0, b0), min(a1, b1), max(a2, b2), max(a3, b3)


@njit(cache=True, inline="always")
def _gather(
    labels: NDArray[np.int32],
    lut: NDArray[np.int32],
    use_lut: bool,
    n: int,
    depth: NDArray[np.float32],
    key: NDArray[np.float32],
    use_key: bool,
) -> tuple[NDArray[np.int32], NDArray[np.float64], NDArray[np.int64]]:
    # One raster pass for every label's sums and box, whatever the label count (the bincount
    # route needs seven passes plus find_objects). With `use_lut` each pixel's label goes
    # through `lut` first and the renumbered map is written too (relabel fused with the
    # statistics); with `use_key` the KEY column is filled. Inlined into its two callers with
    # the flags constant, so neither pays for the other's tests. Rows are read as row slices
    # with unsigned indices (a signed index is tested for wrapping, a 2-D one recomputes its
    # address: 122 -> 101 us at 320 x 240), and a run's count and sums of x and y are whole
    # numbers, exact in float64 in any order, added once from the run's ends (-> 84 us).
    h, w = labels.shape
    oh = h if use_lut else 1
    ow = w if use_lut else 1
    out = np.zeros((oh, ow), np.int32)
    sums = np.zeros((n + 1, N_COLUMNS), np.float64)
    box = np.empty((n + 1, 4), np.int64)
    box[:, 0] = w
    box[:, 1] = h
    box[:, 2] = -1
    box[:, 3] = -1
    uw = np.uint64(w)
    one = np.uint64(1)
    for y in range(h):
        lr = labels[y]
        dr = depth[y]
        orow = out[y] if use_lut else out[0]
        fy = np.float64(y)
        ux = np.uint64(0)
        while ux < uw:
            i = lr[ux]
            if use_lut:
                i = lut[np.uint64(i)]
            if i == 0:
                ux += one
                continue
            # a run of one label: its sums stay in registers, added to pixel by pixel in the same
            # order (the same numbers), and are stored once at the run's end
            start = ux
            sz = sums[i, SUM_Z]
            szz = sums[i, SUM_ZZ]
            sxz = sums[i, SUM_XZ]
            syz = sums[i, SUM_YZ]
            while True:
                if use_lut:
                    orow[ux] = i
                z = np.float64(dr[ux])
                sz += z
                szz += z * z
                sxz += np.float64(ux) * z
                syz += fy * z
                ux += one
                if ux == uw:
                    break
                j = lr[ux]
                if use_lut:
                    j = lut[np.uint64(j)]
                if j != i:
                    break
            x0 = np.int64(start)
            x1 = np.int64(ux) - 1
            k = x1 - x0 + 1
            sums[i, COUNT] += np.float64(k)
            sums[i, SUM_Z] = sz
            sums[i, SUM_ZZ] = szz
            sums[i, SUM_X] += np.float64((x0 + x1) * k // 2)
            sums[i, SUM_Y] += np.float64(y * k)
            sums[i, SUM_XZ] = sxz
            sums[i, SUM_YZ] = syz
            if use_key:
                sums[i, KEY] = key[y, x1]
            if x0 < box[i, 0]:
                box[i, 0] = x0
            if y < box[i, 1]:
                box[i, 1] = y
            if x1 > box[i, 2]:
                box[i, 2] = x1
            if y > box[i, 3]:
                box[i, 3] = y
    return out, sums, box


@njit(cache=True, nogil=True)
def _stats(
    labels: NDArray[np.int32], n: int, depth: NDArray[np.float32], key: NDArray[np.float32]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    _, sums, box = _gather(labels, np.zeros(1, np.int32), False, n, depth, key, True)
    return sums, box


@njit(cache=True, nogil=True)
def relabel_stats(
    labels: NDArray[np.int32], lut: NDArray[np.int32], m: int, depth: NDArray[np.float32]
) -> tuple[NDArray[np.int32], NDArray[np.float64], NDArray[np.int64]]:
    """``lut[labels]`` and the statistics table of it (``KEY`` left 0), in one pass.

    Compiled, for compiled callers too. ``lut`` (int32) maps every label of ``labels`` to
    0..m; the sums are added pixel by pixel in raster order, as :func:`label_stats_fused`
    adds them on the renumbered map, so they are the same numbers.

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
        ``lut[labels]``.
    sums : ndarray of float64, shape (m + 1, N_COLUMNS)
    boxes : ndarray of int64, shape (m + 1, 4)
        Inclusive (x0, y0, x1, y1).
    """
    return _gather(labels, lut, True, m, depth, depth, False)


def label_stats_fused(
    labels: NDArray[np.int32], n: int, depth_mm: NDArray[np.float32], key: NDArray[Any]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Per-label sums and inclusive boxes in one pass.

    Parameters
    ----------
    labels : ndarray of int32, shape (H, W)
        Label map, 0 = none, labels 1..n.
    n : int
        Largest label.
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm).
    key : ndarray, shape (H, W)
        Value stored in the :data:`KEY` column (the last pixel's, in raster order).

    Returns
    -------
    sums : ndarray of float64, shape (n + 1, N_COLUMNS)
        The table of this module's columns.
    boxes : ndarray of int64, shape (n + 1, 4)
        (x0, y0, x1, y1) inclusive; row 0 unused.
    """
    return _stats(
        np.ascontiguousarray(labels, np.int32),
        int(n),
        np.ascontiguousarray(depth_mm, np.float32),
        np.ascontiguousarray(key, np.float32),
    )
