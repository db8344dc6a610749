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
from depthgram.segmentation.surfaces import _inverse

__all__ = ["default_intrinsics", "orientation_classes"]

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
    inverse : ndarray of float32, shape (H, W, 2), optional
        ``1000 / depth_mm`` and the readings (1 / 0) as channels, as
        ``depthgram.segmentation.surfaces._inverse`` gives them, when the caller has them (the
        creases take the same).

    Returns
    -------
    classes : ndarray of int8, shape (H, W)
    """
    return _field(depth_mm, valid, intrinsics, window_px, oblique_deg, jump_rel, False, inverse)[0]


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
    # 1000 / Z (1/m keeps float32 well scaled) and the readings as 1 / 0, in one pass, as the
    # two channels of one image (one box filter for both: the same sums, a test)
    if inverse is None:
        inverse = _inverse(np.ascontiguousarray(depth_mm, np.float32), np.ascontiguousarray(valid, np.bool_))
    # a 3 x 3 valid-weighted mean, then differences over `step` px: the slope of a distant floor
    # (1/Z changes by 1 / (h fy) per row) must stand above the noise of one difference
    # the mean is defined wherever a 3 x 3 neighbour has a reading, which bridges a sieve of
    # dropouts (registered structured light keeps one pixel in four)
    inv3, has = _mean3(
        np.asarray(cv2.boxFilter(inverse, -1, (3, 3), normalize=False, borderType=cv2.BORDER_REPLICATE), np.float32)
    )
    step = max(1, window_px // 2)
    gx = _one_sided(inv3, has, step)
    gy = _one_sided_cols(inv3, has, step)
    # average the gradient over valid pixels only; holes neither pull it to zero nor fake edges.
    # Pixels whose slope is steeper than 80 degrees from the line of sight are left out too: on
    # both sides of an occlusion edge (a smoothed or flying pixel) they would fake a steep plane.
    fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
    steep = np.float32(math.tan(math.radians(80.0)))
    kept = _kept_slopes(gx, gy, has, inv3, np.float32(fx), np.float32(fy), steep)
    k = (window_px, window_px)
    # the count of kept slopes per window and their sums, as channels of one image: OpenCV's
    # row sums of a channel are a chain of dependent additions, three channels run three
    # chains side by side (the same sums as three one-channel filters, a test; 257 -> 159 us
    # at 320 x 240). _classify takes the count at least 1e-6 (np.maximum's float32)
    sums = np.asarray(cv2.boxFilter(kept, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE), np.float32)
    cos_t = math.cos(math.radians(oblique_deg))
    cls = _classify(
        sums,
        inv3,
        valid,
        _jumps(depth_mm, valid, jump_rel),
        _jumps_cols(np.ascontiguousarray(depth_mm), np.ascontiguousarray(valid), np.float32(jump_rel)),
        np.float32(fx),
        np.float32(fy),
        np.float32(cx),
        np.float32(cy),
        np.float32(cos_t),
    )
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
def _mean3(sums: NDArray[np.float32]) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    # the 3 x 3 mean of 1/Z where a neighbour has a reading, from the window sums (H, W, 2:
    # of 1/Z and of the readings, read back per row into buffers): numpy's
    # np.maximum(sum_m, 1e-6) (float32), float32 division and test against 0.5, in one pass
    h, w = sums.shape[0], sums.shape[1]
    flat = sums.reshape((h, 2 * w))
    si = np.empty(w, np.float32)
    sm = np.empty(w, np.float32)
    inv3 = np.empty((h, w), np.float32)
    has = np.empty((h, w), np.bool_)
    eps = np.float32(1e-6)
    half = np.float32(0.5)
    for y in range(h):
        fr = flat[y]
        for ux in range(np.uint64(w)):
            j = np.uint64(2) * ux
            si[ux] = fr[j]
            sm[ux] = fr[j + np.uint64(1)]
        ir = inv3[y]
        hr = has[y]
        for x in range(w):
            d = max(sm[x], eps)
            ir[x] = si[x] / d
            hr[x] = d > half
    return inv3, has


@njit(cache=True, nogil=True)
def _kept_slopes(
    gx: NDArray[np.float32],
    gy: NDArray[np.float32],
    has: NDArray[np.bool_],
    inv3: NDArray[np.float32],
    fx: np.float32,
    fy: np.float32,
    steep: np.float32,
) -> NDArray[np.float32]:
    # pixels with a mean and a slope under 80 degrees keep their slopes (others get 0): returns
    # (H, W, 3) channels 1 / 0 for kept, then the kept x and y slopes, one image for the box
    # filter. One pass for what numpy did in eight; float32 arithmetic as numpy's (its Python
    # scalars act as float32). Each row is computed into three buffers and then interleaved:
    # both loops vectorise (writing the channels straight away made it five times slower).
    h, w = gx.shape
    out = np.empty((h, 3 * w), np.float32)
    mk = np.empty(w, np.float32)
    kx = np.empty(w, np.float32)
    ky = np.empty(w, np.float32)
    zero = np.float32(0.0)
    one = np.float32(1.0)
    for y in range(h):
        ax = gx[y]
        ay = gy[y]
        hs = has[y]
        iv = inv3[y]
        for x in range(w):  # selects, no branch
            lim = steep * iv[x]
            keep = hs[x] & (abs(fx * ax[x]) <= lim) & (abs(fy * ay[x]) <= lim)
            mk[x] = one if keep else zero
            kx[x] = ax[x] if keep else zero
            ky[x] = ay[x] if keep else zero
        o = out[y]
        for ux in range(np.uint64(w)):
            j = np.uint64(3) * ux
            o[j] = mk[ux]
            o[j + np.uint64(1)] = kx[ux]
            o[j + np.uint64(2)] = ky[ux]
    return out.reshape((h, w, 3))


@njit(cache=True, nogil=True, error_model="numpy")
def _classify(
    sums: NDArray[np.float32],
    inv3: NDArray[np.float32],
    valid: NDArray[np.bool_],
    jump_r: NDArray[np.bool_],
    jump_c: NDArray[np.bool_],
    fx: np.float32,
    fy: np.float32,
    cx: np.float32,
    cy: np.float32,
    cos_t: np.float32,
) -> NDArray[np.int8]:
    # the class of each pixel from its window-mean slopes, in one pass instead of a dozen
    # full-frame float32 temporaries; the same float32 operations in the same order, so the
    # classes are those of the numpy expression (tests/reference.py). Branch-free over each
    # row, with numpy's division rules (no zero test; `den` is taken at least 1e-6 as
    # np.maximum did), so that the divisions and square roots vectorise: every pixel is
    # computed, then masked. A pixel beside an occlusion edge along its row or its column
    # (`jump_r`, `jump_c`) is facing. `sums` (H, W, 3): the window's count of kept slopes and
    # their x and y sums, read into three row buffers first (so that the loop still vectorises).
    h, w = inv3.shape
    flat = sums.reshape((h, 3 * w))
    sgx_r = np.empty(w, np.float32)
    sgy_r = np.empty(w, np.float32)
    den_r = np.empty(w, np.float32)
    cls = np.empty((h, w), np.int8)
    tiny = np.float32(1e-12)
    eps = np.float32(1e-6)
    ucol = np.empty(w, np.float32)  # u of each column once: the same float32 division
    for x in range(w):
        ucol[x] = (np.float32(x) - cx) / fx
    vert = np.int8(VERTICAL)
    horiz = np.int8(HORIZONTAL)
    face = np.int8(FACING)
    for y in range(h):
        v = (np.float32(y) - cy) / fy
        sr = flat[y]
        for ux in range(np.uint64(w)):
            j = np.uint64(3) * ux
            den_r[ux] = sr[j]
            sgx_r[ux] = sr[j + np.uint64(1)]
            sgy_r[ux] = sr[j + np.uint64(2)]
        gx = sgx_r
        gy = sgy_r
        dn = den_r
        iv = inv3[y]
        ok = valid[y]
        jr = jump_r[y]
        jc = jump_c[y]
        out = cls[y]
        for x in range(w):
            d = max(dn[x], eps)
            a = fx * (gx[x] / d)
            b = fy * (gy[x] / d)
            c = iv[x] - a * ucol[x] - b * v
            t = cos_t * (np.sqrt(a * a + b * b + c * c) + tiny)
            k = vert if abs(a) >= t else (horiz if abs(b) >= t else face)
            out[x] = k if ok[x] & ~(jr[x] | jc[x]) else face
    return cls


def _jumps(z: NDArray[np.float32], valid: NDArray[np.bool_], jump_rel: float) -> NDArray[np.bool_]:
    """Pixels beside an occlusion edge along rows.

    A step is an edge when it exceeds ``jump_rel`` of the depth and is more than twice the
    steps two pixels before and after it: a floor seen at a grazing angle makes large but
    steady steps, an occlusion one isolated step (or two, with a flying pixel between).
    """
    return _jumps_rows(np.ascontiguousarray(z), np.ascontiguousarray(valid), np.float32(jump_rel))


@njit(cache=True, nogil=True)
def _jumps_rows(z: NDArray[np.float32], valid: NDArray[np.bool_], rel: np.float32) -> NDArray[np.bool_]:
    # per row: the steps, then the edge test, then both neighbours of an edge step marked, each
    # a branch-free loop (selects, so they vectorise); the numpy version made seven full-frame
    # temporaries. float32 throughout, as numpy computed it.
    h, w = z.shape
    out = np.zeros((h, w), np.bool_)
    if w < 2:
        return out
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
            orow[x] = edge[x] | edge[x + 1]
    return out


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
    # one pass instead of ten full-frame numpy temporaries; same float32 arithmetic. The
    # columns with both neighbours in the frame take a loop of their own, free of index tests
    # and branches, which vectorises.
    h, w = inv.shape
    out = np.zeros((h, w), np.float32)
    fstep = np.float32(step)
    lo = min(step, w)
    hi = max(w - step, lo)
    for y in range(h):
        iv = inv[y]
        ok = valid[y]
        o = out[y]
        for x in range(lo):
            okf = x + step < w and ok[x + step] and ok[x]
            o[x] = _slope(iv[x + step] - iv[x] if okf else np.float32(0.0), np.float32(0.0), okf, False, fstep)
        # the interior through shifted views, indexed alike (as the columns' loop): vectorises
        ivf, ivc, ivb = iv[lo + step : hi + step], iv[lo:hi], iv[lo - step : hi - step]
        okf, okc, okb = ok[lo + step : hi + step], ok[lo:hi], ok[lo - step : hi - step]
        oc = o[lo:hi]
        for i in range(hi - lo):
            oc[i] = _slope(ivf[i] - ivc[i], ivc[i] - ivb[i], okf[i] & okc[i], okc[i] & okb[i], fstep)
        for x in range(hi, w):
            okb = x - step >= 0 and ok[x] and ok[x - step]
            o[x] = _slope(np.float32(0.0), iv[x] - iv[x - step] if okb else np.float32(0.0), False, okb, fstep)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _one_sided_cols(inv: NDArray[np.float32], valid: NDArray[np.bool_], step: int) -> NDArray[np.float32]:
    # _one_sided_rows along columns (same arithmetic), a whole row of columns at a time,
    # without the three transposed copies
    h, w = inv.shape
    out = np.zeros((h, w), np.float32)
    fstep = np.float32(step)
    zero = np.float32(0.0)
    for y in range(h):
        hasf = y + step < h
        hasb = y - step >= 0
        iv = inv[y]
        ok = valid[y]
        o = out[y]
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
    return out


@njit(cache=True, nogil=True)
def _jumps_cols(z: NDArray[np.float32], valid: NDArray[np.bool_], rel: np.float32) -> NDArray[np.bool_]:
    # _jumps_rows along columns (same float32 tests), a whole row of columns at a time, without
    # the transposed copies in and out, which cost more than the tests
    h, w = z.shape
    out = np.zeros((h, w), np.bool_)
    if h < 2:
        return out
    m = h - 1
    d = np.zeros((m, w), np.float32)
    edge = np.zeros((m + 2, w), np.bool_)  # edge[y + 1]: step y is an edge; guards at both ends
    zero = np.float32(0.0)
    two = np.float32(2.0)
    for y in range(m):
        for x in range(w):
            d[y, x] = abs(z[y + 1, x] - z[y, x]) if valid[y + 1, x] & valid[y, x] else zero
    for y in range(m):
        for x in range(w):
            around = d[y - 2, x] if y >= 2 else zero
            if y < m - 2:
                around = max(around, d[y + 2, x])
            edge[y + 1, x] = (d[y, x] > rel * max(z[y + 1, x], z[y, x])) & (d[y, x] > two * around)
    for y in range(h):
        for x in range(w):
            out[y, x] = edge[y, x] | edge[y + 1, x]
    return out


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
