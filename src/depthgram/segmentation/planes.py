"""Dominant support planes of any orientation: table tops and floors seen from above at a slant.

The orientation classes of :mod:`depthgram.segmentation.orientation` are taken against the camera's
axes, which suits a level camera. A camera looking down at a table at 45 degrees sees the table
top with its normal 45 degrees from every image axis, so it comes out facing, and the table with
everything on it is one object. Any plane, however oriented, has an inverse depth exactly affine
in pixel coordinates under a pinhole camera::

    1/Z = a u + b v + c

so the dominant planes are found by a robust fit of that affine model (RANSAC over a subsample
of valid pixels, then a least-squares refit on the inliers) without any intrinsics. A plane is a
support when it is large and oblique (its depth spreads over its extent); a fronto-parallel plane
such as a back wall is a facing object in the paper's model.

The same model fitted by least squares to labelled pieces (:func:`plane_sums`,
:func:`planes_from_sums`) gives the plane of each support of the slicing method; pieces of one
plane cut apart by occluders are joined (:func:`coplanar_groups`), and pixels lying on a
support's plane near it are found (:func:`near_planes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.order_stats import percentile32

__all__ = [
    "Plane",
    "coplanar_groups",
    "find_planes",
    "join_near",
    "near_planes",
    "plane_distance_mm",
    "plane_normal",
    "plane_residual_mask",
    "plane_sums",
    "plane_sums_in_boxes",
    "planes_from_sums",
    "sample_points",
]


@dataclass(frozen=True)
class Plane:
    """One support plane found by :func:`find_planes`.

    Attributes
    ----------
    coef : tuple of float
        ``(a, b, c)`` of ``1000 / Z = a u + b v + c`` with ``u`` the column and ``v`` the row (px)
        and Z in mm (so the left side is in 1/m).
    inliers : ndarray of bool, shape (H, W)
        Pixels on the plane that belong to its large connected pieces.
    area : int
        Number of inlier pixels.
    spread : float
        Depth spread over the inliers: (95th - 5th percentile) / median depth.
    """

    coef: tuple[float, float, float]
    inliers: NDArray[np.bool_]
    area: int
    spread: float


def plane_normal(coef: tuple[float, float, float], cam: Intrinsics) -> NDArray[np.float64]:
    """Return the unit normal (camera frame: x right, y down, z forward) of a plane, turned toward the sensor.

    With normalised coordinates ``u' = (u - cx) / fx``: ``1/Z = a fx u' + b fy v' + (c + a cx +
    b cy)``; for a plane ``n . P = d`` this is ``-(n . ray) / d``, so ``n`` is minus that vector.
    """
    a, b, c = coef
    vec = np.array([a * cam.fx, b * cam.fy, c + a * cam.cx + b * cam.cy])
    return -vec / max(float(np.linalg.norm(vec)), 1e-15)


def plane_distance_mm(coef: tuple[float, float, float], cam: Intrinsics) -> float:
    """Distance (mm) from the camera centre to the plane: ``1000 / |(a fx, b fy, c + a cx + b cy)|``."""
    a, b, c = coef
    vec = np.array([a * cam.fx, b * cam.fy, c + a * cam.cx + b * cam.cy])
    return 1000.0 / max(float(np.linalg.norm(vec)), 1e-15)


def plane_residual_mask(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    coef: tuple[float, float, float],
    *,
    tol_mm: float,
    tol_rel: float,
    step: int = 1,
) -> NDArray[np.bool_]:
    """Return the valid pixels within ``max(tol_mm, tol_rel Z)`` of the plane's predicted depth.

    ``step`` > 1: the image is every ``step``-th pixel of every ``step``-th row of the frame the
    plane was fitted in (coefficients in full-frame pixels).
    """
    h, w = depth_mm.shape
    a, b, c = coef
    cols = np.arange(w, dtype=np.float32) * np.float32(step)
    rows = np.arange(h, dtype=np.float32) * np.float32(step)
    inv = (np.float32(a) * cols[None, :] + np.float32(b) * rows[:, None]) + np.float32(c)
    z = depth_mm
    # |Z - Zp| <= tol  <=>  |1000 - Z inv| <= tol * inv, with inv = 1000 / Zp > 0 (no division)
    tol = np.maximum(np.float32(tol_mm), np.float32(tol_rel) * z)
    out: NDArray[np.bool_] = valid & (inv > 0) & (np.abs(np.float32(1000.0) - z * inv) <= tol * inv)
    return out


def _fit(u: NDArray[np.float64], v: NDArray[np.float64], inv: NDArray[np.float64]) -> tuple[float, float, float]:
    a = np.stack([u, v, np.ones_like(u)], axis=1)
    coef = np.linalg.lstsq(a, inv, rcond=None)[0]
    return float(coef[0]), float(coef[1]), float(coef[2])


def find_planes(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    *,
    min_area: float = 0.08,
    min_spread: float = 0.15,
    tol_mm: float = 8.0,
    tol_rel: float = 0.012,
    max_planes: int = 3,
    hypotheses: int = 128,
    sample_step: int | None = None,
    seed: int = 0,
    search: NDArray[np.bool_] | None = None,
) -> list[Plane]:
    """Return the dominant oblique planes of a depth image, largest first.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid.
    valid : ndarray of bool
        Pixels with a reading.
    min_area : float
        Smallest plane kept, as a fraction of the frame's pixels (0..1).
    min_spread : float
        Smallest depth spread (5th to 95th percentile over the median depth) of an oblique plane;
        flatter planes face the sensor and are left to the histogram.
    tol_mm, tol_rel : float
        A pixel lies on a plane when its depth is within ``max(tol_mm, tol_rel Z)`` mm of it.
    max_planes : int
        Most planes searched for.
    hypotheses : int
        RANSAC hypotheses (three-point samples) per plane.
    sample_step : int, optional
        The search runs on every ``sample_step``-th pixel of every ``sample_step``-th row; by
        default the step that leaves about 3000 pixels.
    seed : int
        Seed of the random samples (deterministic results).
    search : ndarray of bool, optional
        Pixels where planes are looked for (default: all valid ones); a plane found there then
        takes every valid pixel on it near its pieces.

    Returns
    -------
    list of Plane
    """
    h, w = depth_mm.shape
    min_px = max(int(min_area * h * w), 3)
    # about 3000 grid points whatever the frame size: the search costs the same at 176 x 132
    # and 640 x 480, and only the final inlier test runs at full resolution
    s = sample_step or max(1, round(math.sqrt(h * w / 3000.0)))
    rng = np.random.default_rng(seed)
    z_sub = np.ascontiguousarray(depth_mm[::s, ::s], dtype=np.float32)
    # the grid's own pixels only, not a full-frame `valid & search`
    left = np.ascontiguousarray(valid[::s, ::s] if search is None else valid[::s, ::s] & search[::s, ::s])
    min_sub = min_px / (s * s)
    t_mm, t_rel = np.float32(tol_mm), np.float32(tol_rel)
    found: list[tuple[tuple[float, float, float], NDArray[np.bool_], float]] = []
    # each search's steps are compiled (numpy's calls on a few thousand points cost more than
    # their arithmetic); the random draws, the solves and the refit stay numpy's, so the planes
    # are those of the numpy route (docs/design-notes.md, "RANSAC")
    for _ in range(max_planes * 2):
        if len(found) >= max_planes:
            break
        u, v, z, tz = _grid_points(z_sub, left, s, t_mm, t_rel)
        if u.size < max(min_sub, 3):
            break
        coef = _ransac(u, v, 1000.0 / z, z, tz, hypotheses, rng)
        if coef is None:
            break
        uo, vo, qo = _inliers(u, v, z, tz, coef[0], coef[1], coef[2])
        if uo.size < min_sub:
            break
        coef = _fit(uo, vo, qo)
        on_img = _take_residual(z_sub, left, coef[0], coef[1], coef[2], t_mm, t_rel, np.float32(s))
        pieces = _large_pieces(on_img, max(int(min_sub) // 4, 1))
        n_on = int(np.count_nonzero(pieces))
        if n_on < min_sub:
            continue
        # np.percentile(z_sub[pieces], (5, 50, 95)), compiled: the same values
        on_z = z_sub[pieces]
        p5, p50, p95 = (percentile32(on_z, q, False) for q in (5.0, 50.0, 95.0))
        spread = float((p95 - p5) / max(p50, 1e-6))
        if spread < min_spread:
            continue  # a fronto-parallel plane (a back wall) is a facing object, not a support
        found.append((coef, pieces, spread))
    if not found:
        return []
    coefs = np.array([c for c, _, _ in found], np.float64)
    # a full-resolution pixel may join a plane when its grid cell or a neighbouring one did:
    # the contact rows at the foot of an object are kept, far pixels on the plane's extension not
    kernel = np.ones((3, 3), np.uint8)
    allowed = np.stack([np.asarray(cv2.dilate(m.view(np.uint8), kernel), np.uint8) for _, m, _ in found])
    which = _assign(depth_mm, valid, coefs, allowed, s, float(tol_mm), float(tol_rel))
    planes: list[Plane] = []
    for k, (coef, _, spread) in enumerate(found, start=1):
        mask = which == k
        area = int(np.count_nonzero(mask))
        if area >= min_px:
            planes.append(Plane(coef, mask, area, spread))
    return planes


@njit(cache=True, nogil=True)
def _assign(
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


def _ransac(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    inv: NDArray[np.float64],
    z: NDArray[np.float64],
    tol: NDArray[np.float64],
    hypotheses: int,
    rng: np.random.Generator,
) -> tuple[float, float, float] | None:
    """Best three-point hypothesis of ``1/Z = a u + b v + c``, scored on at most 2000 points."""
    n = u.size
    pick = rng.integers(0, n, size=(hypotheses, 3))
    a, good = _hypotheses(u, v, pick)
    if not good.any():
        return None
    coef = np.asarray(np.linalg.solve(a[good], inv[pick[good]][..., None])[..., 0], np.float64)
    m = min(n, 2000)
    ev = rng.integers(0, n, size=m) if n > m else np.arange(n)
    best = coef[_best_hypothesis(coef, u, v, z, tol, ev)]
    return float(best[0]), float(best[1]), float(best[2])


@njit(cache=True, nogil=True)
def _hypotheses(
    u: NDArray[np.float64], v: NDArray[np.float64], pick: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    # the 3 x 3 systems [u v 1] of the three-point samples, and which have a solution. The
    # points lie on the integer pixel grid, so the determinant is an integer, exact here;
    # numpy's LU determinant (the numpy route's test |det| > 1e-6) is within 1e-9 of it
    m = pick.shape[0]
    a = np.empty((m, 3, 3), np.float64)
    good = np.empty(m, np.bool_)
    for k in range(m):
        for i in range(3):
            a[k, i, 0] = u[pick[k, i]]
            a[k, i, 1] = v[pick[k, i]]
            a[k, i, 2] = 1.0
        du1 = a[k, 1, 0] - a[k, 0, 0]
        dv1 = a[k, 1, 1] - a[k, 0, 1]
        du2 = a[k, 2, 0] - a[k, 0, 0]
        dv2 = a[k, 2, 1] - a[k, 0, 1]
        good[k] = du1 * dv2 - du2 * dv1 != 0.0
    return a, good


@njit(cache=True, nogil=True)
def _best_hypothesis(
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
    best = -1
    arg = 0
    for k in range(coef.shape[0]):
        a, b, c = coef[k, 0], coef[k, 1], coef[k, 2]
        cnt = 0
        for i in range(m):
            inv = a * ue[i] + b * ve[i] + c
            cnt += (inv > 0) & (abs(1000.0 - ze[i] * inv) <= te[i] * inv)
        if cnt > best:
            best = cnt
            arg = k
    return arg


@njit(cache=True, nogil=True)
def _grid_points(
    z_sub: NDArray[np.float32], left: NDArray[np.bool_], step: int, tol_mm: np.float32, tol_rel: np.float32
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    # column and row (full-frame px), depth (mm) and tolerance (mm) of the grid points still
    # searched, in raster order: numpy's flatnonzero and four gathers, with the tolerance of
    # its float32 np.maximum(tol_mm, tol_rel * z)
    h, w = z_sub.shape
    n = 0
    for y in range(h):
        for x in range(w):
            n += left[y, x]
    u = np.empty(n, np.float64)
    v = np.empty(n, np.float64)
    z = np.empty(n, np.float64)
    tz = np.empty(n, np.float64)
    k = 0
    for y in range(h):
        for x in range(w):
            if left[y, x]:
                zz = z_sub[y, x]
                u[k] = x * step
                v[k] = y * step
                z[k] = zz
                tz[k] = max(tol_mm, tol_rel * zz)
                k += 1
    return u, v, z, tz


@njit(cache=True, nogil=True)
def _inliers(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    z: NDArray[np.float64],
    tol: NDArray[np.float64],
    a: float,
    b: float,
    c: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    # u, v and 1000 / z of the points on the plane, by numpy's float64 test
    # (inv > 0) & (|1000 - z inv| <= tol inv) with inv = a u + b v + c
    n = u.size
    on = np.zeros(n, np.bool_)
    m = 0
    for i in range(n):
        inv = a * u[i] + b * v[i] + c
        if inv > 0 and abs(1000.0 - z[i] * inv) <= tol[i] * inv:
            on[i] = True
            m += 1
    uo = np.empty(m, np.float64)
    vo = np.empty(m, np.float64)
    qo = np.empty(m, np.float64)
    k = 0
    for i in range(n):
        if on[i]:
            uo[k] = u[i]
            vo[k] = v[i]
            qo[k] = 1000.0 / z[i]
            k += 1
    return uo, vo, qo


@njit(cache=True, nogil=True)
def _take_residual(
    z: NDArray[np.float32],
    left: NDArray[np.bool_],
    a: float,
    b: float,
    c: float,
    tol_mm: np.float32,
    tol_rel: np.float32,
    step: np.float32,
) -> NDArray[np.bool_]:
    # plane_residual_mask(z, left, (a, b, c), step=step) in one pass, and its pixels taken out
    # of `left` (in place): the same float32 operations in the same order
    h, w = z.shape
    out = np.zeros((h, w), np.bool_)
    a32, b32, c32 = np.float32(a), np.float32(b), np.float32(c)
    thousand = np.float32(1000.0)
    for y in range(h):
        bv = b32 * (np.float32(y) * step)
        for x in range(w):
            if not left[y, x]:
                continue
            inv = (a32 * (np.float32(x) * step) + bv) + c32
            zz = z[y, x]
            tol = max(tol_mm, tol_rel * zz)
            if inv > 0 and abs(thousand - zz * inv) <= tol * inv:
                out[y, x] = True
                left[y, x] = False
    return out


def _large_pieces(mask: NDArray[np.bool_], min_px: int) -> NDArray[np.bool_]:
    """Pixels of the 8-connected pieces of ``mask`` of at least ``min_px`` pixels.

    A far object that happens to cross the plane's extension makes small pieces; the support
    itself is large even when the objects standing on it cut it apart.
    """
    _, lab, stats, _ = cv2.connectedComponentsWithStats(mask.view(np.uint8), connectivity=8)
    keep = stats[:, cv2.CC_STAT_AREA] >= min_px
    keep[0] = False
    out: NDArray[np.bool_] = keep[lab]
    return out


# Least-squares planes of labelled pieces (the supports of the slicing method)


@njit(cache=True, inline="always")
def flush_plane_run(
    out: NDArray[np.float64], i: int, v: float, c: float, su: float, suu: float, sq: float, suq: float
) -> None:
    """Add one run of label ``i`` along a row at ``v' = v`` to the plane sums of :func:`plane_sums`.

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


