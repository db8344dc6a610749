"""The clearance channel: where the sensor can move without meeting anything too near.

Paper, section 4: "Partial obstruction in the line of view translates to the clearance channel
in navigation." Per image column we take the nearest valid depth among the pixels the body
would sweep (the floor and what is above the body are ignored); columns whose nearest
obstruction is at least the safety distance away are free, and a run of free columns wide
enough for the body is an opening.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.act.config import ActConfig
from depthgram.errors import InputError
from depthgram.frame import Frame

__all__ = ["Channel", "clearance_channel", "column_clearance", "openings"]


@dataclass(frozen=True)
class Channel:
    """A free corridor in the view.

    Attributes
    ----------
    col_start, col_stop : int
        First and last free image column (inclusive).
    center_col : float
        Middle column of the opening (px).
    width_px : int
        Number of free columns.
    angle_deg : float or None
        Heading of the opening's middle from the optical axis (degrees, positive to the right),
        when intrinsics are known.
    width_mm : float or None
        Width of the opening (mm) when intrinsics are known, measured at its pinch: at the depth
        of the nearer of the obstructions flanking it, or at the safety distance where the opening
        runs to the image border (nothing beyond the view is known to be free).
    free_mm : float or None
        Nearest valid obstruction inside the opening (mm): how far the way is known to be free;
        None when no column of the opening has a reading in the body's band.
    """

    col_start: int
    col_stop: int
    center_col: float
    width_px: int
    angle_deg: float | None = None
    width_mm: float | None = None
    free_mm: float | None = None


def column_clearance(frame: Frame, config: ActConfig | None = None) -> NDArray[np.float64]:
    """Nearest valid depth (mm) per column among the pixels the body sweeps.

    Parameters
    ----------
    frame : Frame
        Depth (mm) with its valid mask; intrinsics, when present, select the rows by height.
    config : ActConfig, optional
        Body size, sensor height and floor margin.

    Returns
    -------
    ndarray of float, shape (W,)
        Nearest depth (mm) per column; ``inf`` where the column has no valid reading in the band.
    """
    cfg = config or ActConfig()
    depth = np.asarray(frame.depth, dtype=np.float32)
    if depth.ndim != 2:
        raise InputError(f"{frame.name or f'frame {frame.index}'}: expected a 2-D depth image, got shape {depth.shape}")
    h, _ = depth.shape
    k = frame.intrinsics
    if k is not None:
        # Height above the floor of each point, optical axis horizontal (Y grows downwards):
        # height = sensor - dy * depth with dy = (row - cy) / fy. Both band limits are linear in
        # depth, so each row admits one depth interval: two comparisons per pixel against
        # per-row bounds instead of a full-frame float64 product (docs/design-notes.md).
        dy = (np.arange(h, dtype=np.float64) - k.cy) / k.fy
        lo = np.zeros(h)
        hi = np.full(h, np.inf)
        above_floor = (dy, cfg.sensor_height_mm - cfg.floor_margin_mm)
        below_top = (-dy, cfg.body_height_mm - cfg.sensor_height_mm)
        for a, b in (above_floor, below_top):  # each reads a * depth < b
            with np.errstate(divide="ignore", invalid="ignore"):
                bound = b / a
            hi = np.where(a > 0, np.minimum(hi, bound), hi)
            lo = np.where(a < 0, np.maximum(lo, bound), lo)
            hi = np.where((a == 0) & (b <= 0), -np.inf, hi)
    else:
        r0 = math.floor(cfg.band_rows[0] * h)
        r1 = max(math.ceil(cfg.band_rows[1] * h), r0 + 1)
        lo = np.zeros(h)
        hi = np.full(h, -np.inf)  # rows outside the band admit no depth
        hi[r0:r1] = np.inf
    return _column_min(depth, np.ascontiguousarray(frame.valid, np.bool_), lo.astype(np.float32), hi.astype(np.float32))


@njit(cache=True, nogil=True)
def _column_min(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], lo: NDArray[np.float32], hi: NDArray[np.float32]
) -> NDArray[np.float64]:
    # One pass over the frame for what numpy did in five full-frame temporaries (validity,
    # two band tests, the masked copy, the column minimum); docs/design-notes.md.
    h, w = depth.shape
    out = np.full(w, np.inf, np.float32)
    for y in range(h):
        a = max(lo[y], np.float32(0.0))
        b = hi[y]
        for x in range(w):
            z = depth[y, x]
            if valid[y, x] and z > a and z < b and z < out[x]:
                out[x] = z
    return out.astype(np.float64)


def openings(free: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Return runs of True in a 1-D mask as (start, stop) inclusive column pairs, left to right."""
    f = np.concatenate(([False], np.asarray(free, bool), [False])).astype(np.int8)
    edges = np.diff(f)
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1) - 1
    return [(int(a), int(b)) for a, b in zip(starts, stops, strict=True)]


def clearance_channel(frame: Frame, config: ActConfig | None = None) -> Channel | None:
    """Return the clearance channel of one frame, or None when the way is blocked.

    A column is free when its nearest obstruction in the body's band is at least
    ``config.safety_mm`` away (columns without a reading count as blocked unless
    ``config.unknown_is_free``). Of the runs of free columns at least the body's width wide
    (``body_width_mm`` with intrinsics, ``body_width_px`` without), the one nearest straight
    ahead is returned (``channel_choice="ahead"``), or the widest (``"widest"``).

    Parameters
    ----------
    frame : Frame
        Depth image (mm), valid mask and, when known, intrinsics.
    config : ActConfig, optional

    Returns
    -------
    Channel or None
    """
    cfg = config or ActConfig()
    near = column_clearance(frame, cfg)
    w = near.size
    unknown = ~np.isfinite(near)
    free = (near >= cfg.safety_mm) & ~unknown
    if cfg.unknown_is_free:
        free |= unknown
    k = frame.intrinsics
    cx = k.cx if k is not None else (w - 1) / 2.0
    candidates: list[Channel] = []
    for a, b in openings(free):
        inside = near[a : b + 1]
        seen = inside[np.isfinite(inside)]
        free_mm = float(seen.min()) if seen.size else None
        angle = width_mm = None
        if k is not None:
            flank = [near[i] for i in (a - 1, b + 1) if 0 <= i < w and np.isfinite(near[i])]
            pinch = min([cfg.safety_mm, *flank])
            # Column edges (a - 0.5, b + 0.5) projected at the pinch depth.
            width_mm = float((b - a + 1) / k.fx * pinch)
            angle = math.degrees(math.atan(((a + b) / 2.0 - k.cx) / k.fx))
            if width_mm < cfg.body_width_mm:
                continue
        elif b - a + 1 < cfg.body_width_px:
            continue
        candidates.append(Channel(a, b, (a + b) / 2.0, b - a + 1, angle, width_mm, free_mm))
    if not candidates:
        return None
    if cfg.channel_choice == "widest":
        return max(candidates, key=lambda c: (c.width_px, -abs(c.center_col - cx)))
    return min(candidates, key=lambda c: (abs(c.center_col - cx), -c.width_px))
