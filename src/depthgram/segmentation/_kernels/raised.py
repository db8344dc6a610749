"""The compiled passes of the raised pass (:mod:`depthgram.segmentation.raised`): the gate, the windows, the pieces.

numpy and OpenCV do the same on a support's few hundred blocks or few thousand samples in some
eighty calls, whose overhead was most of the pass: the gate (a support's block plane), the cut
(the windows' test, their 8-connected pieces by the project's union-find, the pieces' tests) and
the kept pieces' pixels below each read their samples once.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label.stats import COUNT, N_COLUMNS
from depthgram.segmentation.label.unionfind import resolve, union

#: what :func:`block_gate` says of a support
NOTHING, PLANE, FEW_BLOCKS, FEW_READINGS = 0, 1, 2, 3


@njit(cache=True, nogil=True)
def _fit(
    mu: NDArray[np.float64], mv: NDArray[np.float64], mq: NDArray[np.float64], keep: NDArray[np.bool_]
) -> NDArray[np.float64]:
    # least squares of mq = a mu + b mv + c over the kept blocks: the normal equations' sums in
    # one pass, solved by LAPACK (numba's np.linalg.solve)
    s_uu = s_uv = s_u = s_vv = s_v = s_1 = s_uq = s_vq = s_q = 0.0
    for i in range(mu.size):
        if keep[i]:
            u, v, q = mu[i], mv[i], mq[i]
            s_uu += u * u
            s_uv += u * v
            s_u += u
            s_vv += v * v
            s_v += v
            s_1 += 1.0
            s_uq += u * q
            s_vq += v * q
            s_q += q
    a = np.array([[s_uu, s_uv, s_u], [s_uv, s_vv, s_v], [s_u, s_v, s_1]])
    if abs(np.linalg.det(a)) < 1e-300:  # fewer than three blocks, or all on one line
        return np.zeros(3)
    return np.linalg.solve(a, np.array([s_uq, s_vq, s_q]))


@njit(cache=True, nogil=True)
def _above(
    coef: NDArray[np.float64], mu: NDArray[np.float64], mv: NDArray[np.float64], z: NDArray[np.float64]
) -> NDArray[np.float64]:
    out = np.empty(z.size)
    for i in range(z.size):
        out[i] = 1000.0 / max(coef[0] * mu[i] + coef[1] * mv[i] + coef[2], 1e-12) - z[i]
    return out


@njit(cache=True, nogil=True)
def block_gate(
    labels: NDArray[np.int32],
    sid: int,
    classes: NDArray[np.int8],
    cls: int,
    depth: NDArray[np.float32],
    x0: int,
    y0: int,
    x1: int,
    y1: int,
    s: int,
    target_blocks: float,
    min_readings: float,
    sigma_0: float,
    sigma_2: float,
    step_0: float,
    step_2: float,
    k_sigma: float,
    rounds: int,
) -> tuple[int, NDArray[np.float64]]:
    # every s-th pixel of the box (x0, y0, x1, y1, exclusive) on the support and of its class cls,
    # averaged over blocks of b x b samples, as raised._block_plane describes (the sensor's
    # sigma and step are sigma_0 + sigma_2 Z^2 and step_0 + step_2 Z^2, mm)
    h, w = y1 - y0, x1 - x0
    gh0, gw0 = (h + s - 1) // s, (w + s - 1) // s
    n_on = 0
    for i in range(gh0):
        for j in range(gw0):
            y, x = y0 + i * s, x0 + j * s
            if labels[y, x] == sid and classes[y, x] == cls:
                n_on += 1
    if n_on * s * s < min_readings:
        return FEW_READINGS, np.zeros(3)
    b = max(2, round(math.sqrt(gh0 * gw0 / target_blocks)))
    gh, gw = gh0 // b, gw0 // b
    if gh * gw < 12:
        return FEW_BLOCKS, np.zeros(3)
    # the blocks wholly on the support: their mean 1000/Z (float32 sums, as OpenCV's area resize)
    mq = np.empty(gh * gw)
    mu = np.empty(gh * gw)
    mv = np.empty(gh * gw)
    n = 0
    cell = float(s * b)
    centre = s * (b - 1) / 2.0
    for r in range(gh):
        for c in range(gw):
            full = True
            acc = np.float32(0.0)
            for i in range(r * b, r * b + b):
                y = y0 + i * s
                for j in range(c * b, c * b + b):
                    x = x0 + j * s
                    if labels[y, x] != sid or classes[y, x] != cls:
                        full = False
                        break
                    acc += np.float32(1000.0) / max(depth[y, x], np.float32(1.0))
                if not full:
                    break
            if full:
                mq[n] = acc / np.float32(b * b)
                mu[n] = c * cell + (centre - (w - 1) / 2.0)
                mv[n] = r * cell + (centre - (h - 1) / 2.0)
                n += 1
    if n < 6:
        return NOTHING, np.zeros(3)
    mq, mu, mv = mq[:n], mu[:n], mv[:n]
    z = 1000.0 / mq
    sigma = sigma_0 + sigma_2 * z * z
    limit = (k_sigma / b) * sigma + (step_0 + step_2 * z * z)
    gate = np.maximum(limit, 2.0 * sigma)
    keep = np.ones(n, np.bool_)
    coef = _fit(mu, mv, mq, keep)
    above = _above(coef, mu, mv, z)
    if not np.any(above > gate):
        return NOTHING, coef
    # the upper medians of the residuals and of their deviations, one-sided cut
    mid = np.sort(above)[n // 2]
    spread = 1.4826 * np.sort(np.abs(above - mid))[n // 2]
    keep = above - mid < np.maximum(2.5 * spread, limit)
    for _ in range(rounds):
        if np.count_nonzero(keep) < 3:
            break
        coef = _fit(mu, mv, mq, keep)
        above = _above(coef, mu, mv, z)
        keep = above < limit
    return (PLANE if np.any(above > gate) else NOTHING), coef


@njit(cache=True, nogil=True)
def _reflect(i: int, n: int) -> int:
    # a window at the box's edge reads it mirrored (... 2 1 | 0 1 2 ... n-2 n-1 | n-2 ...), as a
    # box filter's default border does
    if i < 0:
        return min(-i, n - 1)
    if i >= n:
        return max(2 * n - 2 - i, 0)
    return i


@njit(cache=True, nogil=True)
def _window_test(
    labels: NDArray[np.int32],
    sid: int,
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    depth: NDArray[np.float32],
    x0: int,
    y0: int,
    x1: int,
    y1: int,
    t: int,
    coef: NDArray[np.float64],
    window: int,
    sigma_0: float,
    sigma_2: float,
    step_0: float,
    step_2: float,
    k_sigma: float,
) -> tuple[NDArray[np.bool_], NDArray[np.float32], NDArray[np.float32], NDArray[np.uint8], NDArray[np.bool_]]:
    # raised's window test (its step 2) on every t-th pixel of the box (x0, y0, x1, y1, exclusive):
    # the support's readings (on), their height over the box-centred plane coef and depth, and
    # which windows stand above the plane (high) or lie on it (flat), as raised's step 2 says
    h, w = y1 - y0, x1 - x0
    gh, gw = (h + t - 1) // t, (w + t - 1) // t
    on = np.zeros((gh, gw), np.bool_)
    height = np.zeros((gh, gw), np.float32)
    z = np.zeros((gh, gw), np.float32)
    cu, cv = (w - 1) / 2.0, (h - 1) / 2.0
    for i in range(gh):
        y = y0 + i * t
        for j in range(gw):
            x = x0 + j * t
            if labels[y, x] == sid and valid[y, x] and classes[y, x] == cls:
                plane = coef[0] * (j * t - cu) + coef[1] * (i * t - cv) + coef[2]
                on[i, j] = True
                z[i, j] = depth[y, x]
                if plane > 0:
                    height[i, j] = np.float32(1000.0 / plane) - depth[y, x]
    r = window // 2
    # the support's readings closed by the window (its dropouts bridged); samples beyond the
    # box count neither way
    grown = np.zeros((gh, gw), np.bool_)
    for i in range(gh):
        for j in range(gw):
            hit = False
            for a in range(max(i - r, 0), min(i + r + 1, gh)):
                for b in range(max(j - r, 0), min(j + r + 1, gw)):
                    if on[a, b]:
                        hit = True
                        break
                if hit:
                    break
            grown[i, j] = hit
    high = np.zeros((gh, gw), np.uint8)
    flat = np.zeros((gh, gw), np.bool_)
    least = window * window / 4.0
    for i in range(gh):
        for j in range(gw):
            closed = True
            count = 0.0
            s_h = 0.0
            s_z = 0.0
            for a in range(i - r, i + r + 1):
                ra = _reflect(a, gh)
                inside_a = 0 <= a < gh
                for b in range(j - r, j + r + 1):
                    rb = _reflect(b, gw)
                    if inside_a and 0 <= b < gw and not grown[a, b]:
                        closed = False
                    if on[ra, rb]:
                        count += 1.0
                        s_z += z[ra, rb]
                    s_h += height[ra, rb]
            if not closed or count < least:
                continue
            n = max(count, 1.0)
            mean = s_h / n
            zm = s_z / n
            limit = k_sigma * (sigma_0 + sigma_2 * zm * zm) / math.sqrt(n) + step_0 + step_2 * zm * zm
            if mean > limit:
                high[i, j] = 1
            elif abs(mean) <= limit:
                flat[i, j] = True
    return on, height, z, high, flat


@njit(cache=True, nogil=True)
def _edge_ring(
    comp: NDArray[np.int32],
    k: int,
    boxes: NDArray[np.int64],
    ring_px: int,
    shape: tuple[int, int],
    x0: int,
    y0: int,
    t: int,
) -> int:
    # the ring samples of piece k that fall outside the frame: a piece in a corner has half
    # its ring there, a thing partly out of view along one edge a quarter
    hh, ww = comp.shape
    h, w = shape
    n_out = 0
    for i in range(boxes[k, 1] - ring_px, boxes[k, 3] + ring_px + 1):
        for j in range(boxes[k, 0] - ring_px, boxes[k, 2] + ring_px + 1):
            py, px = y0 + i * t, x0 + j * t
            if 0 <= py < h and 0 <= px < w:
                continue
            near = False
            for a in range(max(i - ring_px, 0), min(i + ring_px + 1, hh)):
                for b in range(max(j - ring_px, 0), min(j + ring_px + 1, ww)):
                    if comp[a, b] == k:
                        near = True
                        break
                if near:
                    break
            if near:
                n_out += 1
    return n_out


@njit(cache=True, nogil=True)
def _component_test(
    comp: NDArray[np.int32],
    n_comp: int,
    boxes: NDArray[np.int64],
    counts: NDArray[np.float64],
    on: NDArray[np.bool_],
    flat: NDArray[np.bool_],
    height: NDArray[np.float32],
    z: NDArray[np.float32],
    min_n: int,
    ring_px: int,
    ring_share: float,
    rise_steps: float,
    outer_resolutions: float,
    ring_missing: float,
    ring_rise: float,
    valid: NDArray[np.bool_],
    x0: int,
    y0: int,
    t: int,
    sigma_0: float,
    sigma_2: float,
    step_0: float,
    step_2: float,
    refuse_corners: bool,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    # raised's tests of each connected piece (its step 3) of the high windows (comp, n_comp,
    # and their inclusive boxes and sample counts, as components gives them): its ring flat and
    # seen (valid at the samples, every t-th pixel from x0, y0), fewer than half the support's
    # readings, a step of rise_steps over its ring with the ring near the
    # plane, and the support beyond the ring (ring_px to 2 ring_px out) within
    # outer_resolutions of the plane; the kept pieces' ids and half heights
    hh, ww = comp.shape
    n_on = 0
    for i in range(hh):
        for j in range(ww):
            if on[i, j]:
                n_on += 1
    kept = np.zeros(n_comp + 1, np.int64)
    halves = np.zeros(n_comp + 1, np.float64)
    n_kept = 0
    grow = 2 * ring_px
    for k in range(1, n_comp + 1):
        if counts[k] < min_n:
            continue
        ya, yb = max(boxes[k, 1] - grow, 0), min(boxes[k, 3] + 1 + grow, hh)
        xa, xb = max(boxes[k, 0] - grow, 0), min(boxes[k, 2] + 1 + grow, ww)
        size = (yb - ya) * (xb - xa)
        inside = np.empty(size, np.float32)
        near = np.empty(size, np.float32)
        outer = np.empty(size, np.float32)
        n_in = n_near = n_ring = n_flat = n_outer = n_missing = 0
        for i in range(ya, yb):
            for j in range(xa, xb):
                if comp[i, j] == k:
                    if on[i, j]:
                        inside[n_in] = height[i, j]
                        n_in += 1
                    continue
                ring = False
                for a in range(max(i - ring_px, ya), min(i + ring_px + 1, yb)):
                    for b in range(max(j - ring_px, xa), min(j + ring_px + 1, xb)):
                        if comp[a, b] == k:
                            ring = True
                            break
                    if ring:
                        break
                if ring:
                    n_ring += 1
                    if flat[i, j]:
                        n_flat += 1
                    if not valid[y0 + i * t, x0 + j * t]:
                        n_missing += 1
                    if on[i, j]:
                        near[n_near] = height[i, j]
                        n_near += 1
                elif on[i, j]:
                    beyond = False
                    for a in range(max(i - 2 * ring_px, ya), min(i + 2 * ring_px + 1, yb)):
                        for b in range(max(j - 2 * ring_px, xa), min(j + 2 * ring_px + 1, xb)):
                            if comp[a, b] == k:
                                beyond = True
                                break
                        if beyond:
                            break
                    if beyond:
                        outer[n_outer] = height[i, j]
                        n_outer += 1
        if refuse_corners:
            n_out = _edge_ring(comp, k, boxes, ring_px, valid.shape, x0, y0, t)
            # more than a third of its ring beyond the frame: not told from a bend there
            if 3 * n_out > n_ring + n_out:
                continue
        if n_flat < ring_share * max(n_ring, 1) or n_in == 0 or n_missing > ring_missing * n_ring:
            continue
        half = 0.5 * np.median(inside[:n_in])
        mine = np.empty(n_in, np.float32)
        zs = np.empty(n_in, np.float32)
        n_mine = 0
        for i in range(ya, yb):
            for j in range(xa, xb):
                if comp[i, j] == k and on[i, j] and height[i, j] > half:
                    mine[n_mine] = height[i, j]
                    zs[n_mine] = z[i, j]
                    n_mine += 1
        if n_mine < min_n or 2 * n_mine > n_on:
            continue
        around = np.median(near[:n_near]) if n_near > 0 else 0.0
        zp = np.median(zs[:n_mine])
        step = step_0 + step_2 * zp * zp
        sigma = sigma_0 + sigma_2 * zp * zp
        resolution = max(step, 2.0 * sigma)
        # the rise is a difference of two medians of many readings: their noise is a fraction
        # of one reading's, so what it must clear is the step (a bend is whole steps) or that
        # fraction, not two of one reading's sigmas
        noise = 2.0 * 1.2533 * sigma * np.sqrt(1.0 / n_mine + 1.0 / max(n_near, 1))
        top = np.median(mine[:n_mine])
        if top - around < rise_steps * max(step, noise) or around > max(ring_rise * top, step):
            continue
        if n_outer > 0 and abs(np.median(outer[:n_outer])) > outer_resolutions * resolution:
            continue
        kept[n_kept] = k
        halves[n_kept] = half
        n_kept += 1
    return kept[:n_kept], halves[:n_kept]


@njit(cache=True, nogil=True)
def _components(
    high: NDArray[np.uint8], min_n: int
) -> tuple[NDArray[np.int32], int, NDArray[np.int64], NDArray[np.float64]]:
    # the 8-connected pieces of high of at least min_n samples, numbered in raster order of their
    # first sample (the project's two-pass labeller; OpenCV's labeller wakes its thread pool,
    # which costs more than labelling a few thousand samples): labels, count, inclusive boxes
    # and the statistics table (COUNT: samples)
    hh, ww = high.shape
    lab = np.zeros((hh, ww), np.int32)
    parent = np.arange(hh * ww // 2 + 2, dtype=np.int32)
    nxt = 1
    for i in range(hh):
        for j in range(ww):
            if not high[i, j]:
                continue
            here = 0
            for a, b in ((i, j - 1), (i - 1, j - 1), (i - 1, j), (i - 1, j + 1)):
                if a >= 0 and 0 <= b < ww and lab[a, b]:
                    here = lab[a, b] if here == 0 else union(parent, here, lab[a, b])
            if here == 0:
                if nxt == parent.size:
                    grown = np.arange(2 * parent.size, dtype=np.int32)
                    grown[: parent.size] = parent
                    parent = grown
                here = nxt
                nxt += 1
            lab[i, j] = here
    psums = np.zeros((nxt, N_COLUMNS), np.float64)
    pboxes = np.empty((nxt, 4), np.int32)
    pboxes[:, 0] = ww
    pboxes[:, 1] = hh
    pboxes[:, 2] = -1
    pboxes[:, 3] = -1
    for i in range(hh):
        for j in range(ww):
            p = lab[i, j]
            if p:
                psums[p, COUNT] += 1.0
                pboxes[p, 0] = min(pboxes[p, 0], j)
                pboxes[p, 1] = min(pboxes[p, 1], i)
                pboxes[p, 2] = max(pboxes[p, 2], j)
                pboxes[p, 3] = max(pboxes[p, 3], i)
    lab, n, sums, boxes = resolve(lab, parent, nxt, psums, pboxes, min_n, True)
    return lab, n, boxes, sums


@njit(cache=True, nogil=True)
def cut(
    labels: NDArray[np.int32],
    sid: int,
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    depth: NDArray[np.float32],
    x0: int,
    y0: int,
    x1: int,
    y1: int,
    t: int,
    coef: NDArray[np.float64],
    window: int,
    ring_px: int,
    sigma_0: float,
    sigma_2: float,
    step_0: float,
    step_2: float,
    k_sigma: float,
    min_n: int,
    ring_share: float,
    rise_steps: float,
    outer_resolutions: float,
    ring_missing: float,
    ring_rise: float,
    refuse_corners: bool,
) -> tuple[
    NDArray[np.int32], NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.float32]
]:
    # raised's steps 2 and 3 in one call: the windows' test on every t-th reading of the box, the
    # standing windows' pieces, and their tests; the pieces' labels and inclusive boxes on the
    # samples, the kept ones with their half heights, and the support's samples and heights
    on, height, z, high, flat = _window_test(
        labels,
        sid,
        valid,
        classes,
        cls,
        depth,
        x0,
        y0,
        x1,
        y1,
        t,
        coef,
        window,
        sigma_0,
        sigma_2,
        step_0,
        step_2,
        k_sigma,
    )
    comp, n, boxes, sums = _components(high, min_n)
    kept, halves = _component_test(
        comp,
        n,
        boxes,
        sums[:, COUNT],
        on,
        flat,
        height,
        z,
        min_n,
        ring_px,
        ring_share,
        rise_steps,
        outer_resolutions,
        ring_missing,
        ring_rise,
        valid,
        x0,
        y0,
        t,
        sigma_0,
        sigma_2,
        step_0,
        step_2,
        refuse_corners,
    )
    return comp, boxes, kept, halves, on, height


@njit(cache=True, nogil=True)
def _grown(m: NDArray[np.bool_], r: int) -> NDArray[np.bool_]:
    # m grown by r px each way (a square window: Chebyshev distance), rows then columns; each
    # pass keeps a running count of the set pixels in its window, so the cost is the box's
    # pixels whatever r
    hh, ww = m.shape
    rows = np.zeros((hh, ww), np.bool_)
    for y in range(hh):
        n = 0
        for x in range(min(r, ww)):
            n += m[y, x]
        for x in range(ww):
            if x + r < ww:
                n += m[y, x + r]
            if x - r - 1 >= 0:
                n -= m[y, x - r - 1]
            rows[y, x] = n > 0
    out = np.zeros((hh, ww), np.bool_)
    count = np.zeros(ww, np.int64)
    for y in range(min(r, hh)):
        for x in range(ww):
            count[x] += rows[y, x]
    for y in range(hh):
        if y + r < hh:
            for x in range(ww):
                count[x] += rows[y + r, x]
        if y - r - 1 >= 0:
            for x in range(ww):
                count[x] -= rows[y - r - 1, x]
        for x in range(ww):
            out[y, x] = count[x] > 0
    return out


@njit(cache=True, nogil=True)
def _in_trough(
    mine: NDArray[np.bool_],
    labels: NDArray[np.int32],
    sid: int,
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    depth: NDArray[np.float32],
    x0: int,
    y0: int,
    w: int,
    h: int,
    xa: int,
    ya: int,
    coef: NDArray[np.float64],
    cu: float,
    cv: float,
    half: float,
    trough: float,
    band_in: int,
    band_out: int,
    comp: NDArray[np.int32],
    j: int,
    t: int,
) -> bool:
    # whether the support's readings band_in..band_out px (a square's distance) beyond the
    # piece's pixels mine (its box from xa, ya in the support's box x0, y0, w x h) have their
    # median height below the plane by more than trough of the piece's median height (2 half);
    # only those within one sample's cell of the piece's samples (comp == j, every t-th pixel)
    mh, mw = mine.shape
    ea, fa = max(ya - band_out, 0), max(xa - band_out, 0)
    eb, fb = min(ya + mh + band_out, h), min(xa + mw + band_out, w)
    m = np.zeros((eb - ea, fb - fa), np.bool_)
    m[ya - ea : ya - ea + mh, xa - fa : xa - fa + mw] = mine
    inner, outer = _grown(m, band_in - 1), _grown(m, band_out)
    # the band's samples within one sample's cell of the piece's: one look-up a pixel below
    ia, ib, ka, kb = ea // t, (eb - 1) // t, fa // t, (fb - 1) // t
    beside = np.zeros((ib - ia + 1, kb - ka + 1), np.bool_)
    for r in range(max(ia - 1, 0), min(ib + 2, comp.shape[0])):
        for q in range(max(ka - 1, 0), min(kb + 2, comp.shape[1])):
            if comp[r, q] == j:
                for a in range(max(r - 1, ia), min(r + 1, ib) + 1):
                    for b in range(max(q - 1, ka), min(q + 1, kb) + 1):
                        beside[a - ia, b - ka] = True
    got = np.empty(m.size, np.float32)
    n = 0
    for y in range(ea, eb):
        for x in range(fa, fb):
            if not outer[y - ea, x - fa] or inner[y - ea, x - fa]:
                continue
            if not beside[y // t - ia, x // t - ka]:
                continue
            yy, xx = y0 + y, x0 + x
            if labels[yy, xx] != sid or not valid[yy, xx] or classes[yy, xx] != cls:
                continue
            plane = coef[0] * (x - cu) + coef[1] * (y - cv) + coef[2]
            if plane > 0:
                got[n] = np.float32(1000.0 / plane) - depth[yy, xx]
                n += 1
    return n > 0 and bool(np.median(got[:n]) < -trough * 2.0 * half)


@njit(cache=True, nogil=True)
def _near_samples(
    comp: NDArray[np.int32],
    j: int,
    on: NDArray[np.bool_],
    height: NDArray[np.float32],
    half: float,
    gx0: int,
    gy0: int,
    gx1: int,
    gy1: int,
) -> NDArray[np.bool_]:
    # the samples gy0 - 1 .. gy1 + 1 by gx0 - 1 .. gx1 + 1 within one sample (a 3 x 3 square) of
    # piece j's samples standing above half its height (its samples lie in its box gx0..gx1,
    # gy0..gy1): a pixel's test in paint is then one look-up, not nine of comp, on and height
    near = np.zeros((gy1 - gy0 + 3, gx1 - gx0 + 3), np.bool_)
    for r in range(gy0, gy1 + 1):
        for s in range(gx0, gx1 + 1):
            if comp[r, s] == j and on[r, s] and height[r, s] > half:
                for a in range(r - gy0, r - gy0 + 3):
                    for b in range(s - gx0, s - gx0 + 3):
                        near[a, b] = True
    return near


@njit(cache=True, nogil=True)
def paint(
    out: NDArray[np.int32],
    labels: NDArray[np.int32],
    sid: int,
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    depth: NDArray[np.float32],
    x0: int,
    y0: int,
    x1: int,
    y1: int,
    t: int,
    coef: NDArray[np.float64],
    comp: NDArray[np.int32],
    boxes: NDArray[np.int64],
    kept: NDArray[np.int64],
    halves: NDArray[np.float64],
    on: NDArray[np.bool_],
    height: NDArray[np.float32],
    min_px: int,
    first: int,
    trough: float,
    band_in: int,
    band_out: int,
) -> tuple[int, NDArray[np.int64]]:
    # the kept pieces' pixels, as raised's step 4 says, written into out as first,
    # first + 1, ... (a later piece over an earlier one); how many had min_px pixels and their
    # boxes (x0, y0, x1, y1, exclusive, in the frame). The heights are float32, as numpy's
    # arithmetic on the frame's float32 depth gives them.
    h, w = y1 - y0, x1 - x0
    cu = np.float32((w - 1) / 2.0)
    cv = np.float32((h - 1) / 2.0)
    a, b, c = np.float32(coef[0]), np.float32(coef[1]), np.float32(coef[2])
    placed = np.zeros((kept.size, 4), np.int64)
    n = 0
    for p in range(kept.size):
        j, half = kept[p], halves[p]
        gx0, gy0, gx1, gy1 = boxes[j, 0], boxes[j, 1], boxes[j, 2], boxes[j, 3]
        ya, yb = max(gy0 * t - t, 0), min(gy1 * t + 2 * t, h)
        xa, xb = max(gx0 * t - t, 0), min(gx1 * t + 2 * t, w)
        near = _near_samples(comp, j, on, height, half, gx0, gy0, gx1, gy1)
        mine = np.zeros((yb - ya, xb - xa), np.bool_)
        count = 0
        for y in range(ya, yb):
            i = y // t
            v = np.float32(y) - cv
            for x in range(xa, xb):
                # within one sample of the piece's samples standing above half its height: a
                # look-up on the samples before the frame's three maps are read
                if not near[i - gy0 + 1, x // t - gx0 + 1]:
                    continue
                yy, xx = y0 + y, x0 + x
                if labels[yy, xx] != sid or not valid[yy, xx] or classes[yy, xx] != cls:
                    continue
                plane = a * (np.float32(x) - cu) + b * v + c
                if plane > 0 and np.float32(1000.0) / plane - depth[yy, xx] > half:
                    mine[y - ya, x - xa] = True
                    count += 1
        if count < min_px:
            continue
        if trough < np.inf and _in_trough(
            mine, labels, sid, valid, classes, cls, depth, x0, y0, w, h, xa, ya, coef, float(cu), float(cv), half,
            trough, band_in, band_out, comp, j, t,
        ):  # fmt: skip
            continue
        for y in range(ya, yb):
            for x in range(xa, xb):
                if mine[y - ya, x - xa]:
                    out[y0 + y, x0 + x] = first + n
        placed[n, 0], placed[n, 1], placed[n, 2], placed[n, 3] = x0 + xa, y0 + ya, x0 + xb, y0 + yb
        n += 1
    return n, placed[:n]
