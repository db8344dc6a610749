"""Wrong units caught at the first frame, by what a depth camera can and cannot see.

A source read in the wrong units gives a scene no camera sees: TUM's 5000 units per metre read as
mm put the median at 12 m, SUN RGB-D without its bit shift at 21 m, NYU's raw disparity at 54 m;
YCB-Video's 0.1 mm units read as mm put the desk at 6.3 m and a twentieth of the readings beyond
14 m; millimetres read with ``--scale 0.1`` put a room at 19 cm, nearer than nearly any depth camera
focuses. :func:`check_first_frame` weighs each way of reading the samples against these limits:

- the near limit: depth cameras read from 0.2-0.5 m on (Kinect and Xtion 0.4-0.5 m, Azure Kinect
  0.25 m, RealSense D435 about 0.2 m; a close-range RealSense D405 from 7 cm is the exception);
- the far limit: none reads beyond about 10 m, and scenes have their median within 8 m;
- the sample grid: a 16-bit image whose readings are all multiples of 10 (or 5) stores a sensor's
  1 mm readings in 0.1 mm (or 0.2 mm) units, whatever the depths look like.

Readings whose median lies outside 50 mm - 8 m always warn; a scene that is only unlikely (nearer
than the near limit, a far tail beyond 10 m) warns when another reading of the same samples is
plausible, and the advice names the one reading that is: drop ``--scale``, or the scale that fits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import PLAUSIBLE_MEDIAN_MM, Frame, warn_units
from depthgram.sources.config import SourceConfig
from depthgram.sources.encodings import decode_kinect_disparity, decode_sun

__all__ = ["Reading", "check_first_frame", "likely_options", "sample_grid"]

#: Linear scales worth proposing (mm per raw unit) and what they are known as.
_SCALES = (
    (0.2, "TUM's 5000 units per metre"),
    (0.1, "0.1 mm units, as YCB-Video"),
    (1000.0, "metres"),
)

#: A median nearer than this (mm) is under the near limit of nearly every depth camera (0.2-0.5 m).
NEAR_LIMIT_MM = 250.0

#: Readings beyond this (mm) are farther than any depth camera reads (Kinect, Xtion and RealSense
#: give noise beyond 8-10 m, Azure Kinect stops at 5.5 m): a twentieth of them there is no scene.
FAR_LIMIT_MM = 10_000.0

#: Raw grids that mean 1 mm readings stored in finer units, and the scale (mm per unit) they imply.
GRIDS = ((10, 0.1), (5, 0.2))

#: Share of samples on the grid for it to count (a few resampled or filled pixels may fall off it).
_GRID_SHARE = 0.995

#: Distinct sample values needed before a grid means anything (a flat test frame is on every grid).
_GRID_MIN_DISTINCT = 32

#: Samples drawn (strided) from a frame for these statistics.
_SAMPLES = 20_000


@dataclass(frozen=True)
class Reading:
    """One way of reading the samples: its scale and the depths it gives (mm).

    Attributes
    ----------
    scale_mm : float
        Millimetres per raw unit.
    median_mm, p5_mm, p95_mm : float
        Median, 5th and 95th percentiles of the valid depths so read (mm).
    """

    scale_mm: float
    median_mm: float
    p5_mm: float
    p95_mm: float

    def impossible(self) -> str:
        """Return why no depth camera gives this median ("" when one can)."""
        lo, hi = PLAUSIBLE_MEDIAN_MM
        if self.median_mm > hi:
            far = f"beyond {hi / 1000:.0f} m, farther than depth cameras read"
            return f"the median depth {self.median_mm:.0f} mm is {far}"
        if self.median_mm < lo:
            return f"the median depth {self.median_mm:.1f} mm is under {lo:.0f} mm, nearer than depth cameras read"
        return ""

    def unlikely(self) -> str:
        """Return why this scene is unlikely for a depth camera ("" when it is plausible)."""
        if self.median_mm < NEAR_LIMIT_MM:
            return (
                f"the median depth {self.median_mm:.0f} mm is nearer than depth cameras read "
                f"(their near limits are 0.2-0.5 m; only close-range ones such as the RealSense D405 read nearer)"
            )
        if self.p95_mm > FAR_LIMIT_MM:
            return (
                f"a twentieth of the depths lie beyond {self.p95_mm / 1000:.1f} m (median {self.median_mm:.0f} mm), "
                f"farther than depth cameras read ({FAR_LIMIT_MM / 1000:.0f} m at most)"
            )
        return ""

    def plausible(self) -> bool:
        """Return whether a depth camera could give these depths."""
        return not (self.impossible() or self.unlikely())


def _reading(raw_values: NDArray[np.float64], scale_mm: float) -> Reading:
    med, p5, p95 = np.percentile(raw_values * scale_mm, [50, 5, 95])
    return Reading(scale_mm, float(med), float(p5), float(p95))


def sample_grid(samples: NDArray[np.generic]) -> tuple[int, float] | None:
    """Return the grid (raw step, implied mm per unit) all integer ``samples`` lie on, or None.

    Parameters
    ----------
    samples : ndarray
        Valid raw samples (no 0 or invalid markers).

    Returns
    -------
    (int, float) or None
        ``(10, 0.1)`` when nearly all are multiples of 10 (1 mm readings in 0.1 mm units), ``(5, 0.2)``
        for multiples of 5 (TUM's 5000 per metre); None for float samples, too few distinct values,
        or no grid.
    """
    if not np.issubdtype(samples.dtype, np.integer) or samples.size == 0:
        return None
    s = samples.astype(np.int64)
    if np.unique(s).size < _GRID_MIN_DISTINCT:
        return None
    for step, scale in GRIDS:
        if float(np.mean(s % step == 0)) >= _GRID_SHARE:
            return step, scale
    return None


def _default_scale(raw: NDArray[np.generic], cfg: SourceConfig) -> float:
    """Return the scale the samples are read with when ``--scale`` is not given."""
    is_int = np.issubdtype(raw.dtype, np.integer)
    return {"mm": 1.0, "m": 1000.0}.get(cfg.encoding, 1.0 if is_int else 1000.0)


def _raw_samples(raw: NDArray[np.generic], frame: Frame) -> NDArray[np.generic]:
    step = max(1, int(np.sqrt(raw.size / _SAMPLES)))
    return raw[::step, ::step][frame.valid[::step, ::step]]


def _encodings(raw: NDArray[np.generic], cfg: SourceConfig) -> list[str]:
    """Return the encodings under which ``raw`` (read as too far) gives a plausible median."""
    out: list[str] = []
    if cfg.encoding not in ("auto", "raw") or raw.dtype != np.uint16:
        return out
    samples: NDArray[np.uint16] = np.asarray(raw, dtype=np.uint16)
    nonzero = samples[samples > 0]
    if nonzero.size == 0:
        return out
    # SUN's shift moves the top 3 bits of mm (0 below 8.2 m) to the bottom: nearly all samples are
    # multiples of 8; a raw Kinect disparity has 11 bits, byte-swapped or not
    sun_like = float(np.mean((nonzero & 7) == 0)) > 0.9
    codes = nonzero if int(nonzero.max()) <= 2047 else nonzero.byteswap()
    kinect_like = int(codes.max()) <= 2047
    lo, hi = PLAUSIBLE_MEDIAN_MM
    if sun_like:
        sun = decode_sun(raw)
        if lo <= float(np.median(sun[sun > 0])) <= hi:
            out.append("--encoding sun (SUN RGB-D's bit-shifted millimetres)")
    if kinect_like:
        mm = decode_kinect_disparity(raw, cfg.invalid)
        if (mm > 0).any() and lo <= float(np.median(mm[mm > 0])) <= hi:
            out.append("--encoding kinect-disparity (raw Kinect disparity, as NYU's raw frames)")
    return out


def likely_options(raw: NDArray[np.generic], frame: Frame, cfg: SourceConfig, *, too_far: bool = True) -> list[str]:
    """Return the reading options under which ``raw`` gives a plausible scene, as flags to print.

    Parameters
    ----------
    raw : ndarray, shape (H, W)
        The samples as stored.
    frame : Frame
        The frame as read with ``cfg`` (its depths were implausible or unlikely).
    cfg : SourceConfig
        The options it was read with.
    too_far : bool
        The depths were too far (else too near): only then are the encodings tried (both turn
        large raw codes into ordinary distances).

    Returns
    -------
    list of str
        The one fix when the samples say which (``["dropping --scale ..."]``, or the scale of the grid
        the samples lie on: ``["--scale 0.1 (...)"]``); else every plausible one; empty when none is.
    """
    out = _encodings(raw, cfg) if too_far else []
    if out or cfg.encoding not in ("auto", "raw", "mm", "m"):
        return out
    samples = _raw_samples(raw, frame)
    if samples.size == 0:
        return out
    values = samples.astype(np.float64)
    used = cfg.scale_mm if cfg.scale_mm is not None else _default_scale(raw, cfg)
    default = _default_scale(raw, cfg)
    if cfg.scale_mm is not None and cfg.scale_mm != default and _reading(values, default).plausible():
        unit = "millimetres" if default == 1.0 else "metres"
        return [f"dropping --scale {cfg.scale_mm:g} (the samples read as {unit} give a plausible scene)"]
    grid = sample_grid(samples)
    if grid is not None and grid[1] != used and _reading(values, grid[1]).plausible():
        step, scale = grid
        return [f"--scale {scale:g} (every sample is a multiple of {step}: 1 mm readings stored in {scale:g} mm units)"]
    for scale, what in _SCALES:
        if scale != used and _reading(values, scale).plausible():
            out.append(f"--scale {scale:g} ({what})")
    return out


def check_first_frame(raw: NDArray[np.generic], frame: Frame, cfg: SourceConfig, where: str) -> None:
    """Warn (:class:`~depthgram.frame.UnitsWarning`) when ``frame`` holds depths no camera gives.

    Called by :func:`depthgram.sources.decode.to_frame` on a source's first frame only: a
    recording read in the wrong units warns once, naming the fix. A median outside 50 mm - 8 m
    always warns; a scene that is only unlikely (:meth:`Reading.unlikely`) warns when another
    reading of the samples is plausible, and then names that one.
    """
    samples = _raw_samples(raw, frame)
    if samples.size == 0:
        return
    used = cfg.scale_mm if cfg.scale_mm is not None else _default_scale(raw, cfg)
    if cfg.encoding in ("auto", "raw", "mm", "m"):
        as_read = _reading(samples.astype(np.float64), used)
    else:  # a decoded encoding: the depths themselves
        d = frame.depth[frame.valid].astype(np.float64)
        as_read = _reading(d[:: max(1, d.size // _SAMPLES)], 1.0)
    hard = as_read.impossible()
    if hard:
        warn_units(where, hard, likely_options(raw, frame, cfg, too_far=as_read.median_mm > PLAUSIBLE_MEDIAN_MM[1]))
        return
    soft = as_read.unlikely()
    if soft:
        fixes = likely_options(raw, frame, cfg, too_far=as_read.p95_mm > FAR_LIMIT_MM)
        if fixes:
            warn_units(where, soft, fixes)
