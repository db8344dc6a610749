"""Slicing for oblique surfaces: floor, ceiling, table tops and walls as compound objects.

The paper cuts the image into slices perpendicular to an oblique surface's running direction:
inside a thin slice the surface has one depth, and successive slices give successive depth
labels, joined into one super-object. Here the surface's running direction is read from the
local orientation (:mod:`depthgram.segmentation.orientation`): horizontal surfaces are cut into
horizontal slices (rows), walls into vertical slices (columns). Pixels of one orientation class
join while depth stays continuous between neighbours, which is exactly "runs of slice segments
with successive depth labels"; each slice of such a run is a ``part``. Objects standing on a
support keep their own (facing) class, so they come out separate from it even where their base
touches it at the same depth.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.attributes import attribute_table
from depthgram.segmentation.coplanar import coplanar_tables
from depthgram.segmentation.label import ACTIVE, BLOCK, HOLE, label_keyed_planes, relabel
from depthgram.segmentation.label.stats import (
    COUNT,
    KEY,
    N_SUMS,
    SUM_X,
    SUM_XZ,
    SUM_Y,
    SUM_YZ,
    SUM_Z,
    SUM_ZZ,
)
from depthgram.segmentation.objects import SceneObject, new_object
from depthgram.segmentation.orientation import HORIZONTAL, VERTICAL
from depthgram.segmentation.plane_sums import planes_from_sums

__all__ = [
    "add_through",
    "compound_parts",
    "drop_classes",
    "join_pieces",
    "slice_parts",
    "small_supports",
    "support_kind",
    "support_pieces",
    "support_pieces_lazy",
    "warm_up",
]


def slice_parts(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    oid: int,
    bbox_xy: tuple[int, int, int, int],
    *,
    horizontal: bool,
    step_of: Callable[[int], int],
    depth_label: object,
    intrinsics: Intrinsics | None,
    first_id: int,
    scale: tuple[int, int, int] | None = None,
) -> tuple[SceneObject, ...]:
    """Return the slice segments of one compound object, nearest first, as ``part`` objects.

    Parameters
    ----------
    labels : ndarray of int32
        Label map holding the object ``oid``.
    depth_mm : ndarray of float32
        Depth (mm).
    oid : int
        The object's id in ``labels``.
    bbox_xy : tuple of int
        Its half-open box (x0, y0, x1, y1), px, holding all its pixels.
    horizontal : bool
        Horizontal slices (rows; floor, ceiling, table tops) or vertical slices (columns; walls).
    step_of : callable
        Slice thickness (px) from the object's extent across the slices (px), e.g.
        :meth:`depthgram.segmentation.SegmentConfig.slice_step`.
    depth_label : callable
        Depths (mm, an array) -> global depth labels, elementwise (as
        :meth:`depthgram.segmentation.histogram.Bands.depth_label`).
    first_id : int
        Id of the first part (parts are not in the label map; ids only name them).
    scale : tuple of int, optional
        ``(step, width, height)`` when ``labels`` is the sampling grid of a frame ``width`` x
        ``height`` px (:func:`depthgram.segmentation.coarse.grid_frame`): the parts' area,
        center and box are given in the frame's pixels (area times ``step`` squared, boxes
        clipped to the frame; the share of the frame, depths and metric attributes are the
        grid's).
    """
    return compound_parts(
        labels, depth_mm, [(oid, bbox_xy, horizontal)], step_of=step_of, depth_label=depth_label,
        intrinsics=intrinsics, first_id=first_id, scale=scale,
    )[0]  # fmt: skip


def compound_parts(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    compounds: list[tuple[int, tuple[int, int, int, int], bool]],
    *,
    step_of: Callable[[int], int],
    depth_label: object,
    intrinsics: Intrinsics | None,
    first_id: int,
    scale: tuple[int, int, int] | None = None,
) -> list[tuple[SceneObject, ...]]:
    """:func:`slice_parts` of several compound objects ``(id, half-open box, horizontal)``, in one pass.

    The parts are numbered on from ``first_id`` in the objects' order; the same parts as one
    :func:`slice_parts` call per object with the ids following on.
    """
    objs = np.empty((len(compounds), 8), np.int64)
    for c, (oid, (x0, y0, x1, y1), horizontal) in enumerate(compounds):
        extent = (y1 - y0) if horizontal else (x1 - x0)
        step = step_of(extent)
        # the kernel takes the box's last column and row (inclusive bounds)
        objs[c] = (oid, x0, y0, x1 - 1, y1 - 1, step, horizontal, (extent + step - 1) // step)
    metric = intrinsics is not None
    cam = (
        (intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy) if intrinsics is not None else (1.0, 1.0, 0.0, 0.0)
    )
    k, w, h = scale if scale is not None else (1, labels.shape[1], labels.shape[0])
    table, ints, owner = _parts_tables(labels, depth_mm, objs, *cam, metric, k, w, h)
    fn = depth_label  # callable, typed loosely to keep this module free of Bands
    # every part's label in one call (one numpy call per part cost more on small frames); a
    # callable giving one label whatever the depth is broadcast
    depths = table[:, 1]
    found = np.asarray(fn(depths))  # type: ignore[operator]
    part_labels = (found if found.shape == depths.shape else np.broadcast_to(found, depths.shape)).tolist()
    total = labels.size
    kk = k * k
    out: list[list[SceneObject]] = [[] for _ in compounds]
    rows = zip(table.tolist(), ints.tolist(), owner.tolist(), part_labels, strict=True)
    for pid, ((c, mean, std, cx, cy, gx, gy, amm), (area, bx0, by0, bx1, by1), o, label) in enumerate(rows, first_id):
        out[o].append(
            new_object(
                pid,
                "part",
                int(label),
                mean,
                std,
                area * kk,
                c / total,
                (cx, cy),
                (bx0, by0, bx1, by1),
                (gx, gy, mean) if metric else None,
                amm if metric else None,
            )
        )
    return [tuple(p) for p in out]


@njit(cache=True, nogil=True)
def _parts_tables(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    objs: NDArray[np.int64],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    metric: bool,
    k: int,
    w: int,
    h: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Return the parts of every object of ``objs``, each object's nearest first, in the objects' order.

    ``objs`` rows: id, inclusive box x0, y0, x1, y1, slice step, horizontal (1 / 0), slices.
    Returns the float attributes (count, mean depth, std, center x, y, centroid X, Y, area
    mm²), the whole numbers (pixel count, half-open box) and the row of ``objs`` of each part;
    centers and boxes times ``k`` (boxes clipped to ``w`` x ``h``), as the frame's pixels of
    a grid of step ``k``. One call for all the compounds of a frame.
    """
    m = 0
    for c in range(objs.shape[0]):
        m += objs[c, 7]
    table = np.empty((m, 8), np.float64)
    ints = np.empty((m, 5), np.int64)
    owner = np.empty(m, np.int64)
    r = 0
    for c in range(objs.shape[0]):
        x0 = objs[c, 1]
        y0 = objs[c, 2]
        # make_objects' attributes in the box's coordinates: the principal point shifted by its corner
        px = cx - x0 if metric else cx
        py = cy - y0 if metric else cy
        # per slice with pixels: count, mean depth, depth std, center x and y (px), centroid X
        # and Y (mm), area (mm²) as attributes.make_objects takes them from the slices' sums
        # (box coordinates), then the half-open box; rows in a stable order of mean depth
        sums, boxes = _part_sums(
            labels, depth, objs[c, 0], x0, y0, objs[c, 3], objs[c, 4], objs[c, 5], objs[c, 6] != 0, objs[c, 7]
        )
        sz = sums[:, SUM_Z]
        attrs = attribute_table(
            sums[:, COUNT], sz, sums[:, SUM_ZZ], sums[:, SUM_X], sums[:, SUM_Y],
            sums[:, SUM_XZ] if metric else sz, sums[:, SUM_YZ] if metric else sz, fx, fy, px, py,
        )  # fmt: skip
        present = np.flatnonzero(attrs[:, 0] > 0)
        # a stable sort on the mean depth, as of the parts in slice order
        order = present[np.argsort(attrs[present, 1], kind="mergesort")]
        for q in range(order.size):
            jq = order[q]
            for j in range(8):
                table[r, j] = attrs[jq, j]
            table[r, 3] = (attrs[jq, 3] + x0) * k
            table[r, 4] = (attrs[jq, 4] + y0) * k
            ints[r, 0] = np.int64(attrs[jq, 0])
            ints[r, 1] = (boxes[jq + 1, 0] + x0) * k
            ints[r, 2] = (boxes[jq + 1, 1] + y0) * k
            right = (boxes[jq + 1, 2] + 1 + x0) * k
            bottom = (boxes[jq + 1, 3] + 1 + y0) * k
            ints[r, 3] = right if right < w else w
            ints[r, 4] = bottom if bottom < h else h
            owner[r] = c
            r += 1
    return table[:r], ints[:r], owner[:r]


