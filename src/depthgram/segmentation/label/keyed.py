"""Connected components of a keyed image in one pass, bridging small holes of invalid pixels.

OpenCV's ``connectedComponentsWithStats`` labels binary images only, and labelling each depth
band by masking would cost (bands x pixels). This union-find labeller joins 4-neighbours whose
keys agree within a tolerance, so one pass labels every band at once (key = band index,
tolerance 0) and also serves region growing (key = depth, tolerance in mm). It skips over short
runs of pixels without a reading, so a surface seen through a sieve of dropouts stays one
component, while a valid pixel of another key always blocks the join. No library kernel does
this (scipy's csgraph needs an explicit edge list; OpenCV's labeller cannot compare depths),
hence numba; ``benchmarks/bench_segmentation.py --profile`` measures the alternatives.

With statistics (:func:`label_keyed_stats`) each component's sums and box (the table of
:mod:`depthgram.segmentation.label.stats`) are gathered while labelling, and components under
a pixel count are dropped before the one relabelling pass.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation._kernels.plane_sums import flush_plane_run
from depthgram.segmentation.label.stats import N_COLUMNS, flush_run
from depthgram.segmentation.label.unionfind import find, fold_tables, resolve, resolve_tables, union

__all__ = ["ACTIVE", "BLOCK", "HOLE", "label_keyed", "label_keyed_planes", "label_keyed_stats", "label_two_classes"]

#: Pixel states for :func:`label_keyed`: a hole may be bridged, an active pixel is labelled,
#: a blocking pixel (valid, but not part of any component) stops a bridge.
HOLE, ACTIVE, BLOCK = 0, 1, 2


@njit(cache=True, nogil=True)
def _label_runs(
    key: NDArray[np.float32],
    state: NDArray[np.int8],
    tol: float,
    rel: float,
    bridge: int,
    depth: NDArray[np.float32],
    stats: bool,
    y0: int,
    y1: int,
    x0: int,
    x1: int,
) -> tuple[NDArray[np.int32], NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int32], NDArray[np.int64]]:
    # First pass of a two-pass labeller with provisional labels. Each column remembers its last
    # pixel with a reading (row, label, key) and the row scan its last one, so the neighbour
    # across a bridged hole is found in O(1) instead of by walking back over the holes. A pixel
    # takes its left or upper neighbour's label; only a meeting of two labels costs a union.
    # With `stats`, sums are gathered per run of one label along a row and flushed once per run.
    # (Band images have their own run-based labeller, bands._label_bands: a mode for them here
    # would put tests on runtime flags inside this pixel loop.)
    # Only the window rows y0..y1 - 1, columns x0..x1 - 1 are read, in frame coordinates (the
    # sums and boxes too); labels are 0 outside it. A window holding every active pixel gives
    # the labels and tables of the whole frame: no join reaches across a pixel outside it.
    # With `stats`, `spans` holds each row's first labelled column and the one after its last
    # (frame columns; 0, 0 for a row without labels), from the runs' ends: the relabelling
    # pass reads only these.
    h, w = state.shape
    lab = np.zeros((h, w), np.int32)
    spans = np.zeros((h, 2), np.int64)
    # one provisional label per pixel at most; np.empty only reserves the memory, the pages
    # of labels never used are never touched (growing the tables inside the loop instead makes
    # numba count references on every pixel)
    nw = x1 - x0
    cap = (y1 - y0) * nw + 1
    parent = np.empty(cap, np.int32)
    sums = np.empty((cap if stats else 1, N_COLUMNS), np.float64)
    boxes = np.empty((cap if stats else 1, 4), np.int32)
    reach = bridge + 1
    # per column of the window; the row scan reads the window's rows as slices from 0 (indices
    # from x0 cost a quarter more: the compiler no longer knows them in bounds and unsigned)
    col_row = np.full(nw, -reach - 1, np.int64)
    col_lab = np.zeros(nw, np.int32)
    col_key = np.zeros(nw, np.float32)
    nxt = 1
    for y in range(y0, y1):
        sr = state[y, x0:x1]
        kr = key[y, x0:x1]
        lr = lab[y, x0:x1]
        # the depth is not read without statistics (and may be a 1 x 1 stand-in then)
        dr = depth[y, x0:x1] if stats else depth[0, 0:1]
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
        first = 0
        for j in range(nw):
            s = sr[j]
            if s == HOLE:
                continue
            active = s == ACTIVE
            kp = kr[j]
            if not active:
                last_x = j
                last_lab = 0
                col_row[j] = y
                col_lab[j] = 0
                continue
            lim = tol + rel * abs(kp)
            left = 0
            if last_lab != 0 and j - last_x <= reach and abs(last_key - kp) <= lim:
                left = last_lab
            up = 0
            cl = col_lab[j]
            if cl != 0 and y - col_row[j] <= reach and abs(col_key[j] - kp) <= lim:
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
                    union(parent, left, up)
                    merged_up = up
            lr[j] = lab_here
            last_x = j
            last_lab = lab_here
            last_key = kp
            col_row[j] = y
            col_lab[j] = lab_here
            col_key[j] = kp
            if stats:
                x = x0 + j
                if lab_here != run:
                    if run != 0:
                        flush_run(sums, boxes, run, c, sz, szz, sx, sxz, y, rx0, rx1, rk)
                    else:
                        # the row's first labelled pixel (a run is never 0 again in a row)
                        first = x
                    run = lab_here
                    c = 0.0
                    sz = 0.0
                    szz = 0.0
                    sx = 0.0
                    sxz = 0.0
                    rx0 = x
                    rk = kp
                z = np.float64(dr[j])
                c += 1.0
                sz += z
                szz += z * z
                sx += x
                sxz += x * z
                rx1 = x
        if stats and run != 0:
            flush_run(sums, boxes, run, c, sz, szz, sx, sxz, y, rx0, rx1, rk)
            spans[y, 0] = first
            spans[y, 1] = rx1 + 1
    return lab, parent, nxt, sums, boxes, spans


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
    lab, parent, nxt, ps, pb, _ = _label_runs(
        k, s, float(tol), float(rel), int(bridge), _NO_DEPTH, False, 0, s.shape[0], 0, s.shape[1]
    )
    labels, n, _, _ = resolve(lab, parent, nxt, ps, pb, 0, False)
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
    rest 1..n in order, and the same sums and boxes as
    :func:`depthgram.segmentation.label.stats.label_stats_fused` on them, but
    the sums are gathered during labelling (no second statistics pass over the image).

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
    n : int
        Number of components kept.
    sums : ndarray of float64, shape (n + 1, N_COLUMNS)
        The table of :mod:`depthgram.segmentation.label.stats`, ``KEY`` holding each
        component's key.
    boxes : ndarray of int64, shape (n + 1, 4)
        Inclusive (x0, y0, x1, y1).
    """
    k = np.ascontiguousarray(key, dtype=np.float32)
    s = np.ascontiguousarray(state, dtype=np.int8)
    z = np.ascontiguousarray(depth_mm, dtype=np.float32)
    lab, parent, nxt, ps, pb, _ = _label_runs(
        k, s, float(tol), float(rel), int(bridge), z, True, 0, k.shape[0], 0, k.shape[1]
    )
    labels, n, sums, boxes = resolve(lab, parent, nxt, ps, pb, int(min_px), True)
    return labels, int(n), sums, boxes


