"""Segment a wide frame on a grid of its pixels, then give every pixel its surface's label.

The default method's cost grows with the pixel count, while what it decides (which surfaces
exist, where they are cut by depth jumps and creases, which are supports) is a property of
surfaces many pixels wide. So a frame wider than ``work_width_px`` is segmented on every
``step``-th pixel of every ``step``-th row, a frame of the same camera with ``1/step`` of its
focal length, and each full-resolution pixel then takes the label of the grid sample next to it
that lies on its own surface: of the (up to) four samples around it, the one of nearest depth
among those the surface labeller itself would join to it (the sensor's tolerance plus the
``max_slope_deg`` term over the distance between them). Boundaries are therefore found at full
resolution; only objects thinner than a grid step can be lost. Real-time plane and object
segmentation of organized point clouds works the same way, on cells first and pixels at the
boundaries last (Feng et al., ICRA 2014; Holz and Behnke, 2012).

The attributes (area, center, box, mean depth, metric centroid and area) are measured again on
the full-resolution label map; a compound's slice parts, which are not in the label map, are
scaled from the grid (``docs/design-notes.md``).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.attributes import Stats, make_objects
from depthgram.segmentation.label.stats import N_COLUMNS, flush_run
from depthgram.segmentation.objects import SceneObject, Segmentation
from depthgram.segmentation.orientation import upsample_classes

__all__ = ["grid_frame", "grid_step", "refine_labels", "to_full_resolution"]


def grid_step(width_px: int, work_width_px: int) -> int:
    """Return the sampling step (px) that brings a frame ``width_px`` wide to ``work_width_px``.

    1 (no sampling) when ``work_width_px`` is 0 or the frame is already narrow enough.
    """
    if work_width_px <= 0 or width_px <= work_width_px:
        return 1
    return math.ceil(width_px / work_width_px)


def grid_frame(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], intrinsics: Intrinsics, step: int
) -> tuple[NDArray[np.float32], NDArray[np.bool_], Intrinsics]:
    """Return the sampling grid of a frame: a reading per ``step`` x ``step`` cell, and its intrinsics.

    Sample ``(i, j)`` is pixel ``(step i, step j)``, or where that pixel has no reading the
    first pixel of its cell that has one (raster order): structured-light holes and shadows
    come in thin stripes and interleaved patterns that a plain ``[::step, ::step]`` would turn
    into whole missing grid rows. The grid is a pinhole camera with focal length and principal
    point divided by ``step`` (not :meth:`Intrinsics.scaled`, which is for images resized by
    averaging, whose pixel centres move).
    """
    k = intrinsics
    z, ok = _grid(np.ascontiguousarray(depth_mm, np.float32), np.ascontiguousarray(valid, np.bool_), int(step))
    return z, ok, Intrinsics(k.fx / step, k.fy / step, k.cx / step, k.cy / step)


@njit(cache=True, nogil=True)
def _grid(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], step: int
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    # hand-written: a strided view plus a fill of the holes from their own cells (no library
    # kernel picks the first valid pixel of each cell)
    h, w = depth.shape
    gh = (h + step - 1) // step
    gw = (w + step - 1) // step
    z = np.zeros((gh, gw), np.float32)
    ok = np.zeros((gh, gw), np.bool_)
    for i in range(gh):
        for j in range(gw):
            y0 = i * step
            x0 = j * step
            if valid[y0, x0]:
                z[i, j] = depth[y0, x0]
                ok[i, j] = True
                continue
            for y in range(y0, min(y0 + step, h)):
                for x in range(x0, min(x0 + step, w)):
                    if valid[y, x] and not ok[i, j]:
                        z[i, j] = depth[y, x]
                        ok[i, j] = True
    return z, ok


def refine_labels(
    grid_labels: NDArray[np.int32],
    grid_depth_mm: NDArray[np.float32],
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    step: int,
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
) -> tuple[NDArray[np.int32], NDArray[np.float64], NDArray[np.int32]]:
    """Full-resolution labels from those of the sampling grid, with their statistics.

    Each pixel with a reading takes, of the (up to) four grid samples around it, the label of
    the one of nearest depth among those on its own surface: within ``tol_0 + tol_2 z**2`` plus
    ``slope_per_px z`` per pixel of (city-block) distance, ``z`` the sample's depth, the rule
    of the surface labeller.
    A grid pixel keeps its own label.

    Parameters
    ----------
    grid_labels : ndarray of int32, shape (ceil(H / step), ceil(W / step))
        Labels of the grid of :func:`grid_frame`, 0 = none.
    grid_depth_mm : ndarray of float32, same shape
        The grid's depth (mm), from :func:`grid_frame`.
    depth_mm : ndarray of float32, shape (H, W)
        Full-resolution depth (mm).
    valid : ndarray of bool, shape (H, W)
        Pixels with a reading; the others get label 0.
    step : int
        Grid step (px).
    tol_0, tol_2 : float
        Join tolerance ``tol_0 + tol_2 z**2`` (mm) of the surface labeller
        (:meth:`SensorModel.tolerance`).
    slope_per_px : float
        Depth allowed per pixel of distance, per mm of depth (``tan(max_slope) / f``).

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
    sums : ndarray of float64, shape (n + 1, N_COLUMNS)
        The statistics table of :mod:`depthgram.segmentation.label.stats` (``KEY`` 0), ``n``
        the largest grid label.
    boxes : ndarray of int32, shape (n + 1, 4)
        Inclusive (x0, y0, x1, y1).
    """
    return _refine(
        np.ascontiguousarray(grid_labels, np.int32),
        np.ascontiguousarray(grid_depth_mm, np.float32),
        np.ascontiguousarray(depth_mm, np.float32),
        np.ascontiguousarray(valid, np.bool_),
        int(step),
        np.float32(tol_0),
        np.float32(tol_2),
        np.float32(slope_per_px),
        int(grid_labels.max(initial=0)),
    )


@njit(cache=True, nogil=True)
def _refine(
    glab: NDArray[np.int32],
    gz: NDArray[np.float32],
    depth: NDArray[np.float32],
    valid: NDArray[np.bool_],
    step: int,
    t0: np.float32,
    t2: np.float32,
    sl: np.float32,
    n_labels: int,
) -> tuple[NDArray[np.int32], NDArray[np.float64], NDArray[np.int32]]:
    # Hand-written: the choice among a pixel's four grid samples by depth and by the surface
    # labeller's own continuity rule has no library kernel (OpenCV's and scipy's upsampling
    # interpolate values, they do not pick a label). Walked cell by cell, so that no pixel pays
    # an integer division and a cell whose four samples carry one label (most of a frame) only
    # asks whether any of them continues the pixel, nearest first. The statistics table of
    # the new map (label.stats' layout) is gathered in the same pass, run by run.
    h, w = depth.shape
    gh, gw = glab.shape
    out = np.zeros((h, w), np.int32)
    # the samples of the grid rows above and below a band of `step` pixel rows, with a column
    # past the end (label 0) so that every pixel reads four candidates
    lab = np.zeros((2, gw + 1), np.int32)
    zs = np.zeros((2, gw + 1), np.float32)
    tol = np.zeros((2, gw + 1), np.float32)
    per_px = np.zeros((2, gw + 1), np.float32)
    one = np.zeros(gw, np.bool_)
    sums = np.zeros((n_labels + 1, N_COLUMNS), np.float64)
    # label.stats' boxes: each label's first row is set when its first run is added
    box = np.empty((n_labels + 1, 4), np.int32)
    box[:, 0] = w
    box[:, 1] = h
    box[:, 2] = -1
    box[:, 3] = -1
    for i0 in range(gh):
        for r in range(2):
            i = i0 + r
            for j in range(gw):
                v = glab[i, j] if i < gh else 0
                lab[r, j] = v
                z = gz[i, j] if v else np.float32(0.0)
                zs[r, j] = z
                tol[r, j] = t0 + t2 * z * z
                per_px[r, j] = sl * z
        for j in range(gw):
            a = lab[0, j]
            one[j] = (
                a != 0
                and (lab[0, j + 1] == 0 or lab[0, j + 1] == a)
                and (lab[1, j] == 0 or lab[1, j] == a)
                and (lab[1, j + 1] == 0 or lab[1, j + 1] == a)
            )
        for dy0 in range(min(step, h - i0 * step)):
            y = i0 * step + dy0
            gy = (np.float32(dy0), np.float32(step - dy0))
            j0 = 0
            dx0 = 0
            run = 0  # the label of the run being summed, its start and sums
            start = 0
            c = sz = szz = sx = sxz = 0.0
            for x in range(w + 1):
                best = 0
                if x < w and valid[y, x]:
                    z = depth[y, x]
                    best_d = np.float32(np.inf)
                    for k in range(4):
                        r = k >> 1
                        j = j0 + (k & 1)
                        cand = lab[r, j]
                        if cand == 0:
                            continue
                        d = abs(zs[r, j] - z)
                        gap = gy[r] + np.float32(dx0 if (k & 1) == 0 else step - dx0)
                        if d < best_d and d <= tol[r, j] + gap * per_px[r, j]:
                            best = cand
                            best_d = d
                            if one[j0]:
                                break
                    out[y, x] = best
                if best != run:
                    if run:
                        if box[run, 3] < 0:
                            box[run, 1] = y
                        flush_run(sums, box, run, c, sz, szz, sx, sxz, y, start, x - 1, 0.0)
                    run = best
                    start = x
                    c = sz = szz = sx = sxz = 0.0
                if best:
                    zf = np.float64(depth[y, x])
                    c += 1.0
                    sz += zf
                    szz += zf * zf
                    sx += x
                    sxz += x * zf
                dx0 += 1
                if dx0 == step:
                    j0 += 1
                    dx0 = 0
    return out, sums, box


def _scaled_part(part: SceneObject, step: int, width: int, height: int) -> SceneObject:
    # the constructor, not dataclasses.replace: some fifty parts a frame, and replace's field
    # introspection cost 0.4 ms of a 7-Scenes frame
    x0, y0, x1, y1 = part.bbox_xy
    cx, cy = part.center_xy
    return SceneObject(
        part.id,
        part.kind,
        part.depth_label,
        part.depth,
        part.depth_std,
        part.area * step * step,
        part.area_fraction,
        (cx * step, cy * step),
        (x0 * step, y0 * step, min(x1 * step, width), min(y1 * step, height)),
        part.centroid_mm,
        part.area_mm2,
        part.parts,
    )


def to_full_resolution(
    grid_seg: Segmentation,
    grid_depth_mm: NDArray[np.float32],
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    intrinsics: Intrinsics | None,
    step: int,
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
) -> Segmentation:
    """Carry the segmentation of the grid of :func:`grid_frame` to the full-resolution frame.

    Labels by :func:`refine_labels`, orientation classes repeated from the grid; each object's
    pixel attributes measured again on the full label map (ids, kinds and depth labels kept);
    slice parts scaled by ``step``.
    """
    labels, sums, boxes = refine_labels(
        grid_seg.labels,
        grid_depth_mm,
        depth_mm,
        valid,
        step,
        tol_0=tol_0,
        tol_2=tol_2,
        slope_per_px=slope_per_px,
    )
    # the classes only describe pixels (views, users); the labels carry the decisions
    classes = None if grid_seg.classes is None else upsample_classes(grid_seg.classes, valid, step)
    objs = grid_seg.objects
    n = max((o.id for o in objs), default=0)
    if n:
        stats = Stats.from_sums(sums[: n + 1], boxes[: n + 1], metric=intrinsics is not None)
        kinds = ["object"] * (n + 1)
        depth_labels = np.zeros(n + 1, np.int64)
        for o in objs:
            kinds[o.id] = o.kind
            depth_labels[o.id] = o.depth_label
        full = {
            o.id: o for o in make_objects(labels, stats, kinds=kinds, depth_labels=depth_labels, intrinsics=intrinsics)
        }
        h, w = depth_mm.shape
        # only compounds have parts to scale; the others are the full-resolution objects as made
        objs = tuple(
            replace(full[o.id], parts=tuple(_scaled_part(p, step, w, h) for p in o.parts)) if o.parts else full[o.id]
            for o in objs
        )
    return replace(grid_seg, labels=labels, objects=objs, classes=classes)
