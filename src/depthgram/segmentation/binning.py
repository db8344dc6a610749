"""Compiled per-pixel passes of histogram thresholding: binning with the histogram, band lookup.

Each is one raster pass where numpy needs several (a boolean gather of the valid pixels, a
scaling, a cast, a scatter back, a bincount, a lookup, a mask for the labeller);
``benchmarks/bench_segmentation.py --stages`` times them.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label import ACTIVE, BLOCK, HOLE

__all__ = ["band_state", "bin_linear", "bin_pixels", "depth_range", "log_counts"]


@njit(cache=True, nogil=True)
def _bins(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], lo: float, step: float, log: bool, nb: int
) -> tuple[NDArray[np.int32], NDArray[np.int64]]:
    # Per row, a branch-free loop writes every pixel's bin (it vectorises), then the row is
    # counted into four interleaved tables: neighbouring pixels mostly fall in the same bin,
    # and one table makes each increment wait for the previous one. Unsigned indices spare
    # numba's negative-index test, which kept the first loop from vectorising.
    h, w = depth.shape
    out = np.empty((h, w), np.int32)
    counts = np.zeros((4, nb + 1), np.int64)
    uw = np.uint64(w)
    top = nb - 1
    inv = 1.0 / step
    for y in range(h):
        zrow = depth[y]
        vrow = valid[y]
        orow = out[y]
        if log:
            for x in range(uw):
                z = math.log(zrow[x]) if vrow[x] else 0.0
                b = min(np.int64((z - lo) / step), top)
                orow[x] = b if vrow[x] else -1
        else:
            for x in range(uw):
                b = min(np.int64((np.float64(zrow[x]) - lo) * inv), top)
                orow[x] = b if vrow[x] else -1
        x = 0
        while x + 3 < w:
            counts[0, np.uint64(orow[x] + 1)] += 1
            counts[1, np.uint64(orow[x + 1] + 1)] += 1
            counts[2, np.uint64(orow[x + 2] + 1)] += 1
            counts[3, np.uint64(orow[x + 3] + 1)] += 1
            x += 4
        while x < w:
            counts[0, np.uint64(orow[x] + 1)] += 1
            x += 1
    return out, counts[0, 1:] + counts[1, 1:] + counts[2, 1:] + counts[3, 1:]


@njit(cache=True, nogil=True)
def _band_state(
    bins: NDArray[np.int32], lut: NDArray[np.int32], valid: NDArray[np.bool_], include: NDArray[np.bool_], use: bool
) -> tuple[NDArray[np.float32], NDArray[np.int8]]:
    h, w = bins.shape
    band = np.full((h, w), -1.0, np.float32)
    state = np.zeros((h, w), np.int8)
    for y in range(h):
        for x in range(w):
            if not valid[y, x]:
                state[y, x] = HOLE
                continue
            b = bins[y, x]
            k = lut[b] if b >= 0 else -1
            if k >= 0 and (not use or include[y, x]):
                band[y, x] = k
                state[y, x] = ACTIVE
            else:
                state[y, x] = BLOCK
    return band, state


@njit(cache=True, nogil=True)
def _range_bits(bits: NDArray[np.uint32]) -> tuple[float, float, int]:
    # positive float32 values order like their bit patterns, and 0 - 1 wraps to the largest
    # uint32, so integer min/max (which vectorise, unlike NaN-aware float min) give the range;
    # the nonzero patterns are the valid pixels
    lo = np.uint32(0xFFFFFFFF)
    hi = np.uint32(0)
    one = np.uint32(1)
    n = 0
    for i in range(bits.size):
        u = bits[i]
        lo = min(lo, u - one)
        hi = max(hi, u)
        n += u != 0
    pair = np.empty(2, np.uint32)
    pair[0] = lo + one
    pair[1] = hi
    z = pair.view(np.float32)
    return float(z[0]), float(z[1]), n


def depth_range(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], *, zero_outside: bool = False
) -> tuple[float, float, int]:
    """Smallest and largest valid depth (mm) and the number of valid pixels.

    ``zero_outside=True`` promises that ``valid`` is exactly ``depth_mm > 0`` with finite
    depths (what :func:`depthgram.segmentation.validate.check_depth` returns): the range is then
    read from the bit patterns of the positive floats, which order as integers do (no
    float comparison per pixel).
    """
    if zero_outside:
        lo, hi, n = _range_bits(depth_mm.reshape(-1).view(np.uint32))
    else:
        n = int(np.count_nonzero(valid))
        lo, hi = cv2.minMaxLoc(depth_mm, valid.view(np.uint8))[:2] if n else (0.0, 0.0)
    if n == 0:
        return float("inf"), float("-inf"), 0
    return float(lo), float(hi), int(n)


def bin_pixels(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], lo: float, step: float, log: bool, nb: int
) -> tuple[NDArray[np.int32], NDArray[np.int64]]:
    """Bin of every valid pixel (-1 elsewhere) and the histogram counts.

    The bin is ``floor((z - lo) / step)``, or ``floor((ln z - lo) / step)`` when ``log``,
    clipped to ``nb - 1``.
    """
    return _bins(depth_mm, valid, float(lo), float(step), bool(log), int(nb))


def log_counts(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], lo_mm: float, hi_mm: float, lo: float, step: float, nb: int
) -> NDArray[np.int64]:
    """Return the counts of :func:`bin_pixels` with ``log`` (the bins themselves not written).

    ``lo_mm`` and ``hi_mm`` are the smallest and largest valid depth. With whole-millimetre
    depths each distinct depth's logarithm is taken once, not every pixel's: the same
    function on the same value, so the same bins.
    """
    if lo_mm == math.floor(lo_mm) and hi_mm - lo_mm <= _MAX_WHOLE_SPAN:
        counts, whole = _log_counts_whole(
            depth_mm, valid, np.float32(lo_mm), int(hi_mm - lo_mm), float(lo), float(step), int(nb)
        )
        if whole:
            return counts
    return _bins(depth_mm, valid, float(lo), float(step), True, int(nb))[1]


#: Widest span (mm) of whole depths :func:`log_counts` counts value by value.
_MAX_WHOLE_SPAN = 1 << 16


@njit(cache=True, nogil=True)
def _log_counts_whole(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], zlo: np.float32, span: int, lo: float, step: float, nb: int
) -> tuple[NDArray[np.int64], bool]:
    # pixels per whole depth, then each depth's bin as _bins takes it (float32 logarithm,
    # float64 after); (empty, False) at the first depth that is not whole
    h, w = depth.shape
    per = np.zeros(span + 1, np.int64)
    for y in range(h):
        zrow = depth[y]
        vrow = valid[y]
        for x in range(w):
            if vrow[x]:
                v = zrow[x] - zlo
                i = int(v)
                if i != v or i > span:
                    return np.zeros(0, np.int64), False
                per[i] += 1
    counts = np.zeros(nb, np.int64)
    top = nb - 1
    for i in range(span + 1):
        c = per[i]
        if c:
            z = np.float64(math.log(zlo + np.float32(i)))
            b = np.int64((z - lo) / step)
            counts[b if b < top else top] += c
    return counts, True


def bin_linear(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], step_mm: float, *, zero_outside: bool = False
) -> tuple[NDArray[np.int32], NDArray[np.int64], float]:
    """:func:`depth_range` and :func:`bin_pixels` with bins ``step_mm`` wide from the nearest depth.

    Returns the bins (-1 where invalid), the counts (empty without a valid pixel) and the
    lower edge of the first bin (mm).
    """
    lo, hi, n = depth_range(depth_mm, valid, zero_outside=zero_outside)
    if n == 0:
        return np.full(depth_mm.shape, -1, np.int32), np.zeros(0, np.int64), 0.0
    bins, counts = _bins(depth_mm, valid, lo, float(step_mm), False, int((hi - lo) / step_mm) + 1)
    return bins, counts, lo


def band_state(
    bins: NDArray[np.int32], lut: NDArray[np.int32], valid: NDArray[np.bool_], include: NDArray[np.bool_] | None
) -> tuple[NDArray[np.float32], NDArray[np.int8]]:
    """Band of each pixel (-1 outside every band) and its labeller state.

    Pixels without a reading are holes; valid pixels outside a band, or outside ``include``,
    block; the rest are active.
    """
    inc = include if include is not None else valid
    return _band_state(bins, lut, valid, inc, include is not None)
