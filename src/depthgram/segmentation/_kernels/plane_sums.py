"""The compiled loops of the plane sums (:mod:`depthgram.segmentation.plane_sums`): runs of one label per row."""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray


@njit(cache=True, inline="always")
def flush_plane_run(
    out: NDArray[np.float64], i: int, v: float, c: float, su: float, suu: float, sq: float, suq: float
) -> None:
    """Add one run of label ``i`` along a row at ``v' = v`` to the sums of plane_sums.plane_sums.

    ``c, su, suu, sq, suq`` are the run's count and sums of u', u'², 1/Z and u'/Z; the row
    terms follow from them since v' is constant along the run. The one place of this
    arithmetic, so that the labeller that gathers the sums on its way
    (:func:`depthgram.segmentation.label.keyed.label_keyed_planes`) adds the same numbers in
    the same order.
    """
    out[i, 0] += suu
    out[i, 1] += v * su
    out[i, 2] += su
    out[i, 3] += v * v * c
    out[i, 4] += v * c
    out[i, 5] += c
    out[i, 6] += suq
    out[i, 7] += v * sq
    out[i, 8] += sq


@njit(cache=True, nogil=True, error_model="numpy")
def plane_sums_boxes(
    labels: NDArray[np.int32],
    n: int,
    ids: NDArray[np.intp],
    boxes: NDArray[np.int64],
    depth: NDArray[np.float32],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
) -> NDArray[np.float64]:
    # plane_sums for one label at a time inside its box: the label's runs are the same, and
    # are met in the same raster order
    w = labels.shape[1]
    out = np.zeros((n + 1, 9), np.float64)
    ucol = np.empty(w, np.float64)
    for x in range(w):
        ucol[x] = (x - cx) / fx
    for k in range(ids.size):
        i = ids[k]
        bx0, by0, bx1, by1 = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3]
        for y in range(by0, by1 + 1):
            v = (y - cy) / fy
            x = bx0
            while x <= bx1:
                if labels[y, x] != i:
                    x += 1
                    continue
                c = 0.0
                su = 0.0
                suu = 0.0
                sq = 0.0
                suq = 0.0
                while x <= bx1 and labels[y, x] == i:
                    u = ucol[x]
                    q = 1.0 / depth[y, x]
                    c += 1.0
                    su += u
                    suu += u * u
                    sq += q
                    suq += u * q
                    x += 1
                flush_plane_run(out, i, v, c, su, suu, sq, suq)
    return out


@njit(cache=True, nogil=True)
def shares_beneath(
    depth: NDArray[np.float32],
    step: int,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    beneath: float,
) -> NDArray[np.float64]:
    # one pass over the sampled pixels for all planes, without the (3, N) table of camera
    # coordinates and the per-plane numpy products over it that it replaced (a visible share of
    # a small frame). The coordinates are numpy's ((u - cx) / fx * Z, ...); the distance's three
    # products are added in order, which a BLAS product may round differently in the last bit:
    # that moves a reading only when it lies within a few 1e-13 mm of the limit
    p = normal.shape[0]
    counts = np.zeros(p, np.int64)
    m = 0
    h, w = depth.shape
    for y in range(0, h, step):
        yy = np.float64(y) - cy
        for x in range(0, w, step):
            z = depth[y, x]
            if z > 0:
                zz = np.float64(z)
                px = (np.float64(x) - cx) / fx * zz
                py = yy / fy * zz
                m += 1
                for j in range(p):
                    if (normal[j, 0] * px + normal[j, 1] * py) + normal[j, 2] * zz + off[j] < -beneath:
                        counts[j] += 1
    out = np.zeros(p, np.float64)
    if m:
        for j in range(p):
            out[j] = counts[j] / m
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def planes_from_sums(
    sums: NDArray[np.float64], min_px: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    # compiled because numpy's batched solve, norm and the table building cost about 60 us of
    # calls per use on a few rows, four uses per frame (over 3 % of the default method at
    # 176 x 132); the solve is LAPACK's through numba's np.linalg.solve. Rows 1.. of fewer
    # than min_px pixels are not solved (NaN): most pieces of a real frame are specks whose
    # planes no caller reads
    m = sums.shape[0]
    normal = np.empty((m, 3), np.float64)
    off = np.empty(m, np.float64)
    count = np.empty(m, np.float64)
    a = np.empty((3, 3), np.float64)
    b = np.empty(3, np.float64)
    eps = 1e-12
    for i in range(m):
        count[i] = sums[i, 5]
        if i > 0 and not count[i] >= min_px:
            normal[i, 0] = normal[i, 1] = normal[i, 2] = off[i] = math.nan
            continue
        if i == 0:
            a[:] = 0.0
            a[0, 0] = a[1, 1] = a[2, 2] = 1.0 + eps
            b[0], b[1], b[2] = 0.0, 0.0, 1.0
        else:
            s = sums[i]
            # numpy adds 1e-12 times the identity: + 0.0 off the diagonal (a -0.0 turns +0.0)
            a[0, 0], a[0, 1], a[0, 2] = s[0] + eps, s[1] + 0.0, s[2] + 0.0
            a[1, 0], a[1, 1], a[1, 2] = s[1] + 0.0, s[3] + eps, s[4] + 0.0
            a[2, 0], a[2, 1], a[2, 2] = s[2] + 0.0, s[4] + 0.0, s[5] + eps
            b[0], b[1], b[2] = s[6], s[7], s[8]
        x = np.linalg.solve(a, b)
        norm = max(math.sqrt((x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]), 1e-15)
        normal[i, 0] = -x[0] / norm
        normal[i, 1] = -x[1] / norm
        normal[i, 2] = -x[2] / norm
        off[i] = 1.0 / norm
    return normal, off, count
