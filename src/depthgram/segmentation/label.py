"""Connected components of a keyed image in one pass, bridging small holes of invalid pixels.

OpenCV's ``connectedComponentsWithStats`` labels binary images only, and labelling each depth
band by masking would cost (bands x pixels). This union-find labeller joins 4-neighbours whose
keys agree within a tolerance, so one pass labels every band at once (key = band index,
tolerance 0) and also serves region growing (key = depth, tolerance in mm). It skips over short
runs of pixels without a reading, so a surface seen through a sieve of dropouts stays one
component, while a valid pixel of another key always blocks the join. No library kernel does
this: scipy's csgraph needs an explicit edge list and took 32 ms against 5.9 ms for this
labeller on region growing at 640 x 480 (``benchmarks/bench_segmentation.py --profile``);
OpenCV's binary labeller takes about 0.6 ms but cannot compare depths. Hence numba.

Every labeller also gathers each component's statistics (count, sums of Z, Z², x, y, xZ, yZ,
box) while labelling and drops components under a pixel count before the one relabelling
pass, so no caller takes a second pass over the label map. Band images are labelled run by
run straight from the histogram bins (:func:`label_bands_stats`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "ACTIVE",
    "BLOCK",
    "HOLE",
    "label_bands_stats",
    "label_keyed",
    "label_keyed_stats",
    "label_stats_fused",
    "plane_sums",
    "relabel",
]

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
def _union(parent: NDArray[np.int32], a: int, b: int) -> int:
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra < rb:
        parent[rb] = ra
        return ra
    parent[ra] = rb
    return rb


@njit(cache=True)
def _label_runs(
    key: NDArray[np.float32],
    state: NDArray[np.int8],
    tol: float,
    rel: float,
    bridge: int,
    depth: NDArray[np.float32],
    stats: bool,
) -> tuple[NDArray[np.int32], NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int32]]:
    # First pass of a two-pass labeller with provisional labels. Each column remembers its last
    # pixel with a reading (row, label, key) and the row scan its last one, so the neighbour
    # across a bridged hole is found in O(1) instead of by walking back over the holes. A pixel
    # takes its left or upper neighbour's label; only a meeting of two labels costs a union.
    # With `stats`, sums are gathered per run of one label along a row and flushed once per run.
    # (Band images have their own run-based labeller, _label_bands: a mode for them here, with
    # its tests on runtime flags inside the pixel loop, made this loop 16-26 % slower.)
    h, w = state.shape
    lab = np.zeros((h, w), np.int32)
    # one provisional label per pixel at most; np.empty only reserves the memory, the pages
    # of labels never used are never touched (growing the tables inside the loop instead made
    # numba count references on every pixel: 3x slower)
    cap = h * w + 1
    parent = np.empty(cap, np.int32)
    sums = np.empty((cap if stats else 1, 8), np.float64)
    boxes = np.empty((cap if stats else 1, 4), np.int32)
    reach = bridge + 1
    col_row = np.full(w, -reach - 1, np.int64)
    col_lab = np.zeros(w, np.int32)
    col_key = np.zeros(w, np.float32)
    nxt = 1
    for y in range(h):
        last_x = -reach - 1
        last_lab = 0
        last_key = np.float32(0.0)
        run = 0
        c = 0.0
        sz = 0.0
        szz = 0.0
        sx = 0.0
        sxz = 0.0
        rx0 = 0
        rx1 = 0
        rk = np.float32(0.0)
        merged_up = 0
        for x in range(w):
            s = state[y, x]
            if s == HOLE:
                continue
            active = s == ACTIVE
            kp = key[y, x]
            if not active:
                last_x = x
                last_lab = 0
                col_row[x] = y
                col_lab[x] = 0
                continue
            lim = tol + rel * abs(kp)
            left = 0
            if last_lab != 0 and x - last_x <= reach and abs(last_key - kp) <= lim:
                left = last_lab
            up = 0
            cl = col_lab[x]
            if cl != 0 and y - col_row[x] <= reach and abs(col_key[x] - kp) <= lim:
                up = cl
            if left == 0 and up == 0:
                merged_up = 0
                parent[nxt] = nxt
                if stats:
                    sums[nxt, :] = 0.0
                    boxes[nxt, 0] = w
                    boxes[nxt, 1] = y
                    boxes[nxt, 2] = -1
                    boxes[nxt, 3] = -1
                lab_here = nxt
                nxt += 1
            elif up == 0 or up == left:
                lab_here = left
            elif left == 0:
                lab_here = up
                merged_up = up
            else:
                lab_here = left
                # along a run under one upper label the union is done once, not per pixel
                if up != merged_up:
                    _union(parent, left, up)
                    merged_up = up
            lab[y, x] = lab_here
            last_x = x
            last_lab = lab_here
            last_key = kp
            col_row[x] = y
            col_lab[x] = lab_here
            col_key[x] = kp
            if stats:
                if lab_here != run:
                    if run != 0:
                        _flush(sums, boxes, run, c, sz, szz, sx, sxz, y, rx0, rx1, rk)
                    run = lab_here
                    c = 0.0
                    sz = 0.0
                    szz = 0.0
                    sx = 0.0
                    sxz = 0.0
                    rx0 = x
                    rk = kp
                z = np.float64(depth[y, x])
                c += 1.0
                sz += z
                szz += z * z
                sx += x
                sxz += x * z
                rx1 = x
        if stats and run != 0:
            _flush(sums, boxes, run, c, sz, szz, sx, sxz, y, rx0, rx1, rk)
    return lab, parent, nxt, sums, boxes


@njit(cache=True, inline="always")
def _flush(
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
    sums[i, 0] += c
    sums[i, 1] += sz
    sums[i, 2] += szz
    sums[i, 3] += sx
    sums[i, 4] += c * y
    sums[i, 5] += sxz
    sums[i, 6] += sz * y
    sums[i, 7] = k
    if x0 < boxes[i, 0]:
        boxes[i, 0] = x0
    if x1 > boxes[i, 2]:
        boxes[i, 2] = x1
    boxes[i, 3] = y  # rows are scanned in order: the latest row is the lowest


#: Float flags for the band labeller: its only float work is the per-run depth sums, which
#: vectorise once they may be reassociated (the sums then differ in the last bits only).
_SUM_FLAGS = {"reassoc", "nsz", "contract"}


@njit(cache=True, fastmath=_SUM_FLAGS)
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
    # holes a run ends at the first other code. Measured at 640 x 480: 1.4 against 2.22 ms
    # for one per-pixel loop.
    h, w = bins.shape
    lab = np.zeros((h, w), np.int32)
    cap = h * w + 1  # np.empty reserves; pages of unused labels are never touched
    parent = np.empty(cap, np.int32)
    sums = np.empty((cap, 8), np.float64)
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
            # column usually still remembers the object above (measured with 10 % random
            # dropouts at 640 x 480: 5.03 -> 4.77 ms)
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
                            _union(parent, lab_run, cl)
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
            _flush(sums, boxes, lab_run, c, sz, szz, sx, sxz, y, a, last, k)
    return lab, parent, nxt, sums, boxes


@njit(cache=True)
def _resolve(
    lab: NDArray[np.int32],
    parent: NDArray[np.int32],
    nxt: int,
    psums: NDArray[np.float64],
    pboxes: NDArray[np.int32],
    min_px: int,
    stats: bool,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    # second pass: provisional labels -> sets numbered in raster order of their first pixel
    # (the root of a set is its smallest provisional label); with `stats`, the sums of each set
    # are added up, sets under `min_px` pixels dropped, and the rest renumbered, all before the
    # one relabelling pass over the image
    final = np.zeros(nxt, np.int32)
    n = 0
    for i in range(1, nxt):
        r = _find(parent, i)
        if r == i:
            n += 1
            final[i] = n
        else:
            final[i] = final[r]
    sums = np.zeros((n + 1, 8), np.float64)
    boxes = np.empty((n + 1, 4), np.int64)
    if stats:
        boxes[:, 0] = lab.shape[1]
        boxes[:, 1] = lab.shape[0]
        boxes[:, 2] = -1
        boxes[:, 3] = -1
        for i in range(1, nxt):
            f = final[i]
            for k in range(7):
                sums[f, k] += psums[i, k]
            sums[f, 7] = psums[i, 7]
            boxes[f, 0] = min(boxes[f, 0], pboxes[i, 0])
            boxes[f, 1] = min(boxes[f, 1], pboxes[i, 1])
            boxes[f, 2] = max(boxes[f, 2], pboxes[i, 2])
            boxes[f, 3] = max(boxes[f, 3], pboxes[i, 3])
        newid = np.zeros(n + 1, np.int32)
        k = 0
        for j in range(1, n + 1):
            if sums[j, 0] >= min_px:
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
    sums[0] = 0.0
    h, w = lab.shape
    boxes[0, 0] = w
    boxes[0, 1] = h
    boxes[0, 2] = -1
    boxes[0, 3] = -1
    # final[0] is 0: one branch-free gather per pixel, with unsigned indices so that it
    # vectorises (the test-and-branch version took twice as long at 1280 x 720)
    uw = np.uint64(w)
    for y in range(h):
        row = lab[y]
        for x in range(uw):
            row[x] = final[np.uint64(row[x])]
    return lab, n, sums, boxes


@njit(cache=True)
def _stats(
    labels: NDArray[np.int32], n: int, depth: NDArray[np.float32], key: NDArray[np.float32]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    # one raster pass for every label's sums and box: the bincount route needs seven passes
    # plus find_objects, measured 3x slower at 640 x 480 (benchmarks/bench_segmentation.py)
    h, w = labels.shape
    sums = np.zeros((n + 1, 8), np.float64)
    box = np.empty((n + 1, 4), np.int64)
    box[:, 0] = w
    box[:, 1] = h
    box[:, 2] = -1
    box[:, 3] = -1
    for y in range(h):
        for x in range(w):
            i = labels[y, x]
            if i == 0:
                continue
            z = np.float64(depth[y, x])
            sums[i, 0] += 1.0
            sums[i, 1] += z
            sums[i, 2] += z * z
            sums[i, 3] += x
            sums[i, 4] += y
            sums[i, 5] += x * z
            sums[i, 6] += y * z
            sums[i, 7] = key[y, x]
            if x < box[i, 0]:
                box[i, 0] = x
            if y < box[i, 1]:
                box[i, 1] = y
            if x > box[i, 2]:
                box[i, 2] = x
            if y > box[i, 3]:
                box[i, 3] = y
    return sums, box


def label_stats_fused(
    labels: NDArray[np.int32], n: int, depth_mm: NDArray[np.float32], key: NDArray[Any]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Per-label sums and inclusive boxes in one pass.

    Returns
    -------
    sums : ndarray of float64, shape (n + 1, 8)
        Count, sum Z, sum Z², sum x, sum y, sum xZ, sum yZ (mm, px), and the key of the label.
    boxes : ndarray of int64, shape (n + 1, 4)
        (x0, y0, x1, y1) inclusive; row 0 unused.
    """
    return _stats(
        np.ascontiguousarray(labels, np.int32),
        int(n),
        np.ascontiguousarray(depth_mm, np.float32),
        np.ascontiguousarray(key, np.float32),
    )


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
    lab, parent, nxt, ps, pb = _label_runs(k, s, float(tol), float(rel), int(bridge), _NO_DEPTH, False)
    labels, n, _, _ = _resolve(lab, parent, nxt, ps, pb, 0, False)
    return labels, int(n)