@njit(cache=True, nogil=True)
def _part_sums(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    oid: int,
    x0: int,
    y0: int,
    x1: int,
    y1: int,
    step: int,
    horizontal: bool,
    n: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    # the statistics of every slice of one object in one pass over its box, in box
    # coordinates and in raster order (the sums of label_stats on a slice-index map, without
    # building the map: three box-sized temporaries per compound before). Row slices with
    # unsigned indices, and each run's count and sum of x (whole numbers, exact in float64 in
    # any order) from its ends: 64 -> 50 us for the two supports of the 320 x 240 grid
    sums = np.zeros((n + 1, N_SUMS), np.float64)
    boxes = np.empty((n + 1, 4), np.int64)
    boxes[:, 0] = x1 - x0 + 1
    boxes[:, 1] = y1 - y0 + 1
    boxes[:, 2] = -1
    boxes[:, 3] = -1
    ubw = np.uint64(x1 - x0 + 1)
    one = np.uint64(1)
    ustep = np.uint64(step)
    for y in range(y0, y1 + 1):
        yy = y - y0
        lr = labels[y, x0 : x1 + 1]
        dr = depth[y, x0 : x1 + 1]
        ux = np.uint64(0)
        while ux < ubw:
            if lr[ux] != oid:
                ux += one
                continue
            # a run of the object inside one slice: sums kept in registers, added once
            xx0 = np.int64(ux)
            j = (yy // step if horizontal else xx0 // step) + 1
            stop = ubw if horizontal else min(ubw, np.uint64(j) * ustep)
            sz = 0.0
            szz = 0.0
            sxz = 0.0
            while ux < stop and lr[ux] == oid:
                z = np.float64(dr[ux])
                sz += z
                szz += z * z
                sxz += np.float64(ux) * z
                ux += one
            xe = np.int64(ux)
            k = xe - xx0
            c = np.float64(k)
            sums[j, COUNT] += c
            sums[j, SUM_Z] += sz
            sums[j, SUM_ZZ] += szz
            sums[j, SUM_X] += np.float64((xx0 + xe - 1) * k // 2)
            sums[j, SUM_Y] += c * yy
            sums[j, SUM_XZ] += sxz
            sums[j, SUM_YZ] += sz * yy
            boxes[j, 0] = min(boxes[j, 0], xx0)
            boxes[j, 1] = min(boxes[j, 1], yy)
            boxes[j, 2] = max(boxes[j, 2], xe - 1)
            boxes[j, 3] = max(boxes[j, 3], yy)
    return sums, boxes


def small_supports(sums: NDArray[np.float64], min_px: int, min_spread: float) -> tuple[NDArray[np.bool_], int]:
    """Return which supports are too small or too flat to keep, and how many.

    A row of the statistics table ``sums`` (row 0 unused) is small when it has fewer than
    ``min_px`` pixels or its depth spread (standard deviation) is under ``min_spread`` times
    its mean depth: numpy's ``(count < min_px) | (std < min_spread * mean)`` with ``mean =
    SUM_Z / max(count, 1)`` and ``std = sqrt(max(SUM_ZZ / max(count, 1) - mean², 0))``.
    """
    count = sums[:, COUNT]
    d = np.maximum(count, 1.0)
    mean = sums[:, SUM_Z] / d
    std = np.sqrt(np.maximum(sums[:, SUM_ZZ] / d - mean * mean, 0.0))
    small = (count < min_px) | (std < min_spread * mean)
    small[0] = False
    return small, int(np.count_nonzero(small))


def support_kind(cls: int, centroid_y_mm: float, is_lowest: bool) -> str:
    """Return the kind of a support component.

    ``wall``; ``floor`` (lowest horizontal below the camera); ``ceiling`` (horizontal above it);
    ``compound`` (other horizontal supports: table tops).
    """
    if cls == VERTICAL:
        return "wall"
    if cls == HORIZONTAL and centroid_y_mm < 0:
        return "ceiling"
    return "floor" if is_lowest else "compound"


@njit(cache=True, nogil=True)
def _class_state(
    valid: NDArray[np.bool_], classes: NDArray[np.int8], cls: np.int8, y0: int, y1: int, x0: int, x1: int
) -> NDArray[np.int8]:
    # labeller state in one pass: pixels of the class are active, other readings block
    # bridges, pixels without a reading are holes (numpy: three full-frame passes); set inside
    # the window rows y0..y1 - 1, columns x0..x1 - 1 only (the labeller reads no other)
    out = np.empty(valid.shape, np.int8)
    for y in range(y0, y1):
        # row slices read from 0 vectorise (indices from x0 made it ten times slower)
        o, c, v = out[y, x0:x1], classes[y, x0:x1], valid[y, x0:x1]
        for x in range(x1 - x0):
            o[x] = (ACTIVE if c[x] == cls else BLOCK) if v[x] else HOLE
    return out


def add_through(
    labels: NDArray[np.int32], more: NDArray[np.int32], lut: NDArray[np.int32], boxes: NDArray[np.int64]
) -> None:
    """Write ``lut[more]`` into ``labels`` (in place) wherever it is > 0.

    ``lut`` must cover every value of ``more``; ``boxes`` (k, 4), inclusive (x0, y0, x1, y1),
    must hold every pixel it maps above 0 (the supports' boxes): only they are read, unless
    they cover more than the frame.
    """
    _add_through(
        labels,
        np.ascontiguousarray(more, np.int32),
        np.ascontiguousarray(lut, np.int32),
        np.ascontiguousarray(boxes, np.int64).reshape(-1, 4),
    )


@njit(cache=True, nogil=True)
def _add_through(
    labels: NDArray[np.int32], more: NDArray[np.int32], lut: NDArray[np.int32], boxes: NDArray[np.int64]
) -> None:
    # boxes may overlap: a pixel read twice is written the same value twice
    boxes = _cover(boxes, labels.shape[0], labels.shape[1])
    for k in range(boxes.shape[0]):
        for y in range(boxes[k, 1], boxes[k, 3] + 1):
            src = more[y]
            dst = labels[y]
            # branch-free with unsigned indices, so that the gather vectorises
            for ux in range(np.uint64(boxes[k, 0]), np.uint64(boxes[k, 2] + 1)):
                v = lut[np.uint64(src[ux])]
                dst[ux] = v if v else dst[ux]


@njit(cache=True, inline="always")
def _cover(boxes: NDArray[np.int64], h: int, w: int) -> NDArray[np.int64]:
    """Return the boxes (k, 4, inclusive), or the whole frame as one box when they cover more than it.

    Taken in the compiled loops that read the boxes: a real frame drops hundreds of specks,
    whose areas a Python loop summed at a visible cost.
    """
    area = 0
    for k in range(boxes.shape[0]):
        area += max(boxes[k, 2] - boxes[k, 0] + 1, 0) * max(boxes[k, 3] - boxes[k, 1] + 1, 0)
    if area < h * w:
        return boxes
    whole = np.empty((1, 4), np.int64)
    whole[0, 0], whole[0, 1], whole[0, 2], whole[0, 3] = 0, 0, w - 1, h - 1
    return whole


def drop_classes(
    labels: NDArray[np.int32],
    through: NDArray[np.int32],
    base: int,
    classes: NDArray[np.int8],
    to_class: int,
    boxes: NDArray[np.int64],
) -> None:
    """Pixels of pieces ``base + 1 .. base + n`` of ``labels`` that ``through`` maps to 0 get class ``to_class``.

    ``through`` has n + 1 entries (piece -> kept support, 0 = dropped); ``classes`` is updated
    in place and other labels are not read (a label map may hold another class's pieces
    after these). ``boxes`` (k, 4), inclusive, must hold every dropped piece (the dropped
    supports' boxes): only they are read, unless they cover more than the frame.
    """
    _drop_classes(
        labels,
        np.ascontiguousarray(through, np.int32),
        int(base),
        classes,
        np.int8(to_class),
        np.ascontiguousarray(boxes, np.int64).reshape(-1, 4),
    )


@njit(cache=True, nogil=True)
def _drop_classes(
    labels: NDArray[np.int32],
    through: NDArray[np.int32],
    base: int,
    classes: NDArray[np.int8],
    to_class: np.int8,
    boxes: NDArray[np.int64],
) -> None:
    n = through.size - 1
    boxes = _cover(boxes, labels.shape[0], labels.shape[1])
    for k in range(boxes.shape[0]):
        for y in range(boxes[k, 1], boxes[k, 3] + 1):
            for x in range(boxes[k, 0], boxes[k, 2] + 1):
                v = labels[y, x] - base
                if v > 0 and v <= n and through[v] == 0:
                    classes[y, x] = to_class


def support_pieces(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    cam: Intrinsics,
    *,
    jump_rel: float,
    bridge: int,
    min_fit_px: int,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """Return the supports of one orientation class: depth-continuous pieces, coplanar ones joined.

    The pixels of class ``cls`` are labelled while depth stays continuous between neighbours
    (within ``jump_rel`` of the depth, across at most ``bridge`` px of holes), and pieces of one
    plane cut apart by occluders are joined
    (:func:`depthgram.segmentation.coplanar.coplanar_groups`). One labelling pass gathers the
    statistics table (:mod:`depthgram.segmentation.label.stats`), its relabelling pass the
    plane sums (:func:`depthgram.segmentation.label.keyed.label_keyed_planes`);
    pieces joined into one plane add their rows (the sums are additive), so neither is taken
    again on the merged labels.

    Returns
    -------
    labels, n
        Merged components 1..n.
    sums : ndarray (n + 1, N_COLUMNS), boxes : ndarray (n + 1, 4), planes : ndarray (n + 1, 9)
        Statistics (``KEY`` 0), inclusive boxes and plane sums per component (row 0 unused).
    """
    labels, merge, n, sums, boxes, planes, _ = support_pieces_lazy(
        depth_mm, valid, classes, cls, cam, jump_rel=jump_rel, bridge=bridge, min_fit_px=min_fit_px
    )
    return (relabel(labels, merge) if merge is not None else labels), n, sums, boxes, planes


def support_pieces_lazy(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    cam: Intrinsics,
    *,
    jump_rel: float,
    bridge: int,
    min_fit_px: int,
    window: tuple[int, int, int, int] | None = None,
    min_plane_px: float = 0.0,
) -> tuple[
    NDArray[np.int32],
    NDArray[np.int32] | None,
    int,
    NDArray[np.float64],
    NDArray[np.int64],
    NDArray[np.float64],
    tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None,
]:
    """:func:`support_pieces` with the joining of pieces left to the caller's next pass.

    Returns the pieces' labels and the lookup table piece -> support (None when no pieces were
    joined; ``merge[labels]`` is what :func:`support_pieces` returns), then n, sums, boxes and
    plane sums of the supports as it does, and ``(normal, off, count)`` of the pieces when
    none were joined (the fit that decided it), else None: a caller that relabels anyway
    (dropping small supports) does it once, and does not solve the same planes again.

    ``window`` ``(y0, y1, x0, x1)`` (half-open, px), when it holds every pixel of the class
    (:func:`depthgram.segmentation.coplanar.class_window`), gives the same results reading these
    rows and columns alone; the labels are 0 outside it. ``min_plane_px``: as for
    :func:`join_pieces`.
    """
    h, w = valid.shape
    win = window if window is not None else (0, h, 0, w)
    state = _class_state(valid, classes, np.int8(cls), *win)
    labels, n, sums, boxes, planes = label_keyed_planes(
        depth_mm, state, depth_mm, cam.fx, cam.fy, cam.cx, cam.cy, rel=jump_rel, bridge=bridge, window=win
    )
    return (labels, *join_pieces(n, sums, boxes, planes, min_fit_px=min_fit_px, min_plane_px=min_plane_px))


def join_pieces(
    n: int,
    sums: NDArray[np.float64],
    boxes: NDArray[np.int64],
    planes: NDArray[np.float64],
    *,
    min_fit_px: int,
    min_plane_px: float = 0.0,
) -> tuple[
    NDArray[np.int32] | None,
    int,
    NDArray[np.float64],
    NDArray[np.int64],
    NDArray[np.float64],
    tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None,
]:
    """Join the coplanar ones among ``n`` labelled pieces, by their tables alone.

    ``sums``, ``boxes`` and ``planes`` are the tables of
    :func:`depthgram.segmentation.label.label_keyed_planes` (row 0 unused). Returns what
    :func:`support_pieces_lazy` returns after the labels: the lookup table piece -> support
    (None when none joined), the number of supports, their tables, and the pieces' plane fit
    when none joined (else None), whose pieces under both ``min_fit_px`` and ``min_plane_px``
    pixels have no plane (NaN: the caller reads the planes of larger pieces alone).
    """
    if n < 2:
        return None, n, sums, boxes, planes, None
    fit = planes_from_sums(planes, min_px=min(min_fit_px, min_plane_px))
    normal, off, count = fit
    # the rows of the joined pieces added (sums, plane sums) and their boxes' union, by the
    # call that joins them
    lut, m, joined = coplanar_tables(normal, off, count, (sums, planes, boxes), min_fit_px=min_fit_px)
    if joined is None:
        return None, n, sums, boxes, planes, fit
    msums, mplanes, mboxes = joined
    msums[:, KEY] = 0.0
    return lut, m, msums, mboxes, mplanes, None


def warm_up() -> None:
    """Nothing left to load: the rows of coplanar pieces joined are added by numpy (kept for callers)."""