@njit(cache=True, nogil=True)
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
    # run (v is constant along a row, so its terms are v times the run's sums) instead of
    # adding nine values into the table at every pixel. With `use_want`, runs of labels
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
            flush_plane_run(out, i, v, c, su, suu, sq, suq)
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


def plane_sums_in_boxes(
    labels: NDArray[np.int32],
    n: int,
    ids: NDArray[np.intp],
    boxes: NDArray[np.int64],
    depth_mm: NDArray[np.float32],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
) -> NDArray[np.float64]:
    """:func:`plane_sums` of the labels ``ids`` only, reading each one's box alone.

    ``boxes`` (k, 4) are the inclusive (x0, y0, x1, y1) of ``ids``, which must hold every
    pixel of the label. The rows of ``ids`` are those of ``plane_sums(..., only=...)`` to the
    last bit (the same runs, added in the same order); the others stay 0. A few supports
    among many objects cover a fraction of the frame.
    """
    return _plane_sums_boxes(
        np.ascontiguousarray(labels, np.int32),
        int(n),
        np.ascontiguousarray(ids, np.intp),
        np.ascontiguousarray(boxes, np.int64),
        np.ascontiguousarray(depth_mm, np.float32),
        float(fx),
        float(fy),
        float(cx),
        float(cy),
    )


