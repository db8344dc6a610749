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
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.label.unionfind import find, union
from depthgram.segmentation.order_stats import percentile32

__all__ = [
    "Plane",
    "class_window",
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
    "shares_beneath",
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
    z_sub = np.ascontiguousarray(depth_mm[::s, ::s], dtype=np.float32)
    min_sub = min_px / (s * s)
    t_mm, t_rel = np.float32(tol_mm), np.float32(tol_rel)
    # the searches are one compiled call (_search_planes): the draws are numpy's (its
    # bounded integers from the seeded bit generator's numbers), the solves and the refit
    # LAPACK's numbers, so the planes are those of the numpy route (docs/design-notes.md, "RANSAC")
    rcond = _EPS
    raw = _raw32(seed, max(max_planes, 0) * 2 * (3 * hypotheses + 2000) + 64)
    while True:
        # the grid's own pixels only, not a full-frame `valid & search` (the search takes them out)
        left = np.ascontiguousarray(valid[::s, ::s] if search is None else valid[::s, ::s] & search[::s, ::s])
        k, coefs, pieces, spreads = _search_planes(
            z_sub, left, s, t_mm, t_rel, min_sub, hypotheses, max_planes, min_spread, raw, rcond
        )
        if k >= 0:
            break
        # rejected draws (each about n / 2**32 likely) used up the numbers: more, and again
        raw = _raw32(seed, 2 * raw.size)
    if not k:
        return []
    found = [((float(c[0]), float(c[1]), float(c[2])), float(sp)) for c, sp in zip(coefs[:k], spreads[:k], strict=True)]
    # a full-resolution pixel may join a plane when its grid cell or a neighbouring one did:
    # the contact rows at the foot of an object are kept, far pixels on the plane's extension not
    allowed = _dilate3(pieces[:k])
    which = _assign(depth_mm, valid, np.ascontiguousarray(coefs[:k]), allowed, s, float(tol_mm), float(tol_rel))
    planes: list[Plane] = []
    for j, (coef, spread) in enumerate(found, start=1):
        mask = which == j
        area = int(np.count_nonzero(mask))
        if area >= min_px:
            planes.append(Plane(coef, mask, area, spread))
    return planes


#: Machine epsilon of float64 (numpy's default ``rcond`` of a least squares is it times the
#: larger dimension), taken once: ``np.finfo`` costs 0.8 us a call.
_EPS = float(np.finfo(np.float64).eps)


@njit(cache=True, nogil=True)
def _dilate3(masks: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """Return each of the stacked masks dilated by a 3 x 3 square, as 0 / 1.

    ``cv2.dilate(mask, np.ones((3, 3)))`` per mask (outside the grid counts as unset): one
    compiled call for the planes of a frame instead of two OpenCV and numpy calls per plane.
    """
    p, h, w = masks.shape
    out = np.zeros((p, h, w), np.uint8)
    for k in range(p):
        for y in range(h):
            for x in range(w):
                if masks[k, y, x]:
                    for yy in range(max(y - 1, 0), min(y + 2, h)):
                        for xx in range(max(x - 1, 0), min(x + 2, w)):
                            out[k, yy, xx] = 1
    return out


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


#: Per seed: the first 32-bit numbers of ``np.random.default_rng(seed)``'s bit generator.
_RAW32: dict[int, NDArray[np.uint32]] = {}


def _raw32(seed: int, count: int) -> NDArray[np.uint32]:
    """Return at least ``count`` of the 32-bit numbers PCG64(``seed``) gives ``Generator.integers``.

    numpy's PCG64 hands out each 64-bit output as two 32-bit numbers, the low half first. The
    plane search draws from the seeded state at every call (the same numbers each frame), so
    they are made once per seed and read by :func:`_bounded` in compiled code: numpy's calls
    for the draws, and seeding or setting back the generator, cost 10-20 us a frame.
    """
    raw = _RAW32.get(seed)
    if raw is None or raw.size < count:
        r64 = np.random.PCG64(seed).random_raw(-(-count // 2))
        raw = np.empty(2 * r64.size, np.uint32)
        raw[0::2] = (r64 & np.uint64(0xFFFFFFFF)).astype(np.uint32)
        raw[1::2] = (r64 >> np.uint64(32)).astype(np.uint32)
        _RAW32[seed] = raw
    return raw


@njit(cache=True, inline="always")
def _bounded(raw: NDArray[np.uint32], pos: int, n: int) -> tuple[int, int]:
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
def _search_planes(
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
    """Run the RANSAC searches of :func:`find_planes` on the grid, in one compiled call.

    Each search draws its three-point samples and (beyond 2000 points) its scoring points as
    ``np.random.default_rng(seed).integers`` would, from the numbers ``raw`` of the seed
    (:func:`_raw32`, :func:`_bounded`), then runs :func:`_search_plane` and
    :func:`_plane_pieces`; a plane too small or too flat is dropped and the search goes on, as
    the numpy route does. ``left`` (the grid points still searched) is taken in place.

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
        u, v, z, tz = _grid_points(z_sub, left, step, tol_mm, tol_rel)
        n = u.size
        if n < max(min_sub, 3.0):
            break
        pick = np.empty((hypotheses, 3), np.int64)
        flat = pick.reshape(hypotheses * 3)
        for i in range(flat.size):
            flat[i], pos = _bounded(raw, pos, n)
            if pos < 0:
                return -1, coefs, masks, spreads
        # the scoring points are drawn after the samples, as the numpy route draws them (it
        # draws none when no sample is solvable, and then stops searching: no later draw differs)
        m = min(n, 2000)
        if n > m:
            ev = np.empty(m, np.int64)
            for i in range(m):
                ev[i], pos = _bounded(raw, pos, n)
                if pos < 0:
                    return -1, coefs, masks, spreads
        else:
            ev = np.arange(n)
        status, a, b, c, on_img = _search_plane(u, v, z, tz, pick, ev, min_sub, eps, z_sub, left, tol_mm, tol_rel, step)
        if status < _FOUND:
            break
        pieces, n_on, p5, p50, p95 = _plane_pieces(on_img, max(int(min_sub) // 4, 1), z_sub, min_sub)
        if n_on < min_sub:
            continue
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

    The three-point samples ``pick`` are solved (:func:`_lu_solve3`, numpy's numbers), scored
    on the points ``ev`` (:func:`_best_hypothesis`), the best one's inliers refitted by least
    squares (LAPACK's ``dgelsd`` through numba, with numpy's default ``rcond``: the same
    numbers as ``np.linalg.lstsq``) and the refitted plane's grid pixels taken out of ``left``
    (:func:`_take_residual`, in place). Compiled because the dozen numpy calls of a search
    (the batched solve, the least squares, the masks) cost more than their arithmetic.

    Returns the outcome (``_NO_SAMPLE``, ``_FEW`` inliers, ``_FOUND``), the refitted
    coefficients and the plane's grid pixels (all False unless found).
    """
    on_img = np.zeros(z_sub.shape, np.bool_)
    a, good = _hypotheses(u, v, pick)
    k = 0
    for i in range(good.size):
        k += good[i]
    if k == 0:
        return _NO_SAMPLE, 0.0, 0.0, 0.0, on_img
    coef = np.empty((k, 3), np.float64)
    x = np.empty(3, np.float64)
    j = 0
    for i in range(good.size):
        if good[i]:
            for r in range(3):
                x[r] = 1000.0 / z[pick[i, r]]
            _lu_solve3(a[i], x)
            coef[j] = x
            j += 1
    best = _best_hypothesis(coef, u, v, z, tol, ev)
    uo, vo, qo = _inliers(u, v, z, tol, coef[best, 0], coef[best, 1], coef[best, 2])
    if uo.size < min_inliers:
        return _FEW, 0.0, 0.0, 0.0, on_img
    sys = np.empty((uo.size, 3), np.float64)
    sys[:, 0] = uo
    sys[:, 1] = vo
    sys[:, 2] = 1.0
    # np.linalg.lstsq's rcond=None is eps times the larger dimension
    fit = np.linalg.lstsq(sys, qo, eps * max(uo.size, 3))[0]
    on_img = _take_residual(z_sub, left, fit[0], fit[1], fit[2], tol_mm, tol_rel, np.float32(step))
    return _FOUND, fit[0], fit[1], fit[2], on_img


@njit(cache=True, nogil=True)
def _plane_pieces(
    on_img: NDArray[np.bool_], piece_px: int, z_sub: NDArray[np.float32], min_px: float
) -> tuple[NDArray[np.bool_], int, float, float, float]:
    """Return a found plane's large pieces on the grid, their pixel count and depth percentiles.

    The pieces are those of :func:`_large_pieces` (8-connected pieces of ``on_img`` of at
    least ``piece_px`` pixels); the 5th, 50th and 95th percentiles of their depth are
    ``np.percentile(z_sub[pieces], (5, 50, 95))`` (counted for whole-number depths,
    :func:`_percentiles_counted`, else :func:`percentile32`: the same values), left at 0 below
    ``min_px`` pixels, where the search drops the plane anyway. One compiled call for OpenCV's
    labelling (30 us on a 3000-point grid, most of it the call) and a handful of numpy calls.
    """
    pieces = _large_pieces(on_img, piece_px)
    h, w = z_sub.shape
    n = 0
    for y in range(h):
        for x in range(w):
            n += pieces[y, x]
    if n < min_px or n == 0:
        return pieces, n, 0.0, 0.0, 0.0
    on_z = np.empty(n, np.float32)
    k = 0
    lo = np.inf
    hi = -np.inf
    whole = True
    for y in range(h):
        for x in range(w):
            if pieces[y, x]:
                v = z_sub[y, x]
                on_z[k] = v
                k += 1
                lo = min(lo, v)
                hi = max(hi, v)
                whole &= np.floor(v) == v
    if whole and hi - lo < _MAX_COUNTED_SPAN:
        p5, p50, p95 = _percentiles_counted(on_z, lo, int(hi - lo))
    else:
        p5 = percentile32(on_z, 5.0, False)
        p50 = percentile32(on_z, 50.0, False)
        p95 = percentile32(on_z, 95.0, False)
    return pieces, n, p5, p50, p95


#: Widest span of whole-number depths (mm) whose percentiles :func:`_percentiles_counted` counts.
_MAX_COUNTED_SPAN = 1 << 16


@njit(cache=True, nogil=True)
def _percentiles_counted(a: NDArray[np.float32], lo: float, span: int) -> tuple[float, float, float]:
    # percentile32(a, q, False) for q = 5, 50, 95 of whole-number values lo .. lo + span: the
    # order statistics around each (n - 1) q / 100 read from the values' counts (one pass
    # instead of three selections; an order statistic is a value of `a` whatever finds it),
    # then percentile32's float32 difference and float64 interpolation
    n = a.size
    count = np.zeros(span + 1, np.int64)
    for i in range(n):
        count[int(a[i] - lo)] += 1
    for v in range(span):
        count[v + 1] += count[v]
    out = np.empty(3, np.float64)
    for t, q in enumerate((5.0, 50.0, 95.0)):
        vi = (n - 1) * (q / 100)
        if vi >= n - 1:
            out[t] = lo + span  # the largest value
            continue
        j = math.floor(vi)
        # the (j)-th and (j + 1)-th smallest: the first values whose running count passes them
        p_lo = np.float32(lo + np.searchsorted(count, j, side="right"))
        p_hi = np.float32(lo + np.searchsorted(count, j + 1, side="right"))
        diff = p_hi - p_lo
        f = vi - j
        if f >= 0.5:
            out[t] = np.float64(p_hi) - np.float64(diff) * (1.0 - f)
        else:
            out[t] = np.float64(p_lo) + np.float64(diff) * f
    return out[0], out[1], out[2]


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
    n_hyp = coef.shape[0]
    # every hypothesis scored on the first block, then each in the order of those counts (most
    # first, ties by index), so that a strong best is known early and the others are left as
    # soon as they cannot be chosen: by blocks (so that the loop still vectorises), a
    # hypothesis before the best so far (by index) when it can no longer reach its count, one
    # after it when it can no longer pass it (argmax keeps the first of equal counts)
    f = min(_SCORE_FIRST, m)
    first = np.empty(n_hyp, np.int64)
    for k in range(n_hyp):
        first[k] = _inliers_counted(coef[k, 0], coef[k, 1], coef[k, 2], ue[:f], ve[:f], ze[:f], te[:f])
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
            cnt += _inliers_counted(a, b, c, ue[i0:i1], ve[i0:i1], ze[i0:i1], te[i0:i1])
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
def _inliers_counted(
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


@njit(cache=True, nogil=True)
def _large_pieces(mask: NDArray[np.bool_], min_px: int) -> NDArray[np.bool_]:
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


@njit(cache=True, nogil=True, error_model="numpy")
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


@njit(cache=True, nogil=True, error_model="numpy")
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


def shares_beneath(
    depth_mm: NDArray[np.float32],
    step: int,
    cam: Intrinsics,
    normal: NDArray[np.float64],
    offset_mm: NDArray[np.float64],
    beneath_mm: float,
) -> NDArray[np.float64]:
    """Return the share of the sampled readings lying more than ``beneath_mm`` beneath each plane.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm); 0 where there is no reading.
    step : int
        Every ``step``-th pixel of every ``step``-th row is read.
    cam : Intrinsics
        The camera's intrinsics (px).
    normal, offset_mm : ndarray, shapes (P, 3) and (P,)
        Planes ``n . X + d = 0`` in camera coordinates (mm), ``n`` a unit normal; the signed
        distance ``n . X + d`` is positive on the camera's side.
    beneath_mm : float
        How far (mm) beyond a plane a reading must lie to count.

    Returns
    -------
    ndarray of float64, shape (P,)
        For each plane, the count of sampled readings at a signed distance below
        ``-beneath_mm`` over the count of sampled readings (0 without readings).
    """
    return _shares_beneath(
        np.asarray(depth_mm, np.float32), int(step), cam.fx, cam.fy, cam.cx, cam.cy,
        np.ascontiguousarray(normal, np.float64), np.ascontiguousarray(offset_mm, np.float64), float(beneath_mm),
    )  # fmt: skip


@njit(cache=True, nogil=True)
def _shares_beneath(
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


#: Stand-in for a missing ``only`` table of :func:`plane_sums` (numba wants an array).
_NO_WANT = np.ones(1, np.bool_)


def planes_from_sums(sums: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return unit normals, offsets (mm) and pixel counts from the sums of :func:`plane_sums` (row 0 unused).

    The sums are additive, so the plane of a union of pieces comes from the sum of their rows
    without another pass over the image. Each row's normal equations (plus 1e-12 on the
    diagonal) are solved as ``np.linalg.solve`` solves them (:func:`_lu_solve3`).
    """
    return _planes_from_sums(np.ascontiguousarray(sums, np.float64))


@njit(cache=True, nogil=True, error_model="numpy")
def _planes_from_sums(
    sums: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    # compiled because numpy's batched solve, norm and the table building cost about 60 us of
    # calls per use on a few rows, four uses per frame. The numbers are numpy's: the solve is
    # LAPACK's (_lu_solve3), the norm adds the squares in order as np.linalg.norm(axis=1) does
    m = sums.shape[0]
    normal = np.empty((m, 3), np.float64)
    off = np.empty(m, np.float64)
    count = np.empty(m, np.float64)
    a = np.empty((3, 3), np.float64)
    x = np.empty(3, np.float64)
    eps = 1e-12
    for i in range(m):
        if i == 0:
            a[:] = 0.0
            a[0, 0] = a[1, 1] = a[2, 2] = 1.0 + eps
            x[0], x[1], x[2] = 0.0, 0.0, 1.0
        else:
            s = sums[i]
            # numpy adds 1e-12 times the identity: + 0.0 off the diagonal (a -0.0 turns +0.0)
            a[0, 0], a[0, 1], a[0, 2] = s[0] + eps, s[1] + 0.0, s[2] + 0.0
            a[1, 0], a[1, 1], a[1, 2] = s[1] + 0.0, s[3] + eps, s[4] + 0.0
            a[2, 0], a[2, 1], a[2, 2] = s[2] + 0.0, s[4] + 0.0, s[5] + eps
            x[0], x[1], x[2] = s[6], s[7], s[8]
        _lu_solve3(a, x)
        norm = max(math.sqrt((x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]), 1e-15)
        normal[i, 0] = -x[0] / norm
        normal[i, 1] = -x[1] / norm
        normal[i, 2] = -x[2] / norm
        off[i] = 1.0 / norm
        count[i] = sums[i, 5]
    return normal, off, count


def _fma_typing(typingctx: object, a: types.Type, b: types.Type, c: types.Type) -> tuple[object, object]:
    # the typing and code of _fma: three float64 in, LLVM's fused multiply-add out
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context: object, builder: ir.IRBuilder, signature: object, args: list[ir.Value]) -> ir.Value:
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


#: ``_fma(a, b, c)``: ``a * b + c`` rounded once (LLVM's ``llvm.fma.f64``), in compiled code only.
_fma = cast(Callable[[float, float, float], float], intrinsic(_fma_typing))


@njit(cache=True, inline="always", error_model="numpy")
def _lu_solve3(a: NDArray[np.float64], x: NDArray[np.float64]) -> None:
    """Solve one 3 x 3 system ``a y = x`` in place, to the last bit as ``np.linalg.solve`` does.

    ``a`` is overwritten by its LU factors and ``x`` by the solution. Compiled so that a
    handful of small systems is not a batched numpy call each (about 30 us of calls around
    nanoseconds of arithmetic). numpy's LAPACK (OpenBLAS ``dgesv``) factors column by
    column (left-looking ``getf2``: each column's update a dot product taken with fused
    multiply-adds, then subtracted; the pivot the first largest magnitude; the column below
    it scaled by the pivot's reciprocal), then solves the two triangles by columns
    (``trsv``: fused multiply-adds, a division by each diagonal). The same operations in the
    same order give the same numbers (a test compares them on many systems); a zero pivot,
    where numpy raises, gives inf or nan here.
    """
    # the matrix and the right-hand side in registers: the pivot's row swaps are selects
    # (which row holds the largest magnitude cannot be predicted: a branch on it flushed the
    # pipeline, and with it the overlap of one system's divisions with the next one's); the
    # rows are swapped whole when the pivot is chosen, as getf2's later columns would be
    a00, a01, a02 = a[0, 0], a[0, 1], a[0, 2]
    a10, a11, a12 = a[1, 0], a[1, 1], a[1, 2]
    a20, a21, a22 = a[2, 0], a[2, 1], a[2, 2]
    x0, x1, x2 = x[0], x[1], x[2]
    # column 0 (no update: the column minus an empty product is itself)
    big = abs(a00)
    s1 = abs(a10) > big
    big = max(big, abs(a10)) if s1 else big
    s2 = abs(a20) > big
    s1 = s1 and not s2
    # rows 0 and 1 or 0 and 2 swapped (x too: its swaps come first in the solve)
    t00, t01, t02, tx = a00, a01, a02, x0
    a00 = a20 if s2 else (a10 if s1 else a00)
    a01 = a21 if s2 else (a11 if s1 else a01)
    a02 = a22 if s2 else (a12 if s1 else a02)
    x0 = x2 if s2 else (x1 if s1 else x0)
    a10, a11, a12, x1 = (t00, t01, t02, tx) if s1 else (a10, a11, a12, x1)
    a20, a21, a22, x2 = (t00, t01, t02, tx) if s2 else (a20, a21, a22, x2)
    p = a00
    if p != 0.0:
        if abs(p) >= 2.2250738585072014e-308:
            rp = 1.0 / p
            a10 *= rp
            a20 *= rp
        else:
            a10 /= p
            a20 /= p
    # column 1: minus L times its U part, then its pivot among rows 1 and 2
    a11 = a11 - _fma(a10, a01, 0.0)
    a21 = a21 - _fma(a20, a01, 0.0)
    sw = abs(a21) > abs(a11)
    a10, a20 = (a20, a10) if sw else (a10, a20)
    a11, a21 = (a21, a11) if sw else (a11, a21)
    a12, a22 = (a22, a12) if sw else (a12, a22)
    x1, x2 = (x2, x1) if sw else (x1, x2)
    p = a11
    if p != 0.0:
        if abs(p) >= 2.2250738585072014e-308:
            a21 *= 1.0 / p
        else:
            a21 /= p
    # column 2
    a12 = a12 - _fma(a10, a02, 0.0)
    a22 = a22 - _fma(a21, a12, _fma(a20, a02, 0.0))
    a[0, 0], a[0, 1], a[0, 2] = a00, a01, a02
    a[1, 0], a[1, 1], a[1, 2] = a10, a11, a12
    a[2, 0], a[2, 1], a[2, 2] = a20, a21, a22
    # the right-hand side through L (unit diagonal) and U, by columns
    x1 = _fma(-x0, a10, x1)
    x2 = _fma(-x0, a20, x2)
    x2 = _fma(-x1, a21, x2)
    x2 /= a22
    x0 = _fma(-x2, a02, x0)
    x1 = _fma(-x2, a12, x1)
    x1 /= a11
    x0 = _fma(-x1, a01, x0)
    x0 /= a00
    x[0], x[1], x[2] = x0, x1, x2


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
    # only pieces big enough for a reliable plane can join: compare those alone (a few),
    # not all pairs of pieces (hundreds of noise specks)
    big = _big_pieces(count, float(min_fit_px))
    if big.size < 2:
        return np.arange(n + 1, dtype=np.int32), n
    nb = normal[big]
    # the cosines are numpy's matrix product (its BLAS kernels' rounding, which compiled dot
    # products do not repeat for every size); the tests and the joins after it are compiled
    lut, m = _coplanar_join(nb @ nb.T, off, big, math.cos(math.radians(max_angle_deg)), float(max_offset_rel), n)
    return lut, int(m)


@njit(cache=True, nogil=True)
def _big_pieces(count: NDArray[np.float64], min_px: float) -> NDArray[np.intp]:
    # the pieces 1..n of at least min_px pixels: np.flatnonzero(count[1:] >= min_px) + 1 in one
    # compiled call (four numpy calls cost more, four uses per frame)
    out = np.empty(count.size, np.intp)
    k = 0
    for i in range(1, count.size):
        if count[i] >= min_px:
            out[k] = i
            k += 1
    return out[:k]


@njit(cache=True, nogil=True)
def _coplanar_join(
    cosines: NDArray[np.float64], off: NDArray[np.float64], big: NDArray[np.intp], min_cos: float, rel: float, n: int
) -> tuple[NDArray[np.int32], int]:
    """Return the groups of the large pieces ``big`` whose planes agree (:func:`coplanar_groups`).

    Pair ``i < j`` joins when ``cosines[i, j] > min_cos`` and ``|off_i - off_j| <= rel
    max(off_i, off_j)``, numpy's tests on the same float64 numbers; compiled because the
    half-dozen numpy calls on a few pieces' matrices cost more than the tests (three uses per
    frame). Returns :func:`_join_groups`' table and group count.
    """
    k = big.size
    join = np.zeros((k, k), np.bool_)
    for i in range(k):
        oi = off[big[i]]
        for j in range(i + 1, k):
            oj = off[big[j]]
            join[i, j] = cosines[i, j] > min_cos and abs(oi - oj) <= rel * max(oi, oj)
    return _join_groups(join, big, n)


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


@njit(cache=True, inline="always")
def _near_box(boxes: NDArray[np.int64], i: int, h: int, w: int) -> tuple[int, int, int, int]:
    # the rows y0..y1 - 1 and columns x0..x1 - 1 where support i's near pixels are looked for:
    # its inclusive box and a tenth of its size more on each side, inside the frame
    bx0, by0, bx1, by1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
    my = (by1 - by0 + 1) // 10 + 1
    mx = (bx1 - bx0 + 1) // 10 + 1
    return max(by0 - my, 0), min(by1 + 1 + my, h), max(bx0 - mx, 0), min(bx1 + 1 + mx, w)


def class_window(
    boxes: NDArray[np.int64], count: NDArray[np.float64], shape: tuple[int, int], *, min_px: int
) -> tuple[int, int, int, int]:
    """Return the window ``(y0, y1, x0, x1)`` (half-open, px) holding a class after :func:`join_near`.

    ``boxes`` (n + 1, 4, inclusive) hold every pixel of the class before (row 0 unused);
    :func:`join_near` with the same ``count`` and ``min_px`` gives it pixels only inside the
    margins it searches around the supports of ``min_px`` pixels or more. The union of both
    holds every pixel of the class after it, so that labelling the class again reads this
    window alone (:func:`depthgram.segmentation.slices.support_pieces_lazy`). An empty table
    gives an empty window.
    """
    y0, y1, x0, x1 = _class_window(np.ascontiguousarray(boxes, np.int64), count, float(min_px), shape[0], shape[1])
    return int(y0), int(y1), int(x0), int(x1)


@njit(cache=True, nogil=True)
def _class_window(
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
