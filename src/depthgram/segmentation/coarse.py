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

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.attributes import ObjectSpec, attribute_rows, objects_from_rows
from depthgram.segmentation.label.stats import N_COLUMNS, flush_run
from depthgram.segmentation.objects import SceneObject
from depthgram.segmentation.orientation import FACING

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
    # kernel picks the first valid pixel of each cell). A grid row is first read from its
    # cells' corners without a branch (unsigned indices: a signed one is wrapped as possibly
    # negative, 50 against 77 us at 640 x 480); only a row with holes searches their cells,
    # each up to its first reading
    h, w = depth.shape
    gh = (h + step - 1) // step
    gw = (w + step - 1) // step
    z = np.empty((gh, gw), np.float32)
    ok = np.empty((gh, gw), np.bool_)
    ustep = np.uint64(step)
    for i in range(gh):
        y0 = i * step
        drow = depth[y0]
        vrow = valid[y0]
        zr = z[i]
        okr = ok[i]
        for uj in range(np.uint64(gw)):
            ux = uj * ustep
            v = vrow[ux]
            okr[uj] = v
            zr[uj] = drow[ux] if v else np.float32(0.0)
        holes = False
        for j in range(gw):
            holes |= not okr[j]
        if not holes:
            continue
        y1 = min(y0 + step, h)
        for j in range(gw):
            if okr[j]:
                continue
            x0 = j * step
            x1 = min(x0 + step, w)
            y = y0
            x = x0 + 1  # the corner has no reading
            while y < y1:
                if x >= x1:
                    y += 1
                    x = x0
                elif valid[y, x]:
                    zr[j] = depth[y, x]
                    okr[j] = True
                    break
                else:
                    x += 1
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
        np.zeros(grid_labels.shape, np.int8),
    )[:3]


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
    gcls: NDArray[np.int8],
) -> tuple[NDArray[np.int32], NDArray[np.float64], NDArray[np.int32], NDArray[np.int8]]:
    # Hand-written: the choice among a pixel's four grid samples by depth and by the surface
    # labeller's own continuity rule has no library kernel (OpenCV's and scipy's upsampling
    # interpolate values, they do not pick a label). Per band of `step` pixel rows, the grid
    # rows above and below are repeated to pixel width once (a pixel's right-hand sample is
    # then `step` places on), so that the choice of each row is one branch-free loop over
    # plain arrays that vectorises; then the row's runs give the statistics table of the new
    # map (label.stats' layout), two rows side by side (_run_sums_two). The orientation
    # classes `gcls` of the grid are repeated in the same loop (upsample_classes' map).
    h, w = depth.shape
    gh, gw = glab.shape
    out = np.empty((h, w), np.int32)  # every pixel is written (_choose_row)
    classes = np.empty((h, w), np.int8)
    wide = max(w + step, (gw + 1) * step)
    cls_up = np.zeros(wide, np.int8)
    lab_up = np.zeros(wide, np.int32)
    z_up = np.zeros(wide, np.float32)
    lab_dn = np.zeros(wide, np.int32)
    z_dn = np.zeros(wide, np.float32)
    # a pixel's distance (px) to the samples of its cell's left and right columns
    dx_left = np.empty(w, np.float32)
    dx_right = np.empty(w, np.float32)
    for x in range(w):
        dx_left[x] = np.float32(x % step)
        dx_right[x] = np.float32(step - x % step)
    sums = np.zeros((n_labels + 1, N_COLUMNS), np.float64)
    # label.stats' boxes: each label's first row is set when its first run is added
    box = np.empty((n_labels + 1, 4), np.int32)
    box[:, 0] = w
    box[:, 1] = h
    box[:, 2] = -1
    box[:, 3] = -1
    # row y + 1's runs while row y is summed (_run_sums_two)
    held_label = np.empty(w + 1, np.int32)
    held_span = np.empty((w + 1, 2), np.int64)
    held_sums = np.empty((w + 1, 3), np.float64)
    _repeat_row(glab, gz, 0, step, lab_dn, z_dn)
    for i0 in range(gh):
        lab_up, lab_dn = lab_dn, lab_up
        z_up, z_dn = z_dn, z_up
        _repeat_row(glab, gz, i0 + 1, step, lab_dn, z_dn)
        for q in range(step):
            for j in range(gw):
                cls_up[j * step + q] = gcls[i0, j]
        y0 = i0 * step
        rows = min(step, h - y0)
        for dy in range(rows):
            y = y0 + dy
            gaps = (np.float32(dy), np.float32(step - dy))
            _choose_row(
                out[y], classes[y], depth[y], valid[y], lab_up, z_up, lab_dn, z_dn, cls_up, dx_left, dx_right, step,
                t0, t2, sl, gaps,
            )  # fmt: skip
        dy = 0
        while dy < rows:
            y = y0 + dy
            if dy + 1 < rows:
                _run_sums_two(
                    out[y], depth[y], out[y + 1], depth[y + 1], y, sums, box, held_label, held_span, held_sums
                )
                dy += 2
            else:
                _run_sums(out[y], depth[y], y, sums, box)
                dy += 1
    return out, sums, box, classes


