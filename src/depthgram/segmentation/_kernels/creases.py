"""The compiled passes of the concave creases (:mod:`depthgram.segmentation.creases`).

Window means of inverse depth, their second differences along four directions and the
labeller state, row by row, with the float32 operations of the numpy route in its order.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label import ACTIVE, BLOCK, HOLE
from depthgram.segmentation.window import bits_range, exact_rows


@njit(cache=True, nogil=True, error_model="numpy")
def inverse_depth(z: NDArray[np.float32], valid: NDArray[np.bool_]) -> NDArray[np.float32]:
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
def creases_from_sums(
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
def creases_window(
    inverse: NDArray[np.float32],
    valid: NDArray[np.bool_],
    c: NDArray[np.float32],
    min_den: np.float32,
    k: int,
    r: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> tuple[NDArray[np.bool_], bool]:
    # creases_from_sums of OpenCV's k x k window sums of `inverse` (2, H, W), taken in the same call
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
def crease_state_from_sums(
    sums: NDArray[np.float32],
    valid: NDArray[np.bool_],
    facing: NDArray[np.bool_],
    c: NDArray[np.float32],
    min_den: np.float32,
    r: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> NDArray[np.int8]:
    # surface_state(valid, facing, creases_from_sums(...)) in one call: each row's creases go to the
    # labeller's state from a row buffer (no crease map, no pass of its own)
    ws, has, bend = _crease_means(sums, valid, c, min_den, geom, noise_scale)
    return _state_from(ws, has, bend, valid, facing, r)


@njit(cache=True, nogil=True, error_model="numpy")
def crease_state_window(
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
    # crease_state_from_sums of OpenCV's k x k window sums of `inverse` (2, H, W), taken in the same
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
def upsample2(sub: NDArray[np.bool_], valid: NDArray[np.bool_]) -> NDArray[np.bool_]:
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
