"""The compiled passes of the surface labeller (:mod:`depthgram.segmentation.surfaces`)."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label import ACTIVE, BLOCK
from depthgram.segmentation.label.stats import relabel_stats
from depthgram.segmentation.label.unionfind import resolve_tables
from depthgram.segmentation.label.unionfind import union as _union

#: Stand-ins for the statistics :func:`depthgram.segmentation.label.unionfind.resolve` does not read here.
NO_SUMS = np.zeros((1, 8), np.float64)
NO_BOXES = np.zeros((1, 4), np.int32)


@njit(cache=True, nogil=True)
def kept_table(
    lab: NDArray[np.int32], parent: NDArray[np.int32], nxt: int, pcount: NDArray[np.int64], min_px: int, seed_px: int
) -> tuple[NDArray[np.int32], NDArray[np.int64], NDArray[np.int32], NDArray[np.int64]]:
    # provisional label -> the final one resolve gives it (raster order of first pixels), or 0
    # for surfaces under min_px pixels (loosen_small); the pixels per final label (0 for the
    # loosened ones); provisional label -> final label of the loosened surfaces of seed_px
    # pixels or more, 0 elsewhere; and the pixels of those per final label (loosen_grow counts
    # down the ones it gives to other surfaces). The last two are one 0 when seed_px >= min_px.
    final, n, _, _ = resolve_tables(lab, parent, nxt, NO_SUMS, NO_BOXES, 0, False)
    count = np.zeros(n + 1, np.int64)
    for i in range(1, nxt):
        count[final[i]] += pcount[i]
    small = count < min_px
    small[0] = True
    table = np.zeros(nxt, np.int32)
    loosened = np.zeros(nxt if seed_px < min_px else 1, np.int32)
    for i in range(1, nxt):
        f = final[i]
        if not small[f]:
            table[i] = f
        elif seed_px < min_px and count[f] >= seed_px:
            loosened[i] = f
    left = np.zeros(n + 1 if seed_px < min_px else 1, np.int64)
    for i in range(n + 1):
        if small[i]:
            if seed_px < min_px and count[i] >= seed_px:
                left[i] = count[i]
            count[i] = 0
    return table, count, loosened, left


@njit(cache=True, nogil=True)
def loosen_grow(
    lab: NDArray[np.int32],
    table: NDArray[np.int32],
    facing: NDArray[np.bool_],
    depth: NDArray[np.float32],
    t0: float,
    t2: float,
    sl: float,
    max_steps: int,
    loosened: NDArray[np.int32],
    left: NDArray[np.int64],
    grower: NDArray[np.int32],
) -> None:
    # Hand-written: a breadth-first growth with a per-step depth test has no library kernel
    # (a distance transform finds the nearest label but cannot follow the surface).
    # loosen_small and reattach's growth on labels read through `table` (a pixel's label is
    # table[lab]; reattach passes final labels and the identity table): one pass marks the
    # loose pixels (facing, label 0) and queues the seeds (loose, beside a labelled pixel) in
    # raster order, then the breadth-first growth; a grown pixel takes its neighbour's label
    # in `lab`, which is the same label through the table. `lab` is written in place. With a
    # `loosened` table of more than one entry (kept_table's), a grown pixel of a loosened
    # surface counts down that surface's `left`. Only the surfaces with a label in `grower`
    # grow: `table` itself, or the part of it that restore_unclaimed restored.
    counting = loosened.size > 1
    h, w = lab.shape
    loose = np.zeros((h, w), np.bool_)
    pending = np.zeros((h, w), np.bool_)
    queue = np.empty(h * w + 1, np.int64)  # reserved only: pages past the queue's end stay untouched
    steps = np.empty(h * w + 1, np.int32)
    tail = 0
    for y in range(h):
        for x in range(w):
            if facing[y, x] and table[lab[y, x]] == 0:
                loose[y, x] = True
                if (
                    (x > 0 and grower[lab[y, x - 1]] > 0)
                    or (x < w - 1 and grower[lab[y, x + 1]] > 0)
                    or (y > 0 and grower[lab[y - 1, x]] > 0)
                    or (y < h - 1 and grower[lab[y + 1, x]] > 0)
                ):
                    queue[tail] = y * w + x
                    steps[tail] = 1
                    pending[y, x] = True
                    tail += 1
    head = 0
    while head < tail:
        p = queue[head]
        k = steps[head]
        head += 1
        y = p // w
        x = p - y * w
        z = depth[y, x]
        best = 0
        for d in range(4):
            yy = y + (1 if d == 0 else -1 if d == 1 else 0)
            xx = x + (1 if d == 2 else -1 if d == 3 else 0)
            if yy < 0 or yy >= h or xx < 0 or xx >= w or grower[lab[yy, xx]] == 0:
                continue
            zz = depth[yy, xx]
            zm = min(z, zz)
            if abs(z - zz) <= t0 + t2 * zm * zm + sl * zm:
                best = lab[yy, xx]
                break
        if best == 0:
            continue
        if counting:
            left[loosened[lab[y, x]]] -= 1
        lab[y, x] = best
        if k >= max_steps:
            continue
        for d in range(4):
            yy = y + (1 if d == 0 else -1 if d == 1 else 0)
            xx = x + (1 if d == 2 else -1 if d == 3 else 0)
            if 0 <= yy < h and 0 <= xx < w and loose[yy, xx] and table[lab[yy, xx]] == 0 and not pending[yy, xx]:
                pending[yy, xx] = True
                queue[tail] = yy * w + xx
                steps[tail] = k + 1
                tail += 1


@njit(cache=True, nogil=True)
def restore_unclaimed(
    table: NDArray[np.int32],
    loosened: NDArray[np.int32],
    count: NDArray[np.int64],
    left: NDArray[np.int64],
    seed_px: int,
) -> None:
    # after the growth: the pixels of a loosened surface that no surface took back (`left`)
    # are that surface again when there are seed_px of them; table and count in place
    left[0] = 0
    for i in range(loosened.size):
        f = loosened[i]
        if f > 0 and left[f] >= seed_px:
            table[i] = f
            count[f] = left[f]


@njit(cache=True, nogil=True)
def keep_through(
    lab: NDArray[np.int32], table: NDArray[np.int32], count: NDArray[np.int64], min_px: int, depth: NDArray[np.float32]
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    # keep_large of the labels table[lab], in the one relabelling pass of relabel_stats (numba's
    # cache of this function holds relabel_stats' code as it was compiled: a change there
    # reaches it when this file changes too)
    n = count.size - 1
    lut = np.zeros(n + 1, np.int32)
    m = 0
    for i in range(1, n + 1):
        if count[i] >= min_px:
            m += 1
            lut[i] = m
    through = np.empty(table.size, np.int32)
    for i in range(table.size):
        through[i] = lut[table[i]]
    out, sums, box = relabel_stats(lab, through, m, depth)
    return out, m, sums, box


@njit(cache=True, inline="always")
def _continuous(za: np.float32, zb: np.float32, gap: int, t0: float, t2: float, sl: float) -> bool:
    zm = min(za, zb)
    return bool(abs(za - zb) <= t0 + t2 * zm * zm + gap * sl * zm)


@njit(cache=True, nogil=True)
def label_surfaces(
    depth: NDArray[np.float32], state: NDArray[np.int8], t0: float, t2: float, sl: float, bridge: int
) -> tuple[NDArray[np.int32], NDArray[np.int32], int, NDArray[np.int64]]:
    # Hand-written: no library labels components under a depth-difference rule with hole
    # bridging (scipy and OpenCV label binary images). The first pass of a two-pass labeller:
    # a pixel continuing its left neighbour (the last active pixel of the row, across at most
    # `bridge` holes) takes its provisional label, one continuing the pixel above (the last
    # active one of the column) joins that label; only two different labels cost a union.
    # The components are those of a union-find over every continuous row and column pair (the
    # version before: a root search for both pixels of every pair), numbered by _resolve in
    # raster order of their first pixel as before.
    h, w = depth.shape
    lab = np.zeros((h, w), np.int32)
    parent = np.empty(h * w + 1, np.int32)  # reserved only: pages of unused labels stay untouched
    count = np.empty(h * w + 1, np.int64)  # pixels per provisional label, for surfaces_kept
    lastrow = np.full(w, -1, np.int64)
    nxt = 1
    for y in range(h):
        last = -1
        for x in range(w):
            s = state[y, x]
            if s == ACTIVE:
                z = depth[y, x]
                left = 0
                if last >= 0 and x - last - 1 <= bridge and _continuous(depth[y, last], z, x - last, t0, t2, sl):
                    left = lab[y, last]
                up = 0
                ly = lastrow[x]
                if ly >= 0 and y - ly - 1 <= bridge and _continuous(depth[ly, x], z, y - ly, t0, t2, sl):
                    up = lab[ly, x]
                if left == 0 and up == 0:
                    parent[nxt] = nxt
                    count[nxt] = 0
                    here = nxt
                    nxt += 1
                elif up == 0 or up == left:
                    here = left
                elif left == 0:
                    here = up
                else:
                    here = left
                    _union(parent, left, up)
                lab[y, x] = here
                count[here] += 1
                last = x
                lastrow[x] = y
            elif s == BLOCK:
                last = -1
                lastrow[x] = -1
    return lab, parent, nxt, count


@njit(cache=True, nogil=True)
def keep_counted(
    labels: NDArray[np.int32], count: NDArray[np.int64], min_px: int, depth: NDArray[np.float32]
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    # keep_large with the pixels per label already counted
    n = count.size - 1
    lut = np.zeros(n + 1, np.int32)
    m = 0
    for i in range(1, n + 1):
        if count[i] >= min_px:
            m += 1
            lut[i] = m
    out, sums, box = relabel_stats(labels, lut, m, depth)
    return out, m, sums, box


@njit(cache=True, nogil=True)
def count_labels(labels: NDArray[np.int32], n: int) -> NDArray[np.int64]:
    # pixels per label
    h, w = labels.shape
    count = np.zeros(n + 1, np.int64)
    for y in range(h):
        for x in range(w):
            count[labels[y, x]] += 1
    return count
