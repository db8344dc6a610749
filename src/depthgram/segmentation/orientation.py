"""Which pixels lie on horizontal supports (floor, ceiling, table tops) and which on walls.

Why inverse depth: for any plane n·P = d seen through a pinhole, ``1/Z = (n_x u' + n_y v' +
n_z) / d`` with ``u' = (u - cx) / fx``, ``v' = (v - cy) / fy``. So the image gradient of 1/Z
gives the plane normal up to scale: ``n ∝ (fx ∂(1/Z)/∂u, fy ∂(1/Z)/∂v, 1/Z - ...)``. A surface
facing the sensor has a flat 1/Z, a floor or a table top changes steadily from row to row
(∂Z/∂y ≠ 0, the hint the slices exploit), a wall from column to column. The gradient is taken
over a box window of valid pixels (hole-aware), and not at occlusion edges, where a depth jump
would fake a steep surface.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.creases import inverse_depth
from depthgram.segmentation.creases import warm_up as warm_up_creases
from depthgram.segmentation.window import bits_range, exact_rows, start_columns, window_row

__all__ = ["default_intrinsics", "load_opencv_routes", "orientation_classes"]

#: Classes returned by :func:`orientation_classes`.
FACING, HORIZONTAL, VERTICAL = 0, 1, 2


def default_intrinsics(shape: tuple[int, int]) -> Intrinsics:
    """Pinhole guess for a frame without calibration: 64 degrees horizontal field of view."""
    h, w = shape
    f = 0.8 * w
    return Intrinsics(f, f, (w - 1) / 2.0, (h - 1) / 2.0)


def orientation_classes(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    intrinsics: Intrinsics,
    *,
    window_px: int = 7,
    oblique_deg: float = 35.0,
    jump_rel: float = 0.05,
    inverse: NDArray[np.float32] | None = None,
) -> NDArray[np.int8]:
    """Per-pixel class: 0 facing the sensor (or unknown), 1 horizontal, 2 vertical lateral.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid.
    valid : ndarray of bool
        Pixels with a reading.
    intrinsics : Intrinsics
        Camera intrinsics (px).
    window_px : int
        Side of the smoothing window (px).
    oblique_deg : float
        Largest angle (degrees) between the surface normal and the image's vertical axis for a
        horizontal surface, or its horizontal axis for a wall.
    jump_rel : float
        Relative depth step between neighbours marking an occlusion edge.
    inverse : ndarray of float32, shape (2, H, W), optional
        ``1000 / depth_mm`` and the readings (1 / 0) as two planes, as
        :func:`depthgram.segmentation.creases.inverse_depth` gives them, when the caller has them (the
        creases take the same).

    Returns
    -------
    classes : ndarray of int8, shape (H, W)
    """
    return _field(depth_mm, valid, intrinsics, window_px, oblique_deg, jump_rel, False, inverse)[0]


def load_opencv_routes() -> None:
    """Load (on a fresh install: compile) the kernels of a frame whose window sums OpenCV takes.

    The orientation field and the creases sum their windows themselves where float64 adds them
    exactly (:mod:`depthgram.segmentation.window`); a frame whose values span too many octaves
    takes OpenCV's sums and the kernels that read them (:func:`_classify`,
    :func:`depthgram.segmentation.creases.warm_up`). No frame of the recordings at hand
    does, so a stream would load them in its middle.
    """
    f = np.float32(1.0)
    ok = np.ones((2, 2), np.bool_)
    _classify(np.zeros((2, 2, 3), np.float32), np.ones((2, 2), np.float32), ok, ~ok, f, f, f, f, f)
    warm_up_creases()


def _field(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    intrinsics: Intrinsics,
    window_px: int,
    oblique_deg: float,
    jump_rel: float,
    want_normals: bool,
    inverse: NDArray[np.float32] | None = None,
) -> tuple[NDArray[np.int8], NDArray[np.float32] | None]:
    h, w = depth_mm.shape
    # 1000 / Z (1/m keeps float32 well scaled) and the readings as 1 / 0, in one pass, as two
    # planes
    if inverse is None:
        inverse = inverse_depth(np.ascontiguousarray(depth_mm, np.float32), np.ascontiguousarray(valid, np.bool_))
    # a 3 x 3 valid-weighted mean, then differences over `step` px: the slope of a distant floor
    # (1/Z changes by 1 / (h fy) per row) must stand above the noise of one difference
    # the mean is defined wherever a 3 x 3 neighbour has a reading, which bridges a sieve of
    # dropouts (registered structured light keeps one pixel in four).
    # Average the gradient over valid pixels only; holes neither pull it to zero nor fake edges.
    # Pixels whose slope is steeper than 80 degrees from the line of sight are left out too: on
    # both sides of an occlusion edge (a smoothed or flying pixel) they would fake a steep plane.
    # One compiled pass for the mean, both slopes, the kept slopes and the occlusion edges
    # (:func:`_slopes`; they were eight calls, OpenCV's 3 x 3 box filter among them)
    fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
    steep = np.float32(math.tan(math.radians(80.0)))
    step = max(1, window_px // 2)
    z = np.ascontiguousarray(depth_mm)
    ok = np.ascontiguousarray(valid)
    inv3, kept, edge, ranges = _slopes(
        inverse, z, ok, step, np.float32(fx), np.float32(fy), steep, np.float32(jump_rel)
    )
    cos_t = math.cos(math.radians(oblique_deg))
    cam = (np.float32(fx), np.float32(fy), np.float32(cx), np.float32(cy), np.float32(cos_t))
    if not want_normals:
        # the window sums of the count of kept slopes and of the slopes, taken row by row
        # inside the classes' pass (no sums image), in an order of our own: OpenCV's to the
        # last bit where float64 adds them exactly (:mod:`depthgram.segmentation.window`; a
        # frame whose slopes span too many octaves takes OpenCV's filter below)
        cls, exact = _classify_window(kept, ranges, window_px, inv3, ok, edge, *cam)
        if exact:
            return cls, None
    k = (window_px, window_px)
    # the count of kept slopes per window and their sums, as channels of one image: OpenCV's
    # row sums of a channel are a chain of dependent additions, three channels run three
    # chains side by side (the same sums as three one-channel filters, a test; 257 -> 159 us
    # at 320 x 240). _classify takes the count at least 1e-6 (np.maximum's float32)
    img = cv2.merge([kept[0], kept[1], kept[2]])
    sums = np.asarray(cv2.boxFilter(img, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE), np.float32)
    cls = _classify(sums, inv3, ok, edge, *cam)
    if not want_normals:  # segmentation needs the classes only
        return cls, None
    den = np.maximum(sums[:, :, 0], np.float32(1e-6))
    sgx, sgy = sums[:, :, 1], sums[:, :, 2]
    gx = np.asarray(sgx / den, np.float32)
    gy = np.asarray(sgy / den, np.float32)
    a = fx * gx
    b = fy * gy
    u = ((np.arange(w, dtype=np.float32) - cx) / fx)[None, :]
    v = ((np.arange(h, dtype=np.float32) - cy) / fy)[:, None]
    c = inv3 - a * u - b * v
    norm = np.sqrt(a * a + b * b + c * c) + 1e-12
    # (a, b, c) . ray = 1/Z > 0 always, so its opposite is the normal turned toward the sensor
    sign = np.float32(-1.0) / norm
    normals = np.stack([a * sign, b * sign, c * sign], axis=-1).astype(np.float32)
    return cls, normals


@njit(cache=True, nogil=True, error_model="numpy")
def _slopes(
    inverse: NDArray[np.float32],
    z: NDArray[np.float32],
    valid: NDArray[np.bool_],
    step: int,
    fx: np.float32,
    fy: np.float32,
    steep: np.float32,
    rel: np.float32,
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.bool_], NDArray[np.int64]]:
    """Return the 3 x 3 mean of 1/Z, the kept slopes (3, H, W), the occlusion edges and the slopes' ranges.

    ``inverse`` (2, H, W): 1000 / Z and the readings
    (:func:`~depthgram.segmentation.creases.inverse_depth`). The mean is numpy's
    ``s_inv / np.maximum(s_m, 1e-6)`` (float32) of OpenCV's 3 x 3 unnormalised box sums with
    replicated borders (:func:`_box3_mean`, the same sums); the slopes are :func:`_one_sided`
    along rows and columns of the mean where it is defined, kept under 80 degrees
    (:func:`_kept_row`); the edges are :func:`_jumps` along rows or columns. One compiled call
    instead of eight (OpenCV's box filter among them), whose dispatch and temporaries cost more
    than their arithmetic on small frames. ``ranges`` (4, H): each row's
    :func:`~depthgram.segmentation.window.bits_range` of the kept x slopes, then of the y slopes.
    """
    h, w = z.shape
    inv3, has = _box3_mean(inverse)
    kept = np.empty((3, h, w), np.float32)
    gx = np.empty(w, np.float32)
    gy = np.empty(w, np.float32)
    ranges = np.empty((4, h), np.int64)
    for y in range(h):
        _one_sided_row(inv3[y], has[y], step, gx)
        _one_sided_col(inv3, has, y, step, gy)
        kx, ky = kept[1, y], kept[2, y]
        _kept_row(gx, gy, has[y], inv3[y], fx, fy, steep, kept[0, y], kx, ky)
        # each row's range of kept slopes, for the window sums' exactness test
        ranges[0, y], ranges[1, y] = bits_range(kx)
        ranges[2, y], ranges[3, y] = bits_range(ky)
    edge = np.zeros((h, w), np.bool_)
    _row_edges_into(z, valid, rel, edge)
    _col_edges_into(z, valid, rel, edge)
    return inv3, kept, edge, ranges


@njit(cache=True, nogil=True, error_model="numpy")
def _box3_row(s: NDArray[np.float32], d: NDArray[np.float64]) -> None:
    # OpenCV's row sums of a 3-wide box (RowSum, ksize 3) on a row with replicated borders:
    # (s[x - 1] + s[x]) + s[x + 1] in float64, left to right
    w = s.size
    if w == 1:
        d[0] = (np.float64(s[0]) + np.float64(s[0])) + np.float64(s[0])
        return
    d[0] = (np.float64(s[0]) + np.float64(s[0])) + np.float64(s[1])
    a, b, c = s[: w - 2], s[1 : w - 1], s[2:]
    di = d[1 : w - 1]
    for i in range(w - 2):
        di[i] = (np.float64(a[i]) + np.float64(b[i])) + np.float64(c[i])
    d[w - 1] = (np.float64(s[w - 2]) + np.float64(s[w - 1])) + np.float64(s[w - 1])


@njit(cache=True, nogil=True, error_model="numpy")
def _box3_rows(inverse: NDArray[np.float32], y: int, di: NDArray[np.float64], dm: NDArray[np.float64]) -> None:
    # the row sums of both planes' source row y
    _box3_row(inverse[0, y], di)
    _box3_row(inverse[1, y], dm)


@njit(cache=True, nogil=True, error_model="numpy")
def _box3_mean(inverse: NDArray[np.float32]) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    # the 3 x 3 mean of 1/Z where a neighbour has a reading: OpenCV's boxFilter of each plane
    # of `inverse`, (3, 3), normalize=False, borderType=BORDER_REPLICATE, computed as OpenCV
    # computes a float32 image (float64 row sums; float64 column sums kept running down the
    # rows, SUM + new row given as float32, then the row leaving the window taken off), then
    # numpy's np.maximum(s_m, 1e-6) (float32), float32 division and test against 0.5
    h, w = inverse.shape[1], inverse.shape[2]
    inv3 = np.empty((h, w), np.float32)
    has = np.empty((h, w), np.bool_)
    # row sums of source rows y - 1, y, y + 1 (clamped: replicated border rows)
    ri = np.empty((3, w), np.float64)
    rm = np.empty((3, w), np.float64)
    sum_i = np.zeros(w, np.float64)
    sum_m = np.zeros(w, np.float64)
    _box3_rows(inverse, 0, ri[0], rm[0])
    ri[1] = ri[0]
    rm[1] = rm[0]
    # OpenCV's column filter starts from zeros and adds the first ksize - 1 rows (row -1 = row 0)
    for x in range(w):
        sum_i[x] += ri[0, x]
        sum_m[x] += rm[0, x]
    for x in range(w):
        sum_i[x] += ri[1, x]
        sum_m[x] += rm[1, x]
    eps = np.float32(1e-6)
    half = np.float32(0.5)
    prev, cur, nxt = 0, 1, 2
    for y in range(h):
        _box3_rows(inverse, min(y + 1, h - 1), ri[nxt], rm[nxt])
        pi, pm, ni, nm = ri[prev], rm[prev], ri[nxt], rm[nxt]
        ir = inv3[y]
        hr = has[y]
        for x in range(w):
            s0 = sum_i[x] + ni[x]
            s1 = sum_m[x] + nm[x]
            sum_i[x] = s0 - pi[x]
            sum_m[x] = s1 - pm[x]
            d = max(np.float32(s1), eps)
            ir[x] = np.float32(s0) / d
            hr[x] = d > half
        prev, cur, nxt = cur, nxt, prev
    return inv3, has


@njit(cache=True, nogil=True)
def _kept_row(
    ax: NDArray[np.float32],
    ay: NDArray[np.float32],
    hs: NDArray[np.bool_],
    iv: NDArray[np.float32],
    fx: np.float32,
    fy: np.float32,
    steep: np.float32,
    mk: NDArray[np.float32],
    kx: NDArray[np.float32],
    ky: NDArray[np.float32],
) -> None:
    # pixels with a mean and a slope under 80 degrees keep their slopes (others get 0): `mk`
    # gets 1 / 0 for kept, `kx` and `ky` the kept x and y slopes (rows of the three channel
    # planes). numpy's float32 arithmetic (its Python scalars act as float32)
    w = ax.size
    zero = np.float32(0.0)
    one = np.float32(1.0)
    for x in range(w):  # selects, no branch
        lim = steep * iv[x]
        keep = hs[x] & (abs(fx * ax[x]) <= lim) & (abs(fy * ay[x]) <= lim)
        mk[x] = one if keep else zero
        kx[x] = ax[x] if keep else zero
        ky[x] = ay[x] if keep else zero


@njit(cache=True, nogil=True, error_model="numpy")
def _classify(
    sums: NDArray[np.float32],
    inv3: NDArray[np.float32],
    valid: NDArray[np.bool_],
    edge: NDArray[np.bool_],
    fx: np.float32,
    fy: np.float32,
    cx: np.float32,
    cy: np.float32,
    cos_t: np.float32,
) -> NDArray[np.int8]:
    # the class of each pixel from its window-mean slopes, in one pass instead of a dozen
    # full-frame float32 temporaries (:func:`_classify_row`). `sums` (H, W, 3): the window's
    # count of kept slopes and their x and y sums, read into three row buffers first (so that
    # the loop still vectorises).
    h, w = inv3.shape
    flat = sums.reshape((h, 3 * w))
    sgx_r = np.empty(w, np.float32)
    sgy_r = np.empty(w, np.float32)
    den_r = np.empty(w, np.float32)
    cls = np.empty((h, w), np.int8)
    ucol = _column_u(w, cx, fx)
    for y in range(h):
        sr = flat[y]
        for ux in range(np.uint64(w)):
            j = np.uint64(3) * ux
            den_r[ux] = sr[j]
            sgx_r[ux] = sr[j + np.uint64(1)]
            sgy_r[ux] = sr[j + np.uint64(2)]
        _classify_row(den_r, sgx_r, sgy_r, inv3, valid, edge, ucol, y, fx, fy, cy, cos_t, cls[y])
    return cls


@njit(cache=True, inline="always")
def _column_u(w: int, cx: np.float32, fx: np.float32) -> NDArray[np.float32]:
    # u = (x - cx) / fx of each column, once per frame (the same float32 division the numpy
    # expression makes per pixel): read by _classify_row
    ucol = np.empty(w, np.float32)
    for x in range(w):
        ucol[x] = (np.float32(x) - cx) / fx
    return ucol


@njit(cache=True, inline="always", error_model="numpy")
def _classify_row(
    dn: NDArray[np.float32],
    gx: NDArray[np.float32],
    gy: NDArray[np.float32],
    inv3: NDArray[np.float32],
    valid: NDArray[np.bool_],
    edge: NDArray[np.bool_],
    ucol: NDArray[np.float32],
    y: int,
    fx: np.float32,
    fy: np.float32,
    cy: np.float32,
    cos_t: np.float32,
    out: NDArray[np.int8],
) -> None:
    # row y's classes from its window counts and slope sums: the same float32 operations in
    # the same order as the numpy expression (tests/reference.py). Branch-free over the row,
    # with numpy's division rules (no zero test; `den` is taken at least 1e-6 as np.maximum
    # did), so that the divisions and square roots vectorise: every pixel is computed, then
    # masked. A pixel beside an occlusion edge along its row or its column (`edge`) is facing.
    w = dn.size
    tiny = np.float32(1e-12)
    eps = np.float32(1e-6)
    vert = np.int8(VERTICAL)
    horiz = np.int8(HORIZONTAL)
    face = np.int8(FACING)
    v = (np.float32(y) - cy) / fy
    iv = inv3[y]
    ok = valid[y]
    er = edge[y]
    for x in range(w):
        d = max(dn[x], eps)
        a = fx * (gx[x] / d)
        b = fy * (gy[x] / d)
        c = iv[x] - a * ucol[x] - b * v
        t = cos_t * (np.sqrt(a * a + b * b + c * c) + tiny)
        k = vert if abs(a) >= t else (horiz if abs(b) >= t else face)
        out[x] = k if ok[x] & ~er[x] else face


@njit(cache=True, nogil=True, error_model="numpy")
def _classify_window(
    kept: NDArray[np.float32],
    ranges: NDArray[np.int64],
    k: int,  # odd
    inv3: NDArray[np.float32],
    valid: NDArray[np.bool_],
    edge: NDArray[np.bool_],
    fx: np.float32,
    fy: np.float32,
    cx: np.float32,
    cy: np.float32,
    cos_t: np.float32,
) -> tuple[NDArray[np.int8], bool]:
    """Return :func:`_classify` of OpenCV's ``k x k`` replicated-border window sums of ``kept``, and True.

    The sums are taken row by row in float64 (a column sum running down the rows, then the
    ``k`` columns of the window added across) and given as float32 to the classes' row: no
    sums image. When :func:`~depthgram.segmentation.window.exact_rows` holds for the slopes'
    ``ranges`` (:func:`_slopes`) every float64 intermediate here and in OpenCV is exact, so the
    sums are OpenCV's to the last bit; the count channel (whole numbers) always is. Otherwise,
    or for an even ``k``, nothing is computed and the flag is False (the caller takes OpenCV's
    filter).
    """
    r = k // 2
    n = k * k
    if k % 2 == 0 or not (
        exact_rows(ranges[0], ranges[1], n, r + 1, r) and exact_rows(ranges[2], ranges[3], n, r + 1, r)
    ):
        return np.empty((0, 0), np.int8), False
    if k == 7:  # the default: its span a constant in the compiled loops (53 -> 49 us at 176 x 132)
        return _classes_of_windows(kept, 3, inv3, valid, edge, fx, fy, cx, cy, cos_t), True
    return _classes_of_windows(kept, r, inv3, valid, edge, fx, fy, cx, cy, cos_t), True


@njit(cache=True, inline="always", error_model="numpy")
def _classes_of_windows(
    kept: NDArray[np.float32],
    r: int,
    inv3: NDArray[np.float32],
    valid: NDArray[np.bool_],
    edge: NDArray[np.bool_],
    fx: np.float32,
    fy: np.float32,
    cx: np.float32,
    cy: np.float32,
    cos_t: np.float32,
) -> NDArray[np.int8]:
    # the body of _classify_window for windows 2 r + 1 wide
    h, w = inv3.shape
    # per channel plane: the column sums in the middle of a row padded by r pixels each side;
    # the count (whole numbers up to k * k) is exact in float32, which adds twice as many at once
    pad_n = np.empty(w + 2 * r, np.float32)
    pad_x = np.empty(w + 2 * r, np.float64)
    pad_y = np.empty(w + 2 * r, np.float64)
    pairs_n = np.empty(w + 2 * r, np.float32)
    pairs = np.empty(w + 2 * r, np.float64)
    cnt, sx, sy = kept[0], kept[1], kept[2]
    start_columns(cnt, r, pad_n)
    start_columns(sx, r, pad_x)
    start_columns(sy, r, pad_y)
    mid_n, mid_x, mid_y = pad_n[r : r + w], pad_x[r : r + w], pad_y[r : r + w]
    pairs_x = np.empty(w + 2 * r, np.float64)
    sgx_r = np.empty(w, np.float32)
    sgy_r = np.empty(w, np.float32)
    den_r = np.empty(w, np.float32)
    cls = np.empty((h, w), np.int8)
    ucol = _column_u(w, cx, fx)
    for y in range(h):
        if y > 0:
            # the three channels' column sums in one loop (next_columns' arithmetic): three
            # loops cost 12 % more
            yn, yo = min(y + r, h - 1), max(y - r - 1, 0)
            an, bn, cn, ao, bo, co = cnt[yn], sx[yn], sy[yn], cnt[yo], sx[yo], sy[yo]
            for x in range(w):
                mid_n[x] = (mid_n[x] + an[x]) - ao[x]
                mid_x[x] = (mid_x[x] + bn[x]) - bo[x]
                mid_y[x] = (mid_y[x] + cn[x]) - co[x]
        if r == 3:
            # window.window_row's pairs and arithmetic on the three channels at once: one loop
            # for the pairs and one for the sums instead of three each, written out here (a
            # helper taking the buffers made the loops 8 % slower)
            for i in range(3):
                pad_n[i], pad_n[3 + w + i] = mid_n[0], mid_n[w - 1]
                pad_x[i], pad_x[3 + w + i] = mid_x[0], mid_x[w - 1]
                pad_y[i], pad_y[3 + w + i] = mid_y[0], mid_y[w - 1]
            for i in range(w + 5):
                pairs_n[i] = pad_n[i] + pad_n[i + 1]
                pairs_x[i] = pad_x[i] + pad_x[i + 1]
                pairs[i] = pad_y[i] + pad_y[i + 1]
            for x in range(w):
                den_r[x] = (pairs_n[x] + pairs_n[x + 2]) + (pairs_n[x + 4] + pad_n[x + 6])
                sgx_r[x] = np.float32((pairs_x[x] + pairs_x[x + 2]) + (pairs_x[x + 4] + pad_x[x + 6]))
                sgy_r[x] = np.float32((pairs[x] + pairs[x + 2]) + (pairs[x + 4] + pad_y[x + 6]))
        else:
            window_row(pad_n, r, pairs_n, den_r)
            window_row(pad_x, r, pairs, sgx_r)
            window_row(pad_y, r, pairs, sgy_r)
        _classify_row(den_r, sgx_r, sgy_r, inv3, valid, edge, ucol, y, fx, fy, cy, cos_t, cls[y])
    return cls


def _jumps(z: NDArray[np.float32], valid: NDArray[np.bool_], jump_rel: float) -> NDArray[np.bool_]:
    """Pixels beside an occlusion edge along rows.

    A step is an edge when it exceeds ``jump_rel`` of the depth and is more than twice the
    steps two pixels before and after it: a floor seen at a grazing angle makes large but
    steady steps, an occlusion one isolated step (or two, with a flying pixel between).
    """
    out = np.zeros(z.shape, np.bool_)
    _row_edges_into(np.ascontiguousarray(z), np.ascontiguousarray(valid), np.float32(jump_rel), out)
    return out


@njit(cache=True, nogil=True)
def _row_edges_into(z: NDArray[np.float32], valid: NDArray[np.bool_], rel: np.float32, out: NDArray[np.bool_]) -> None:
    # per row: the steps, then the edge test, then both neighbours of an edge step marked
    # (or-ed into `out`), each a branch-free loop (selects, so they vectorise); the numpy
    # version made seven full-frame temporaries. float32 throughout, as numpy computed it.
    h, w = z.shape
    if w < 2:
        return
    m = w - 1
    d = np.zeros(m, np.float32)
    around = np.zeros(m, np.float32)
    edge = np.zeros(m + 2, np.bool_)  # edge[x + 1]: step x is an edge; guards at both ends
    zero = np.float32(0.0)
    two = np.float32(2.0)
    for y in range(h):
        zr = z[y]
        vr = valid[y]
        for x in range(m):
            d[x] = abs(zr[x + 1] - zr[x]) if vr[x + 1] & vr[x] else zero
        for x in range(m):
            around[x] = zero
        for x in range(2, m):
            around[x] = d[x - 2]
        for x in range(m - 2):
            around[x] = max(around[x], d[x + 2])
        for x in range(m):
            edge[x + 1] = (d[x] > rel * max(zr[x + 1], zr[x])) & (d[x] > two * around[x])
        orow = out[y]
        for x in range(w):
            orow[x] = orow[x] | edge[x] | edge[x + 1]


def _one_sided(inv: NDArray[np.float32], valid: NDArray[np.bool_], step: int) -> NDArray[np.float32]:
    """Return the derivative along rows (per px), the smaller of the forward and backward differences.

    Beside an occlusion edge one of the two differences crosses the edge; the smaller one stays
    on the pixel's own surface, so a floor pixel next to a box keeps the floor's slope. Pixels
    whose neighbours both lack a reading get 0 (no evidence of a slope).
    """
    return _one_sided_rows(np.ascontiguousarray(inv), np.ascontiguousarray(valid), step)


@njit(cache=True, inline="always", error_model="numpy")
def _slope(f: np.float32, b: np.float32, okf: bool, okb: bool, fstep: np.float32) -> np.float32:
    # the smaller of the forward and backward differences over `fstep` px, as selects (no
    # branch), 0 without either
    inf = np.float32(np.inf)
    f = f if okf else inf
    b = b if okb else inf
    g = f if abs(f) <= abs(b) else b
    return g / fstep if okf | okb else np.float32(0.0)


@njit(cache=True, nogil=True, error_model="numpy")
def _one_sided_rows(inv: NDArray[np.float32], valid: NDArray[np.bool_], step: int) -> NDArray[np.float32]:
    h, w = inv.shape
    out = np.zeros((h, w), np.float32)
    for y in range(h):
        _one_sided_row(inv[y], valid[y], step, out[y])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _one_sided_row(iv: NDArray[np.float32], ok: NDArray[np.bool_], step: int, o: NDArray[np.float32]) -> None:
    # one row of _one_sided; same float32 arithmetic as the ten full-frame numpy temporaries it
    # replaced. The columns with both neighbours in the row take a loop of their own, free of
    # index tests and branches, which vectorises.
    w = iv.size
    fstep = np.float32(step)
    lo = min(step, w)
    hi = max(w - step, lo)
    for x in range(lo):
        okf = x + step < w and ok[x + step] and ok[x]
        o[x] = _slope(iv[x + step] - iv[x] if okf else np.float32(0.0), np.float32(0.0), okf, False, fstep)
    # the interior through shifted views, indexed alike (as the columns' loop): vectorises
    ivf, ivc, ivb = iv[lo + step : hi + step], iv[lo:hi], iv[lo - step : hi - step]
    vf, vc, vb = ok[lo + step : hi + step], ok[lo:hi], ok[lo - step : hi - step]
    oc = o[lo:hi]
    for i in range(hi - lo):
        oc[i] = _slope(ivf[i] - ivc[i], ivc[i] - ivb[i], vf[i] & vc[i], vc[i] & vb[i], fstep)
    for x in range(hi, w):
        okb = x - step >= 0 and ok[x] and ok[x - step]
        o[x] = _slope(np.float32(0.0), iv[x] - iv[x - step] if okb else np.float32(0.0), False, okb, fstep)


@njit(cache=True, nogil=True, error_model="numpy")
def _one_sided_cols(inv: NDArray[np.float32], valid: NDArray[np.bool_], step: int) -> NDArray[np.float32]:
    # _one_sided_rows along columns (same arithmetic), a whole row of columns at a time,
    # without the three transposed copies
    h, w = inv.shape
    out = np.zeros((h, w), np.float32)
    for y in range(h):
        _one_sided_col(inv, valid, y, step, out[y])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _one_sided_col(
    inv: NDArray[np.float32], valid: NDArray[np.bool_], y: int, step: int, o: NDArray[np.float32]
) -> None:
    # row y of _one_sided_cols
    h, w = inv.shape
    fstep = np.float32(step)
    zero = np.float32(0.0)
    hasf = y + step < h
    hasb = y - step >= 0
    iv = inv[y]
    ok = valid[y]
    if hasf and hasb:
        ivf = inv[y + step]
        okn = valid[y + step]
        ivb = inv[y - step]
        okp = valid[y - step]
        for x in range(w):
            o[x] = _slope(ivf[x] - iv[x], iv[x] - ivb[x], okn[x] & ok[x], ok[x] & okp[x], fstep)
    elif hasf:
        ivf = inv[y + step]
        okn = valid[y + step]
        for x in range(w):
            o[x] = _slope(ivf[x] - iv[x], zero, okn[x] & ok[x], False, fstep)
    elif hasb:
        ivb = inv[y - step]
        okp = valid[y - step]
        for x in range(w):
            o[x] = _slope(zero, iv[x] - ivb[x], False, ok[x] & okp[x], fstep)
    else:
        for x in range(w):
            o[x] = zero


@njit(cache=True, nogil=True)
def _jumps_cols(z: NDArray[np.float32], valid: NDArray[np.bool_], rel: np.float32) -> NDArray[np.bool_]:
    # _jumps_rows along columns (same float32 tests)
    out = np.zeros(z.shape, np.bool_)
    _col_edges_into(z, valid, rel, out)
    return out


@njit(cache=True, nogil=True)
def _col_edges_into(z: NDArray[np.float32], valid: NDArray[np.bool_], rel: np.float32, out: NDArray[np.bool_]) -> None:
    # _row_edges_into along columns (same float32 tests, or-ed into `out`), a whole row of
    # columns at a time, without the transposed copies in and out, which cost more than the
    # tests; row slices and the border rows' cases outside the column loops, so that they
    # vectorise (indexing the frame in 2-D with the tests inside ran at a third of the speed)
    h, w = z.shape
    if h < 2:
        return
    m = h - 1
    d = np.empty((m, w), np.float32)
    zero = np.float32(0.0)
    two = np.float32(2.0)
    for y in range(m):
        dr, za, zb, va, vb = d[y], z[y + 1], z[y], valid[y + 1], valid[y]
        for x in range(w):
            dr[x] = abs(za[x] - zb[x]) if va[x] & vb[x] else zero
    around = np.empty(w, np.float32)
    prev = np.zeros(w, np.bool_)  # step y - 1 is an edge
    cur = np.zeros(w, np.bool_)
    for y in range(m):
        if y >= 2 and y < m - 2:
            dm, dp = d[y - 2], d[y + 2]
            for x in range(w):
                around[x] = max(dm[x], dp[x])
        elif y >= 2:
            dm = d[y - 2]
            for x in range(w):
                around[x] = dm[x]
        elif y < m - 2:
            dp = d[y + 2]
            for x in range(w):
                around[x] = max(zero, dp[x])
        else:
            for x in range(w):
                around[x] = zero
        dr, za, zb = d[y], z[y + 1], z[y]
        for x in range(w):
            cur[x] = (dr[x] > rel * max(za[x], zb[x])) & (dr[x] > two * around[x])
        # pixel row y is beside step y - 1 or step y
        orow = out[y]
        for x in range(w):
            orow[x] = orow[x] | prev[x] | cur[x]
        prev, cur = cur, prev
    orow = out[m]
    for x in range(w):
        orow[x] = orow[x] | prev[x]


def upsample_classes(cls: NDArray[np.int8], valid: NDArray[np.bool_], k: int) -> NDArray[np.int8]:
    """Classes of a frame subsampled by ``k`` repeated back to full size, facing without a reading.

    Parameters
    ----------
    cls : ndarray of int8
        Classes of ``valid[::k, ::k]``.
    valid : ndarray of bool, shape (H, W)
        Pixels with a reading at full size.
    k : int
        Subsampling step.

    Returns
    -------
    ndarray of int8, shape (H, W)
    """
    return _upsample(cls, np.ascontiguousarray(valid), int(k))


@njit(cache=True, nogil=True)
def _upsample(cls: NDArray[np.int8], valid: NDArray[np.bool_], k: int) -> NDArray[np.int8]:
    # one pass for numpy's two repeats, crop, masked write and copy
    # (a table of source columns: an integer division per pixel made it several times slower;
    # each source row expanded once for its k rows, whose loop is then a select that vectorises)
    h, w = valid.shape
    out = np.empty((h, w), np.int8)
    src = np.empty(w, np.int64)
    for x in range(w):
        src[x] = x // k
    wide = np.empty(w, np.int8)
    face = np.int8(FACING)
    for y in range(h):
        if y % k == 0:
            crow = cls[y // k]
            for x in range(w):
                wide[x] = crow[src[x]]
        vrow = valid[y]
        orow = out[y]
        for x in range(w):
            orow[x] = wide[x] if vrow[x] else face
    return out
