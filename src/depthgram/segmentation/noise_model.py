"""What the depth camera can resolve: its depth step and noise as functions of depth.

Every depth tolerance of the segmentation (when two neighbours lie on one surface, when a crease
is real, how wide a histogram bin must be) is a property of the sensor, not of the scene:

- structured light (Kinect v1, Asus Xtion, PrimeSense, RealSense D400) measures disparity, so
  its depth comes in steps ``dz = z**2 * disparity_step / (f * baseline)`` that grow with the
  square of depth, and its noise grows the same way;
- time of flight measures phase, so its depth is quantised in the output unit (1 mm for 16-bit
  PNGs, ``range / 255`` for the paper's 8-bit sensor) and its noise also grows with distance
  (the returned light falls with ``z**2``).

Both are covered by one model, ``step(z) = step_0 + step_2 z**2`` and ``sigma(z) = sigma_0 +
sigma_2 z**2`` (mm), either taken from a named profile or estimated from the frame itself
(:func:`estimate_sensor`). Inverse depth ``1/z`` is the natural coordinate of such a sensor: a
disparity step is the same size everywhere in it, and a plane is affine in it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.errors import InputError
from depthgram.segmentation.order_stats import kth_pair, median_inplace

__all__ = ["PROFILES", "SensorModel", "estimate_sensor", "sensor_model"]


@dataclass(frozen=True)
class SensorModel:
    """Depth step and noise of a depth camera as functions of depth (all in mm).

    Attributes
    ----------
    name : str
        Profile name, or ``auto`` when estimated from a frame.
    step_0, step_2 : float
        Quantisation step ``step(z) = step_0 + step_2 * z**2`` (mm; ``step_2`` in 1/mm).
    sigma_0, sigma_2 : float
        Noise standard deviation ``sigma(z) = sigma_0 + sigma_2 * z**2`` (mm; ``sigma_2`` in 1/mm).
    """

    name: str
    step_0: float
    step_2: float
    sigma_0: float
    sigma_2: float

    def __post_init__(self) -> None:
        for field in ("step_0", "step_2", "sigma_0", "sigma_2"):
            v = getattr(self, field)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(f"sensor model {self.name!r}: {field} = {v!r}, expected a finite number >= 0")
            # Python floats whatever was given (a numpy float64 is a float too): numpy treats a
            # Python scalar as weak, so the tolerances keep the frame's float32, and the compiled
            # creases take only Python numbers (a numpy scalar sent them down the numpy route,
            # 0.4 ms slower at 176 x 132)
            object.__setattr__(self, field, float(v))

    def step(self, z_mm: float | NDArray[np.floating]) -> float | NDArray[np.floating]:
        """Depth quantisation step (mm) at depth ``z_mm``."""
        return self.step_0 + self.step_2 * np.square(z_mm)

    def sigma(self, z_mm: float | NDArray[np.floating]) -> float | NDArray[np.floating]:
        """Depth noise standard deviation (mm) at depth ``z_mm``."""
        return self.sigma_0 + self.sigma_2 * np.square(z_mm)

    def resolution(self, z_mm: float | NDArray[np.floating]) -> float | NDArray[np.floating]:
        """Return the smallest depth difference (mm) the sensor tells apart at ``z_mm``.

        The larger of one quantisation step and two noise deviations (a difference of two readings).
        """
        return np.maximum(self.step(z_mm), 2.0 * self.sigma(z_mm))

    def tolerance(self, k: float) -> tuple[float, float]:
        """Return ``(a, b)`` of the join tolerance ``a + b * z**2`` (mm): ``k`` resolutions.

        Each term takes the larger of its step and noise parts, so the tolerance is at least
        ``k * resolution(z)`` at every depth.
        """
        return k * max(self.step_0, 2.0 * self.sigma_0), k * max(self.step_2, 2.0 * self.sigma_2)

    def describe(self) -> str:
        """One line for people: step and noise at 1 and 3 m."""
        s1, s3 = float(self.step(1000.0)), float(self.step(3000.0))
        n1, n3 = float(self.sigma(1000.0)), float(self.sigma(3000.0))
        steps = f"depth step {s1:.1f} mm at 1 m, {s3:.1f} mm at 3 m"
        return f"{self.name}: {steps}; noise {n1:.1f} mm at 1 m, {n3:.1f} mm at 3 m"


def _structured_light(name: str, f_px: float, baseline_mm: float, subpixel: float, noise_px: float) -> SensorModel:
    # a disparity d = f b / z changed by one subpixel step moves depth by z**2 step / (f b)
    fb = f_px * baseline_mm
    return SensorModel(name, 0.0, subpixel / fb, 0.0, noise_px / fb)


#: Named sensor profiles, for users who know their camera. Structured light from the published
#: optics (focal length at 640 px width, baseline, subpixel step of the disparity) and the
#: disparity noise reported for each family; ToF from the makers' random-error figures.
PROFILES: dict[str, SensorModel] = {
    # Kinect v1, Asus Xtion, PrimeSense Carmine: f 580 px, baseline 75 mm, 1/8 px disparity steps,
    # noise about 1.5 mm at 1 m and 4 cm at 5 m (Khoshelham and Elberink 2012)
    "kinect-v1": _structured_light("kinect-v1", 580.0, 75.0, 1.0 / 8.0, 0.065),
    # Intel RealSense D415/D435 at 640 px: f about 380 px, baseline 50 mm, 1/32 px subpixel
    # steps, RMS disparity noise about 0.08 px (Intel's depth-quality white paper)
    "realsense-d400": _structured_light("realsense-d400", 380.0, 50.0, 1.0 / 32.0, 0.08),
    # Azure Kinect (ToF, NFOV): 1 mm output unit, random error about 1 mm + 0.1 % of depth
    # (written here as its z**2 equivalent at the typical 1.5 m working distance)
    "azure-kinect": SensorModel("azure-kinect", 1.0, 0.0, 1.0, 0.0007e-3),
    # the paper's sensor and this project's simulator: 8-bit depth over about 3 m
    "tof": SensorModel("tof", 12.0, 0.0, 4.0, 0.0),
}
PROFILES["xtion"] = PROFILES["primesense"] = PROFILES["kinect-v1"]


def sensor_model(name: str) -> SensorModel:
    """Return the named profile; raises :class:`InputError` naming the known ones."""
    try:
        return PROFILES[name]
    except KeyError:
        raise InputError(f"unknown sensor profile {name!r}; known: 'auto', {', '.join(sorted(PROFILES))}") from None


def estimate_sensor(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], *, max_samples: int = 20_000
) -> SensorModel:
    """Estimate the depth step and noise of the camera from one frame.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid.
    valid : ndarray of bool
        Pixels with a reading.
    max_samples : int
        About how many pixel triples are read, so that the estimate stays a small share of a
        frame: every ``H * (W - 2) // max_samples``-th row (at least every row), which reads up
        to twice as many on a frame with fewer than ``2 * max_samples`` (every pixel of a
        176 x 132 frame, 20,416 at 640 x 480). On the YCB-Video frames 20,000 samples gave the
        same model as 60,000.

    Returns
    -------
    SensorModel
        Named ``auto``.

    Notes
    -----
    Step: along a row, most neighbours on a smooth surface read either the same value or the
    next one the sensor can produce, so the smallest non-zero absolute difference, taken per
    depth range (the 20th percentile of non-zero differences among small ones), is the step
    there. Noise: the second difference ``z[x-1] - 2 z[x] + z[x+1]`` of a smooth surface is
    noise with variance ``6 sigma**2`` (plus quantisation, ``step**2 / 2``); its robust spread
    (MAD) per depth range gives sigma. Each is fitted as ``a + b z**2`` by least squares over the
    depth ranges, so a structured-light camera comes out with ``b`` and a ToF camera with ``a``.
    """
    h, w = depth_mm.shape
    if w < 3:
        return PROFILES["tof"]
    # (a frame without readings needs no test of its own: it has no samples, so no fit)
    rows = max(1, h * (w - 2) // max_samples)
    # the samples, their order, each depth range's estimates and both least squares in one
    # compiled call
    fit, sol = _range_fit(depth_mm, valid, rows)
    if not fit.shape[0]:
        return PROFILES["tof"]
    # Python floats, as the compiled solve returned them before (numpy scalars in a model
    # send the creases to their numpy route)
    a1, b1, a2, b2 = sol.tolist()
    s0, s2 = _non_negative(fit[:, 0], fit[:, 1], a1, b1)
    n0, n2 = _non_negative(fit[:, 0], fit[:, 2], a2, b2)
    return SensorModel("auto", s0, s2, n0, n2)


@njit(cache=True, nogil=True)
def _range_fit(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    # the steps of estimate_sensor from the samples to the fit: the samples, the stable order
    # (_counting_order with the smallest and largest depth taken in the samples' own pass, so
    # no pass of its own), the range estimates, and with two ranges or more _lstsq_a_bz2 of
    # step and sigma against depth squared, one call instead of five. Returns the rows of the
    # ranges with enough differences (median depth, step, sigma, 1; none below 200 samples)
    # and (a, b) of the step's and the sigma's least squares (zeros with fewer than two rows).
    est = _range_estimates_counted(depth, valid, rows)
    m = 0
    for i in range(est.shape[0]):
        if est[i, 3] > 0:
            m += 1
    fit = np.empty((m, 4), np.float64)
    m = 0
    for i in range(est.shape[0]):
        if est[i, 3] > 0:
            fit[m] = est[i]
            m += 1
    sol = np.zeros(4, np.float64)
    if m > 1:
        # numpy's z * z of the fit's depths, then the same solve as _fit_a_bz2
        x = fit[:, 0] * fit[:, 0]
        sol[0], sol[1] = _lstsq_a_bz2(x, fit[:, 1].copy())
        sol[2], sol[3] = _lstsq_a_bz2(x, fit[:, 2].copy())
    return fit, sol


@njit(cache=True, nogil=True)
def _range_estimates_counted(depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int) -> NDArray[np.float64]:
    # _range_estimates_all without the samples' order: when every reading of the sampled rows
    # is a whole number in [1, 2**24) (what most cameras give), the ranges' order statistics
    # come from counts. The depths' counts give each equal-count range's limits and median
    # depth; a table gives each depth its range (its pixels' differences counted in that
    # range's histograms), and only the few depths tied across a range boundary take their
    # pixels' places in raster order, as the stable order did. Other frames take
    # _range_estimates_all (the same values: a test holds both).
    key, d1, d2, lo, hi, whole = _whole_samples(depth, valid, rows)
    if not whole or hi - lo >= 1 << 20 or 0.05 * hi > _MAX_WHOLE_LIM:
        return _range_estimates_all(depth, valid, rows)
    if hi < lo:  # no reading in the sampled rows
        return np.zeros((0, 4), np.float64)
    # each depth's count (slot 0 holds the places without a sample), the places keyed in place
    count = np.zeros(hi - lo + 2, np.int32)
    off = np.int32(1 - lo)
    for i in range(key.size):
        j = max(key[i] + off, np.int32(0))
        key[i] = j
        count[np.uint64(j)] += 1
    n = key.size - count[0]
    if n < 200:
        return np.zeros((0, 4), np.float64)
    k = min(12, max(2, n // 400))
    return _ranges_from_counts(key, d1, d2, count, lo, n, k)


@njit(cache=True, nogil=True)
def _whole_samples(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int
) -> tuple[NDArray[np.int32], NDArray[np.int32], NDArray[np.int32], int, int, bool]:
    # every ``rows``-th row, every place x in 1 .. w - 2 in raster order: the depth (0 unless
    # x and both row neighbours have a reading), |z[x+1] - z[x]| and (z[x-1] - 2 z[x]) + z[x+1]
    # as whole numbers, with the smallest and largest reading of the rows and whether every
    # reading of the rows is a whole number in [1, 2**24) (only then are the rest meaningful).
    # Each row's readings are tested and made whole in one loop and its places written in
    # another, both without branches, so that they vectorise.
    h, w = depth.shape
    n_rows = (h + rows - 1) // rows
    places = max(w - 2, 0)
    key = np.empty(n_rows * places, np.int32)
    d1 = np.empty(n_rows * places, np.int32)
    d2 = np.empty(n_rows * places, np.int32)
    iz = np.empty(w, np.int32)
    ok = np.empty(w, np.uint8)
    none = np.int32(1 << 30)
    lo = none
    hi = np.int32(0)
    bad = np.uint8(0)
    p = 0
    for y in range(0, h, rows):
        zrow = depth[y]
        vrow = valid[y]
        for x in range(w):
            v = zrow[x]
            m = np.uint8(vrow[x])
            g = np.uint8((v >= np.float32(1.0)) & (v < np.float32(16777216.0)) & (np.floor(v) == v)) & m
            bad |= m ^ g
            t = np.int32(v) if g else np.int32(0)
            iz[x] = t
            ok[x] = g
            lo = min(lo, t if g else none)
            hi = max(hi, t)
        for x in range(1, w - 1):
            b = iz[x]
            c = iz[x + 1]
            key[p + x - 1] = b if ok[x - 1] & ok[x] & ok[x + 1] else np.int32(0)
            d1[p + x - 1] = abs(c - b)
            d2[p + x - 1] = (iz[x - 1] - 2 * b) + c
        p += places
    return key, d1, d2, int(lo), int(hi), bad == 0


@njit(cache=True, nogil=True)
def _ranges_from_counts(
    key: NDArray[np.int32],
    d1: NDArray[np.int32],
    d2: NDArray[np.int32],
    count: NDArray[np.int32],
    lo: int,
    n: int,
    k: int,
) -> NDArray[np.float64]:
    # _range_estimates_whole for the samples of _whole_samples, keyed (depth - lo + 1, 0 for a
    # place without a sample) and counted per depth (count), n of them in k ranges
    each, extra = divmod(n, k)
    ends = np.empty(k + 1, np.int64)
    ends[0] = 0
    for r in range(k):
        ends[r + 1] = ends[r] + each + (1 if r < extra else 0)
    # the places in the order of each range's median: its middle one or two
    mid = np.empty(2 * k, np.int64)
    for r in range(k):
        m = ends[r + 1] - ends[r]
        mid[2 * r] = ends[r] + m // 2 - (1 - m % 2)
        mid[2 * r + 1] = ends[r] + m // 2
    at_mid = np.empty(2 * k, np.int64)
    # one walk over the depths: each depth's range, or (negative) its number among the depths
    # whose pixels straddle a range boundary, with the place of its first pixel
    span = count.size
    table = np.zeros(span, np.int32)
    first = np.empty(k, np.int64)
    n_split = 0
    r = 0
    s = 0
    t = 0
    for v in range(1, span):
        c = count[v]
        if c == 0:
            continue
        e = s + c
        while t < 2 * k and mid[t] < e:
            at_mid[t] = v
            t += 1
        while s >= ends[r + 1]:
            r += 1
        if e <= ends[r + 1]:
            table[v] = r
        else:
            n_split += 1
            table[v] = -n_split
            first[n_split - 1] = s
        s = e
    zc = np.empty(k, np.float64)
    for r in range(k):
        a = float(at_mid[2 * r] - 1 + lo)
        b = float(at_mid[2 * r + 1] - 1 + lo)
        zc[r] = b if (ends[r + 1] - ends[r]) % 2 else (a + b) / 2.0
    # one histogram row per range (and one for the places without a sample), wide enough for
    # the last range's tolerance: |d1| clamped to 0 .. top + 1, d2 + top + 1 to 0 .. 2 top + 2
    # after them, so a difference outside a range's own tolerance lands in a bin it does not read
    top = math.ceil(0.05 * zc[k - 1]) - 1
    w1 = top + 2
    width = w1 + 2 * top + 3
    for v in range(span):
        if table[v] >= 0:
            table[v] *= width
    table[0] = k * width
    c1 = np.int32(top + 1)
    c2 = np.int32(2 * top + 2)
    for i in range(key.size):
        d1[i] = min(d1[i], c1)
        d2[i] = np.int32(w1) + min(max(d2[i] + c1, np.int32(0)), c2)
    hist = np.zeros((k + 1) * width, np.int32)
    seen = np.zeros(k, np.int64)
    for i in range(key.size):
        row = table[np.uint64(key[i])]
        if row < 0:
            # a straddling depth: its pixels take their places in raster order
            j = -1 - row
            pos = first[j] + seen[j]
            seen[j] += 1
            big = each + 1
            row = width * (pos // big if pos < extra * big else extra + (pos - extra * big) // each)
        hist[np.uint64(row + d1[i])] += 1
        hist[np.uint64(row + d2[i])] += 1
    # each range's order statistics with _range_estimates_whole's arithmetic
    out = np.zeros((k, 4), np.float64)
    h3 = np.zeros(4 * top + 2, np.int64)
    for r in range(k):
        lim = 0.05 * zc[r]
        top1 = math.ceil(lim) - 1
        top2 = top1
        base = r * width
        h1 = hist[base : base + top1 + 1]
        h1[0] = 0  # no zero differences
        h2 = hist[base + w1 + top + 1 - top2 : base + w1 + top + 2 + top2]
        n1 = 0
        for v in range(1, top1 + 1):
            n1 += h1[v]
        n2 = 0
        for v in range(2 * top2 + 1):
            n2 += h2[v]
        if n1 < 20 or n2 < 20:
            continue
        step, sigma = _count_statistics(h1, n1, top1, h2, n2, top2, h3)
        out[r, 0] = zc[r]
        out[r, 1] = step
        out[r, 2] = sigma
        out[r, 3] = 1.0
    return out


@njit(cache=True, nogil=True)
def _range_estimates_all(depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int) -> NDArray[np.float64]:
    # each depth range's row of the estimate (no rows below 200 samples)
    z, d1, d2, lo, hi = _triples_span(depth, valid, rows)
    if z.size < 200:
        return np.zeros((0, 4), np.float64)
    # depth ranges of equal pixel count, so each fit point has the same weight of evidence
    n_bins = min(12, max(2, z.size // 400))
    # which of the pixels tied at a range boundary fall on each side changes the estimate, so
    # ties keep raster order (a stable sort): numpy's default sort left it to the CPU's SIMD
    # level (docs/design-notes.md, "The sensor estimate's order")
    order = _counting_order_span(z, lo, hi)
    if order.size == z.size:
        # whole-millimetre depths (what most cameras give): their differences are whole too,
        # and each range's order statistics are read from counts, without sorting copies
        return _range_estimates_whole(z, d1, d2, order, n_bins)
    order = _radix_order(z.astype(np.float32).view(np.uint32))
    return _range_estimates(z, d1, d2, order, n_bins)


@njit(cache=True, nogil=True)
def _triples_span(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float, float]:
    # every ``rows``-th row: the depth of each pixel whose two row neighbours also have a
    # reading, its first difference z[x+1] - z[x] (absolute) and its second difference
    # (z[x-1] - 2 z[x]) + z[x+1], in raster order, with the smallest and largest depth of the
    # samples (0 and 0 when none)
    h, w = depth.shape
    n_rows = (h + rows - 1) // rows
    cap = n_rows * max(w - 2, 0)
    z = np.empty(cap, np.float64)
    d1 = np.empty(cap, np.float64)
    d2 = np.empty(cap, np.float64)
    k = 0
    lo = 0.0
    hi = 0.0
    for y in range(0, h, rows):
        for x in range(1, w - 1):
            if valid[y, x - 1] and valid[y, x] and valid[y, x + 1]:
                a = np.float64(depth[y, x - 1])
                b = np.float64(depth[y, x])
                c = np.float64(depth[y, x + 1])
                z[k] = b
                d1[k] = abs(c - b)
                d2[k] = (a - 2.0 * b) + c
                # as _counting_order takes them: from the first depth on
                lo = b if k == 0 else min(lo, b)
                hi = b if k == 0 else max(hi, b)
                k += 1
    return z[:k], d1[:k], d2[:k], lo, hi


def stable_order(z: NDArray[np.float64]) -> NDArray[np.intp]:
    """Return the indices that sort the positive depths ``z`` (mm), equal values in index order.

    ``np.argsort(z, kind="stable")``, in O(n): one counting pass over whole-millimetre depths
    (what most cameras give), else a three-pass radix sort on the depths' float32 bit patterns,
    which order positive floats as their values (depths are float32 readings, so the cast is
    exact).
    """
    out: NDArray[np.intp] = _counting_order(z)
    if out.size != z.size:
        out = _radix_order(z.astype(np.float32).view(np.uint32))
    return out


@njit(cache=True, nogil=True)
def _counting_order(z: NDArray[np.float64]) -> NDArray[np.intp]:
    # a stable counting sort when every depth is a whole number within 2**20 of the smallest;
    # an empty array otherwise
    n = z.size
    if n == 0:
        return np.empty(0, np.intp)
    lo = z[0]
    hi = z[0]
    for i in range(1, n):
        lo = min(lo, z[i])
        hi = max(hi, z[i])
    return _counting_order_span(z, lo, hi)


@njit(cache=True, nogil=True)
def _counting_order_span(z: NDArray[np.float64], lo: float, hi: float) -> NDArray[np.intp]:
    # _counting_order given the smallest (lo) and largest (hi) of the depths
    n = z.size
    if n == 0:
        return np.empty(0, np.intp)
    if hi - lo >= 1 << 20:
        return np.empty(0, np.intp)
    span = int(hi - lo) + 1
    count = np.zeros(span + 1, np.int64)
    key = np.empty(n, np.int32)
    for i in range(n):
        v = z[i] - lo
        d = int(v)
        if d != v:
            return np.empty(0, np.intp)
        key[i] = d
        count[d + 1] += 1
    for j in range(span):
        count[j + 1] += count[j]
    out = np.empty(n, np.intp)
    for i in range(n):
        d = key[i]
        out[count[d]] = i
        count[d] += 1
    return out


@njit(cache=True, nogil=True)
def _radix_order(key: NDArray[np.uint32]) -> NDArray[np.intp]:
    # least significant digit first (11, 11 and 10 bits); each pass is a stable counting sort,
    # so equal keys keep their index order
    n = key.size
    order = np.arange(n)
    nxt = np.empty(n, np.intp)
    count = np.zeros(2049, np.int64)
    for shift in (0, 11, 22):
        count[:] = 0
        for i in range(n):
            count[((key[i] >> shift) & 0x7FF) + 1] += 1
        for j in range(2048):
            count[j + 1] += count[j]
        for t in range(n):
            i = order[t]
            d = (key[i] >> shift) & 0x7FF
            nxt[count[d]] = i
            count[d] += 1
        order, nxt = nxt, order
    return order


@njit(cache=True, nogil=True)
def _percentile20(a: NDArray[np.float64]) -> float:
    # np.percentile(a, 20) (method linear) with numpy's arithmetic (_lerp from the nearer end)
    n = a.size
    vi = (n - 1) * (20 / 100)
    j = math.floor(vi)
    if vi >= n - 1:
        return float(a.max())
    lo, hi = kth_pair(a, j)
    t = vi - j
    diff = hi - lo
    return hi - diff * (1.0 - t) if t >= 0.5 else lo + diff * t


@njit(cache=True, nogil=True)
def _median_sorted(a: NDArray[np.float64]) -> float:
    n = a.size
    h = n // 2
    return float(a[h]) if n % 2 else float((a[h - 1] + a[h]) / 2.0)


@njit(cache=True, nogil=True)
def _range_estimates(
    z: NDArray[np.float64],
    d1: NDArray[np.float64],
    d2: NDArray[np.float64],
    order: NDArray[np.intp],
    k: int,
) -> NDArray[np.float64]:
    # per depth range (the parts of np.array_split(order, k): the first size % k one longer):
    # median depth, step, sigma, and 1 when the range had enough differences (else 0)
    zs = z[order]
    d1s = d1[order]
    d2s = d2[order]
    out = np.zeros((k, 4), np.float64)
    each, extra = divmod(zs.size, k)
    lo = 0
    for i in range(k):
        hi = lo + each + (1 if i < extra else 0)
        zc = _median_sorted(zs[lo:hi])
        lim = 0.05 * zc
        # a jump to another surface is not noise: keep differences within 5 % of depth
        a = d1s[lo:hi]
        nz = a[(a > 1e-6) & (a < lim)]
        c = d2s[lo:hi]
        b = c[np.abs(c) < lim]
        lo = hi
        if nz.size < 20 or b.size < 20:
            continue
        step = _percentile20(nz)
        mad = median_inplace(np.abs(b - median_inplace(b.copy()))) * 1.4826
        sigma2 = max(mad * mad - step * step / 2.0, 0.0) / 6.0
        out[i, 0] = zc
        out[i, 1] = step
        out[i, 2] = math.sqrt(sigma2)
        out[i, 3] = 1.0
    return out


#: Widest depth tolerance (mm) whose differences :func:`_range_estimates_whole` counts.
_MAX_WHOLE_LIM = 1 << 13


@njit(cache=True, nogil=True)
def _range_estimates_whole(
    z: NDArray[np.float64],
    d1: NDArray[np.float64],
    d2: NDArray[np.float64],
    order: NDArray[np.intp],
    k: int,
) -> NDArray[np.float64]:
    # _range_estimates for whole-number depths (so whole differences): the same values, each
    # order statistic read from the counts of the range's differences in one pass over its
    # pixels instead of masked copies and selections (an order statistic is a value of the
    # sample whatever finds it; the arithmetic on them is _range_estimates'). A range whose
    # tolerance is too wide to count is left to _range_estimates' own steps.
    n = z.size
    out = np.zeros((k, 4), np.float64)
    each, extra = divmod(n, k)
    # the ranges follow depth: the last one has the widest tolerance
    # capped before the ceiling: math.ceil of a far reading (1e30 mm) overflows int64 (issue 32.2)
    top = math.ceil(min(0.05 * z[order[n - 1]], _MAX_WHOLE_LIM)) if n else 0
    h1 = np.zeros(top + 1, np.int64)
    h2 = np.zeros(2 * top + 1, np.int64)
    h3 = np.zeros(4 * top + 2, np.int64)
    lo = 0
    for i in range(k):
        hi = lo + each + (1 if i < extra else 0)
        m = hi - lo
        h = m // 2
        zc = float(z[order[lo + h]]) if m % 2 else float((z[order[lo + h - 1]] + z[order[lo + h]]) / 2.0)
        lim = 0.05 * zc
        if lim > _MAX_WHOLE_LIM:
            sel = order[lo:hi]
            out[i] = _range_estimates(z[sel], d1[sel], d2[sel], np.arange(m), 1)[0]
            lo = hi
            continue
        # differences kept: 1e-6 < |d1| < lim (whole: 1..top1) and |d2| < lim (-top2..top2)
        top1 = math.ceil(lim) - 1
        top2 = top1
        n1 = 0
        n2 = 0
        for t in range(lo, hi):
            j = order[t]
            a = d1[j]
            if a > 1e-6 and a < lim:
                h1[int(a)] += 1
                n1 += 1
            c = d2[j]
            if abs(c) < lim:
                h2[int(c) + top2] += 1
                n2 += 1
        lo = hi
        if n1 >= 20 and n2 >= 20:
            step, sigma = _count_statistics(h1, n1, top1, h2, n2, top2, h3)
            out[i, 0] = zc
            out[i, 1] = step
            out[i, 2] = sigma
            out[i, 3] = 1.0
        h1[: top1 + 1] = 0
        h2[: 2 * top2 + 1] = 0
    return out


@njit(cache=True, inline="always")
def _count_statistics(
    h1: NDArray[np.integer], n1: int, top1: int, h2: NDArray[np.integer], n2: int, top2: int, h3: NDArray[np.int64]
) -> tuple[float, float]:
    # One depth range's step and sigma from the counts of its differences, with
    # _range_estimates' arithmetic (an order statistic is a value of the sample whatever finds
    # it): h1[v] counts the first differences of value v (1..top1, n1 of them), h2[v + top2]
    # the second differences of value v (-top2..top2, n2 of them), both at least 20. h3 is a
    # zeroed scratch of 4 * top2 + 2 counts, left zeroed. The one place both counted routes
    # (_range_estimates_counted, _range_estimates_whole) read their statistics.
    # np.percentile(nz, 20) as _percentile20 takes it
    vi = (n1 - 1) * (20 / 100)
    jj = math.floor(vi)
    if vi >= n1 - 1:
        step = float(_kth_count(h1, top1 + 1, n1 - 1))
    else:
        p_lo = float(_kth_count(h1, top1 + 1, jj))
        p_hi = float(_kth_count(h1, top1 + 1, jj + 1))
        tt = vi - jj
        diff = p_hi - p_lo
        step = p_hi - diff * (1.0 - tt) if tt >= 0.5 else p_lo + diff * tt
    # the median of b, then the median of |b - med| (whole or half numbers: counted at twice
    # their value)
    hb = n2 // 2
    if n2 % 2:
        med = float(_kth_count(h2, 2 * top2 + 1, hb) - top2)
    else:
        med = (
            float(_kth_count(h2, 2 * top2 + 1, hb - 1) - top2) + float(_kth_count(h2, 2 * top2 + 1, hb) - top2)
        ) / 2.0
    size3 = 4 * top2 + 2
    for v in range(2 * top2 + 1):
        cnt = h2[v]
        if cnt:
            h3[int(abs(float(v - top2) - med) * 2.0)] += cnt
    if n2 % 2:
        dev = _kth_count(h3, size3, hb) / 2.0
    else:
        dev = (_kth_count(h3, size3, hb - 1) / 2.0 + _kth_count(h3, size3, hb) / 2.0) / 2.0
    h3[:size3] = 0
    mad = dev * 1.4826
    sigma2 = max(mad * mad - step * step / 2.0, 0.0) / 6.0
    return step, math.sqrt(sigma2)


@njit(cache=True, nogil=True)
def _kth_count(count: NDArray[np.integer], size: int, k: int) -> int:
    # the index of the k-th (0-based) counted value among count[:size]
    seen = 0
    for v in range(size):
        seen += count[v]
        if seen > k:
            return v
    return size - 1


def _fit_a_bz2(z: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float]:
    """Non-negative least squares of ``y = a + b z**2`` (two unknowns: solved in closed form)."""
    if z.size == 1:
        return float(y[0]), 0.0
    x = z * z
    a, b = _lstsq_a_bz2(np.ascontiguousarray(x), np.ascontiguousarray(y))
    return _non_negative(z, y, a, b)


def _non_negative(z: NDArray[np.float64], y: NDArray[np.float64], a: float, b: float) -> tuple[float, float]:
    """:func:`_fit_a_bz2` given the least squares ``(a, b)`` of ``y = a + b z**2`` (unread for one point)."""
    if z.size == 1:
        return float(y[0]), 0.0
    if a < 0:  # all of it grows with depth
        x = z * z
        return 0.0, float(max(np.dot(x, y) / np.dot(x, x), 0.0))
    if b < 0:  # none of it does
        return float(np.mean(y)), 0.0
    return a, b


@njit(cache=True, nogil=True)
def _lstsq_a_bz2(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float]:
    """Least squares ``(a, b)`` of ``y = a + b x``: ``np.linalg.lstsq``'s numbers, compiled.

    numba's ``lstsq`` calls LAPACK's ``dgelsd`` as numpy does, here with numpy's default
    ``rcond`` (machine epsilon times the larger dimension), so the solution is numpy's to the
    last bit; compiled because the numpy call costs about 30 us around a 12 x 2 problem.
    """
    m = x.size
    a = np.empty((m, 2), np.float64)
    a[:, 0] = 1.0
    a[:, 1] = x
    sol = np.linalg.lstsq(a, y, 2.220446049250313e-16 * max(m, 2))[0]
    return sol[0], sol[1]
