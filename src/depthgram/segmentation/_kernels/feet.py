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
def _add(sums: NDArray[np.float64], u: float, v: float, q: float) -> None:
    # the normal equations' sums of q = a u + b v + c: uu, uv, u, vv, v, 1, uq, vq, q
    sums[0] += u * u
    sums[1] += u * v
    sums[2] += u
    sums[3] += v * v
    sums[4] += v
    sums[5] += 1.0
    sums[6] += u * q
    sums[7] += v * q
    sums[8] += q


@njit(cache=True, nogil=True)
def _solve3(sums: NDArray[np.float64]) -> tuple[bool, float, float, float]:
    # q = a u + b v + c by least squares from the sums :func:`_add` gathers (Cramer's rule: a
    # 3 x 3 per fit, where LAPACK's call costs more than the solve)
    s_uu, s_uv, s_u, s_vv, s_v, s_1, s_uq, s_vq, s_q = sums
    det = s_uu * (s_vv * s_1 - s_v * s_v) - s_uv * (s_uv * s_1 - s_v * s_u) + s_u * (s_uv * s_v - s_vv * s_u)
    scale = s_uu * s_vv * s_1
    if scale <= 0.0 or abs(det) <= 1e-9 * scale:
        return False, 0.0, 0.0, 0.0
    a = (s_uq * (s_vv * s_1 - s_v * s_v) - s_uv * (s_vq * s_1 - s_v * s_q) + s_u * (s_vq * s_v - s_vv * s_q)) / det
    b = (s_uu * (s_vq * s_1 - s_q * s_v) - s_uq * (s_uv * s_1 - s_v * s_u) + s_u * (s_uv * s_q - s_vq * s_u)) / det
    c = (s_uu * (s_vv * s_q - s_v * s_vq) - s_uv * (s_uv * s_q - s_vq * s_u) + s_uq * (s_uv * s_v - s_vv * s_u)) / det
    return True, a, b, c


@njit(cache=True, nogil=True)
def _beside(labels: NDArray[np.int32], ok: NDArray[np.bool_], y: int, x: int, sid: int, oid: int) -> bool:
    # a reading of the support with one of the object's beside it (4-neighbours)
    if labels[y, x] != sid or not ok[y, x]:
        return False
    hgt, wid = labels.shape
    return bool(
        (y > 0 and labels[y - 1, x] == oid)
        or (y + 1 < hgt and labels[y + 1, x] == oid)
        or (x > 0 and labels[y, x - 1] == oid)
        or (x + 1 < wid and labels[y, x + 1] == oid)
    )


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
    sums = np.empty(9)
    for r in range(_ROUNDS):
        sums[:] = 0.0
        for k in range(n):
            if keep[k]:
                _add(sums, xs[k], ys[k], qs[k])
        if sums[5] < _MIN_RING:
            break
        found, a, b, c = _solve3(sums)
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
    ok: NDArray[np.bool_],
    oid: int,
    sid: int,
    seeds: tuple[int, int, int, int],
    chunk: int,
    radius: int,
) -> tuple[bool, NDArray[np.float64]]:
    """Fit the object's surface ``1000 / Z = a x + b y + c`` per chunk of its outline beside the support.

    The seeds' box (inclusive: the support's readings beside the object) is cut into chunks of
    ``chunk`` px along its longer side; each chunk's plane is fitted over the object's readings
    within ``radius`` of the chunk's own seeds' box (an outline running diagonally keeps its
    fits near it). Returns whether the chunks run along x, and per chunk ``(found, a, b, c)``
    in the frame's columns and rows.
    """
    hgt, wid = labels.shape
    bx0, by0, bx1, by1 = seeds
    along_x = bx1 - bx0 >= by1 - by0
    start, stop = (bx0, bx1) if along_x else (by0, by1)
    n = (stop - start) // chunk + 1
    # each chunk's seeds across the chunks' direction
    lo_across = np.full(n, 1 << 30, np.int64)
    hi_across = np.full(n, -1, np.int64)
    for y in range(by0, by1 + 1):
        for x in range(bx0, bx1 + 1):
            if _beside(labels, ok, y, x, sid, oid):
                k, across = ((x - start) // chunk, y) if along_x else ((y - start) // chunk, x)
                lo_across[k] = min(lo_across[k], across)
                hi_across[k] = max(hi_across[k], across)
    out = np.zeros((n, 4))
    sums = np.empty(9)
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
        sums[:] = 0.0
        for y in range(y0, y1 + 1):
            for x in range(x0, x1 + 1):
                if labels[y, x] == oid:
                    _add(sums, float(x - x0), float(y - y0), 1000.0 / depth[y, x])
        if sums[5] < _MIN_FACE:
            continue
        found, a, b, c = _solve3(sums)
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
def _seed_boxes(
    labels: NDArray[np.int32],
    ok: NDArray[np.bool_],
    supports: NDArray[np.int32],
    n_objects: int,
    objects: NDArray[np.bool_],
    boxes: NDArray[np.int64],
) -> NDArray[np.int64]:
    """Return per (object, support) the inclusive box of the support's readings beside the object (x0 > x1: none).

    A reading of a support with an object's reading beside it, looked for where the two boxes meet.
    """
    hgt, wid = labels.shape
    k = supports.size
    out = np.empty((n_objects + 1, k, 4), np.int64)
    out[:, :, 0] = wid
    out[:, :, 1] = hgt
    out[:, :, 2] = -1
    out[:, :, 3] = -1
    for j in range(k):
        sid = supports[j]
        for o in range(1, n_objects + 1):
            if not objects[o]:
                continue
            # a support's reading beside the object lies in both boxes, the object's grown by one
            x0, y0 = max(boxes[o, 0] - 1, boxes[sid, 0]), max(boxes[o, 1] - 1, boxes[sid, 1])
            x1, y1 = min(boxes[o, 2] + 1, boxes[sid, 2]), min(boxes[o, 3] + 1, boxes[sid, 3])
            b = out[o, j]
            for y in range(y0, y1 + 1):
                for x in range(x0, x1 + 1):
                    if _beside(labels, ok, y, x, sid, o):
                        b[0] = min(b[0], x)
                        b[1] = min(b[1], y)
                        b[2] = max(b[2], x)
                        b[3] = max(b[3], y)
    return out


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
    seeds = _seed_boxes(labels, ok, supports, n_objects, objects, boxes)
    moved = 0
    queue = np.empty((0, 3), np.int64)
    for j in range(supports.size):
        sid = supports[j]
        for oid in range(1, n_objects + 1):
            bx0, by0, bx1, by1 = seeds[oid, j, 0], seeds[oid, j, 1], seeds[oid, j, 2], seeds[oid, j, 3]
            if bx0 > bx1:
                continue
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
            along_x, planes = _chunk_planes(labels, depth, ok, oid, sid, (bx0, by0, bx1, by1), chunk, fit_radius)
            seen = np.zeros((ry1 - ry0 + 1, rx1 - rx0 + 1), np.bool_)
            if queue.shape[0] < seen.size:
                queue = np.empty((seen.size, 3), np.int64)
            head = tail = 0
            for y in range(by0, by1 + 1):
                for x in range(bx0, bx1 + 1):
                    if _beside(labels, ok, y, x, sid, oid):
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
