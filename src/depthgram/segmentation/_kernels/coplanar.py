"""The compiled loops of :mod:`depthgram.segmentation.coplanar`: plane agreement tests and near-plane pixels."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray


@njit(cache=True, nogil=True)
def coplanar_join(
    cosines: NDArray[np.float64],
    off: NDArray[np.float64],
    big: NDArray[np.intp],
    min_cos: float,
    rel: float,
    n: int,
    boxes: NDArray[np.int64],
) -> tuple[NDArray[np.int32], int, NDArray[np.intp], NDArray[np.intp], NDArray[np.int64]]:
    """Return the groups of the large pieces ``big`` whose planes agree (``coplanar.coplanar_groups``).

    Pair ``i < j`` joins when ``cosines[i, j] > min_cos`` and ``|off_i - off_j| <= rel
    max(off_i, off_j)``, numpy's tests on the same float64 numbers; compiled because the
    half-dozen numpy calls on a few pieces' matrices cost more than the tests (three uses per
    frame). Returns each piece's group (0 for piece 0's) and the group count, then, when
    pieces joined and ``boxes`` (inclusive, a row per piece) are given, the pieces sorted
    stably by group, where each group starts in that order, and the union of each group's
    boxes (:func:`_grouped`; else empty arrays).
    """
    # union of the joined pairs (the smaller root becomes the root), then the groups numbered
    # 1..m in the order of their smallest piece (np.unique of the roots); pieces 0..n. A Python
    # loop over every piece (hundreds of noise specks on a real frame) cost more than the rest.
    k = big.size
    parent = np.arange(n + 1)
    for i in range(k):
        oi = off[big[i]]
        for j in range(i + 1, k):
            oj = off[big[j]]
            if not (cosines[i, j] > min_cos and abs(oi - oj) <= rel * max(oi, oj)):
                continue
            a = big[i]
            while parent[a] != a:
                a = parent[a]
            b = big[j]
            while parent[b] != b:
                b = parent[b]
            if a != b:
                parent[max(a, b)] = min(a, b)
    lut = np.empty(n + 1, np.int32)
    m = -1
    for i in range(n + 1):
        r = i
        while parent[r] != r:
            r = parent[r]
        if r == i:
            m += 1
            lut[i] = m
        else:
            lut[i] = lut[r]
    if m == n or boxes.shape[0] != n + 1:
        return lut, m, np.empty(0, np.intp), np.empty(0, np.intp), boxes[:0]
    order, starts, mboxes = _grouped(lut, m, boxes)
    return lut, m, order, starts, mboxes


@njit(cache=True, inline="always")
def _grouped(
    lut: NDArray[np.int32], m: int, boxes: NDArray[np.int64]
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.int64]]:
    # np.argsort(lut, kind="stable"), np.searchsorted of the sorted groups for 0..m (every
    # group has a piece) and each group's boxes' union (min and max: any order gives them),
    # by counting, where numpy took seven calls a join
    count = np.zeros(m + 1, np.intp)
    for i in range(lut.size):
        count[lut[i]] += 1
    starts = np.empty(m + 1, np.intp)
    at = 0
    for g in range(m + 1):
        starts[g] = at
        at += count[g]
    place = starts.copy()
    order = np.empty(lut.size, np.intp)
    mboxes = np.empty((m + 1, 4), np.int64)
    for i in range(lut.size):
        g = lut[i]
        if place[g] == starts[g]:
            mboxes[g] = boxes[i]
        else:
            mboxes[g, 0] = min(mboxes[g, 0], boxes[i, 0])
            mboxes[g, 1] = min(mboxes[g, 1], boxes[i, 1])
            mboxes[g, 2] = max(mboxes[g, 2], boxes[i, 2])
            mboxes[g, 3] = max(mboxes[g, 3], boxes[i, 3])
        order[place[g]] = i
        place[g] += 1
    return order, starts, mboxes


@njit(cache=True, nogil=True, error_model="numpy")
def mark_near(
    out: NDArray[np.bool_],
    ids: NDArray[np.intp],
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    boxes: NDArray[np.int64],
    depth: NDArray[np.float32],
    candidates: NDArray[np.bool_],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    tol_rel: float,
) -> None:
    # per support, one loop over its box grown by a tenth, where numpy built six box-sized
    # temporaries per support. Same float64 arithmetic.
    h, w = depth.shape
    ucol = np.empty(w, np.float64)  # u of each column once (the same division, the same numbers)
    for x in range(w):
        ucol[x] = (x - cx) / fx
    for i in ids:
        y0, y1, x0, x1 = _near_box(boxes, i, h, w)
        n0, n1, n2, d = normal[i, 0], normal[i, 1], normal[i, 2], off[i]
        for y in range(y0, y1):
            v = (y - cy) / fy
            cr = candidates[y, x0:x1]
            zr = depth[y, x0:x1]
            ur = ucol[x0:x1]
            orow = out[y, x0:x1]
            # every pixel of the row computed and masked (numpy's division rule, d is not 0),
            # so that the divisions vectorise
            for j in range(x1 - x0):
                # 1/Z predicted by the plane: -(n . ray) / d
                inv_pred = -(n0 * ur[j] + n1 * v + n2) / d
                hit = cr[j] & (inv_pred > 0) & (abs(inv_pred * np.float64(zr[j]) - 1.0) <= tol_rel)
                orow[j] = orow[j] | hit


@njit(cache=True, inline="always")
def _near_box(boxes: NDArray[np.int64], i: int, h: int, w: int) -> tuple[int, int, int, int]:
    # the rows y0..y1 - 1 and columns x0..x1 - 1 where support i's near pixels are looked for:
    # its inclusive box and a tenth of its size more on each side, inside the frame
    bx0, by0, bx1, by1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
    my = (by1 - by0 + 1) // 10 + 1
    mx = (bx1 - bx0 + 1) // 10 + 1
    return max(by0 - my, 0), min(by1 + 1 + my, h), max(bx0 - mx, 0), min(bx1 + 1 + mx, w)


@njit(cache=True, nogil=True)
def class_window(
    boxes: NDArray[np.int64], count: NDArray[np.float64], min_px: float, h: int, w: int
) -> tuple[int, int, int, int]:
    y0, y1, x0, x1 = h, 0, w, 0
    for i in range(1, boxes.shape[0]):
        if count[i] >= min_px:
            a0, a1, b0, b1 = _near_box(boxes, i, h, w)
        else:
            a0, a1, b0, b1 = boxes[i, 1], boxes[i, 3] + 1, boxes[i, 0], boxes[i, 2] + 1
        y0, y1, x0, x1 = min(y0, a0), max(y1, a1), min(x0, b0), max(x1, b1)
    if y0 >= y1 or x0 >= x1:
        return 0, 0, 0, 0
    return y0, y1, x0, x1


@njit(cache=True, nogil=True, error_model="numpy")
def join_near(
    classes: NDArray[np.int8],
    valid: NDArray[np.bool_],
    cls: np.int8,
    facing: np.int8,
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    boxes: NDArray[np.int64],
    depth: NDArray[np.float32],
    min_px: float,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    tol_rel: float,
) -> int:
    # mark_near's test on the candidates read from the classes: a pixel one support takes is no
    # longer a candidate for the next, which near_planes' union of the supports' tests gives
    # too. The same float64 arithmetic as mark_near.
    h, w = depth.shape
    ucol = np.empty(w, np.float64)
    for x in range(w):
        ucol[x] = (x - cx) / fx
    joined = 0
    for i in range(1, count.size):
        if not count[i] >= min_px:
            continue
        y0, y1, x0, x1 = _near_box(boxes, i, h, w)
        n0, n1, n2, d = normal[i, 0], normal[i, 1], normal[i, 2], off[i]
        for y in range(y0, y1):
            v = (y - cy) / fy
            cr = classes[y, x0:x1]
            vr = valid[y, x0:x1]
            zr = depth[y, x0:x1]
            ur = ucol[x0:x1]
            for j in range(x1 - x0):
                inv_pred = -(n0 * ur[j] + n1 * v + n2) / d
                hit = vr[j] & (cr[j] == facing) & (inv_pred > 0) & (abs(inv_pred * np.float64(zr[j]) - 1.0) <= tol_rel)
                cr[j] = cls if hit else cr[j]
                joined += hit
    return joined