def label_keyed_stats(
    key: NDArray[Any],
    state: NDArray[np.int8],
    depth_mm: NDArray[np.float32],
    *,
    tol: float = 0.0,
    rel: float = 0.0,
    bridge: int = 0,
    min_px: int = 1,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    """:func:`label_keyed`, components under ``min_px`` pixels dropped, with their statistics.

    Same labels as ``label_keyed`` followed by dropping small components and renumbering the
    rest 1..n in order, and the same sums and boxes as :func:`label_stats_fused` on them, but
    the sums are gathered during labelling (no second statistics pass over the image).

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
    n : int
        Number of components kept.
    sums : ndarray of float64, shape (n + 1, 8)
        As :func:`label_stats_fused`, column 7 holding the key of each component.
    boxes : ndarray of int64, shape (n + 1, 4)
        Inclusive (x0, y0, x1, y1).
    """
    k = np.ascontiguousarray(key, dtype=np.float32)
    s = np.ascontiguousarray(state, dtype=np.int8)
    z = np.ascontiguousarray(depth_mm, dtype=np.float32)
    lab, parent, nxt, ps, pb = _label_runs(k, s, float(tol), float(rel), int(bridge), z, True)
    labels, n, sums, boxes = _resolve(lab, parent, nxt, ps, pb, int(min_px), True)
    return labels, int(n), sums, boxes


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

    Equal to :func:`label_keyed_stats` on the band image and state of
    :func:`depthgram.segmentation.binning.band_state` (``tol=0``), without writing either image:
    the band of a pixel is ``lut[bins]``, pixels without a reading are holes, valid pixels
    outside every band or outside ``include`` block. Column 7 of ``sums`` is the band.
    ``depth_mm`` must be 0 wherever ``valid`` is False (as
    :func:`depthgram.segmentation.validate.check_depth` returns it): holes inside a run are summed
    with the run's pixels and must add nothing.
    """
    inc = include if include is not None else _NO_MASK
    labels, n, sums, boxes = _label_bands_resolved(
        bins, lut, valid, inc, include is not None, int(bridge), depth_mm, int(min_px)
    )
    return labels, int(n), sums, boxes


#: Stand-in for a missing ``include`` mask (numba wants an array); never written.
_NO_MASK = np.zeros((1, 1), np.bool_)


@njit(cache=True)
def _label_bands_resolved(
    bins: NDArray[np.int32],
    lut: NDArray[np.int32],
    valid: NDArray[np.bool_],
    include: NDArray[np.bool_],
    use_include: bool,
    bridge: int,
    depth: NDArray[np.float32],
    min_px: int,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    # both passes behind one call: each call from Python costs microseconds of argument
    # checks, which count on small frames
    lab, parent, nxt, ps, pb = _label_bands(bins, lut, valid, include, use_include, bridge, depth)
    return _resolve(lab, parent, nxt, ps, pb, min_px, True)


#: Stand-in for the depth image :func:`_label_runs` does not read without statistics.
_NO_DEPTH = np.zeros((1, 1), np.float32)


@njit(cache=True)
def _plane_sums(
    labels: NDArray[np.int32],
    n: int,
    depth: NDArray[np.float32],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    want: NDArray[np.bool_],
    use_want: bool,
) -> NDArray[np.float64]:
    # sums are gathered in registers along each run of one label in a row and added once per
    # run (v is constant along a row, so its terms are v times the run's sums): 2-3x faster
    # than adding nine values into the table at every pixel. With `use_want`, runs of labels
    # not wanted are stepped over (no division per pixel): a few supports among all objects.
    h, w = labels.shape
    out = np.zeros((n + 1, 9), np.float64)
    # u' of each column once rather than at every pixel (the same division, the same numbers)
    ucol = np.empty(w, np.float64)
    for x in range(w):
        ucol[x] = (x - cx) / fx
    for y in range(h):
        v = (y - cy) / fy
        x = 0
        while x < w:
            i = labels[y, x]
            if i == 0:
                x += 1
                continue
            if use_want and not want[i]:
                while x < w and labels[y, x] == i:
                    x += 1
                continue
            c = 0.0
            su = 0.0
            suu = 0.0
            sq = 0.0
            suq = 0.0
            while x < w and labels[y, x] == i:
                u = ucol[x]
                q = 1.0 / depth[y, x]
                c += 1.0
                su += u
                suu += u * u
                sq += q
                suq += u * q
                x += 1
            out[i, 0] += suu
            out[i, 1] += v * su
            out[i, 2] += su
            out[i, 3] += v * v * c
            out[i, 4] += v * c
            out[i, 5] += c
            out[i, 6] += suq
            out[i, 7] += v * sq
            out[i, 8] += sq
    return out


def plane_sums(
    labels: NDArray[np.int32],
    n: int,
    depth_mm: NDArray[np.float32],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    only: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """Normal-equation sums of the plane fit ``1/Z = alpha u' + beta v' + gamma`` per label.

    Columns: u'u', u'v', u', v'v', v', 1, u'/Z, v'/Z, 1/Z with ``u' = (x - cx) / fx``,
    ``v' = (y - cy) / fy`` (one pass; the bincount route took nine). ``only`` (bool per label,
    length ``n + 1``): the rows of other labels stay 0 and their pixels cost no arithmetic.
    """
    want = _NO_WANT if only is None else np.ascontiguousarray(only, np.bool_)
    return _plane_sums(
        np.ascontiguousarray(labels, np.int32),
        int(n),
        np.ascontiguousarray(depth_mm, np.float32),
        float(fx),
        float(fy),
        float(cx),
        float(cy),
        want,
        only is not None,
    )


#: Stand-in for a missing ``only`` table of :func:`plane_sums` (numba wants an array).
_NO_WANT = np.ones(1, np.bool_)


@njit(cache=True)
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

    numpy's fancy indexing with an int32 index image took 0.95 ms at 640 x 576 against 0.2 ms
    for this loop, and the slicing method renumbers full label maps several times per frame.
    ``labels`` must hold indices into ``lut`` (0 .. lut.size - 1).
    """
    return _relabel(np.ascontiguousarray(labels, np.int32), np.ascontiguousarray(lut, np.int32))
