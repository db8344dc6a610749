"""Wrong units caught at the first frame: implausible depths and the reading options that fix them.

A source read in the wrong units gives depths no camera reads (TUM's 5000 units per metre read
as mm: a median of 12 m; SUN RGB-D without its bit shift: 21 m; NYU's raw disparity: 54 m).
:func:`check_first_frame` tries the reading options that could explain the raw samples and names
those that give a plausible median, so the warning says which flag to pass.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import PLAUSIBLE_MEDIAN_MM, Frame, implausible_depth, warn_units
from depthgram.sources.config import SourceConfig

__all__ = ["check_first_frame", "likely_options"]

#: Linear scales worth proposing (mm per raw unit) and what they are known as.
_SCALES = (
    (0.2, "TUM's 5000 units per metre"),
    (0.1, "0.1 mm units, as YCB-Video"),
    (1000.0, "metres"),
)


def _median(values: NDArray[np.floating]) -> float | None:
    step = max(1, values.size // 10_000)
    d = values.ravel()[::step]
    d = d[np.isfinite(d) & (d > 0)]
    return float(np.median(d)) if d.size else None


def _plausible(mm: float | None) -> bool:
    lo, hi = PLAUSIBLE_MEDIAN_MM
    return mm is not None and lo <= mm <= hi


def likely_options(raw: NDArray[np.generic], frame: Frame, cfg: SourceConfig, *, too_far: bool = True) -> list[str]:
    """Return reading options under which ``raw`` gives a plausible median depth, as flags to print.

    Parameters
    ----------
    raw : ndarray, shape (H, W)
        The samples as stored.
    frame : Frame
        The frame as read with ``cfg`` (its median was implausible).
    cfg : SourceConfig
        The options it was read with.
    too_far : bool
        The median was beyond the plausible range (else under it): only then are the encodings
        tried (both turn large raw codes into ordinary distances).

    Returns
    -------
    list of str
        e.g. ``["--scale 0.2 (TUM's 5000 units per metre)"]``; the encodings are tried only on
        integer images read with ``auto``.
    """
    from depthgram.sources.decode import decode_kinect_disparity, decode_sun

    out: list[str] = []
    med = _median(frame.depth[frame.valid])
    if med is None:
        return out
    is_int = np.issubdtype(raw.dtype, np.integer)
    if too_far and cfg.encoding in ("auto", "raw") and raw.dtype == np.uint16:
        samples: NDArray[np.uint16] = np.asarray(raw, dtype=np.uint16)
        nonzero = samples[samples > 0]
        # SUN's shift moves the top 3 bits of mm (0 below 8.2 m) to the bottom: nearly all samples are
        # multiples of 8; a raw Kinect disparity has 11 bits, byte-swapped or not
        sun_like = nonzero.size > 0 and float(np.mean((nonzero & 7) == 0)) > 0.9
        codes = nonzero if nonzero.size == 0 or int(nonzero.max()) <= 2047 else nonzero.byteswap()
        kinect_like = nonzero.size > 0 and int(codes.max()) <= 2047
        if sun_like and _plausible(_median(decode_sun(raw).astype(np.float32))):
            out.append("--encoding sun (SUN RGB-D's bit-shifted millimetres)")
        if kinect_like and _plausible(_median(decode_kinect_disparity(raw, cfg.invalid))):
            out.append("--encoding kinect-disparity (raw Kinect disparity, as NYU's raw frames)")
    if not out:
        # the scale that frame was read with is folded into med: propose the absolute one
        used = cfg.scale_mm if cfg.scale_mm is not None else (1.0 if is_int else 1000.0)
        for scale, what in _SCALES:
            if scale != used and _plausible(med * scale / used):
                out.append(f"--scale {scale:g} ({what})")
    return out


def check_first_frame(raw: NDArray[np.generic], frame: Frame, cfg: SourceConfig, where: str) -> None:
    """Warn (:class:`~depthgram.frame.UnitsWarning`) when ``frame`` holds implausible depths.

    Called by :func:`depthgram.sources.decode.to_frame` on a source's first frame only: a
    recording read in the wrong units warns once, naming the likely option.
    """
    found = implausible_depth(frame.depth, frame.valid)
    if found:
        warn_units(where, found[0], likely_options(raw, frame, cfg, too_far=found[1]))
