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

__all__ = [
    "CORRELATION_WINDOW_FRACTION",
    "PROFILES",
    "SensorModel",
    "averaged_over_window",
    "estimate_sensor",
    "sensor_model",
]

#: Width of a structured-light or active-stereo camera's correlation window as a share of its
#: frame width: the disparity of a pixel is matched over a window of about 7-9 px at 640 px
#: (Kinect v1 / Xtion / PrimeSense's 9 x 9 block; RealSense D400's census window), so each
#: reading is a mean over it and a bend of the surface is spread over it. The wider, 9 px.
CORRELATION_WINDOW_FRACTION = 9.0 / 640.0


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
    window_fraction : float
        Width of the window each reading is averaged over, as a share of the frame width
        (dimensionless; :data:`CORRELATION_WINDOW_FRACTION` for a camera that matches a pattern
        over a window, structured light or active stereo); 0 for a camera that measures each
        pixel on its own (time of flight). Sets the concave creases' span
        (:func:`depthgram.segmentation.creases.crease_span_px`).
    """

    name: str
    step_0: float
    step_2: float
    sigma_0: float
    sigma_2: float
    window_fraction: float = 0.0

    def __post_init__(self) -> None:
        if not (isinstance(self.window_fraction, (int, float)) and 0.0 <= self.window_fraction <= 1.0):
            raise InputError(
                f"sensor model {self.name!r}: window_fraction = {self.window_fraction!r}, expected a share in [0, 1]"
            )
        object.__setattr__(self, "window_fraction", float(self.window_fraction))
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
    return SensorModel(name, 0.0, subpixel / fb, 0.0, noise_px / fb, CORRELATION_WINDOW_FRACTION)


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
        Named ``auto``; its ``window_fraction`` is :data:`CORRELATION_WINDOW_FRACTION` when the
        frame reads as averaged over a correlation window (:func:`averaged_over_window`), else 0.

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
    fit, sol = _range_fit(depth_mm, valid, rows)
    if not fit.shape[0]:
        return PROFILES["tof"]
    # Python floats (numpy scalars in a model send the creases to their numpy route)
    a1, b1, a2, b2 = sol.tolist()
    s0, s2 = _non_negative(fit[:, 0], fit[:, 1], a1, b1)
    n0, n2 = _non_negative(fit[:, 0], fit[:, 2], a2, b2)
    # the depth ranges have equal counts: their middle one's depth is about the frame's median
    z_mid = float(fit[fit.shape[0] // 2, 0])
    window = CORRELATION_WINDOW_FRACTION if averaged_over_window(s0, s2, n0, n2, z_mid) else 0.0
    return SensorModel("auto", s0, s2, n0, n2, window)


def averaged_over_window(step_0: float, step_2: float, sigma_0: float, sigma_2: float, z_mm: float) -> bool:
    """Whether a frame's estimated model reads as a camera that matches over a correlation window.

    Parameters
    ----------
    step_0, step_2, sigma_0, sigma_2 : float
        The estimated step ``step_0 + step_2 z**2`` and noise ``sigma_0 + sigma_2 z**2`` (mm;
        ``step_2``, ``sigma_2`` in 1/mm), as :class:`SensorModel` holds them.
    z_mm : float
        Depth (mm) at which they are compared: about the frame's median.

    Returns
    -------
    bool
        True for structured light or active stereo, False for time of flight.

    Notes
    -----
    A structured-light or stereo camera measures a disparity, matched over a window of pixels:
    its depth comes in disparity steps that grow as ``z**2``, and each reading is a mean over
    the window, so the per-pixel noise left between two readings is a fraction of a step. A
    time-of-flight pixel measures its own phase: its step is the output unit (flat in depth)
    and its noise is its own, a sizeable share of a unit or more (the Azure Kinect frame: 0.4 of
    its 1.3 mm step at 1.5 m; the simulator's ToF: 2.5 steps). So the frame reads as averaged
    when its noise is below a step and either its step grows as ``z**2`` (the larger part at
    ``z_mm``: the Kinect v1 of 7-Scenes and TUM, the RealSense of NVlabs, the simulator's
    structured light) or its noise is below a quarter of a step (a disparity resampled to whole
    millimetres, as YCB-Video's Xtion frames: a 1 mm step and 0.05-0.1 mm of noise). With the
    noise at or above a step, the estimated step is the noise's, not a quantisation's, and says
    nothing of the family: no window.
    """
    step = step_0 + step_2 * z_mm * z_mm
    sigma = sigma_0 + sigma_2 * z_mm * z_mm
    if not step > 0.0 or sigma >= step:
        return False
    return step_2 * z_mm * z_mm >= step_0 or sigma < 0.25 * step


def _range_fit(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return the rows of the depth ranges with enough differences and the two fits over them.

    The steps of :func:`estimate_sensor` from the samples to the fit: the range estimates
    (median depth, step, sigma, 1; none below 200 samples) and, with two ranges or more,
    ``(a, b)`` of the step's and the sigma's least squares against depth squared (zeros with
    fewer than two rows).
    """
    est = _range_estimates_counted(depth, valid, rows)
    fit = est[est[:, 3] > 0]
    sol = np.zeros(4, np.float64)
    if fit.shape[0] > 1:
        # a straight line through (z**2, step) and (z**2, sigma): slope from the centred sums
        # (np.linalg.lstsq costs three times as much around two unknowns); lstsq's minimum-norm
        # answer when every range has one depth
        x = fit[:, 0] * fit[:, 0]
        m = x.size
        # np.mean's value (its sum over the count) without its Python wrapper, called per frame
        x_mean = np.add.reduce(x) / m
        dx = x - x_mean
        sxx = float(dx @ dx)
        y = fit[:, 1:3]
        if sxx > 0.0:
            y_mean = np.add.reduce(y, axis=0) / m
            b = dx @ (y - y_mean) / sxx
            sol[0::2] = y_mean - b * x_mean
            sol[1::2] = b
        else:
            sol[:] = np.linalg.lstsq(np.stack([np.ones_like(x), x], axis=1), y, rcond=None)[0].T.reshape(4)
    return fit, sol


def _range_estimates_counted(depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int) -> NDArray[np.float64]:
    """Each depth range's row of the estimate (median depth, step, sigma, 1; none below 200 samples).

    When every reading of the sampled rows is a whole number in [1, 2**24) (what most cameras
    give), the ranges' order statistics come from counts in one compiled call
    (:func:`_ranges_from_counts`); other frames take the readable route
    (:func:`range_estimates_readable`), which gives the same values (a test holds both). Kept
    compiled: the estimate runs in every ``segment`` call, and the readable route's stable sort
    and per-range selections cost 0.4-1 ms a frame against 0.1 ms here (over 30 % of the
    default method at 176 x 132).
    """
    est, counted = _ranges_from_counts(depth, valid, rows)
    return est if counted else range_estimates_readable(depth, valid, rows)


#: Widest depth tolerance (mm) whose differences :func:`_ranges_from_counts` counts.
_MAX_WHOLE_LIM = 1 << 13


def range_estimates_readable(depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int) -> NDArray[np.float64]:
    """Return the depth ranges' estimates of :func:`estimate_sensor`, in numpy: the readable route.

    Every ``rows``-th row, each pixel whose two row neighbours have a reading gives its depth,
    its first difference ``|z[x+1] - z[x]|`` and its second difference ``(z[x-1] - 2 z[x]) +
    z[x+1]``. The samples, in depth order (stable: which of the pixels tied at a range boundary
    fall on each side changes the estimate), are split in ``k`` ranges of equal count (the
    parts of ``np.array_split``); per range: the median depth, the step (20th percentile of the
    non-zero first differences within 5 % of that depth: a jump to another surface is not
    noise) and sigma (the MAD of the second differences within 5 %, less quantisation). Rows
    ``(median depth, step, sigma, 1)``, or zeros where a range had under 20 differences; no
    rows below 200 samples.
    """
    zr = depth[::rows].astype(np.float64)
    vr = valid[::rows]
    ok = vr[:, :-2] & vr[:, 1:-1] & vr[:, 2:]
    a, z, c = zr[:, :-2][ok], zr[:, 1:-1][ok], zr[:, 2:][ok]
    if z.size < 200:
        return np.zeros((0, 4), np.float64)
    d1 = np.abs(c - z)
    d2 = (a - 2.0 * z) + c
    # depth ranges of equal pixel count, so each fit point has the same weight of evidence
    k = min(12, max(2, z.size // 400))
    out = np.zeros((k, 4), np.float64)
    for i, part in enumerate(np.array_split(np.argsort(z, kind="stable"), k)):
        zc = float(np.median(z[part]))
        lim = 0.05 * zc
        p1 = d1[part]
        nz = p1[(p1 > 1e-6) & (p1 < lim)]
        p2 = d2[part]
        b = p2[np.abs(p2) < lim]
        if nz.size < 20 or b.size < 20:
            continue
        step = float(np.percentile(nz, 20))
        mad = float(np.median(np.abs(b - np.median(b)))) * 1.4826
        sigma2 = max(mad * mad - step * step / 2.0, 0.0) / 6.0
        out[i] = zc, step, math.sqrt(sigma2), 1.0
    return out


@njit(cache=True, nogil=True)
def _ranges_from_counts(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int
) -> tuple[NDArray[np.float64], bool]:
    # range_estimates_readable from counts, and True; (empty, False) unless every reading of
    # the sampled rows is a whole number in [1, 2**24) within a span and a depth it counts.
    # The samples are taken as whole numbers; then, without their order, the depths' counts
    # give each equal-count range's limits and median depth; a table gives each depth its
    # range (its pixels' differences counted in that range's histograms), and only the few
    # depths tied across a range boundary take their pixels' places in raster order, as the
    # stable order does. Each range's order statistics are read from the counts of its
    # differences (an order statistic is a value of the sample whatever finds it).
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
    at = 0
    for y in range(0, h, rows):
        zrow = depth[y]
        vrow = valid[y]
        for x in range(w):
            zv = zrow[x]
            has = np.uint8(vrow[x])
            whole = np.uint8((zv >= np.float32(1.0)) & (zv < np.float32(16777216.0)) & (np.floor(zv) == zv)) & has
            bad |= has ^ whole
            zi = np.int32(zv) if whole else np.int32(0)
            iz[x] = zi
            ok[x] = whole
            lo = min(lo, zi if whole else none)
            hi = max(hi, zi)
        for x in range(1, w - 1):
            zm = iz[x]
            zn = iz[x + 1]
            key[at + x - 1] = zm if ok[x - 1] & ok[x] & ok[x + 1] else np.int32(0)
            d1[at + x - 1] = abs(zn - zm)
            d2[at + x - 1] = (iz[x - 1] - 2 * zm) + zn
        at += places
    if bad != 0 or hi - lo >= 1 << 20 or 0.05 * hi > _MAX_WHOLE_LIM:
        return np.zeros((0, 4), np.float64), False
    if hi < lo:  # no reading in the sampled rows
        return np.zeros((0, 4), np.float64), True
    # each depth's count (slot 0 holds the places without a sample), the places keyed in place
    count = np.zeros(hi - lo + 2, np.int32)
    off = np.int32(1 - lo)
    for i in range(key.size):
        j = max(key[i] + off, np.int32(0))
        key[i] = j
        count[np.uint64(j)] += 1
    n = key.size - count[0]
    if n < 200:
        return np.zeros((0, 4), np.float64), True
    k = min(12, max(2, n // 400))
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
    # each range's order statistics with range_estimates_readable's arithmetic
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
        # the range's step and sigma from the counts of its differences: h1[v] counts the first
        # differences of value v (1..top1, n1 of them), h2[v + top2] the second differences of
        # value v (-top2..top2, n2 of them); h3 is a zeroed scratch, left zeroed.
        # The step: np.percentile(nz, 20), numpy's linear interpolation from the nearer end
        # (the k-th smallest counted value is the first whose running count passes k)
        cum1 = np.cumsum(h1[: top1 + 1])
        vi = (n1 - 1) * (20 / 100)
        jj = math.floor(vi)
        if vi >= n1 - 1:
            step = float(np.searchsorted(cum1, n1 - 1, side="right"))
        else:
            p_lo = float(np.searchsorted(cum1, jj, side="right"))
            p_hi = float(np.searchsorted(cum1, jj + 1, side="right"))
            tt = vi - jj
            diff = p_hi - p_lo
            step = p_hi - diff * (1.0 - tt) if tt >= 0.5 else p_lo + diff * tt
        # the median of b, then the median of |b - med| (whole or half numbers: counted at twice
        # their value)
        cum2 = np.cumsum(h2[: 2 * top2 + 1])
        hb = n2 // 2
        if n2 % 2:
            med = float(np.searchsorted(cum2, hb, side="right") - top2)
        else:
            lo2 = np.searchsorted(cum2, hb - 1, side="right")
            med = (float(lo2 - top2) + float(np.searchsorted(cum2, hb, side="right") - top2)) / 2.0
        size3 = 4 * top2 + 2
        for v in range(2 * top2 + 1):
            cnt = h2[v]
            if cnt:
                h3[int(abs(float(v - top2) - med) * 2.0)] += cnt
        cum3 = np.cumsum(h3[:size3])
        if n2 % 2:
            dev = np.searchsorted(cum3, hb, side="right") / 2.0
        else:
            dev = (
                np.searchsorted(cum3, hb - 1, side="right") / 2.0 + np.searchsorted(cum3, hb, side="right") / 2.0
            ) / 2.0
        h3[:size3] = 0
        mad = dev * 1.4826
        sigma2 = max(mad * mad - step * step / 2.0, 0.0) / 6.0
        out[r, 0] = zc[r]
        out[r, 1] = step
        out[r, 2] = math.sqrt(sigma2)
        out[r, 3] = 1.0
    return out, True


def _non_negative(z: NDArray[np.float64], y: NDArray[np.float64], a: float, b: float) -> tuple[float, float]:
    """Return the non-negative least squares of ``y = a + b z**2``, given the plain one ``(a, b)``.

    ``(a, b)`` is unread for one point.
    """
    if z.size == 1:
        return float(y[0]), 0.0
    if a < 0:  # all of it grows with depth
        x = z * z
        return 0.0, float(max(np.dot(x, y) / np.dot(x, x), 0.0))
    if b < 0:  # none of it does
        return float(np.mean(y)), 0.0
    return a, b
