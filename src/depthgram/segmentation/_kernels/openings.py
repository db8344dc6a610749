"""The compiled tests of :func:`depthgram.segmentation.openings.merge_openings`."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray


@njit(cache=True, nogil=True)
def openings_table(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    objs: NDArray[np.int64],
    z_mean: NDArray[np.float64],
    focal_px: float,
    ring_px: int,
    jump: float,
    min_share: float,
) -> NDArray[np.int32]:
    # merge_openings in one compiled call: the pair test, the ring tests, the table. Empty when
    # nothing joins. The cheap tests first, for every pair (R, A): some nearer A that holds R's
    # columns, R no deeper behind it than it is wide (the ring costs a dilation of R's box); the
    # float64 arithmetic of the n x n numpy test it replaces (a dozen calls, most of the time
    # at small sizes), pair by pair
    n = z_mean.size - 1
    todo = np.empty(n, np.intp)
    k = 0
    for r in range(1, n + 1):
        if objs[r, 2] < 0:
            continue
        zr = z_mean[r]
        for a in range(1, n + 1):
            if a == r:
                continue
            wa = objs[a, 2] - objs[a, 0] + 1
            width = wa * z_mean[a] / focal_px
            margin = 0.15 * wa
            if (
                z_mean[a] < zr
                and zr - z_mean[a] <= width
                and objs[a, 0] - margin <= objs[r, 0]
                and objs[r, 2] <= objs[a, 2] + margin
            ):
                todo[k] = r
                k += 1
                break
    parent = np.arange(n + 1)
    if k:
        opening_parents(labels, depth, objs, z_mean, todo[:k], parent, ring_px, jump, min_share, focal_px)
    changed = False
    for i in range(n + 1):
        changed |= parent[i] != i
    if not changed:
        return np.zeros(0, np.int32)
    # each surface's root, the roots numbered 1..m in increasing order (np.unique's)
    roots = parent.copy()
    for i in range(n + 1):
        j = i
        while roots[j] != j:
            j = roots[j]
        roots[i] = j
    new = np.zeros(n + 1, np.int32)
    for i in range(1, n + 1):
        new[roots[i]] = 1
    m = 0
    for i in range(n + 1):
        if new[i]:
            m += 1
            new[i] = m
    out = np.empty(n + 1, np.int32)
    for i in range(n + 1):
        out[i] = new[roots[i]]
    return out


@njit(cache=True, nogil=True)
def opening_parents(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    objs: NDArray[np.int64],
    z_mean: NDArray[np.float64],
    todo: NDArray[np.intp],
    parent: NDArray[np.intp],
    ring_px: int,
    jump: float,
    min_share: float,
    focal_px: float,
) -> None:
    # the ring tests of merge_openings for each candidate R, in one compiled pass per R's box
    # (numpy and OpenCV: a dozen calls per R, most of the time at small sizes). The ring is
    # R's box dilated by ring_px (a square), without R, where there is a reading.
    h, w = labels.shape
    n = z_mean.size - 1
    cand = np.zeros(n + 1, np.int64)
    for r in todo:
        x0, y0, x1, y1 = objs[r, 0], objs[r, 1], objs[r, 2], objs[r, 3]
        ya, yb = max(0, y0 - ring_px), min(h, y1 + ring_px + 1)
        xa, xb = max(0, x0 - ring_px), min(w, x1 + ring_px + 1)
        bh, bw = yb - ya, xb - xa
        # square dilation by a summed-area table of R's pixels: a pixel is in the ring when the
        # square around it holds one (read only for pixels that are not R's, with a reading)
        sat = np.zeros((bh + 1, bw + 1), np.int32)
        for y in range(bh):
            acc = 0
            for x in range(bw):
                acc += labels[ya + y, xa + x] == r
                sat[y + 1, x + 1] = sat[y, x + 1] + acc
        zr = z_mean[r]
        n_ring = 0
        n_level = 0
        cand[:] = 0
        ring_own = np.empty(bh * bw, np.int32)
        ring_z = np.empty(bh * bw, np.float32)
        for y in range(bh):
            qa, qb = max(0, y - ring_px), min(bh, y + ring_px + 1)
            for x in range(bw):
                o = labels[ya + y, xa + x]
                z = depth[ya + y, xa + x]
                if o == r or not z > 0:
                    continue
                pa, pb = max(0, x - ring_px), min(bw, x + ring_px + 1)
                if sat[qb, pb] - sat[qa, pb] - sat[qb, pa] + sat[qa, pa] == 0:
                    continue
                ring_own[n_ring] = o
                ring_z[n_ring] = z
                n_ring += 1
                if o > 0:
                    cand[o] += 1
        if n_ring == 0:
            continue
        a = 0
        best = 0
        for i in range(1, n + 1):
            if cand[i] > best:
                best = cand[i]
                a = i
        if a == 0:
            continue
        on_a = np.empty(best, np.float32)
        k = 0
        for i in range(n_ring):
            if ring_own[i] == a:
                on_a[k] = ring_z[i]
                k += 1
            # ring pixels at R's own depth that are not A's: R would continue into something else
            elif abs(np.float64(ring_z[i]) - zr) <= jump:
                n_level += 1
        # the median of A's ring depths (a selection) last: the other tests are a few
        # operations and reject most candidates (58 -> 45 us on the 320 x 240 grid)
        if best / n_ring < min_share or n_level / n_ring > 0.15:
            continue
        ax0, ax1 = objs[a, 0], objs[a, 2]
        margin = 0.15 * (ax1 - ax0 + 1)
        if x0 < ax0 - margin or x1 > ax1 + margin:
            continue
        width_mm = (ax1 - ax0 + 1) * z_mean[a] / focal_px
        if zr - z_mean[a] > width_mm:
            continue
        # np.median of A's ring depths, in float32 as numpy takes it (the mean of the two
        # middle values of an even count)
        h2 = best // 2
        part = np.partition(on_a, h2)
        med = part[h2] if best % 2 else (part[:h2].max() + part[h2]) / np.float32(2.0)
        if med >= zr:
            continue
        parent[r] = a
