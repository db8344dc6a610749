"""Same-band components straight from the histogram bins, with their statistics.

The keyed labeller (:mod:`depthgram.segmentation.label.keyed`) on a band image would need the
band image and its state image written first; this run-based labeller reads each pixel's band
through the bin -> band table instead and labels a row run by run, gathering the statistics
table of :mod:`depthgram.segmentation.label.stats` as it goes.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label.stats import N_COLUMNS, flush_run
from depthgram.segmentation.label.unionfind import resolve, union

__all__ = ["label_bands_stats"]


#: Float flags for the band labeller: its only float work is the per-run depth sums, which
#: vectorise once they may be reassociated (the sums then differ in the last bits only).
_SUM_FLAGS = {"reassoc", "nsz", "contract"}


@njit(cache=True, nogil=True, fastmath=_SUM_FLAGS)
def _label_bands(
    bins: NDArray[np.int32],
    lut: NDArray[np.int32],
    valid: NDArray[np.bool_],
    include: NDArray[np.bool_],
    use_include: bool,
    bridge: int,
    depth: NDArray[np.float32],
) -> tuple[NDArray[np.int32], NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int32]]:
    # First pass of a run-based two-pass labeller for band images (equal keys join). Each row
    # is coded once (band >= 0, -1 blocking, -2 hole) through the bin -> band table, so no band
    # image is written; a run is a stretch of one band with holes of at most `bridge` px; it
    # takes the label of the first upper neighbour it joins (else a new one) and every other
    # upper label costs one union. Each column remembers its last pixel with a reading (row,
    # label, band), so the upper neighbour across a bridged hole is found in O(1).
    # Most runs lie under one upper run of their band: a branch-free (vectorised) test over the
    # run says so, and only the others take the per-pixel union loop. Holes hold depth 0, so
    # the depth sums need no test per pixel either. Loops index with unsigned integers, which
    # spares numba's negative-index test (it kept them from vectorising). In a row without
    # holes a run ends at the first other code.
    h, w = bins.shape
    lab = np.zeros((h, w), np.int32)
    cap = h * w + 1  # np.empty reserves; pages of unused labels are never touched
    parent = np.empty(cap, np.int32)
    sums = np.empty((cap, N_COLUMNS), np.float64)
    boxes = np.empty((cap, 4), np.int32)
    reach = bridge + 1
    col_row = np.full(w, -reach - 1, np.int32)
    col_lab = np.zeros(w, np.int32)
    col_k = np.full(w, -1, np.int32)
    code = np.empty(w + 1, np.int32)
    uw = np.uint64(w)
    nxt = 1
    for y in range(h):
        brow = bins[y]
        vrow = valid[y]
        holes = 0
        for ux in range(uw):
            b = brow[ux]
            kb = lut[np.uint64(max(b, 0))]
            on = (kb >= 0) & (b >= 0)
            if use_include:
                on &= include[y, ux]
            code[ux] = kb if on else (-1 if vrow[ux] else -2)
            holes += not vrow[ux]
        code[w] = -1  # sentinel: ends the last run
        zrow = depth[y]
        lrow = lab[y]
        x = 0
        while x < w:
            k = code[x]
            if k < 0:
                if k == -1:  # a valid pixel outside every band stops vertical bridges
                    col_row[x] = y
                    col_k[x] = -1
                x += 1
                continue
            a = x
            x += 1
            if holes == 0:
                # a row without holes: a run is a stretch of equal codes (one test per pixel)
                while code[x] == k:
                    x += 1
                last = x - 1
                n_in = x - a
            else:
                last = a
                n_in = 1
                while True:
                    kx = code[x]
                    if kx == k:
                        last = x
                        n_in += 1
                    elif kx != -2 or x - last >= reach:
                        break
                    x += 1
                x = last + 1
            ua = np.uint64(a)
            ue = np.uint64(last + 1)
            whole = n_in == last + 1 - a
            first = col_lab[ua]
            k32 = np.int32(k)
            differ = np.int32(0)
            oldest = np.int32(y)
            for ux in range(ua, ue):
                differ |= (col_lab[ux] ^ first) | (col_k[ux] ^ k32)
                oldest = min(oldest, col_row[ux])
            lab_run = 0
            # the run's holes are in the test too, a superset of its pixels: under a hole the
            # column usually still remembers the object above, and with random dropouts more
            # runs take this short way
            if differ == 0 and first != 0 and y - oldest <= reach:
                lab_run = first
            else:
                merged = 0
                for ux in range(ua, ue):
                    cl = col_lab[ux]
                    if cl != merged and code[ux] == k and col_k[ux] == k and y - col_row[ux] <= reach:
                        if lab_run == 0:
                            lab_run = cl
                        else:
                            union(parent, lab_run, cl)
                        merged = cl
            if lab_run == 0:
                lab_run = nxt
                parent[nxt] = nxt
                sums[nxt, :] = 0.0
                boxes[nxt, 0] = w
                boxes[nxt, 1] = y
                boxes[nxt, 2] = -1
                boxes[nxt, 3] = -1
                nxt += 1
            sz = 0.0
            szz = 0.0
            sxz = 0.0
            if whole:
                for ux in range(ua, ue):
                    z = np.float64(zrow[ux])
                    sz += z
                    szz += z * z
                    sxz += np.float64(ux) * z
                    lrow[ux] = lab_run
                    col_lab[ux] = lab_run
                    col_k[ux] = k
                    col_row[ux] = y
                c = float(n_in)
                sx = float((a + last) * n_in // 2)
            else:
                for ux in range(ua, ue):
                    z = np.float64(zrow[ux])
                    sz += z
                    szz += z * z
                    sxz += np.float64(ux) * z
                c = 0.0
                sx = 0.0
                for ux in range(ua, ue):
                    if code[ux] == k:
                        lrow[ux] = lab_run
                        col_lab[ux] = lab_run
                        col_k[ux] = k
                        col_row[ux] = y
                        c += 1.0
                        sx += np.float64(ux)
            flush_run(sums, boxes, lab_run, c, sz, szz, sx, sxz, y, a, last, k)
    return lab, parent, nxt, sums, boxes


def label_bands_stats(
    bins: NDArray[np.int32],
    lut: NDArray[np.int32],
    valid: NDArray[np.bool_],
    include: NDArray[np.bool_] | None,
    depth_mm: NDArray[np.float32],
    *,
    bridge: int = 0,
    min_px: int = 1,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    """Same-band components straight from histogram bins, with their statistics.

    Equal to :func:`depthgram.segmentation.label.keyed.label_keyed_stats` on the band image and state of
    :func:`depthgram.segmentation.binning.band_state` (``tol=0``), without writing either image:
    the band of a pixel is ``lut[bins]``, pixels without a reading are holes, valid pixels
    outside every band or outside ``include`` block. The ``KEY`` column of ``sums`` is the band.
    ``depth_mm`` must be 0 wherever ``valid`` is False (as
    :func:`depthgram.segmentation.validate.check_depth` returns it): holes inside a run are summed
    with the run's pixels and must add nothing.
    """
    inc = include if include is not None else _NO_MASK
    lab, parent, nxt, ps, pb = _label_bands(bins, lut, valid, inc, include is not None, int(bridge), depth_mm)
    labels, n, sums, boxes = resolve(lab, parent, nxt, ps, pb, int(min_px), True)
    return labels, int(n), sums, boxes


#: Stand-in for a missing ``include`` mask (numba wants an array); never written.
_NO_MASK = np.zeros((1, 1), np.bool_)
