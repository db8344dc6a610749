"""The compiled pass of :mod:`depthgram.segmentation.feet`: each object's foot taken back from its support.

It reads only the supports' readings within a few pixels of the objects standing on them, and
per reading two small least-squares fits (the support's plane around the object, the object's
own surface around the reading) whose numpy calls would cost more than their arithmetic.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label.stats import COUNT, SUM_X, SUM_XZ, SUM_Y, SUM_YZ, SUM_Z, SUM_ZZ

#: rounds of the support's plane fit around an object: least squares, then a robust one
_ROUNDS = 2
#: readings the support's plane around an object needs
_MIN_RING = 30
#: readings the support's box around an object is sampled to (every t-th each way)
_RING_READINGS = 500
#: readings of the object the fit of its surface around a reading needs
_MIN_FACE = 6


@njit(cache=True, nogil=True)
def _solve3(
    s_uu: float, s_uv: float, s_u: float, s_vv: float, s_v: float, s_1: float, s_uq: float, s_vq: float, s_q: float
) -> tuple[bool, float, float, float]:
    # q = a u + b v + c by least squares from its normal equations' sums (Cramer's rule: a 3 x 3
    # per reading, where LAPACK's call costs more than the solve)
    det = s_uu * (s_vv * s_1 - s_v * s_v) - s_uv * (s_uv * s_1 - s_v * s_u) + s_u * (s_uv * s_v - s_vv * s_u)
    scale = s_uu * s_vv * s_1
    if scale <= 0.0 or abs(det) <= 1e-9 * scale:
        return False, 0.0, 0.0, 0.0
    a = (s_uq * (s_vv * s_1 - s_v * s_v) - s_uv * (s_vq * s_1 - s_v * s_q) + s_u * (s_vq * s_v - s_vv * s_q)) / det
    b = (s_uu * (s_vq * s_1 - s_q * s_v) - s_uq * (s_uv * s_1 - s_v * s_u) + s_u * (s_uv * s_q - s_vq * s_u)) / det
    c = (s_uu * (s_vv * s_q - s_v * s_vq) - s_uv * (s_uv * s_q - s_vq * s_u) + s_uq * (s_uv * s_v - s_vv * s_u)) / det
    return True, a, b, c


@njit(cache=True, nogil=True)
def _ring_plane(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    sid: int,
    inner: tuple[int, int, int, int],
    outer: tuple[int, int, int, int],
) -> tuple[bool, float, float, float]:
    """Fit the support's plane ``1000 / Z = a x + b y + c`` over its readings between two boxes (inclusive)."""
    x0, y0, x1, y1 = outer
    # every t-th reading each way: the plane of a few hundred readings is known far better than
    # a reading, and a long object's ring would hold thousands
    t = max(1, int(math.sqrt((x1 - x0 + 1) * (y1 - y0 + 1) / _RING_READINGS)))
    cap = ((y1 - y0) // t + 1) * ((x1 - x0) // t + 1)
    xs = np.empty(cap)
    ys = np.empty(cap)
    qs = np.empty(cap)
    n = 0
    for y in range(y0, y1 + 1, t):
        for x in range(x0, x1 + 1, t):
            if labels[y, x] == sid and ok[y, x] and not (inner[0] <= x <= inner[2] and inner[1] <= y <= inner[3]):
                xs[n] = x - x0
                ys[n] = y - y0
                qs[n] = 1000.0 / depth[y, x]
                n += 1
    if n < _MIN_RING:
        return False, 0.0, 0.0, 0.0
    xs, ys, qs = xs[:n], ys[:n], qs[:n]
    keep = np.ones(n, np.bool_)
    found, a, b, c = False, 0.0, 0.0, 0.0
    for r in range(_ROUNDS):
        s_uu = s_uv = s_u = s_vv = s_v = s_1 = s_uq = s_vq = s_q = 0.0
        for k in range(n):
            if keep[k]:
                u, v, q = xs[k], ys[k], qs[k]
                s_uu += u * u
                s_uv += u * v
                s_u += u
                s_vv += v * v
                s_v += v
                s_1 += 1.0
                s_uq += u * q
                s_vq += v * q
                s_q += q
        if s_1 < _MIN_RING:
            break
        found, a, b, c = _solve3(s_uu, s_uv, s_u, s_vv, s_v, s_1, s_uq, s_vq, s_q)
        if not found or r == _ROUNDS - 1:
            break
        # robust rounds: what lies on the ring but not on the table (another object's edge, a
        # shadow's flying readings) is cut at three deviations of the median's
        res = np.abs(qs - (a * xs + b * ys + c))
        cut = 3.0 * 1.4826 * np.median(res)
        for k in range(n):
            keep[k] = res[k] <= cut
    # back to the frame's columns and rows
    return found, a, b, c - a * x0 - b * y0


@njit(cache=True, nogil=True)
def _chunk_planes(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    oid: int,
    seeds: NDArray[np.int64],
    box: tuple[int, int, int, int],
    chunk: int,
    radius: int,
) -> tuple[bool, NDArray[np.float64]]:
    """Fit the object's surface ``1000 / Z = a x + b y + c`` per chunk of its outline beside the support.

    ``seeds`` (N, 2): the support's readings beside the object (row, column), ``box`` their
    inclusive box, cut into chunks of ``chunk`` px along its longer side; each chunk's plane is
    fitted over the object's readings within ``radius`` of the chunk's own seeds' box (an
    outline running diagonally keeps its fits near it). Returns whether the chunks run along
    x, and per chunk ``(found, a, b, c)`` in the frame's columns and rows.
    """
    hgt, wid = labels.shape
    bx0, by0, bx1, by1 = box
    along_x = bx1 - bx0 >= by1 - by0
    start, stop = (bx0, bx1) if along_x else (by0, by1)
    n = (stop - start) // chunk + 1
    # each chunk's seeds across the chunks' direction
    lo_across = np.full(n, 1 << 30, np.int64)
    hi_across = np.full(n, -1, np.int64)
    for i in range(seeds.shape[0]):
        y, x = seeds[i, 0], seeds[i, 1]
        k, across = ((x - start) // chunk, y) if along_x else ((y - start) // chunk, x)
        lo_across[k] = min(lo_across[k], across)
        hi_across[k] = max(hi_across[k], across)
    out = np.zeros((n, 4))
    for k in range(n):
        if hi_across[k] < 0:
            continue
        lo, hi = start + k * chunk - radius, min(start + (k + 1) * chunk - 1, stop) + radius
        if along_x:
            x0, x1 = max(lo, 0), min(hi, wid - 1)
            y0, y1 = max(lo_across[k] - radius, 0), min(hi_across[k] + radius, hgt - 1)
        else:
            x0, x1 = max(lo_across[k] - radius, 0), min(hi_across[k] + radius, wid - 1)
            y0, y1 = max(lo, 0), min(hi, hgt - 1)
        s_uu = s_uv = s_u = s_vv = s_v = s_1 = s_uq = s_vq = s_q = 0.0
        for y in range(y0, y1 + 1):
            v = float(y - y0)
            for x in range(x0, x1 + 1):
                if labels[y, x] == oid and depth[y, x] > 0:
                    u = float(x - x0)
                    q = 1000.0 / depth[y, x]
                    s_uu += u * u
                    s_uv += u * v
                    s_u += u
                    s_vv += v * v
                    s_v += v
                    s_1 += 1.0
                    s_uq += u * q
                    s_vq += v * q
                    s_q += q
        if s_1 < _MIN_FACE:
            continue
        found, a, b, c = _solve3(s_uu, s_uv, s_u, s_vv, s_v, s_1, s_uq, s_vq, s_q)
        if found:
            out[k, 0], out[k, 1], out[k, 2], out[k, 3] = 1.0, a, b, c - a * x0 - b * y0
    return along_x, out


@njit(cache=True, nogil=True)
def _move(sums: NDArray[np.float64], src: int, dst: int, x: float, y: float, z: float) -> None:
    # one reading's statistics from one row to another, as the labelling pass sums them (float32 depth)
    sums[src, COUNT] -= 1.0
    sums[dst, COUNT] += 1.0
    sums[src, SUM_Z] -= z
    sums[dst, SUM_Z] += z
    sums[src, SUM_ZZ] -= z * z
    sums[dst, SUM_ZZ] += z * z
    sums[src, SUM_X] -= x
    sums[dst, SUM_X] += x
    sums[src, SUM_Y] -= y
    sums[dst, SUM_Y] += y
    sums[src, SUM_XZ] -= x * z
    sums[dst, SUM_XZ] += x * z
    sums[src, SUM_YZ] -= y * z
    sums[dst, SUM_YZ] += y * z


@njit(cache=True, nogil=True)
def _seeds(
    labels: NDArray[np.int32],
    ok: NDArray[np.bool_],
    supports: NDArray[np.int32],
    n_objects: int,
    objects: NDArray[np.bool_],
    boxes: NDArray[np.int64],
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Return the supports' readings beside the objects (N, 2: row, column) and where each pair's run is.

    ``runs[o, j]`` is ``(first, stop)`` of object ``o`` beside support ``supports[j]``. A
    reading of the support with one of the object's beside it (4-neighbours) lies where the
    support's box and the object's, grown by one, meet: only there is it looked for.
    """
    hgt, wid = labels.shape
    k = supports.size
    runs = np.zeros((n_objects + 1, k, 2), np.int64)
    meets = np.zeros((n_objects + 1, k, 4), np.int64)
    size = 0
    for j in range(k):
        sid = supports[j]
        for o in range(1, n_objects + 1):
            x0, y0 = max(boxes[o, 0] - 1, boxes[sid, 0]), max(boxes[o, 1] - 1, boxes[sid, 1])
            x1, y1 = min(boxes[o, 2] + 1, boxes[sid, 2]), min(boxes[o, 3] + 1, boxes[sid, 3])
            if objects[o] and x0 <= x1 and y0 <= y1:
                meets[o, j, 0], meets[o, j, 1], meets[o, j, 2], meets[o, j, 3] = x0, y0, x1, y1
                size += (x1 - x0 + 1) * (y1 - y0 + 1)
            else:
                meets[o, j, 0] = 1
                meets[o, j, 2] = 0
    pix = np.empty((size, 2), np.int64)
    n = 0
    for j in range(k):
        sid = supports[j]
        for o in range(1, n_objects + 1):
            runs[o, j, 0] = n
            for y in range(meets[o, j, 1], meets[o, j, 3] + 1):
                for x in range(meets[o, j, 0], meets[o, j, 2] + 1):
                    if labels[y, x] != sid or not ok[y, x]:
                        continue
                    for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                        yy, xx = y + dy, x + dx
                        if 0 <= yy < hgt and 0 <= xx < wid and labels[yy, xx] == o:
                            pix[n, 0], pix[n, 1] = y, x
                            n += 1
                            break
            runs[o, j, 1] = n
    return pix[:n], runs


@njit(cache=True, nogil=True)
def feet(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    supports: NDArray[np.int32],
    n_objects: int,
    min_px: float,
    reach: int,
    fit_radius: int,
    noise: tuple[float, float, float, float, float],
    sums: NDArray[np.float64],
    boxes: NDArray[np.int64],
) -> int:
    """Give each object the readings of its foot its supports hold; return how many moved (in place).

    ``labels``: objects 1..``n_objects``, then supports; ``supports`` the ids read. ``noise``:
    ``(sigma_0, sigma_2, step_0, step_2, k_sigma)`` of the sensor model (mm, 1/mm). ``sums``
    and ``boxes`` (inclusive) are the statistics table's, kept in step.
    """
    hgt, wid = labels.shape
    s0, s2, q0, q2, k_sigma = noise
    objects = np.zeros(n_objects + 1, np.bool_)
    for o in range(1, n_objects + 1):
        objects[o] = sums[o, COUNT] >= min_px
    pix, runs = _seeds(labels, ok, supports, n_objects, objects, boxes)
    moved = 0
    queue = np.empty((0, 3), np.int64)
    for j in range(supports.size):
        sid = supports[j]
        for oid in range(1, n_objects + 1):
            first, stop = runs[oid, j, 0], runs[oid, j, 1]
            if first == stop:
                continue
            seeds = pix[first:stop]
            bx0, bx1 = seeds[:, 1].min(), seeds[:, 1].max()
            by0, by1 = seeds[:, 0].min(), seeds[:, 0].max()
            # the region read: the reach around the readings beside the object
            rx0, ry0 = max(bx0 - reach, 0), max(by0 - reach, 0)
            rx1, ry1 = min(bx1 + reach, wid - 1), min(by1 + reach, hgt - 1)
            far = 3 * reach
            found, pa, pb, pc = _ring_plane(
                labels,
                depth,
                ok,
                sid,
                (rx0, ry0, rx1, ry1),
                (max(bx0 - far, 0), max(by0 - far, 0), min(bx1 + far, wid - 1), min(by1 + far, hgt - 1)),
            )
            if not found:
                continue
            chunk = reach
            along_x, planes = _chunk_planes(labels, depth, oid, seeds, (bx0, by0, bx1, by1), chunk, fit_radius)
            seen = np.zeros((ry1 - ry0 + 1, rx1 - rx0 + 1), np.bool_)
            if queue.shape[0] < seen.size:
                queue = np.empty((seen.size, 3), np.int64)
            head = tail = 0
            for i in range(seeds.shape[0]):
                y, x = seeds[i, 0], seeds[i, 1]
                # a reading moved to an object before this one is no longer the support's
                if labels[y, x] == sid:
                    seen[y - ry0, x - rx0] = True
                    queue[tail, 0], queue[tail, 1], queue[tail, 2] = y, x, 1
                    tail += 1
            while head < tail:
                y, x, d = queue[head, 0], queue[head, 1], queue[head, 2]
                head += 1
                z = float(depth[y, x])
                on_plane = 1000.0 / max(pa * x + pb * y + pc, 1e-12)
                # a foot stands above the support by more than the noise, and the object's own
                # surface continued to it explains it better than the support's plane
                if on_plane - z <= k_sigma * (s0 + s2 * z * z) + q0 + q2 * z * z:
                    continue
                k = min(max(((x - bx0) if along_x else (y - by0)) // chunk, 0), planes.shape[0] - 1)
                q = planes[k, 1] * x + planes[k, 2] * y + planes[k, 3]
                if planes[k, 0] == 0.0 or q <= 0.0 or abs(1000.0 / q - z) >= on_plane - z:
                    continue
                labels[y, x] = oid
                moved += 1
                _move(sums, sid, oid, float(x), float(y), z)
                boxes[oid, 0] = min(boxes[oid, 0], x)
                boxes[oid, 1] = min(boxes[oid, 1], y)
                boxes[oid, 2] = max(boxes[oid, 2], x)
                boxes[oid, 3] = max(boxes[oid, 3], y)
                if d >= reach:
                    continue
                for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                    yy, xx = y + dy, x + dx
                    if not (ry0 <= yy <= ry1 and rx0 <= xx <= rx1) or seen[yy - ry0, xx - rx0]:
                        continue
                    if labels[yy, xx] == sid and ok[yy, xx]:
                        seen[yy - ry0, xx - rx0] = True
                        queue[tail, 0], queue[tail, 1], queue[tail, 2] = yy, xx, d + 1
                        tail += 1
    return moved


@njit(cache=True, nogil=True)
def take_back(
    labels: NDArray[np.int32],
    before: NDArray[np.int32],
    origin: tuple[int, int],
    dropped: NDArray[np.bool_],
    depth: NDArray[np.float32],
    sums: NDArray[np.float64],
) -> int:
    """Undo the objects in ``dropped``: their feet go back to their supports, their own readings to 0.

    ``before`` is the label map's box at ``origin`` (row, column) as it was before the feet
    were given, holding every reading of those objects. ``sums`` follows (in place); the rows
    of the dropped objects end at 0. Returns the readings moved.
    """
    y0, x0 = origin
    hgt, wid = before.shape
    moved = 0
    for i in range(hgt):
        y = y0 + i
        row, old = labels[y], before[i]
        for j in range(wid):
            o = row[x0 + j]
            if o >= dropped.size or not dropped[o]:
                continue
            s = old[j]
            if s != o:
                x = x0 + j
                row[x] = s
                _move(sums, o, s, float(x), float(y), float(depth[y, x]))
            else:
                row[x0 + j] = 0
            moved += 1
    for o in range(dropped.size):
        if dropped[o]:
            sums[o, :] = 0.0
    return moved