@njit(cache=True, inline="always")
def _repeat_row(
    glab: NDArray[np.int32], gz: NDArray[np.float32], i: int, step: int, lab: NDArray[np.int32], z: NDArray[np.float32]
) -> None:
    # grid row i's labels and depths (0 without a label), each repeated `step` times; 0 past
    # the grid's last row and column
    gh, gw = glab.shape
    if i >= gh:
        lab[:] = 0
        z[:] = 0.0
        return
    for s in range(step):
        for j in range(gw):
            v = glab[i, j]
            lab[j * step + s] = v
            z[j * step + s] = gz[i, j] if v else np.float32(0.0)
    for x in range(gw * step, lab.size):
        lab[x] = 0
        z[x] = 0.0


@njit(cache=True, nogil=True)
def _choose_row(
    out: NDArray[np.int32],
    classes: NDArray[np.int8],
    depth: NDArray[np.float32],
    valid: NDArray[np.bool_],
    lab_up: NDArray[np.int32],
    z_up: NDArray[np.float32],
    lab_dn: NDArray[np.int32],
    z_dn: NDArray[np.float32],
    cls_up: NDArray[np.int8],
    dx_left: NDArray[np.float32],
    dx_right: NDArray[np.float32],
    step: int,
    t0: np.float32,
    t2: np.float32,
    sl: np.float32,
    gaps: tuple[np.float32, np.float32],
) -> None:
    # One row: of the samples up left, up right, down left, down right (that order), the one
    # of least depth difference (the first of equal ones) among those within reach, in the
    # float32 operations of the surface labeller's rule (`tol_0 + tol_2 z**2`, then `gap *
    # slope z`); 0 without a reading. Every test computed and selected, no branch, so the
    # loop vectorises. The right-hand samples are read through views `step` on: an index
    # x + step would be wrapped as a possibly negative one, which turned the loads into gathers.
    # The row's classes: the up left sample's, facing without a reading.
    inf = np.float32(np.inf)
    facing = np.int8(FACING)
    g_up, g_dn = gaps
    lab_upr = lab_up[step:]
    z_upr = z_up[step:]
    lab_dnr = lab_dn[step:]
    z_dnr = z_dn[step:]
    for x in range(out.size):
        z = depth[x]
        c = lab_up[x]
        zs = z_up[x]
        d = abs(zs - z)
        ok = (c != 0) & (d <= (t0 + t2 * zs * zs) + (g_up + dx_left[x]) * (sl * zs))
        best = c if ok else np.int32(0)
        best_d = d if ok else inf
        c = lab_upr[x]
        zs = z_upr[x]
        d = abs(zs - z)
        ok = (c != 0) & (d <= (t0 + t2 * zs * zs) + (g_up + dx_right[x]) * (sl * zs)) & (d < best_d)
        best = c if ok else best
        best_d = d if ok else best_d
        c = lab_dn[x]
        zs = z_dn[x]
        d = abs(zs - z)
        ok = (c != 0) & (d <= (t0 + t2 * zs * zs) + (g_dn + dx_left[x]) * (sl * zs)) & (d < best_d)
        best = c if ok else best
        best_d = d if ok else best_d
        c = lab_dnr[x]
        zs = z_dnr[x]
        d = abs(zs - z)
        ok = (c != 0) & (d <= (t0 + t2 * zs * zs) + (g_dn + dx_right[x]) * (sl * zs)) & (d < best_d)
        best = c if ok else best
        out[x] = best if valid[x] else np.int32(0)
        classes[x] = cls_up[x] if valid[x] else facing