@njit(cache=True, nogil=True, error_model="numpy")
def _relabel_planes(
    lab: NDArray[np.int32],
    final: NDArray[np.int32],
    n: int,
    depth: NDArray[np.float32],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    y0: int,
    y1: int,
    x0: int,
    x1: int,
    spans: NDArray[np.int64],
) -> NDArray[np.float64]:
    # The relabelling pass of resolve, gathering on the way the plane sums that
    # _kernels.plane_sums.plane_sums takes from the final labels: the same runs of one final label along a
    # row, the same float64 operations in the same order, hence the same numbers, without a
    # second pass over the image. Each run is added by planes.flush_plane_run, as there; the
    # per-pixel sums below must stay those of _kernels.plane_sums.plane_sums (tests/test_segment_kernels.py
    # compares the two). Only the window rows y0..y1 - 1, columns x0..x1 - 1 of _label_runs,
    # and of each row only its labelled span (`spans`, from the labeller): the pixels outside
    # it are 0 and stay 0 (final[0] is 0), and a run of 0 adds nothing.
    out = np.zeros((n + 1, 9), np.float64)
    ucol = np.empty(x1 - x0, np.float64)
    for x in range(x0, x1):
        ucol[x - x0] = (x - cx) / fx
    for y in range(y0, y1):
        a = spans[y, 0]
        b = spans[y, 1]
        if a >= b:
            continue
        v = (y - cy) / fy
        # the span's rows as slices read from 0, as in _label_runs
        row = lab[y, a:b]
        zr = depth[y, a:b]
        uc = ucol[a - x0 : b - x0]
        run = 0
        c = 0.0
        su = 0.0
        suu = 0.0
        sq = 0.0
        suq = 0.0
        for x in range(b - a):
            i = final[row[x]]
            row[x] = i
            if i != run:
                if run != 0:
                    flush_plane_run(out, run, v, c, su, suu, sq, suq)
                run = i
                c = 0.0
                su = 0.0
                suu = 0.0
                sq = 0.0
                suq = 0.0
            if i != 0:
                u = uc[x]
                q = 1.0 / zr[x]
                c += 1.0
                su += u
                suu += u * u
                sq += q
                suq += u * q
        if run != 0:
            flush_plane_run(out, run, v, c, su, suu, sq, suq)
    return out


