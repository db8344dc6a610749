"""The compiled steps of the RANSAC plane search (:mod:`depthgram.segmentation.ransac`).

The three-point samples are drawn from numpy's random stream, solved, scored and refitted in
one compiled call per frame: the dozen numpy calls of a search cost more than its arithmetic.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label.unionfind import find, union
from depthgram.segmentation.order_stats import percentile32


@njit(cache=True, nogil=True)
def assign_planes(
    depth: NDArray[np.float32],
    valid: NDArray[np.bool_],
    coefs: NDArray[np.float64],
    allowed: NDArray[np.uint8],
    step: int,
    tol_mm: float,
    tol_rel: float,
) -> NDArray[np.int8]:
    # the first plane (1..P) each pixel lies on, 0 for none, in one pass over the frame: the
    # numpy route needs half a dozen full-frame temporaries per plane
    h, w = depth.shape
    out = np.zeros((h, w), np.int8)
    # each column's cell once: an integer division at every pixel cost more than the test
    cell_of = np.empty(w, np.int64)
    for x in range(w):
        cell_of[x] = x // step
    for y in range(h):
        cy = y // step
        for x in range(w):
            if not valid[y, x]:
                continue
            z = np.float64(depth[y, x])
            tol = max(tol_mm, tol_rel * z)
            cx = cell_of[x]
            for k in range(coefs.shape[0]):
                if not allowed[k, cy, cx]:
                    continue
                inv = coefs[k, 0] * x + coefs[k, 1] * y + coefs[k, 2]
                if inv > 0 and abs(1000.0 - z * inv) <= tol * inv:
                    out[y, x] = k + 1
                    break
    return out


@njit(cache=True, inline="always")
def bounded(raw: NDArray[np.uint32], pos: int, n: int) -> tuple[int, int]:
    """Return an integer in ``[0, n)`` drawn from ``raw[pos:]`` as numpy draws it, and the next position.

    ``Generator.integers(0, n)``'s bounded draw for a range under 2**32 (Lemire's multiply-and-reject on 32-bit
    numbers, ``buffered_bounded_lemire_uint32``), so the same numbers from the same stream.
    The position is -1 when ``raw`` ran out.
    """
    excl = np.uint64(n)
    low = np.uint64(0xFFFFFFFF)
    if pos >= raw.size:
        return 0, -1
    m = np.uint64(raw[pos]) * excl
    pos += 1
    left = m & low
    if left < excl:
        threshold = (low - (excl - np.uint64(1))) % excl
        while left < threshold:
            if pos >= raw.size:
                return 0, -1
            m = np.uint64(raw[pos]) * excl
            pos += 1
            left = m & low
    return int(m >> np.uint64(32)), pos


@njit(cache=True, nogil=True)
def search_planes(
    z_sub: NDArray[np.float32],
    left: NDArray[np.bool_],
    step: int,
    tol_mm: np.float32,
    tol_rel: np.float32,
    min_sub: float,
    hypotheses: int,
    max_planes: int,
    min_spread: float,
    raw: NDArray[np.uint32],
    eps: float,
) -> tuple[int, NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
    """Run the RANSAC searches of :func:`depthgram.segmentation.ransac.find_planes` on the grid, in one compiled call.

    Each search draws its three-point samples and (beyond 2000 points) its scoring points as
    ``np.random.default_rng(seed).integers`` would, from the numbers ``raw`` of the seed
    (:func:`depthgram.segmentation.ransac._raw32`, :func:`bounded`), then runs :func:`_search_plane`
    and keeps the plane's large pieces (:func:`large_pieces`); a plane too small or too flat
    is dropped and the search goes on, as the numpy route does. ``left`` (the grid points
    still searched) is taken in place.

    Returns the number of planes found (-1 when ``raw`` ran out), their coefficients, their
    large pieces on the grid and their depth spreads (the first rows).
    """
    hs, ws = z_sub.shape
    rows = max(max_planes, 1)
    coefs = np.zeros((rows, 3), np.float64)
    masks = np.zeros((rows, hs, ws), np.bool_)
    spreads = np.zeros(rows, np.float64)
    k = 0
    pos = 0
    for _ in range(max_planes * 2):
        if k >= max_planes:
            break
        # column and row (full-frame px), depth (mm) and tolerance (mm) of the grid points still
        # searched, in raster order, the tolerance numpy's float32 np.maximum(tol_mm, tol_rel * z)
        n = 0
        for y in range(hs):
            for x in range(ws):
                n += left[y, x]
        u = np.empty(n, np.float64)
        v = np.empty(n, np.float64)
        z = np.empty(n, np.float64)
        tz = np.empty(n, np.float64)
        j = 0
        for y in range(hs):
            for x in range(ws):
                if left[y, x]:
                    zz = z_sub[y, x]
                    u[j] = x * step
                    v[j] = y * step
                    z[j] = zz
                    tz[j] = max(tol_mm, tol_rel * zz)
                    j += 1
        if n < max(min_sub, 3.0):
            break
        pick = np.empty((hypotheses, 3), np.int64)
        flat = pick.reshape(hypotheses * 3)
        for i in range(flat.size):
            flat[i], pos = bounded(raw, pos, n)
            if pos < 0:
                return -1, coefs, masks, spreads
        # the scoring points are drawn after the samples, as the numpy route draws them (it
        # draws none when no sample is solvable, and then stops searching: no later draw differs)
        m = min(n, 2000)
        if n > m:
            ev = np.empty(m, np.int64)
            for i in range(m):
                ev[i], pos = bounded(raw, pos, n)
                if pos < 0:
                    return -1, coefs, masks, spreads
        else:
            ev = np.arange(n)
        status, a, b, c, on_img = _search_plane(u, v, z, tz, pick, ev, min_sub, eps, z_sub, left, tol_mm, tol_rel, step)
        if status < _FOUND:
            break
        # the plane's large pieces and the 5th, 50th and 95th percentiles of their depth,
        # np.percentile(z_sub[pieces], (5, 50, 95))
        pieces = large_pieces(on_img, max(int(min_sub) // 4, 1))
        on_z = z_sub.ravel()[pieces.ravel()]
        if on_z.size < min_sub or on_z.size == 0:
            continue
        p5 = percentile32(on_z, 5.0, False)
        p50 = percentile32(on_z, 50.0, False)
        p95 = percentile32(on_z, 95.0, False)
        spread = (p95 - p5) / max(p50, 1e-6)
        if spread < min_spread:
            continue  # a fronto-parallel plane (a back wall) is a facing object, not a support
        coefs[k, 0] = a
        coefs[k, 1] = b
        coefs[k, 2] = c
        masks[k] = pieces
        spreads[k] = spread
        k += 1
    return k, coefs, masks, spreads


#: :func:`_search_plane`'s outcome: no solvable sample, too few inliers, a plane found.
_NO_SAMPLE, _FEW, _FOUND = 0, 1, 2


@njit(cache=True, nogil=True, error_model="numpy")
def _search_plane(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    z: NDArray[np.float64],
    tol: NDArray[np.float64],
    pick: NDArray[np.int64],
    ev: NDArray[np.int64],
    min_inliers: float,
    eps: float,
    z_sub: NDArray[np.float32],
    left: NDArray[np.bool_],
    tol_mm: np.float32,
    tol_rel: np.float32,
    step: int,
) -> tuple[int, float, float, float, NDArray[np.bool_]]:
    """One RANSAC search of ``1000 / Z = a u + b v + c`` on the grid points, compiled end to end.

    The three-point samples ``pick`` are solved (in closed form), scored
    on the points ``ev`` (:func:`best_hypothesis`), the best one's inliers refitted by least
    squares (LAPACK's ``dgelsd`` through numba, with numpy's default ``rcond``: the same
    numbers as ``np.linalg.lstsq``) and the refitted plane's grid pixels taken out of ``left``
    (in place). Compiled because the dozen numpy calls of a search
    (the batched solve, the least squares, the masks) cost more than their arithmetic.

    Returns the outcome (``_NO_SAMPLE``, ``_FEW`` inliers, ``_FOUND``), the refitted
    coefficients and the plane's grid pixels (all False unless found).
    """
    on_img = np.zeros(z_sub.shape, np.bool_)
    # each sample's plane through its three points (u, v, 1000 / z), by Cramer's rule on the
    # differences from its first point; the points lie on the integer pixel grid, so the
    # determinant is an integer, exact here, and zero for three points on a line
    m = pick.shape[0]
    coef = np.empty((m, 3), np.float64)
    k = 0
    for i in range(m):
        p0, p1, p2 = pick[i, 0], pick[i, 1], pick[i, 2]
        du1, dv1 = u[p1] - u[p0], v[p1] - v[p0]
        du2, dv2 = u[p2] - u[p0], v[p2] - v[p0]
        det = du1 * dv2 - du2 * dv1
        if det == 0.0:
            continue
        q0 = 1000.0 / z[p0]
        dq1 = 1000.0 / z[p1] - q0
        dq2 = 1000.0 / z[p2] - q0
        a = (dq1 * dv2 - dq2 * dv1) / det
        b = (du1 * dq2 - du2 * dq1) / det
        coef[k, 0] = a
        coef[k, 1] = b
        coef[k, 2] = q0 - a * u[p0] - b * v[p0]
        k += 1
    if k == 0:
        return _NO_SAMPLE, 0.0, 0.0, 0.0, on_img
    coef = coef[:k]
    best = best_hypothesis(coef, u, v, z, tol, ev)
    # the points on the best plane, [u v 1] and 1000 / z, refitted by least squares (one pass:
    # numpy's masks cost six temporaries)
    a, b, c = coef[best, 0], coef[best, 1], coef[best, 2]
    n = u.size
    sys = np.empty((n, 3), np.float64)
    qo = np.empty(n, np.float64)
    m_on = 0
    for i in range(n):
        inv = a * u[i] + b * v[i] + c
        if inv > 0 and abs(1000.0 - z[i] * inv) <= tol[i] * inv:
            sys[m_on, 0] = u[i]
            sys[m_on, 1] = v[i]
            sys[m_on, 2] = 1.0
            qo[m_on] = 1000.0 / z[i]
            m_on += 1
    if m_on < min_inliers:
        return _FEW, 0.0, 0.0, 0.0, on_img
    # np.linalg.lstsq's rcond=None is eps times the larger dimension
    fit = np.linalg.lstsq(sys[:m_on], qo[:m_on], eps * max(m_on, 3))[0]
    # the refitted plane's grid pixels (ransac.plane_residual_mask's float32 operations in
    # its order), taken out of `left`
    hs, ws = z_sub.shape
    a32, b32, c32 = np.float32(fit[0]), np.float32(fit[1]), np.float32(fit[2])
    s32 = np.float32(step)
    thousand = np.float32(1000.0)
    for y in range(hs):
        bv = b32 * (np.float32(y) * s32)
        for x in range(ws):
            if not left[y, x]:
                continue
            inv32 = (a32 * (np.float32(x) * s32) + bv) + c32
            zz = z_sub[y, x]
            t32 = max(tol_mm, tol_rel * zz)
            if inv32 > 0 and abs(thousand - zz * inv32) <= t32 * inv32:
                on_img[y, x] = True
                left[y, x] = False
    return _FOUND, fit[0], fit[1], fit[2], on_img


@njit(cache=True, nogil=True)
def best_hypothesis(
    coef: NDArray[np.float64],
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    z: NDArray[np.float64],
    tol: NDArray[np.float64],
    ev: NDArray[np.int64],
) -> int:
    # the first hypothesis with the most inliers among the points `ev` (np.argmax of the
    # scores), without the (hypotheses x points) temporaries of numpy broadcasting
    # (docs/design-notes.md, "RANSAC scoring")
    m = ev.size
    ue = np.empty(m, np.float64)
    ve = np.empty(m, np.float64)
    ze = np.empty(m, np.float64)
    te = np.empty(m, np.float64)
    for i in range(m):
        j = ev[i]
        ue[i] = u[j]
        ve[i] = v[j]
        ze[i] = z[j]
        te[i] = tol[j]
    n_hyp = coef.shape[0]
    # every hypothesis scored on the first block, then each in the order of those counts (most
    # first, ties by index), so that a strong best is known early and the others are left as
    # soon as they cannot be chosen: by blocks (so that the loop still vectorises), a
    # hypothesis before the best so far (by index) when it can no longer reach its count, one
    # after it when it can no longer pass it (argmax keeps the first of equal counts)
    f = min(_SCORE_FIRST, m)
    first = np.empty(n_hyp, np.int64)
    for k in range(n_hyp):
        first[k] = inliers_counted(coef[k, 0], coef[k, 1], coef[k, 2], ue[:f], ve[:f], ze[:f], te[:f])
    # a stable counting sort on f - count: most first, equal counts in index order
    start = np.zeros(f + 2, np.int64)
    for k in range(n_hyp):
        start[f - first[k] + 1] += 1
    for j in range(f + 1):
        start[j + 1] += start[j]
    order = np.empty(n_hyp, np.int64)
    for k in range(n_hyp):
        d = f - first[k]
        order[start[d]] = k
        start[d] += 1
    best = -1
    arg = 0
    for t in range(n_hyp):
        k = order[t]
        a, b, c = coef[k, 0], coef[k, 1], coef[k, 2]
        cnt = first[k]
        need = best if k < arg else best + 1
        i0 = f
        while i0 < m and cnt + (m - i0) >= need:
            i1 = min(i0 + _SCORE_BLOCK, m)
            cnt += inliers_counted(a, b, c, ue[i0:i1], ve[i0:i1], ze[i0:i1], te[i0:i1])
            i0 = i1
        if cnt >= need:  # scored to the end (a hypothesis left early is below need)
            best = cnt
            arg = k
    return arg


#: Points every RANSAC hypothesis is scored on before they are ordered by their counts there.
_SCORE_FIRST = 256


#: Points scored between two checks of whether a RANSAC hypothesis can still be chosen.
_SCORE_BLOCK = 64


@njit(cache=True, inline="always")
def inliers_counted(
    a: float, b: float, c: float, u: NDArray[np.float64], v: NDArray[np.float64], z: NDArray[np.float64],
    tol: NDArray[np.float64],
) -> int:  # fmt: skip
    # the points on the plane among these; views from index 0, so that the loop vectorises
    # (an offset index would keep numba's negative-index check in it)
    cnt = 0
    for i in range(u.size):
        inv = a * u[i] + b * v[i] + c
        cnt += (inv > 0) & (abs(1000.0 - z[i] * inv) <= tol[i] * inv)
    return cnt


@njit(cache=True, nogil=True)
def large_pieces(mask: NDArray[np.bool_], min_px: int) -> NDArray[np.bool_]:
    """Return the pixels of the 8-connected pieces of ``mask`` of at least ``min_px`` pixels.

    A far object that happens to cross the plane's extension makes small pieces; the support
    itself is large even when the objects standing on it cut it apart. Union-find over each
    row's runs, a run joined to the previous row's runs it touches, corners included (the
    pieces are a property of the mask alone: OpenCV's labelling gives the same); a set per
    pixel cost three times as much (9.6 against 2.7 us on a 44 x 59 grid).
    """
    h, w = mask.shape
    cap = h * ((w + 1) // 2)
    x0s = np.empty(cap, np.int32)
    x1s = np.empty(cap, np.int32)
    parent = np.empty(cap, np.int32)
    first = np.empty(h + 1, np.int64)
    n = 0
    above = 0  # the previous row's first run
    for y in range(h):
        first[y] = n
        x = 0
        p = above
        while x < w:
            if not mask[y, x]:
                x += 1
                continue
            s = x
            while x < w and mask[y, x]:
                x += 1
            x0s[n] = s
            x1s[n] = x
            parent[n] = n
            # the previous row's runs touching columns s - 1 .. x (8-connected); one that ends
            # before s - 1 touches no later run of this row either
            while p < first[y] and x1s[p] < s:
                p += 1
            q = p
            while q < first[y] and x0s[q] <= x:
                union(parent, n, q)
                q += 1
            n += 1
        above = first[y]
    first[h] = n
    size = np.zeros(n, np.int32)
    for r in range(n):
        size[find(parent, r)] += x1s[r] - x0s[r]
    out = np.zeros((h, w), np.bool_)
    for y in range(h):
        for r in range(first[y], first[y + 1]):
            if size[find(parent, r)] >= min_px:
                out[y, x0s[r] : x1s[r]] = True
    return out