@njit(cache=True, inline="always")
def _add_run(
    sums: NDArray[np.float64],
    box: NDArray[np.int32],
    i: int,
    start: int,
    stop: int,
    sz: float,
    szz: float,
    sxz: float,
    y: int,
) -> None:
    # the run's count and sum of x are whole numbers, exact in float64 whichever way they are
    # added: taken from its ends
    if box[i, 3] < 0:
        box[i, 1] = y
    n = stop - start
    flush_run(
        sums, box, i, np.float64(n), sz, szz, np.float64((start + stop - 1) * n // 2), sxz, y, start, stop - 1, 0.0
    )


@njit(cache=True, nogil=True)
def _run_sums(
    labels: NDArray[np.int32], depth: NDArray[np.float32], y: int, sums: NDArray[np.float64], box: NDArray[np.int32]
) -> None:
    # One row's runs added to the table, each run's sums added pixel by pixel from 0 in
    # column order and then to its label's row. Every pixel is added: a run of label 0 is
    # thrown away at its end, so no test per pixel.
    run = 0
    start = 0
    sz = szz = sxz = 0.0
    for x in range(labels.size):
        a = labels[x]
        if a != run:
            if run:
                _add_run(sums, box, run, start, x, sz, szz, sxz, y)
            run = a
            start = x
            sz = szz = sxz = 0.0
        z = np.float64(depth[x])
        sz += z
        szz += z * z
        sxz += x * z
    if run:
        _add_run(sums, box, run, start, labels.size, sz, szz, sxz, y)


@njit(cache=True, nogil=True)
def _run_sums_two(
    labels_a: NDArray[np.int32],
    depth_a: NDArray[np.float32],
    labels_b: NDArray[np.int32],
    depth_b: NDArray[np.float32],
    y: int,
    sums: NDArray[np.float64],
    box: NDArray[np.int32],
    held_label: NDArray[np.int32],
    held_span: NDArray[np.int64],
    held_sums: NDArray[np.float64],
) -> None:
    # _run_sums of rows y and y + 1 in one loop: a run's additions are a chain, each waiting
    # for the one before, and two rows make two chains that run side by side. Row y + 1's
    # runs (label, start and stop, sums of Z, Z², xZ) are held and added after row y's, in
    # the order _run_sums adds them (the same sums).
    w = labels_a.size
    ra = 0
    sa = 0
    sza = szza = sxza = 0.0
    rb = 0
    sb = 0
    szb = szzb = sxzb = 0.0
    k = 0
    for x in range(w):
        a = labels_a[x]
        b = labels_b[x]
        if a != ra:
            if ra:
                _add_run(sums, box, ra, sa, x, sza, szza, sxza, y)
            ra = a
            sa = x
            sza = szza = sxza = 0.0
        if b != rb:
            if rb:
                k = _hold(held_label, held_span, held_sums, k, rb, sb, x, szb, szzb, sxzb)
            rb = b
            sb = x
            szb = szzb = sxzb = 0.0
        za = np.float64(depth_a[x])
        zb = np.float64(depth_b[x])
        sza += za
        szb += zb
        szza += za * za
        szzb += zb * zb
        sxza += x * za
        sxzb += x * zb
    if ra:
        _add_run(sums, box, ra, sa, w, sza, szza, sxza, y)
    if rb:
        k = _hold(held_label, held_span, held_sums, k, rb, sb, w, szb, szzb, sxzb)
    for j in range(k):
        s = held_sums[j]
        _add_run(sums, box, held_label[j], held_span[j, 0], held_span[j, 1], s[0], s[1], s[2], y + 1)


@njit(cache=True, inline="always")
def _hold(
    label: NDArray[np.int32],
    span: NDArray[np.int64],
    sums: NDArray[np.float64],
    k: int,
    i: int,
    start: int,
    stop: int,
    sz: float,
    szz: float,
    sxz: float,
) -> int:
    # run k of the held row; returns the count of held runs
    label[k] = i
    span[k, 0] = start
    span[k, 1] = stop
    sums[k, 0] = sz
    sums[k, 1] = szz
    sums[k, 2] = sxz
    return k + 1


def to_full_resolution(
    grid_labels: NDArray[np.int32],
    grid_classes: NDArray[np.int8],
    specs: list[ObjectSpec],
    grid_depth_mm: NDArray[np.float32],
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    intrinsics: Intrinsics | None,
    step: int,
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
) -> tuple[NDArray[np.int32], NDArray[np.int8], list[SceneObject]]:
    """Carry the segmentation of the grid of :func:`grid_frame` to the full-resolution frame.

    Returns the labels of :func:`refine_labels`, the orientation classes repeated from the
    grid's (facing without a reading), and the objects of ``specs`` (ids 1..n in order, with
    kinds, depth labels and the parts, already in the frame's pixels) with their pixel
    attributes measured on the full label map.
    """
    labels, sums, boxes, classes = _refine(
        np.ascontiguousarray(grid_labels, np.int32),
        np.ascontiguousarray(grid_depth_mm, np.float32),
        np.ascontiguousarray(depth_mm, np.float32),
        np.ascontiguousarray(valid, np.bool_),
        int(step),
        np.float32(tol_0),
        np.float32(tol_2),
        np.float32(slope_per_px),
        int(grid_labels.max(initial=0)),
        np.ascontiguousarray(grid_classes, np.int8),
    )
    n = len(specs)
    if not n:
        return labels, classes, []
    cam = intrinsics or Intrinsics(1.0, 1.0, 0.0, 0.0)
    rows = attribute_rows(sums[: n + 1], cam).tolist()
    objects = objects_from_rows(specs, rows, boxes.tolist(), labels.size, metric=intrinsics is not None)
    return labels, classes, objects
