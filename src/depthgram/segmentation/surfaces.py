"""Objects as depth-continuous surfaces bounded by depth jumps and concave creases.

The paper's global histogram groups pixels by depth band, which fails on real cameras in three
ways: an object spanning several bands is cut into slabs (a person walking toward a Kinect), a
small object without a histogram peak of its own is handed to the band of the wall behind it,
and two objects touching at one depth become one. Grouping by the surface instead avoids all
three: two neighbouring pixels belong to one object when their depths differ by no more than
the sensor can resolve (:class:`~depthgram.segmentation.sensor.SensorModel`) plus what a surface
sloping at up to ``max_slope_deg`` moves over the distance between them, and when no concave
crease (the inside corner where a mug stands against a box, or a box on a table) runs between
them. A convex edge (the corner of a box showing two faces, the rim of a cup) does not separate,
as in the convexity rule of LCCP (Stein et al., CVPR 2014): objects are convex where they bend.

The depth bands of the histogram still name each object's ``depth_label`` (the grammar's
``o_<label>``); they no longer decide which pixels belong together.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label import ACTIVE, BLOCK, HOLE
from depthgram.segmentation.label.stats import relabel_stats
from depthgram.segmentation.label.unionfind import resolve as _resolve
from depthgram.segmentation.label.unionfind import resolve_tables
from depthgram.segmentation.label.unionfind import union as _union
from depthgram.segmentation.order_stats import kth_smallest, next_smallest, percentile32
from depthgram.segmentation.sensor import SensorModel
from depthgram.segmentation.window import bits_range, exact_rows

__all__ = [
    "concave_creases",
    "crease_scale_px",
    "crease_state",
    "facing_halves",
    "keep_large",
    "label_surfaces",
    "loosen_small",
    "merge_openings",
    "reattach",
    "surface_state",
    "surfaces_kept",
]


def crease_scale_px(width_px: int) -> int:
    """Distance (px) over which creases are looked for: about 1/128 of the frame width.

    A crease is a change of slope; it must be judged over a span wider than the sensor's
    smoothing (structured light correlates over 7-9 px windows) yet narrower than the objects.
    """
    return max(2, round(width_px / 128))


@njit(cache=True, nogil=True)
def facing_halves(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], include: NDArray[np.bool_], none_mm: float
) -> tuple[NDArray[np.bool_], NDArray[np.float32], NDArray[np.bool_], float]:
    """Return the facing readings and what the depth labels' histogram reads of them, in one call.

    ``valid & include``; its every 2nd row and column of depth and of the mask (as
    ``np.ascontiguousarray(depth[::2, ::2])``); and the 95th percentile (``np.percentile``'s
    value) of the depths of every 4th row and column of the facing readings, or ``none_mm``
    when there are none. One compiled call for six numpy calls on small frames.
    """
    h, w = depth.shape
    facing = np.empty((h, w), np.bool_)
    for y in range(h):
        f, v, inc = facing[y], valid[y], include[y]
        for x in range(w):
            f[x] = v[x] & inc[x]
    h2 = (h + 1) // 2
    w2 = (w + 1) // 2
    d2 = np.empty((h2, w2), np.float32)
    m2 = np.empty((h2, w2), np.bool_)
    for i in range(h2):
        for j in range(w2):
            d2[i, j] = depth[2 * i, 2 * j]
            m2[i, j] = facing[2 * i, 2 * j]
    sample = np.empty(((h2 + 1) // 2) * ((w2 + 1) // 2), np.float32)
    k = 0
    for i in range(0, h2, 2):
        for j in range(0, w2, 2):
            if m2[i, j]:
                sample[k] = d2[i, j]
                k += 1
    far = percentile32(sample[:k], 95.0, True) if k else none_mm
    return facing, d2, m2, far


def concave_creases(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    sensor: SensorModel,
    *,
    scale_px: int,
    min_angle_deg: float,
    focal_px: float,
    inverse: NDArray[np.float32] | None = None,
) -> NDArray[np.bool_]:
    """Pixels on a concave crease (an inside corner seen from the camera).

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid.
    valid : ndarray of bool
        Pixels with a reading.
    sensor : SensorModel
        Sets the noise floor of the test.
    scale_px : int
        Half-span (px) of the second difference.
    min_angle_deg : float
        Smallest bend (degrees) between the two surfaces that counts as a crease, for a surface
        facing the sensor.
    focal_px : float
        Focal length (px).
    inverse : ndarray of float32, shape (2, H, W), optional
        ``1000 / depth_mm`` and the readings (1 / 0) of this frame as :func:`_inverse` gives
        them, when the caller has them (the orientation field takes the same): read where the
        creases are taken on every pixel.

    Returns
    -------
    ndarray of bool, shape (H, W)

    Notes
    -----
    A plane is affine in inverse depth ``w = 1/z`` (see :mod:`depthgram.segmentation.orientation`),
    so the second difference ``w(p - r e) + w(p + r e) - 2 w(p)`` is zero on any plane whatever
    its slant, positive where the surface bends away from the camera on both sides (concave,
    an inside corner: depth has a ridge) and negative where it bends toward it (convex). Divided
    by ``w``, a bend between two surfaces with slopes ``tan a`` and ``tan b`` toward the camera
    gives about ``r (tan a + tan b) / f`` whatever the depth. It is taken along rows, columns
    and both diagonals of a valid-weighted box mean; a span across a depth jump is skipped (it
    is an occlusion edge, not a crease). The threshold is the larger of the bend of
    ``min_angle_deg`` and four times the noise of the smoothed second difference.
    """
    if depth_mm.shape[1] > 320 and scale_px >= 4:
        # a crease is a band about 2 r wide: on every 2nd pixel of a wide frame it is found at
        # a quarter of the cost, with half the span and focal length
        sub = concave_creases(
            np.ascontiguousarray(depth_mm[::2, ::2]),
            np.ascontiguousarray(valid[::2, ::2]),
            sensor,
            scale_px=scale_px // 2,
            min_angle_deg=min_angle_deg,
            focal_px=focal_px / 2.0,
        )
        return _upsample2(sub, np.ascontiguousarray(valid, np.bool_))
    k, geom, noise_scale = _crease_factors(scale_px, min_angle_deg, focal_px)
    if not _compiled_model(sensor):
        return _creases_numpy(depth_mm, valid, sensor, scale_px, k, geom, noise_scale)
    im, ok, c32, min_den, r = _crease_inputs(depth_mm, valid, sensor, scale_px, k, inverse)
    creases, exact = _creases_window(im, ok, c32, min_den, k, r, geom, noise_scale)
    if exact:
        return creases
    return _creases(_window_sums(im, k), ok, c32, min_den, r, geom, noise_scale)


def _crease_factors(scale_px: int, min_angle_deg: float, focal_px: float) -> tuple[int, np.float32, np.float32]:
    """Return the creases' window width (px), bend of ``min_angle_deg`` over the span, and noise factor."""
    k = 2 * (scale_px // 2) + 1
    geom = np.float32(scale_px * math.tan(math.radians(min_angle_deg)) / focal_px)
    noise_scale = np.float32(math.sqrt(6.0) / (0.7 * k))
    return k, geom, noise_scale


def _compiled_model(sensor: SensorModel) -> bool:
    """Whether the compiled creases repeat this model's arithmetic (else the numpy route).

    A model's coefficients are float values: numpy float scalars are taken as the floats they
    hold, whose float32 arithmetic the compiled route repeats (the numpy route would compute in
    float64 with them: strong scalars). Only another model's arithmetic, or coefficients of
    another kind, go the numpy way.
    """
    coefs = (sensor.step_0, sensor.step_2, sensor.sigma_0, sensor.sigma_2)
    plain = all(type(c) in (int, float, np.float64, np.float32) for c in coefs)
    return plain and type(sensor).resolution is SensorModel.resolution


def _crease_inputs(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    sensor: SensorModel,
    scale_px: int,
    k: int,
    inverse: NDArray[np.float32] | None,
) -> tuple[Any, ...]:
    # the compiled route's arguments: 1000 / z and the readings (2, H, W), the readings,
    # coefficients, the least count of readings, span
    z = np.ascontiguousarray(depth_mm, np.float32)
    ok = np.ascontiguousarray(valid, np.bool_)
    im = inverse if inverse is not None else _inverse(z, ok)
    # the sensor's coefficients as float32, as numpy's scalar rules make Python floats in
    # _creases_numpy
    coefs = (sensor.step_0, sensor.step_2, sensor.sigma_0, sensor.sigma_2)
    c32 = np.array([float(c) for c in coefs], np.float32)
    return im, ok, c32, np.float32(0.5 * k * k), int(scale_px)


def _window_sums(im: NDArray[np.float32], k: int) -> NDArray[np.float32]:
    # OpenCV's k x k window sums of 1000 / z and the readings, for a frame whose values
    # window.exact_rows refused: both from one two-channel filter (the same sums as one
    # filter each, a test)
    img = cv2.merge([im[0], im[1]])
    return np.asarray(cv2.boxFilter(img, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT), np.float32)


def crease_state(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    facing: NDArray[np.bool_],
    sensor: SensorModel,
    *,
    scale_px: int,
    min_angle_deg: float,
    focal_px: float,
    inverse: NDArray[np.float32] | None = None,
) -> NDArray[np.int8]:
    """Labeller state of :func:`label_surfaces` with the frame's concave creases blocking.

    ``surface_state(valid, facing, concave_creases(...))`` (the same arguments), in one
    compiled call where :func:`concave_creases` takes its compiled route: the creases go to
    the state row by row, without a crease map.
    """
    wide = depth_mm.shape[1] > 320 and scale_px >= 4
    if wide or not _compiled_model(sensor):
        creases = concave_creases(
            depth_mm, valid, sensor, scale_px=scale_px, min_angle_deg=min_angle_deg, focal_px=focal_px, inverse=inverse
        )
        return surface_state(np.ascontiguousarray(valid, np.bool_), np.ascontiguousarray(facing, np.bool_), creases)
    k, geom, noise_scale = _crease_factors(scale_px, min_angle_deg, focal_px)
    im, ok, c32, min_den, r = _crease_inputs(depth_mm, valid, sensor, scale_px, k, inverse)
    face = np.ascontiguousarray(facing, np.bool_)
    # the window sums taken row by row in the same call, OpenCV's to the last bit where
    # window.exact_rows holds (always on real frames so far), else OpenCV's
    state, exact = _crease_state_window(im, ok, face, c32, min_den, k, r, geom, noise_scale)
    if exact:
        return state
    return _crease_state(_window_sums(im, k), ok, face, c32, min_den, r, geom, noise_scale)


@njit(cache=True, nogil=True, error_model="numpy")
def _inverse(z: NDArray[np.float32], valid: NDArray[np.bool_]) -> NDArray[np.float32]:
    # (2, H, W): 1000 / z and 1 where there is a reading, else 0, as two planes (the window
    # sums read each plane's rows: the readings' in float32, whole numbers). Every pixel
    # divided and masked (numpy's division rule, no zero test), so that the loop vectorises
    h, w = z.shape
    out = np.empty((2, h, w), np.float32)
    thousand = np.float32(1000.0)
    zero = np.float32(0.0)
    one = np.float32(1.0)
    for y in range(h):
        zr = z[y]
        vr = valid[y]
        inv = out[0, y]
        m = out[1, y]
        for x in range(w):
            ok = vr[x]
            q = thousand / zr[x]
            inv[x] = q if ok else zero
            m[x] = one if ok else zero
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _creases(
    sums: NDArray[np.float32],
    valid: NDArray[np.bool_],
    c: NDArray[np.float32],
    min_den: np.float32,
    r: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> NDArray[np.bool_]:
    # _creases_numpy in two passes instead of about 60 full-frame temporaries: the window
    # means and the threshold of each pixel (_crease_means), then each row's four directions
    # (_crease_row). Every operation is the float32 one numpy does there, in the same order (no
    # fast-math, no contraction), so the same creases (a test compares the two). `sums`
    # (H, W, 2): the window sums of 1000 / z and of the readings.
    ws, has, bend = _crease_means(sums, valid, c, min_den, geom, noise_scale)
    return _creases_from(ws, has, bend, r)


@njit(cache=True, nogil=True, error_model="numpy")
def _creases_window(
    inverse: NDArray[np.float32],
    valid: NDArray[np.bool_],
    c: NDArray[np.float32],
    min_den: np.float32,
    k: int,
    r: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> tuple[NDArray[np.bool_], bool]:
    # _creases of OpenCV's k x k window sums of `inverse` (2, H, W), taken in the same call
    # (_crease_means_window), and True; False (and nothing computed) where they could differ
    # from OpenCV's
    ws, has, bend, exact = _crease_means_window(inverse, valid, c, min_den, k, geom, noise_scale)
    if not exact:
        return np.empty((0, 0), np.bool_), False
    return _creases_from(ws, has, bend, r), True


@njit(cache=True, inline="always", error_model="numpy")
def _creases_from(
    ws: NDArray[np.float32], has: NDArray[np.bool_], bend: NDArray[np.float32], r: int
) -> NDArray[np.bool_]:
    h, w = ws.shape
    out = np.empty((h, w), np.bool_)
    for y in range(h):
        _crease_row(ws, has, bend, y, r, out[y])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _crease_state(
    sums: NDArray[np.float32],
    valid: NDArray[np.bool_],
    facing: NDArray[np.bool_],
    c: NDArray[np.float32],
    min_den: np.float32,
    r: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> NDArray[np.int8]:
    # surface_state(valid, facing, _creases(...)) in one call: each row's creases go to the
    # labeller's state from a row buffer (no crease map, no pass of its own)
    ws, has, bend = _crease_means(sums, valid, c, min_den, geom, noise_scale)
    return _state_from(ws, has, bend, valid, facing, r)


@njit(cache=True, nogil=True, error_model="numpy")
def _crease_state_window(
    inverse: NDArray[np.float32],
    valid: NDArray[np.bool_],
    facing: NDArray[np.bool_],
    c: NDArray[np.float32],
    min_den: np.float32,
    k: int,
    r: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> tuple[NDArray[np.int8], bool]:
    # _crease_state of OpenCV's k x k window sums of `inverse` (2, H, W), taken in the same
    # call (_crease_means_window), and True; False (and nothing computed) where they could
    # differ from OpenCV's
    ws, has, bend, exact = _crease_means_window(inverse, valid, c, min_den, k, geom, noise_scale)
    if not exact:
        return np.empty((0, 0), np.int8), False
    return _state_from(ws, has, bend, valid, facing, r), True


@njit(cache=True, inline="always", error_model="numpy")
def _state_from(
    ws: NDArray[np.float32],
    has: NDArray[np.bool_],
    bend: NDArray[np.float32],
    valid: NDArray[np.bool_],
    facing: NDArray[np.bool_],
    r: int,
) -> NDArray[np.int8]:
    h, w = valid.shape
    state = np.empty((h, w), np.int8)
    row = np.empty(w, np.bool_)
    active = np.int8(ACTIVE)
    block = np.int8(BLOCK)
    hole = np.int8(HOLE)
    for y in range(h):
        _crease_row(ws, has, bend, y, r, row)
        sr = state[y]
        vr = valid[y]
        fr = facing[y]
        for x in range(w):
            sr[x] = (active if fr[x] > row[x] else block) if vr[x] else hole
    return state


@njit(cache=True, inline="always", error_model="numpy")
def _crease_means(
    sums: NDArray[np.float32],
    valid: NDArray[np.bool_],
    c: NDArray[np.float32],
    min_den: np.float32,
    geom: np.float32,
    noise_scale: np.float32,
) -> tuple[NDArray[np.float32], NDArray[np.bool_], NDArray[np.float32]]:
    # each pixel's window mean of 1000 / z (0 without enough readings), whether it has one
    # where there is a reading, and its bend threshold times the mean; the window sums are
    # read back per row into buffers. Every pixel computed, then masked (numpy's division
    # rule: a window without enough readings divides by a small or zero count harmlessly), so
    # that the divisions vectorise
    h, w = valid.shape
    flat = sums.reshape((h, 2 * w))
    ws = np.empty((h, w), np.float32)
    dr = np.empty(w, np.float32)
    has = np.empty((h, w), np.bool_)
    bend = np.empty((h, w), np.float32)
    for y in range(h):
        wr = ws[y]
        fr = flat[y]
        for ux in range(np.uint64(w)):
            j = np.uint64(2) * ux
            wr[ux] = fr[j]
            dr[ux] = fr[j + np.uint64(1)]
        _crease_mean_row(wr, dr, valid[y], has[y], bend[y], c, min_den, geom, noise_scale)
    return ws, has, bend


@njit(cache=True, inline="always", error_model="numpy")
def _crease_means_window(
    inverse: NDArray[np.float32],
    valid: NDArray[np.bool_],
    c: NDArray[np.float32],
    min_den: np.float32,
    k: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> tuple[NDArray[np.float32], NDArray[np.bool_], NDArray[np.float32], bool]:
    # _crease_means of OpenCV's k x k window sums of `inverse` (2, H, W) (zeros outside the
    # frame), the sums taken row by row here (a column sum running down the rows, then the k
    # columns across), in an order of our own: OpenCV's to the last bit when
    # window.exact_rows holds for the rows' ranges of 1000 / z (the readings are 1 or 0).
    # Otherwise nothing is computed and the flag is False (the caller takes OpenCV's filter)
    h, w = valid.shape
    r = k // 2
    iv, rd = inverse[0], inverse[1]
    hi = np.empty(h, np.int64)
    lo = np.empty(h, np.int64)
    for y in range(h):  # the readings (whole numbers) need no test
        hi[y], lo[y] = bits_range(iv[y])
    ws = np.empty((h, w), np.float32)
    has = np.empty((h, w), np.bool_)
    bend = np.empty((h, w), np.float32)
    if not exact_rows(hi, lo, k * k, r + 1, r):
        return ws, has, bend, False
    # per plane: the column sums in the middle of a row padded by r zeros each side (the
    # readings in float32, whole numbers up to k * k)
    pad_i = np.zeros(w + 2 * r, np.float64)
    pad_m = np.zeros(w + 2 * r, np.float32)
    mid_i, mid_m = pad_i[r : r + w], pad_m[r : r + w]
    for d in range(min(r, h - 1) + 1):  # the rows above the first are zeros
        a, b = iv[d], rd[d]
        for x in range(w):
            mid_i[x] += a[x]
            mid_m[x] += b[x]
    acc_i = np.empty(w, np.float64)
    acc_m = np.empty(w, np.float32)
    dr = np.empty(w, np.float32)
    for y in range(h):
        if y > 0:
            add = y + r < h
            sub = y - r - 1 >= 0
            if add and sub:
                an, bn, ao, bo = iv[y + r], rd[y + r], iv[y - r - 1], rd[y - r - 1]
                for x in range(w):
                    mid_i[x] = (mid_i[x] + an[x]) - ao[x]
                    mid_m[x] = (mid_m[x] + bn[x]) - bo[x]
            elif add:
                an, bn = iv[y + r], rd[y + r]
                for x in range(w):
                    mid_i[x] += an[x]
                    mid_m[x] += bn[x]
            elif sub:
                ao, bo = iv[y - r - 1], rd[y - r - 1]
                for x in range(w):
                    mid_i[x] -= ao[x]
                    mid_m[x] -= bo[x]
        wr = ws[y]
        if r == 1:
            for x in range(w):
                wr[x] = np.float32((pad_i[x] + pad_i[x + 1]) + pad_i[x + 2])
                dr[x] = (pad_m[x] + pad_m[x + 1]) + pad_m[x + 2]
        else:
            for x in range(w):
                acc_i[x] = pad_i[x]
                acc_m[x] = pad_m[x]
            for d in range(1, 2 * r + 1):
                for x in range(w):
                    acc_i[x] += pad_i[x + d]
                    acc_m[x] += pad_m[x + d]
            for x in range(w):
                wr[x] = np.float32(acc_i[x])
                dr[x] = acc_m[x]
        _crease_mean_row(wr, dr, valid[y], has[y], bend[y], c, min_den, geom, noise_scale)
    return ws, has, bend, True


@njit(cache=True, inline="always", error_model="numpy")
def _crease_mean_row(
    wr: NDArray[np.float32],
    dr: NDArray[np.float32],
    vr: NDArray[np.bool_],
    hr: NDArray[np.bool_],
    br: NDArray[np.float32],
    c: NDArray[np.float32],
    min_den: np.float32,
    geom: np.float32,
    noise_scale: np.float32,
) -> None:
    # one row of _crease_means: `wr` (the window sums of 1000 / z in, the means out), `dr`
    # (the window counts of readings); `hr` and `br` out
    thousand = np.float32(1000.0)
    one = np.float32(1.0)
    two = np.float32(2.0)
    four = np.float32(4.0)
    c0, c1, c2, c3 = c[0], c[1], c[2], c[3]
    zero = np.float32(0.0)
    for x in range(wr.size):
        keep = dr[x] >= min_den
        wc = wr[x] / dr[x]
        z = thousand / wc
        sq = z * z
        res = max(c0 + c1 * sq, two * (c2 + c3 * sq))
        noise = res / two / max(z, one) * noise_scale
        hr[x] = keep & vr[x]  # the result is kept where there is a reading only
        wr[x] = wc if keep else zero
        br[x] = max(geom, four * noise) * wc if keep else zero


@njit(cache=True, inline="always", error_model="numpy")
def _crease_row(
    ws: NDArray[np.float32],
    has: NDArray[np.bool_],
    bend: NDArray[np.float32],
    y: int,
    r: int,
    out: NDArray[np.bool_],
) -> None:
    # row y's creases: along the row, the column and both diagonals, each one branch-free
    # loop that vectorises (a per-pixel loop with the four tests behind branches took 3x as
    # long); the neighbours' own `has` is not needed: a neighbour without a mean reads 0
    # here, which fails the jump test against a positive mean as it failed numpy's validity
    # test. Neighbours `r` places on are read through views (an index x + r would be wrapped
    # as a possibly negative one)
    h, w = ws.shape
    two = np.float32(2.0)
    jump = np.float32(0.06)
    ur = np.uint64(r)
    uw = np.uint64(w)
    wr = ws[y]
    hr = has[y]
    er = bend[y]
    out[:] = False
    if w > 2 * r:
        left = wr[: w - 2 * r]
        right = wr[2 * r :]
        for ux in range(ur, uw - ur):
            wc = wr[ux]
            a = right[ux - ur]
            b = left[ux - ur]
            lim = jump * wc
            out[ux] = hr[ux] & (abs(a - wc) <= lim) & (abs(b - wc) <= lim) & ((a + b) - two * wc > er[ux])
    if y < r or y >= h - r:
        return
    dn = ws[y + r]
    up = ws[y - r]
    for ux in range(uw):
        wc = wr[ux]
        a = dn[ux]
        b = up[ux]
        lim = jump * wc
        out[ux] |= hr[ux] & (abs(a - wc) <= lim) & (abs(b - wc) <= lim) & ((a + b) - two * wc > er[ux])
    if w <= 2 * r:
        return
    dn_right = dn[2 * r :]
    up_right = up[2 * r :]
    for ux in range(ur, uw - ur):
        # down right and up left
        wc = wr[ux]
        a = dn_right[ux - ur]
        b = up[ux - ur]
        lim = jump * wc
        out[ux] |= hr[ux] & (abs(a - wc) <= lim) & (abs(b - wc) <= lim) & ((a + b) - two * wc > er[ux])
    for ux in range(ur, uw - ur):
        # down left and up right
        wc = wr[ux]
        a = dn[ux - ur]
        b = up_right[ux - ur]
        lim = jump * wc
        out[ux] |= hr[ux] & (abs(a - wc) <= lim) & (abs(b - wc) <= lim) & ((a + b) - two * wc > er[ux])


@njit(cache=True, nogil=True)
def _upsample2(sub: NDArray[np.bool_], valid: NDArray[np.bool_]) -> NDArray[np.bool_]:
    # each pixel of the half-resolution map repeated 2 x 2, where there is a reading
    # each half-resolution row expanded once for its two rows, whose loop then vectorises
    h, w = valid.shape
    out = np.zeros((h, w), np.bool_)
    wide = np.empty(w, np.bool_)
    for y in range(h):
        if y & 1 == 0:
            srow = sub[y >> 1]
            for x in range(w):
                wide[x] = srow[x >> 1]
        vrow = valid[y]
        orow = out[y]
        for x in range(w):
            orow[x] = wide[x] & vrow[x]
    return out


def _creases_numpy(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    sensor: SensorModel,
    scale_px: int,
    k: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> NDArray[np.bool_]:
    """:func:`concave_creases` at full resolution in numpy.

    The reference of the compiled :func:`_creases`, and the route for a sensor model whose
    arithmetic it does not know.
    """
    h, w = depth_mm.shape
    inv = np.zeros((h, w), np.float32)
    np.divide(np.float32(1000.0), depth_mm, out=inv, where=valid)
    m = valid.astype(np.float32)
    den = np.asarray(cv2.boxFilter(m, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT), np.float32)
    ws = np.asarray(cv2.boxFilter(inv, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT), np.float32)
    has = den >= 0.5 * k * k
    np.divide(ws, den, out=ws, where=has)
    ws[~has] = 0.0
    z = np.zeros_like(ws)
    np.divide(np.float32(1000.0), ws, out=z, where=has)
    # relative noise of w equals that of z; a mean over ~k*k/2 readings and a second difference
    # of three such means (variance 6x)
    rel_noise = np.asarray(sensor.resolution(z), np.float32) / 2.0 / np.maximum(z, 1.0)
    noise = rel_noise * noise_scale
    thr = np.maximum(geom, 4.0 * noise)
    out = np.zeros((h, w), np.bool_)
    r = scale_px
    jump = np.float32(0.06)
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a, ha = _shifted(ws, has, dy * r, dx * r)
        b, hb = _shifted(ws, has, -dy * r, -dx * r)
        sec = (a + b) - 2.0 * ws
        ok = has & ha & hb
        ok &= np.abs(a - ws) <= jump * ws
        ok &= np.abs(b - ws) <= jump * ws
        out |= ok & (sec > thr * ws)
    return out & valid


def _shifted(
    img: NDArray[np.float32], has: NDArray[np.bool_], dy: int, dx: int
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """``img[y + dy, x + dx]`` at every pixel, with ``False`` validity outside the frame."""
    h, w = img.shape
    out = np.zeros_like(img)
    ok = np.zeros_like(has)
    ys, yd = (slice(dy, h), slice(0, h - dy)) if dy >= 0 else (slice(0, h + dy), slice(-dy, h))
    xs, xd = (slice(dx, w), slice(0, w - dx)) if dx >= 0 else (slice(0, w + dx), slice(-dx, w))
    out[yd, xd] = img[ys, xs]
    ok[yd, xd] = has[ys, xs]
    return out, ok


def label_surfaces(
    depth_mm: NDArray[np.float32],
    state: NDArray[np.int8],
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
    bridge_px: int,
) -> tuple[NDArray[np.int32], int]:
    """4-connected components of active pixels whose depths are continuous.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm).
    state : ndarray of int8, shape (H, W)
        :data:`~depthgram.segmentation.label.HOLE` (no reading: bridged),
        :data:`~depthgram.segmentation.label.ACTIVE` (to label) or
        :data:`~depthgram.segmentation.label.BLOCK` (never crossed).
    tol_0, tol_2 : float
        Depth tolerance ``tol_0 + tol_2 z**2`` (mm) between two readings of one surface.
    slope_per_px : float
        Depth a surface may move per pixel of distance, per mm of depth (``tan(max_slope) / f``).
    bridge_px : int
        Longest run of holes crossed along a row or column.

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
        1..n in raster order of each component's first pixel; 0 elsewhere.
    n : int
    """
    lab, parent, nxt, _ = _label_surfaces(
        np.ascontiguousarray(depth_mm, np.float32),
        np.ascontiguousarray(state, np.int8),
        float(tol_0),
        float(tol_2),
        float(slope_per_px),
        int(bridge_px),
    )
    labels, n, _, _ = _resolve(lab, parent, nxt, _NO_SUMS, _NO_BOXES, 0, False)
    return labels, int(n)


def surfaces_kept(
    depth_mm: NDArray[np.float32],
    state: NDArray[np.int8],
    facing: NDArray[np.bool_],
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
    bridge_px: int,
    min_px: int,
    max_px: int,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    """Return the surfaces of ``min_px`` pixels or more once loose pixels are reattached, with statistics.

    :func:`label_surfaces`, :func:`loosen_small`, :func:`reattach` (up to ``max_px`` steps) and
    :func:`keep_large` in a row, with the same labels and statistics, in fewer passes over
    the frame: the labeller counts its pixels; one pass marks the loose pixels and the seeds
    of the growth, which works in place on the provisional labels read through their final
    ids; one pass relabels with the statistics. No pass counts labels again: the surfaces
    left after loosening all have ``min_px`` pixels or more and growth only adds to them, so
    ``keep_large`` keeps exactly those.

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
        1..n as :func:`keep_large` numbers them; 0 elsewhere.
    n : int
    sums : ndarray of float64, shape (n + 1, N_COLUMNS)
    boxes : ndarray of int64, shape (n + 1, 4)
        The statistics table and inclusive boxes of :func:`keep_large`.
    """
    z = np.ascontiguousarray(depth_mm, np.float32)
    lab, parent, nxt, pcount = _label_surfaces(
        z, np.ascontiguousarray(state, np.int8), float(tol_0), float(tol_2), float(slope_per_px), int(bridge_px)
    )
    table, count = _kept_table(lab, parent, nxt, pcount, int(min_px))
    _loosen_grow(
        lab,
        table,
        np.ascontiguousarray(facing, np.bool_),
        z,
        float(tol_0),
        float(tol_2),
        float(slope_per_px),
        int(max_px),
    )
    labels, n, sums, boxes = _keep_through(lab, table, count, int(min_px), z)
    return labels, int(n), sums, boxes


@njit(cache=True, nogil=True)
def _kept_table(
    lab: NDArray[np.int32], parent: NDArray[np.int32], nxt: int, pcount: NDArray[np.int64], min_px: int
) -> tuple[NDArray[np.int32], NDArray[np.int64]]:
    # provisional label -> the final one resolve gives it (raster order of first pixels), or 0
    # for surfaces under min_px pixels (loosen_small); and the pixels per final label (0 for
    # the loosened ones)
    final, n, _, _ = resolve_tables(lab, parent, nxt, _NO_SUMS, _NO_BOXES, 0, False)
    count = np.zeros(n + 1, np.int64)
    for i in range(1, nxt):
        count[final[i]] += pcount[i]
    small = count < min_px
    small[0] = True
    table = np.zeros(nxt, np.int32)
    for i in range(1, nxt):
        table[i] = 0 if small[final[i]] else final[i]
    for i in range(n + 1):
        if small[i]:
            count[i] = 0
    return table, count


@njit(cache=True, nogil=True)
def _loosen_grow(
    lab: NDArray[np.int32],
    table: NDArray[np.int32],
    facing: NDArray[np.bool_],
    depth: NDArray[np.float32],
    t0: float,
    t2: float,
    sl: float,
    max_steps: int,
) -> None:
    # Hand-written: a breadth-first growth with a per-step depth test has no library kernel
    # (a distance transform finds the nearest label but cannot follow the surface).
    # loosen_small and reattach's growth on labels read through `table` (a pixel's label is
    # table[lab]; reattach passes final labels and the identity table): one pass marks the
    # loose pixels (facing, label 0) and queues the seeds (loose, beside a labelled pixel) in
    # raster order, then the breadth-first growth; a grown pixel takes its neighbour's label
    # in `lab`, which is the same label through the table. `lab` is written in place.
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
                    (x > 0 and table[lab[y, x - 1]] > 0)
                    or (x < w - 1 and table[lab[y, x + 1]] > 0)
                    or (y > 0 and table[lab[y - 1, x]] > 0)
                    or (y < h - 1 and table[lab[y + 1, x]] > 0)
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
            if yy < 0 or yy >= h or xx < 0 or xx >= w or table[lab[yy, xx]] == 0:
                continue
            zz = depth[yy, xx]
            zm = min(z, zz)
            if abs(z - zz) <= t0 + t2 * zm * zm + sl * zm:
                best = lab[yy, xx]
                break
        if best == 0:
            continue
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
def _keep_through(
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


#: Stand-ins for the statistics :func:`depthgram.segmentation.label.unionfind.resolve` does not read here.
_NO_SUMS = np.zeros((1, 8), np.float64)
_NO_BOXES = np.zeros((1, 4), np.int32)


@njit(cache=True, inline="always")
def _continuous(za: np.float32, zb: np.float32, gap: int, t0: float, t2: float, sl: float) -> bool:
    zm = min(za, zb)
    return bool(abs(za - zb) <= t0 + t2 * zm * zm + gap * sl * zm)


@njit(cache=True, nogil=True)
def _label_surfaces(
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


def reattach(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    loose: NDArray[np.bool_],
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
    max_px: int,
) -> NDArray[np.int32]:
    """Grow labels into loose pixels (a crease, a dropped speck) along depth-continuous paths.

    A loose pixel takes the label of a 4-neighbour that has one when their depths are
    continuous as :func:`label_surfaces` tests them, at most ``max_px`` steps from the labelled
    pixel it started from; the others stay 0. Breadth first, so each pixel goes to the nearest
    surface it continues. Returns a new array.
    """
    out = np.array(labels, dtype=np.int32, copy=True)
    if loose.any():
        # the default's growth on provisional labels, here through the identity table
        _loosen_grow(
            out,
            np.arange(int(out.max(initial=0)) + 1, dtype=np.int32),
            np.ascontiguousarray(loose, np.bool_),
            np.ascontiguousarray(depth_mm, np.float32),
            float(tol_0),
            float(tol_2),
            float(slope_per_px),
            int(max_px),
        )
    return out


def merge_openings(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    boxes: NDArray[np.int64],
    z_mean: NDArray[np.float64],
    *,
    focal_px: float,
    ring_px: int,
    jump_mm: NDArray[np.float32] | float,
    min_share: float = 0.3,
) -> NDArray[np.int32] | None:
    """Join the inside of a cup, bowl or open box to the object around it.

    Seen from above, the inside of a cup is a surface of its own: the near rim hides its lower
    part behind a depth step, and a structured-light camera loses the thin rim itself. It is
    recognised by how it borders the rest of the frame: a surface R is the inside of a nearer
    surface A when

    - at least ``min_share`` of R's border ring (``ring_px`` wide, valid pixels) lies on A,
      and A is nearer there (R is seen past A's edge);
    - little of the rest of the ring (at most 15 %) lies at R's depth: R borders other things
      only across depth steps (it occludes them or they occlude it), so it does not rest on
      or continue into anything but A;
    - R lies within A's columns, and no deeper behind A than A is wide (an opening is inside
      its object).

    An object standing behind A and narrower than it, no farther behind it than A is wide and
    visible only above it, would pass the same tests; the tabletop recordings show none.

    Parameters
    ----------
    labels : ndarray of int32, shape (H, W)
        Surfaces 1..n.
    depth_mm : ndarray of float32
        Depth (mm), 0 where invalid.
    boxes : ndarray of int, shape (n + 1, 4)
        Inclusive (x0, y0, x1, y1) of each label; row 0 unused.
    z_mean : ndarray of float, shape (n + 1,)
        Mean depth (mm) of each label.
    focal_px : float
        Focal length (px), for the metric width of A.
    ring_px : int
        Width (px) of the border ring read around R.
    jump_mm : float
        Depth difference (mm) beyond which a ring pixel is across a step from R.
    min_share : float
        Share of R's ring that must lie on A.

    Returns
    -------
    ndarray of int32 or None
        Lookup table old label -> new label (1..m), or None when nothing joins.
    """
    n = z_mean.size - 1
    if n < 2:
        return None
    jump = float(np.max(jump_mm)) if np.ndim(jump_mm) else float(jump_mm)
    table = _openings_table(
        labels,
        depth_mm,
        np.ascontiguousarray(boxes, np.int64),
        np.ascontiguousarray(z_mean, np.float64),
        float(focal_px),
        int(ring_px),
        jump,
        float(min_share),
    )
    return table if table.size else None


@njit(cache=True, nogil=True)
def _openings_table(
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
        _opening_parents(labels, depth, objs, z_mean, todo[:k], parent, ring_px, jump, min_share, focal_px)
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
def _opening_parents(
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
        if _median32(on_a) >= zr:
            continue
        parent[r] = a


@njit(cache=True, nogil=True)
def _median32(a: NDArray[np.float32]) -> Any:
    # np.median of float32 values, in float32 as numpy computes it (the mean of the two middle
    # values of an even count)
    n = a.size
    h = n // 2
    if n % 2:
        return kth_smallest(a, h)
    # the order statistics come back as float64 (exact); their mean is taken in float32
    lo = np.float32(kth_smallest(a, h - 1))
    hi = np.float32(next_smallest(a, h - 1))
    return (lo + hi) / np.float32(2.0)


@njit(cache=True, nogil=True)
def surface_state(valid: NDArray[np.bool_], facing: NDArray[np.bool_], creases: NDArray[np.bool_]) -> NDArray[np.int8]:
    """Labeller state of :func:`label_surfaces`.

    Facing pixels off a crease are active, other readings block, pixels without a reading are holes
    (one pass for numpy's four).
    """
    h, w = valid.shape
    out = np.empty((h, w), np.int8)
    for y in range(h):
        for x in range(w):
            if not valid[y, x]:
                out[y, x] = HOLE
            elif facing[y, x] and not creases[y, x]:
                out[y, x] = ACTIVE
            else:
                out[y, x] = BLOCK
    return out


@njit(cache=True, nogil=True)
def loosen_small(labels: NDArray[np.int32], n: int, facing: NDArray[np.bool_], min_px: int) -> NDArray[np.bool_]:
    """Facing pixels without a label or in a component under ``min_px`` pixels.

    Returned as a mask, their labels set to 0 (in place). One count and one pass for numpy's
    bincount, gather and two masked writes.
    """
    h, w = labels.shape
    count = _count_labels(labels, n)
    small = count < min_px
    small[0] = True
    loose = np.zeros((h, w), np.bool_)
    for y in range(h):
        for x in range(w):
            if facing[y, x] and small[labels[y, x]]:
                loose[y, x] = True
                labels[y, x] = 0
    return loose


@njit(cache=True, nogil=True)
def keep_large(
    labels: NDArray[np.int32], n: int, min_px: int, depth: NDArray[np.float32]
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    """Renumber the components of at least ``min_px`` pixels 1..m in order, with their statistics.

    The sums and inclusive boxes are those of
    :func:`depthgram.segmentation.label.label_stats_fused` (key 0).

    One count, then one pass that relabels and sums
    (:func:`depthgram.segmentation.label.stats.relabel_stats`), for numpy's bincount, the
    relabelling pass and the statistics pass.
    """
    return _keep_counted(labels, _count_labels(labels, n), min_px, depth)


@njit(cache=True, nogil=True)
def _keep_counted(
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
def _count_labels(labels: NDArray[np.int32], n: int) -> NDArray[np.int64]:
    # pixels per label
    h, w = labels.shape
    count = np.zeros(n + 1, np.int64)
    for y in range(h):
        for x in range(w):
            count[labels[y, x]] += 1
    return count