def label_keyed_planes(
    key: NDArray[Any],
    state: NDArray[np.int8],
    depth_mm: NDArray[np.float32],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    *,
    tol: float = 0.0,
    rel: float = 0.0,
    bridge: int = 0,
    min_px: int = 1,
    window: tuple[int, int, int, int] | None = None,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """:func:`label_keyed_stats` and the plane sums of its components, gathered while relabelling.

    Returns what ``label_keyed_stats`` returns, then the table of
    :func:`depthgram.segmentation.plane_sums.plane_sums` on the returned labels (same numbers),
    shape (n + 1, 9), for pixel focal lengths ``fx``, ``fy`` and principal point ``cx``, ``cy``
    (px).

    ``window`` ``(y0, y1, x0, x1)`` (half-open, px): only these rows and columns are read (the
    rest of ``state`` may hold anything) and labelled, the tables in frame coordinates. A
    window holding every active pixel gives the whole frame's results to the last bit at the
    cost of the window.
    """
    k = np.ascontiguousarray(key, dtype=np.float32)
    s = np.ascontiguousarray(state, dtype=np.int8)
    z = np.ascontiguousarray(depth_mm, dtype=np.float32)
    y0, y1, x0, x1 = window if window is not None else (0, k.shape[0], 0, k.shape[1])
    lab, n, sums, boxes, planes = _label_planes(
        k, s, float(tol), float(rel), int(bridge), z, int(min_px), float(fx), float(fy), float(cx), float(cy),
        int(y0), int(y1), int(x0), int(x1),
    )  # fmt: skip
    return lab, int(n), sums, boxes, planes


@njit(cache=True, nogil=True)
def _label_planes(
    key: NDArray[np.float32],
    state: NDArray[np.int8],
    tol: float,
    rel: float,
    bridge: int,
    depth: NDArray[np.float32],
    min_px: int,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    y0: int,
    y1: int,
    x0: int,
    x1: int,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    # label_keyed_planes' three passes (labelling, the tables, the relabelling with the plane
    # sums) in one compiled call: three calls from Python cost more than their joins on a
    # small frame
    lab, parent, nxt, ps, pb, spans = _label_runs(key, state, tol, rel, bridge, depth, True, y0, y1, x0, x1)
    final, n, sums, boxes = resolve_tables(lab, parent, nxt, ps, pb, min_px, True)
    planes = _relabel_planes(lab, final, n, depth, fx, fy, cx, cy, y0, y1, x0, x1, spans)
    return lab, n, sums, boxes, planes


@njit(cache=True, nogil=True)
def _label_runs_two(
    depth: NDArray[np.float32],
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    ca: np.int8,
    cb: np.int8,
    rel: float,
    bridge: int,
) -> tuple[
    NDArray[np.int32],
    NDArray[np.int32],
    NDArray[np.int8],
    int,
    NDArray[np.float64],
    NDArray[np.int32],
    NDArray[np.int64],
]:
    # _label_runs with key = depth and statistics, for the pixels of two classes at once: what
    # two calls with the states ACTIVE for one class, BLOCK for the other readings and HOLE
    # elsewhere give, in one pass over the frame. A pixel of one class is a blocking reading to
    # the other: a neighbour (or the last reading across a bridge) of the other class never
    # joins, as a BLOCK pixel never does. Provisional labels are shared (each class's own are
    # still increasing in raster order of creation, so _resolve_two numbers each class as
    # _label_runs' resolve does), and each class keeps its own run of sums along a row: a run
    # of one class is not cut by a pixel of the other (a BLOCK pixel does not cut it either),
    # so every label's sums are added in the same order as by _label_runs.
    h, w = depth.shape
    lab = np.zeros((h, w), np.int32)
    # each row's labelled span, as _label_runs gives it
    spans = np.zeros((h, 2), np.int64)
    cap = h * w + 1
    parent = np.empty(cap, np.int32)
    pcls = np.empty(cap, np.int8)
    sums = np.empty((cap, N_COLUMNS), np.float64)
    boxes = np.empty((cap, 4), np.int32)
    reach = bridge + 1
    col_row = np.full(w, -reach - 1, np.int64)
    col_lab = np.zeros(w, np.int32)
    col_cls = np.zeros(w, np.int8)
    col_key = np.zeros(w, np.float32)
    nxt = 1
    for y in range(h):
        last_x = -reach - 1
        last_lab = 0
        last_cls = np.int8(0)
        last_key = np.float32(0.0)
        merged_up = 0
        # the open run of sums of each class (a: ca, b: cb)
        run_a = 0
        ca_c = 0.0
        ca_sz = 0.0
        ca_szz = 0.0
        ca_sx = 0.0
        ca_sxz = 0.0
        ca_x0 = 0
        ca_x1 = 0
        ca_k = np.float32(0.0)
        run_b = 0
        cb_c = 0.0
        cb_sz = 0.0
        cb_szz = 0.0
        cb_sx = 0.0
        cb_sxz = 0.0
        cb_x0 = 0
        cb_x1 = 0
        cb_k = np.float32(0.0)
        first = w
        for x in range(w):
            if not valid[y, x]:
                continue
            c = classes[y, x]
            if c != ca and c != cb:
                last_x = x
                last_lab = 0
                col_row[x] = y
                col_lab[x] = 0
                continue
            kp = depth[y, x]
            lim = rel * abs(kp)
            left = 0
            if last_lab != 0 and last_cls == c and x - last_x <= reach and abs(last_key - kp) <= lim:
                left = last_lab
            up = 0
            cl = col_lab[x]
            if cl != 0 and col_cls[x] == c and y - col_row[x] <= reach and abs(col_key[x] - kp) <= lim:
                up = cl
            if left == 0 and up == 0:
                merged_up = 0
                parent[nxt] = nxt
                pcls[nxt] = c
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
                if up != merged_up:
                    union(parent, left, up)
                    merged_up = up
            lab[y, x] = lab_here
            last_x = x
            last_lab = lab_here
            last_cls = c
            last_key = kp
            col_row[x] = y
            col_lab[x] = lab_here
            col_cls[x] = c
            col_key[x] = kp
            z = np.float64(depth[y, x])
            if c == ca:
                if lab_here != run_a:
                    if run_a != 0:
                        flush_run(sums, boxes, run_a, ca_c, ca_sz, ca_szz, ca_sx, ca_sxz, y, ca_x0, ca_x1, ca_k)
                    else:
                        # the class's first labelled pixel in the row
                        first = min(first, x)
                    run_a = lab_here
                    ca_c = 0.0
                    ca_sz = 0.0
                    ca_szz = 0.0
                    ca_sx = 0.0
                    ca_sxz = 0.0
                    ca_x0 = x
                    ca_k = kp
                ca_c += 1.0
                ca_sz += z
                ca_szz += z * z
                ca_sx += x
                ca_sxz += x * z
                ca_x1 = x
            else:
                if lab_here != run_b:
                    if run_b != 0:
                        flush_run(sums, boxes, run_b, cb_c, cb_sz, cb_szz, cb_sx, cb_sxz, y, cb_x0, cb_x1, cb_k)
                    else:
                        first = min(first, x)
                    run_b = lab_here
                    cb_c = 0.0
                    cb_sz = 0.0
                    cb_szz = 0.0
                    cb_sx = 0.0
                    cb_sxz = 0.0
                    cb_x0 = x
                    cb_k = kp
                cb_c += 1.0
                cb_sz += z
                cb_szz += z * z
                cb_sx += x
                cb_sxz += x * z
                cb_x1 = x
        # the row's labelled span: from its first run's start to its last run's end
        last = -1
        if run_a != 0:
            flush_run(sums, boxes, run_a, ca_c, ca_sz, ca_szz, ca_sx, ca_sxz, y, ca_x0, ca_x1, ca_k)
            last = ca_x1
        if run_b != 0:
            flush_run(sums, boxes, run_b, cb_c, cb_sz, cb_szz, cb_sx, cb_sxz, y, cb_x0, cb_x1, cb_k)
            last = max(last, cb_x1)
        if last >= 0:
            spans[y, 0] = first
            spans[y, 1] = last + 1
    return lab, parent, pcls, nxt, sums, boxes, spans


@njit(cache=True, nogil=True)
def _resolve_two(
    lab: NDArray[np.int32],
    parent: NDArray[np.int32],
    pcls: NDArray[np.int8],
    ca: np.int8,
    nxt: int,
    psums: NDArray[np.float64],
    pboxes: NDArray[np.int32],
) -> tuple[NDArray[np.int32], int, int, NDArray[np.float64], NDArray[np.int64]]:
    # resolve_tables (min_px 1: nothing dropped) of both classes of _label_runs_two: the sets of
    # class `ca` numbered 1..na and those of the other na + 1..na + nb, each in raster order of
    # its first pixel; each set's rows added in provisional order, as resolve_tables adds them
    final = np.zeros(nxt, np.int32)
    na = 0
    nb = 0
    for i in range(1, nxt):
        r = find(parent, i)
        if r == i:
            if pcls[i] == ca:
                na += 1
                final[i] = na
            else:
                nb += 1
                final[i] = -nb
        else:
            final[i] = final[r]
    for i in range(1, nxt):
        if final[i] < 0:
            final[i] = na - final[i]
    sums, boxes = fold_tables(final, nxt, na + nb, psums, pboxes, lab.shape[0], lab.shape[1])
    return final, na, nb, sums, boxes


def label_two_classes(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls_a: int,
    cls_b: int,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    *,
    rel: float,
    bridge: int,
) -> tuple[NDArray[np.int32], int, int, NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """:func:`label_keyed_planes` of the pixels of two classes, in one pass for both.

    For each class, what ``label_keyed_planes(depth_mm, state, depth_mm, ..., rel=rel,
    bridge=bridge)`` gives with ``state`` ACTIVE on the class's pixels, BLOCK on other readings
    and HOLE where ``valid`` is False: the same components, numbers, sums, boxes and plane sums
    to the last bit.

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
        Components of class ``cls_a`` as 1..na, those of ``cls_b`` as na + 1..na + nb.
    na, nb : int
    sums, boxes, planes : ndarray
        The tables of ``label_keyed_planes`` for the na + nb components (row 0 unused): class
        ``cls_b``'s own tables are row 0 and rows na + 1.. of them.
    """
    z = np.ascontiguousarray(depth_mm, dtype=np.float32)
    lab, na, nb, sums, boxes, planes = _two_classes(
        z,
        np.ascontiguousarray(valid, np.bool_),
        np.ascontiguousarray(classes, np.int8),
        np.int8(cls_a),
        np.int8(cls_b),
        float(rel),
        int(bridge),
        float(fx),
        float(fy),
        float(cx),
        float(cy),
    )
    return lab, int(na), int(nb), sums, boxes, planes


@njit(cache=True, nogil=True)
def _two_classes(
    z: NDArray[np.float32],
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    ca: np.int8,
    cb: np.int8,
    rel: float,
    bridge: int,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
) -> tuple[NDArray[np.int32], int, int, NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    # label_two_classes' three passes in one compiled call (as _label_planes)
    lab, parent, pcls, nxt, ps, pb, spans = _label_runs_two(z, valid, classes, ca, cb, rel, bridge)
    final, na, nb, sums, boxes = _resolve_two(lab, parent, pcls, ca, nxt, ps, pb)
    h, w = z.shape
    planes = _relabel_planes(lab, final, na + nb, z, fx, fy, cx, cy, 0, h, 0, w, spans)
    return lab, na, nb, sums, boxes, planes


#: Stand-in for the depth image :func:`_label_runs` does not read without statistics.
_NO_DEPTH = np.zeros((1, 1), np.float32)
