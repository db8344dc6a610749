"""The global depth histogram, its peaks and the paper's 10 % cuts (paper, section 3).

For each peak, the following minimum is the lowest bin between it and the next peak (for the
last peak, up to the end). The band of a peak runs from a leading cut to a trailing cut placed
``fraction`` of the peak-to-minimum distance from the minimum (``cut_from="minimum"``) or from
the peak (``cut_from="peak"``); pixels between bands are background in the paper
(``gap_pixels="background"``), or go to the band on their side of the minimum (``nearest``).

Both readings are compared on the simulator's seeded scenes by ``benchmarks/table1.py
--readings`` (figures in docs/performance.md, the choice in docs/design-notes.md).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from depthgram.segmentation.binning import bin_linear, bin_pixels, depth_range, log_counts
from depthgram.segmentation.config import SegmentConfig
from depthgram.segmentation.objects import Histogram

__all__ = ["Bands", "bin_counts", "bin_index", "depth_bands"]


def bin_index(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], config: SegmentConfig, *, zero_outside: bool = False
) -> tuple[NDArray[np.int32], NDArray[np.float64], NDArray[np.int64]]:
    """Histogram bin of every pixel, the bin edges (mm) and the counts per bin.

    Invalid pixels get bin -1. With ``depth_dependent_bins`` the edges are geometric, so a
    bin is ``bin_mm`` wide at ``ref_depth_mm`` and proportional to depth elsewhere.
    ``zero_outside``: see :func:`depthgram.segmentation.binning.depth_range`.
    """
    depth = np.ascontiguousarray(depth_mm, np.float32)
    ok = np.ascontiguousarray(valid, np.bool_)
    if not config.depth_dependent_bins:
        bins, counts, lo = bin_linear(depth, ok, config.bin_mm, zero_outside=zero_outside)
        if counts.size == 0:
            return bins, np.zeros(1), counts
        edges: NDArray[np.float64] = lo + config.bin_mm * np.arange(counts.size + 1, dtype=np.float64)
        return bins, edges, counts
    lo, hi, n = depth_range(depth, ok, zero_outside=zero_outside)
    if n == 0:
        return np.full(depth.shape, -1, np.int32), np.zeros(1), np.zeros(0, np.int64)
    step = math.log1p(config.bin_mm / config.ref_depth_mm)
    l0 = math.log(lo)
    nb = int((math.log(hi) - l0) / step) + 1
    bins, counts = bin_pixels(depth, ok, l0, step, True, nb)
    edges = np.exp(l0 + step * np.arange(nb + 1))
    return bins, edges, counts


def bin_counts(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], config: SegmentConfig
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Return the edges and counts of :func:`bin_index` (``zero_outside`` False), not the bin of every pixel."""
    if not config.depth_dependent_bins:
        _, edges, counts = bin_index(depth_mm, valid, config)
        return edges, counts
    return log_bin_counts(depth_mm, valid, config.bin_mm, config.ref_depth_mm)