@njit(cache=True, nogil=True)
def _plane_sums_boxes(
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
    # _plane_sums for one label at a time inside its box: the label's runs are the same, and
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


def sample_points(depth_mm: NDArray[np.float32], step: int, cam: Intrinsics) -> NDArray[np.float64]:
    """Camera coordinates (mm), shape (3, N), of every ``step``-th pixel of every ``step``-th row with a reading.

    In raster order: x = (u - cx) / fx * Z, y = (v - cy) / fy * Z, Z, with (u, v) the pixel.
    """
    return _sample_points(np.asarray(depth_mm, np.float32), int(step), cam.fx, cam.fy, cam.cx, cam.cy)


@njit(cache=True, nogil=True)
def _sample_points(
    depth: NDArray[np.float32], step: int, fx: float, fy: float, cx: float, cy: float
) -> NDArray[np.float64]:
    # (3, N) camera coordinates (mm) of every `step`-th pixel of every `step`-th row with a
    # reading, in raster order: numpy's nonzero, gather and three products in one pass, the
    # same float64 operations
    zs = depth[::step, ::step]
    h, w = zs.shape
    m = 0
    for y in range(h):
        for x in range(w):
            m += zs[y, x] > 0
    pts = np.empty((3, m), np.float64)
    k = 0
    for y in range(h):
        for x in range(w):
            if zs[y, x] > 0:
                zz = np.float64(zs[y, x])
                pts[0, k] = (np.float64(x * step) - cx) / fx * zz
                pts[1, k] = (np.float64(y * step) - cy) / fy * zz
                pts[2, k] = zz
                k += 1
    return pts


#: Stand-in for a missing ``only`` table of :func:`plane_sums` (numba wants an array).
_NO_WANT = np.ones(1, np.bool_)


def planes_from_sums(sums: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return unit normals, offsets (mm) and pixel counts from the sums of :func:`plane_sums` (row 0 unused).

    The sums are additive, so the plane of a union of pieces comes from the sum of their rows
    without another pass over the image.
    """
    m = sums.shape[0]
    ata = np.empty((m, 3, 3))
    ata[:, 0, 0], ata[:, 0, 1], ata[:, 0, 2] = sums[:, 0], sums[:, 1], sums[:, 2]
    ata[:, 1, 0], ata[:, 1, 1], ata[:, 1, 2] = sums[:, 1], sums[:, 3], sums[:, 4]
    ata[:, 2, 0], ata[:, 2, 1], ata[:, 2, 2] = sums[:, 2], sums[:, 4], sums[:, 5]
    atb = sums[:, 6:9].copy()
    ata[0] = np.eye(3)
    atb[0] = (0.0, 0.0, 1.0)
    ata += np.eye(3) * 1e-12
    coef = np.linalg.solve(ata, atb[..., None])[..., 0]
    norm = np.maximum(np.linalg.norm(coef, axis=1), 1e-15)
    return -coef / norm[:, None], 1.0 / norm, sums[:, 5]


def coplanar_groups(
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    *,
    max_angle_deg: float = 10.0,
    max_offset_rel: float = 0.08,
    min_fit_px: int = 1,
) -> tuple[NDArray[np.int32], int]:
    """Join pieces of one plane cut apart by occluders (the floor between two boxes).

    Pieces join when their normals (from :func:`planes_from_sums`) agree within
    ``max_angle_deg`` and their plane offsets within ``max_offset_rel``. Pieces under
    ``min_fit_px`` pixels are left alone: a few rows give no reliable plane (a cup's rim would
    join the table top).

    Returns
    -------
    lut : ndarray of int32, shape (n + 1,)
        Piece -> group (row 0 maps to 0); groups are numbered 1..m in the order of their first
        piece.
    m : int
        Number of groups.
    """
    n = normal.shape[0] - 1
    ident = np.arange(n + 1, dtype=np.int32)
    # only pieces big enough for a reliable plane can join: compare those alone (a few),
    # not all pairs of pieces (hundreds of noise specks)
    big = np.flatnonzero(count >= min_fit_px)
    big = big[big > 0]
    if big.size < 2:
        return ident, n
    nb, ob = normal[big], off[big]
    same_dir = nb @ nb.T > math.cos(math.radians(max_angle_deg))
    close = np.abs(ob[:, None] - ob[None, :]) <= max_offset_rel * np.maximum(ob[:, None], ob[None, :])
    join = np.triu(same_dir & close, 1)
    if not join.any():
        return ident, n
    lut, m = _join_groups(join, big.astype(np.intp), n)
    return lut, int(m)


@njit(cache=True, nogil=True)
def _join_groups(join: NDArray[np.bool_], big: NDArray[np.intp], n: int) -> tuple[NDArray[np.int32], int]:
    # union of the joined pairs (the smaller root becomes the root), then the groups numbered
    # 1..m in the order of their smallest piece (np.unique of the roots); pieces 0..n. A Python
    # loop over every piece (hundreds of noise specks on a real frame) cost more than the rest.
    parent = np.arange(n + 1)
    k = join.shape[0]
    for i in range(k):
        for j in range(k):
            if not join[i, j]:
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
    return lut, m


def near_planes(
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    boxes: NDArray[np.int64],
    depth_mm: NDArray[np.float32],
    candidates: NDArray[np.bool_],
    cam: Intrinsics,
    *,
    min_px: int,
    tol_rel: float,
) -> NDArray[np.bool_]:
    """Candidate pixels whose depth lies on the plane of a support of >= ``min_px`` pixels.

    ``normal``, ``off`` (mm), ``count`` and inclusive ``boxes`` per support (row 0 unused), as
    :func:`planes_from_sums` and the labellers give them. Only pixels inside the support's box
    grown by a tenth are tested, so a far object that happens to lie on the plane's extension
    elsewhere is not taken; a pixel is on the plane when ``|Z / Z_plane - 1| <= tol_rel``.
    """
    out = np.zeros(depth_mm.shape, bool)
    ids = np.flatnonzero(count >= min_px)
    ids = ids[ids > 0]
    if ids.size:
        _near(out, ids, normal, off, boxes, depth_mm, candidates, cam.fx, cam.fy, cam.cx, cam.cy, float(tol_rel))
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _near(
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
        bx0, by0, bx1, by1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        my = (by1 - by0 + 1) // 10 + 1
        mx = (bx1 - bx0 + 1) // 10 + 1
        y0, y1 = max(by0 - my, 0), min(by1 + 1 + my, h)
        x0, x1 = max(bx0 - mx, 0), min(bx1 + 1 + mx, w)
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


def join_near(
    classes: NDArray[np.int8],
    valid: NDArray[np.bool_],
    cls: int,
    facing: int,
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    boxes: NDArray[np.int64],
    depth_mm: NDArray[np.float32],
    cam: Intrinsics,
    *,
    min_px: int,
    tol_rel: float,
) -> int:
    """Give class ``cls`` (in place) to the pixels :func:`near_planes` finds; return how many.

    The candidates are the valid pixels of class ``facing``: the result is that of
    ``near = near_planes(..., valid & (classes == facing), ...)`` followed by
    ``classes[near] = cls``, in one pass over the supports' boxes without the frame-sized
    candidate and result masks.
    """
    return int(
        _join_near(
            classes,
            np.ascontiguousarray(valid, np.bool_),
            np.int8(cls),
            np.int8(facing),
            normal,
            off,
            count,
            boxes,
            np.ascontiguousarray(depth_mm, np.float32),
            float(min_px),
            cam.fx,
            cam.fy,
            cam.cx,
            cam.cy,
            float(tol_rel),
        )
    )


@njit(cache=True, nogil=True, error_model="numpy")
def _join_near(
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
    # _near's test on the candidates read from the classes: a pixel one support takes is no
    # longer a candidate for the next, which near_planes' union of the supports' tests gives
    # too. The same float64 arithmetic as _near.
    h, w = depth.shape
    ucol = np.empty(w, np.float64)
    for x in range(w):
        ucol[x] = (x - cx) / fx
    joined = 0
    for i in range(1, count.size):
        if not count[i] >= min_px:
            continue
        bx0, by0, bx1, by1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        my = (by1 - by0 + 1) // 10 + 1
        mx = (bx1 - bx0 + 1) // 10 + 1
        y0, y1 = max(by0 - my, 0), min(by1 + 1 + my, h)
        x0, x1 = max(bx0 - mx, 0), min(bx1 + 1 + mx, w)
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
