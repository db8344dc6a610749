"""The depth change of each object read from the pixels that stay in it (issue 13, item 1).

The paper reads radial motion from the change of an object's mean depth. On a moving camera
that mean moves with what part of the object is seen: a wall cut by the image edge, a floor
uncovered by the camera's turn, a segment that gains an arm or a few pixels of floor. The
change of its *core* does not: the pixels that belong to the object in this frame and, moved
back by the image motion, belonged to the same track's segment in the previous frame. Their
mean depth difference is the radial motion of the same surface points, which is what a
radial velocity of a surface means (and what the ground truth of
:func:`depthgram.dynamics.evaluate.radial_velocity_from_poses` carries each pixel through).

The image motion is one shift per frame, found by phase correlation of the two frames' depth
gradients (OpenCV): a hand-held camera's turn moves the whole image alike (on 7-Scenes the
true flow varies by about 1 px around a median of 2-9 px per frame), and an object moving in
front of a still camera leaves most of the image, and so the shift, at rest.

What was measured against what: on 7-Scenes (Kinect v1, hand-held, 300 frames) the tracker's
readings against the poses' truth, per object kind, for the mean depth, the median, a 10-90 %
trimmed mean, the core without a shift, the core moved by the object's centroid motion, the
core moved by this image shift and by the poses' true median flow, and a range-flow
constraint fit per object; on the simulator's ``approach``, ``crossing`` and ``person``
scenes against their exact radial velocities. ``benchmarks/bench_tracking.py --depth core``
and ``--depth plain`` give the figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["FramePixels", "core_depth_change", "image_shift"]

#: Side of the grid on which the image shift is found (px of the down-sampled image).
_SHIFT_W, _SHIFT_H = 160, 120
#: A pixel pair whose depths differ by more than this fraction of the depth is taken for an
#: edge the shift did not line up (another surface), not for motion: 10 % of the depth in one
#: frame is 90 m/s at 3 m and 30 frames/s.
_EDGE_FRACTION = 0.1


#: Peak of the phase correlation below which the image shift is taken as none.
_MIN_RESPONSE = 0.5


@dataclass(frozen=True, eq=False)
class FramePixels:
    """One frame's depth and label map, as handed to :meth:`depthgram.dynamics.Tracker.update`.

    Attributes
    ----------
    depth_mm : ndarray of float, shape (H, W)
        Depth (mm); 0 or NaN where invalid.
    labels : ndarray of int, shape (H, W)
        Object id (``SceneObject.id``) per pixel, 0 for none.
    """

    depth_mm: NDArray[np.floating]
    labels: NDArray[np.integer]


def _structure(depth_mm: NDArray[np.floating]) -> NDArray[np.float32]:
    """Down-sampled depth gradient magnitude (mm/px), clipped.

    The scene's edges, whose place moves with the image while their depth offset (the radial motion)
    does not matter.
    """
    z = np.nan_to_num(np.asarray(depth_mm, dtype=np.float32), nan=0.0)
    small = cv2.resize(z, (_SHIFT_W, _SHIFT_H), interpolation=cv2.INTER_AREA)
    gx = cv2.Sobel(small, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(small, cv2.CV_32F, 0, 1)
    return np.asarray(np.clip(cv2.magnitude(gx, gy), 0.0, 200.0), dtype=np.float32)


def image_shift(prev_depth_mm: NDArray[np.floating], depth_mm: NDArray[np.floating]) -> tuple[float, float]:
    """Return the image motion from the previous frame to this one, one shift for the whole frame.

    Parameters
    ----------
    prev_depth_mm, depth_mm : ndarray of float, shape (H, W)
        The two frames' depth (mm), 0 or NaN where invalid.

    Returns
    -------
    (dx, dy) : tuple of float
        Shift (px, full resolution) such that the scene point at ``(x, y)`` in this frame was
        at ``(x + dx, y + dy)`` in the previous one.
    """
    h, w = np.shape(depth_mm)
    win = cv2.createHanningWindow((_SHIFT_W, _SHIFT_H), cv2.CV_32F)
    (sx, sy), response = cv2.phaseCorrelate(_structure(prev_depth_mm), _structure(depth_mm), win)
    if not response >= _MIN_RESPONSE:
        # No clear peak: a still view of smooth surfaces (the simulator's), whose gradients
        # are mostly noise. Most of such an image does not move.
        return 0.0, 0.0
    return -float(sx) * w / _SHIFT_W, -float(sy) * h / _SHIFT_H


#: Pixels of an object's core read per candidate motion: larger objects are read on a grid
#: of every k-th row and column (their mean change needs no more).
_CORE_SAMPLE_PX = 3000


class _Core:
    """One object's pixels this frame and the part of the previous frame its motions can reach.

    The pixel ``p`` of this frame was at ``c + (p - c) * scale + shift`` in the previous one,
    ``c`` the box's centre: an object coming closer grows in the image about itself, and
    reading its previous depth at the same pixel would read a point further out on its
    surface. The previous depth is read bilinearly, from four pixels that all belong to the
    track's previous segment: on a steep flank (a cylinder's side) half a pixel is tens of
    millimetres.
    """

    def __init__(
        self,
        prev: FramePixels,
        now: FramePixels,
        oid: int,
        pid: int,
        box: tuple[int, int, int, int],
        motions: Sequence[tuple[float, float]],
        scale: float,
    ) -> None:
        x0, y0, x1, y1 = box
        h, w = np.shape(now.labels)
        step = max(1, math.isqrt(max((x1 - x0) * (y1 - y0), 1) // _CORE_SAMPLE_PX))
        z1 = np.asarray(now.depth_mm[y0:y1:step, x0:x1:step], dtype=np.float32)
        self.own = (np.asarray(now.labels[y0:y1:step, x0:x1:step]) == oid) & (z1 > 0)
        self.z1 = z1
        self.area = int(np.count_nonzero(self.own)) * step * step
        cx, cy = 0.5 * (x0 + x1 - 1), 0.5 * (y0 + y1 - 1)
        self.xs = (np.arange(x0, x1, step, dtype=np.float32) - cx) * scale + cx
        self.ys = (np.arange(y0, y1, step, dtype=np.float32) - cy) * scale + cy
        # the previous frame's window that every motion can reach, with a pixel to spare
        dxs = [m[0] for m in motions]
        dys = [m[1] for m in motions]
        self.wx0 = max(math.floor(float(self.xs[0]) + min(dxs)) - 1, 0) if self.xs.size else 0
        self.wy0 = max(math.floor(float(self.ys[0]) + min(dys)) - 1, 0) if self.ys.size else 0
        wx1 = min(math.ceil(float(self.xs[-1]) + max(dxs)) + 2, w) if self.xs.size else 0
        wy1 = min(math.ceil(float(self.ys[-1]) + max(dys)) + 2, h) if self.ys.size else 0
        if wx1 <= self.wx0 or wy1 <= self.wy0:
            self.z0 = self.mine = np.zeros((1, 1), np.float32)
            return
        z0 = np.asarray(prev.depth_mm[self.wy0 : wy1, self.wx0 : wx1], dtype=np.float32)
        self.z0 = np.ascontiguousarray(z0)
        lab0 = np.asarray(prev.labels[self.wy0 : wy1, self.wx0 : wx1])
        self.mine = ((lab0 == pid) & (z0 > 0)).astype(np.float32)

    def stats(self, shift: tuple[float, float]) -> tuple[int, float, float]:
        """Core size (sampled px), mean depth change (mm) and its spread (mm) under ``shift``."""
        if self.area == 0:
            return 0, math.nan, math.nan
        shape = self.z1.shape
        map_x = np.ascontiguousarray(np.broadcast_to(self.xs[None, :] + (shift[0] - self.wx0), shape), np.float32)
        map_y = np.ascontiguousarray(np.broadcast_to(self.ys[:, None] + (shift[1] - self.wy0), shape), np.float32)
        z0 = cv2.remap(self.z0, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        inside = cv2.remap(self.mine, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        d = self.z1 - z0
        core = self.own & (inside > 0.999) & (np.abs(d) <= _EDGE_FRACTION * self.z1)
        dc = d[core].astype(np.float64)
        if dc.size == 0:
            return 0, math.nan, math.nan
        return int(dc.size), float(dc.mean()), float(dc.std())


def core_depth_change(
    prev: FramePixels,
    now: FramePixels,
    pairs: Mapping[int, tuple[int, tuple[int, int, int, int], Sequence[tuple[float, float]], float]],
    shift: tuple[float, float],
    *,
    min_px: int = 20,
    min_share: float = 0.1,
    prefer: float = 0.8,
) -> dict[int, float]:
    """Mean depth change of each object's core from the previous frame (mm).

    Two image motions are tried per object: the frame's ``shift`` and the object's own (its
    track's motion in the image). The object's own is taken only where it lines the core up
    clearly better (the spread of the depth change falls below ``prefer`` times the frame
    shift's): an object moving across a still view (the simulator's cart) needs its own, while
    a surface cut by the image edge moves its outline, and with it the centre, for reasons
    other than motion.

    Parameters
    ----------
    prev, now : FramePixels
        The previous and this frame.
    pairs : mapping
        This frame's object id to (the id the same track had in the previous frame, the
        object's bbox (x0, y0, x1, y1) px half-open, the track's own image motions to try,
        each (dx, dy) px as in ``shift``, and the object's image scale from the previous
        frame to this one, the ratio of its depths then and now).
    shift : tuple of float
        (dx, dy) px from :func:`image_shift`.
    min_px : int
        Fewest core pixels for a reading (px).
    min_share : float
        Smallest core as a share of the object's valid pixels this frame: below it the object
        is mostly new surface and its core says little (0..1).
    prefer : float
        How much smaller the spread under the object's own motion must be to take it (0..1).

    Returns
    -------
    dict of int to float
        Object id (this frame) to ``mean(z_now - z_prev)`` over its core (mm); objects without
        a core of ``min_px`` pixels and ``min_share`` of their area are left out.
    """
    if np.shape(prev.labels) != np.shape(now.labels) or np.shape(prev.depth_mm) != np.shape(now.depth_mm):
        return {}
    out: dict[int, float] = {}
    for oid, (pid, box, owns, scale) in pairs.items():
        core = _Core(prev, now, oid, pid, box, [shift, *owns], scale)
        n, mean, spread = core.stats(shift)
        # sizes on the sampled grid, compared with the area on it
        k = max(core.area // max(int(np.count_nonzero(core.own)), 1), 1)
        ok = n * k >= min_px and n * k >= min_share * core.area
        tried = [shift]
        for own in owns:
            # a motion within a quarter pixel of one tried reads the same core
            if any(abs(own[0] - t[0]) + abs(own[1] - t[1]) < 0.25 for t in tried):
                continue
            tried.append(own)
            n2, mean2, spread2 = core.stats(own)
            if n2 * k >= min_px and n2 * k >= min_share * core.area and (not ok or spread2 < prefer * spread):
                n, mean, spread, ok = n2, mean2, spread2 / prefer, True
        if ok:
            out[oid] = mean
    return out
