"""Pieces of one plane: coplanar pieces joined, and pixels on a support's plane near it.

Pieces of one support cut apart by occluders are joined when their planes (from
:func:`depthgram.segmentation.plane_sums.planes_from_sums`) agree (:func:`coplanar_groups`);
pixels lying on a support's plane near it are found (:func:`near_planes`) or given the
support's class (:func:`join_near`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation._kernels import coplanar as kernels_coplanar

__all__ = ["class_window", "coplanar_groups", "coplanar_tables", "join_near", "near_planes"]


def coplanar_groups(
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    *,
    max_angle_deg: float = 10.0,
    max_offset_rel: float = 0.08,
    min_fit_px: int = 1,
) -> tuple[NDArray[np.int32], int]:
    """Join pieces of one plane cut apart by occluders (the floor between two boxes).

    Pieces join when their normals (from :func:`depthgram.segmentation.plane_sums.planes_from_sums`) agree within
    ``max_angle_deg`` and their plane offsets within ``max_offset_rel``. Pieces under
    ``min_fit_px`` pixels are left alone: a few rows give no reliable plane (a cup's rim would
    join the table top).

    Returns
    -------
    lut : ndarray of int32, shape (n + 1,)
        Piece -> group (row 0 maps to 0); groups are numbered 1..m in the order of their first
        piece.
    m : int
        Number of groups.
    """
    lut, m, _, _, _ = _join(normal, off, count, max_angle_deg, max_offset_rel, min_fit_px, _NO_BOXES)
    return lut, m


def coplanar_tables(
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    tables: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]],
    *,
    max_angle_deg: float = 10.0,
    max_offset_rel: float = 0.08,
    min_fit_px: int = 1,
) -> tuple[NDArray[np.int32], int, tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]] | None]:
    """:func:`coplanar_groups` with the groups' tables, from the pieces' ``tables``.

    ``tables`` are the pieces' statistics, plane sums and inclusive boxes (a row per piece, row
    0 unused). Returns ``lut`` and ``m`` as :func:`coplanar_groups` does, and, when pieces
    joined, each group's rows: its pieces' rows added (``np.add.reduceat`` of the rows sorted
    stably by group) and its pieces' boxes' union (None when none joined).
    """
    sums, planes, boxes = tables
    lut, m, order, starts, mboxes = _join(
        normal, off, count, max_angle_deg, max_offset_rel, min_fit_px, np.ascontiguousarray(boxes, np.int64)
    )
    if m == normal.shape[0] - 1:
        return lut, m, None
    return lut, m, (np.add.reduceat(sums[order], starts), np.add.reduceat(planes[order], starts), mboxes)


#: Boxes for :func:`_join` when the caller wants the groups alone (typed as real ones).
_NO_BOXES = np.zeros((0, 4), np.int64)


def _join(
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    max_angle_deg: float,
    max_offset_rel: float,
    min_fit_px: int,
    boxes: NDArray[np.int64],
) -> tuple[NDArray[np.int32], int, NDArray[np.intp], NDArray[np.intp], NDArray[np.int64]]:
    """Return the groups of :func:`coplanar_groups` and the kernel's order, starts and boxes of them."""
    n = normal.shape[0] - 1
    # only pieces big enough for a reliable plane can join: compare those alone (a few),
    # not all pairs of pieces (hundreds of noise specks)
    big = np.nonzero(count[1:] >= min_fit_px)[0] + 1
    if big.size < 2:
        none = np.zeros(0, np.intp)
        return np.arange(n + 1, dtype=np.int32), n, none, none, _NO_BOXES
    nb = normal[big]
    # the cosines are numpy's matrix product (its BLAS kernels' rounding, which compiled dot
    # products do not repeat for every size); the tests and the joins after it are compiled
    lut, m, order, starts, mboxes = kernels_coplanar.coplanar_join(
        nb @ nb.T, off, big, math.cos(math.radians(max_angle_deg)), float(max_offset_rel), n, boxes
    )
    return lut, int(m), order, starts, mboxes


def near_planes(
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    boxes: NDArray[np.int64],
    depth_mm: NDArray[np.float32],
    candidates: NDArray[np.bool_],
    cam: Intrinsics,
    *,
    min_px: int,
    tol_rel: float,
) -> NDArray[np.bool_]:
    """Candidate pixels whose depth lies on the plane of a support of >= ``min_px`` pixels.

    ``normal``, ``off`` (mm), ``count`` and inclusive ``boxes`` per support (row 0 unused), as
    :func:`depthgram.segmentation.plane_sums.planes_from_sums` and the labellers give them. Only
    pixels inside the support's box grown by a tenth are tested, so a far object that happens to
    lie on the plane's extension elsewhere is not taken; a pixel is on the plane when ``|Z / Z_plane - 1| <= tol_rel``.
    """
    out = np.zeros(depth_mm.shape, bool)
    ids = np.flatnonzero(count >= min_px)
    ids = ids[ids > 0]
    if ids.size:
        kernels_coplanar.mark_near(
            out, ids, normal, off, boxes, depth_mm, candidates, cam.fx, cam.fy, cam.cx, cam.cy, float(tol_rel)
        )
    return out


def join_near(
    classes: NDArray[np.int8],
    valid: NDArray[np.bool_],
    cls: int,
    facing: int,
    normal: NDArray[np.float64],
    off: NDArray[np.float64],
    count: NDArray[np.float64],
    boxes: NDArray[np.int64],
    depth_mm: NDArray[np.float32],
    cam: Intrinsics,
    *,
    min_px: int,
    tol_rel: float,
) -> int:
    """Give class ``cls`` (in place) to the pixels :func:`near_planes` finds; return how many.

    The candidates are the valid pixels of class ``facing``: the result is that of
    ``near = near_planes(..., valid & (classes == facing), ...)`` followed by
    ``classes[near] = cls``, in one pass over the supports' boxes without the frame-sized
    candidate and result masks.
    """
    return int(
        kernels_coplanar.join_near(
            classes,
            np.ascontiguousarray(valid, np.bool_),
            np.int8(cls),
            np.int8(facing),
            normal,
            off,
            count,
            boxes,
            np.ascontiguousarray(depth_mm, np.float32),
            float(min_px),
            cam.fx,
            cam.fy,
            cam.cx,
            cam.cy,
            float(tol_rel),
        )
    )


def class_window(
    boxes: NDArray[np.int64], count: NDArray[np.float64], shape: tuple[int, int], *, min_px: int
) -> tuple[int, int, int, int]:
    """Return the window ``(y0, y1, x0, x1)`` (half-open, px) holding a class after :func:`join_near`.

    ``boxes`` (n + 1, 4, inclusive) hold every pixel of the class before (row 0 unused);
    :func:`join_near` with the same ``count`` and ``min_px`` gives it pixels only inside the
    margins it searches around the supports of ``min_px`` pixels or more. The union of both
    holds every pixel of the class after it, so that labelling the class again reads this
    window alone (:func:`depthgram.segmentation.slices.support_pieces_lazy`). An empty table
    gives an empty window.
    """
    y0, y1, x0, x1 = kernels_coplanar.class_window(
        np.ascontiguousarray(boxes, np.int64), count, float(min_px), shape[0], shape[1]
    )
    return int(y0), int(y1), int(x0), int(x1)