def log_bin_counts(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    bin_mm: float,
    ref_depth_mm: float,
    span: tuple[float, float, int] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Return the edges and counts of depth-dependent bins ``bin_mm`` wide at ``ref_depth_mm`` (mm).

    :func:`bin_counts` of a config with ``depth_dependent_bins``, for a caller whose bin width
    changes with every frame (building and checking a config per frame cost more than this).
    ``span``: the smallest and largest valid depth and their count
    (:func:`~depthgram.segmentation.binning.depth_range`), when the caller has them.
    """
    depth = np.ascontiguousarray(depth_mm, np.float32)
    ok = np.ascontiguousarray(valid, np.bool_)
    lo, hi, n = depth_range(depth, ok) if span is None else span
    if n == 0:
        return np.zeros(1), np.zeros(0, np.int64)
    step = math.log1p(bin_mm / ref_depth_mm)
    l0 = math.log(lo)
    nb = int((math.log(hi) - l0) / step) + 1
    counts = log_counts(depth, ok, lo, hi, l0, step, nb)
    edges = np.exp(l0 + step * np.arange(nb + 1))
    return edges, counts


class Bands:
    """Depth bands of one histogram: a bin -> band lookup table and the band limits.

    Attributes
    ----------
    histogram : Histogram
        Edges, counts, peak depths and trailing cuts (mm).
    lut : ndarray of int32, shape (B,)
        Band of each bin, -1 for bins between bands.
    lower, upper : ndarray of float64, shape (K,)
        Leading and trailing cut of each band (mm), nearest band first.
    """

    def __init__(self, histogram: Histogram, lut: NDArray[np.int32], lower: NDArray[np.float64]) -> None:
        self.histogram = histogram
        self.lut = lut
        self.lower = lower
        self.upper = histogram.cuts

    def limits_mm(self) -> NDArray[np.float64]:
        """Leading and trailing cut of each band (K x 2, mm), nearest band first."""
        limits = np.empty((self.lower.size, 2))
        limits[:, 0] = self.lower
        limits[:, 1] = self.upper
        return limits

    @property
    def n(self) -> int:
        """Number of bands."""
        return int(self.lut.max(initial=-1)) + 1

    def depth_label(self, depth_mm: NDArray[np.floating] | float) -> NDArray[np.intp]:
        """Depth label on the global scale: the number of trailing cuts nearer than ``depth_mm``.

        Equal to the band index inside a band; monotonic in depth, so slice parts of an oblique
        surface get successive labels.
        """
        return np.searchsorted(self.upper, np.asarray(depth_mm), side="left")


@njit(cache=True, nogil=True)
def _cuts(
    smooth: NDArray[np.float64], peaks: NDArray[np.intp], t: float, nearest: bool
) -> tuple[NDArray[np.int32], NDArray[np.int64], NDArray[np.int64]]:
    # The paper's 10 % rule, once per peak. Compiled because on small frames the loop's
    # bookkeeping in Python (list slices, numpy scalars) cost more than the histogram itself.
    nb = smooth.size
    k = peaks.size
    lut = np.full(nb, -1, np.int32)
    first = np.empty(k, np.int64)
    last = np.empty(k, np.int64)
    prev_min = 0
    for i in range(k):
        p = peaks[i]
        # following minimum: lowest smoothed bin before the next peak (first one on ties)
        stop = peaks[i + 1] if i + 1 < k else nb - 1
        nxt = p
        for j in range(p + 1, stop + 1):
            if smooth[j] < smooth[nxt]:
                nxt = j
        if i + 1 == k and smooth[nxt] > 0:
            nxt = nb - 1
        lo_bin = p - t * (p - prev_min)
        hi_bin = p + t * (nxt - p)
        a = max(math.ceil(lo_bin - 1e-9), 0)
        b = min(math.floor(hi_bin + 1e-9), nb - 1)
        first[i] = a
        last[i] = b
        if nearest:
            # the gap on each side goes to this band up to the minimum (the next band overwrites it)
            a = prev_min if i else 0
            b = nxt if i + 1 < k else nb - 1
        lut[a : b + 1] = i
        prev_min = nxt
    return lut, first, last


@lru_cache(maxsize=16)
def _gaussian_weights(sigma: float) -> NDArray[np.float64]:
    """Return the kernel ``gaussian_filter1d`` uses for ``sigma``: its response to a unit impulse."""
    radius = int(4.0 * sigma + 0.5)  # gaussian_filter1d's default truncate=4.0
    impulse = np.zeros(2 * radius + 1)
    impulse[radius] = 1.0
    weights: NDArray[np.float64] = gaussian_filter1d(impulse, sigma, mode="constant")
    weights.setflags(write=False)
    return weights


@njit(cache=True, nogil=True)
def _smooth_padded(counts: NDArray[np.int64], weights: NDArray[np.float64]) -> NDArray[np.float64]:
    # scipy's gaussian_filter1d (mode "reflect") with the same weights and the same order of
    # operations, so the same numbers (a test compares them on random histograms), written
    # into a zero-padded array for the peak search. Kept compiled: scipy's gaussian_filter1d
    # and find_peaks cost 28 us more a frame (+22 % for the threshold method at 176 x 132).
    n = counts.size
    r = (weights.size - 1) // 2
    out = np.zeros(n + 2)
    for i in range(n):
        t = counts[i] * weights[r]
        for j in range(r, 0, -1):  # outermost pair first, as scipy sums a symmetric kernel
            a = i - j
            while a < 0 or a >= n:  # reflect about the edges: (d c b a | a b c d | d c b a)
                a = -a - 1 if a < 0 else 2 * n - a - 1
            b = i + j
            while b < 0 or b >= n:
                b = -b - 1 if b < 0 else 2 * n - b - 1
            t += (counts[a] + counts[b]) * weights[r + j]
        out[i + 1] = t
    return out


@njit(cache=True, nogil=True)
def prominent_peaks(x: NDArray[np.float64], min_prominence: float) -> NDArray[np.intp]:
    """Return the peaks of ``x`` of at least ``min_prominence``, in order.

    ``scipy.signal.find_peaks(x, prominence=min_prominence)[0]``, step by step: a peak is a
    sample (the middle one, rounded down, of a flat top) higher than both neighbours; its
    prominence is its height over the higher of the lowest points on each side before a
    higher sample. Kept compiled (with :func:`_smooth_padded`: 28 us a frame, +22 % for the
    threshold method at 176 x 132, against scipy's calls); the same float64 comparisons and
    subtraction give the same peaks (a test compares them). No warning for a prominence of
    0, which a strict local maximum never has.
    """
    n = x.size
    tops = np.empty(max(n // 2, 1), np.intp)
    m = 0
    i = 1
    i_max = n - 1
    while i < i_max:
        if x[i - 1] < x[i]:
            i_ahead = i + 1
            while i_ahead < i_max and x[i_ahead] == x[i]:
                i_ahead += 1
            if x[i_ahead] < x[i]:
                tops[m] = (i + i_ahead - 1) // 2
                m += 1
                i = i_ahead
        i += 1
    out = np.empty(m, np.intp)
    k = 0
    for j in range(m):
        peak = tops[j]
        top = x[peak]
        i = peak
        left_min = top
        while 0 <= i and x[i] <= top:
            if x[i] < left_min:
                left_min = x[i]
            i -= 1
        i = peak
        right_min = top
        while i <= i_max and x[i] <= top:
            if x[i] < right_min:
                right_min = x[i]
            i += 1
        if min_prominence <= top - max(left_min, right_min):
            out[k] = peak
            k += 1
    return out[:k]


def depth_bands(counts: NDArray[np.int64], edges: NDArray[np.float64], config: SegmentConfig) -> Bands:
    """Peaks and cuts of a histogram from :func:`bin_index`."""
    nb = edges.size - 1
    n_valid = int(counts.sum())
    if nb == 0 or n_valid == 0:
        empty = np.zeros(0)
        return Bands(Histogram(edges, counts, empty, empty), np.full(max(nb, 1), -1, np.int32), empty)
    # padded with a zero bin at each end so that a peak in the first or last bin is found too
    if config.smooth_bins > 0:
        padded = _smooth_padded(np.ascontiguousarray(counts, np.int64), _gaussian_weights(float(config.smooth_bins)))
    else:
        padded = np.concatenate(([0.0], counts.astype(np.float64), [0.0]))
    smooth = padded[1:-1]
    peaks = prominent_peaks(padded, max(config.min_prominence * n_valid, 1e-9)) - 1
    t = 1.0 - config.fraction if config.cut_from == "minimum" else config.fraction
    lut, first, last = _cuts(np.ascontiguousarray(smooth, np.float64), peaks, t, config.gap_pixels == "nearest")
    lower = edges[first]
    upper = edges[last + 1]
    centers = 0.5 * (edges[peaks] + edges[peaks + 1])
    hist = Histogram(edges=edges, counts=counts, peaks=centers, cuts=upper)
    return Bands(hist, lut, lower)
