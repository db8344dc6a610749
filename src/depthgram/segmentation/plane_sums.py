"""Least-squares planes of labelled pieces: the normal-equation sums and the planes from them.

The plane ``1/Z = alpha u' + beta v' + gamma`` (normalised image coordinates) of each label is
fitted from nine sums gathered in one pass (:func:`plane_sums`); the sums are additive, so the
plane of a union of pieces comes from the sum of their rows (:func:`planes_from_sums`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation._kernels import plane_sums as kernels_sums

__all__ = ["plane_sums", "plane_sums_in_boxes", "planes_from_sums", "shares_beneath"]


def plane_sums(
    labels: NDArray[np.int32],
    n: int,
    depth_mm: NDArray[np.float32],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    only: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """Normal-equation sums of the plane fit ``1/Z = alpha u' + beta v' + gamma`` per label.

    Columns: u'u', u'v', u', v'v', v', 1, u'/Z, v'/Z, 1/Z with ``u' = (x - cx) / fx``,
    ``v' = (y - cy) / fy``: nine ``np.bincount`` over the labelled pixels. ``only`` (bool per
    label, length ``n + 1``): the rows of other labels stay 0. The segmentation gathers these
    sums while labelling (:func:`depthgram.segmentation.label.label_keyed_planes`) or reads a
    few labels' boxes (:func:`plane_sums_in_boxes`); this is the readable route they are
    tested against.
    """
    lab = np.asarray(labels)
    keep = lab > 0
    if only is not None:
        keep &= np.asarray(only, np.bool_)[lab]
    ys, xs = np.nonzero(keep)
    ids = lab[keep]
    u = (xs - float(cx)) / float(fx)
    v = (ys - float(cy)) / float(fy)
    q = 1.0 / np.asarray(depth_mm, np.float32)[keep].astype(np.float64)
    cols = (u * u, u * v, u, v * v, v, np.ones_like(u), u * q, v * q, q)
    out = np.zeros((int(n) + 1, 9), np.float64)
    for j, col in enumerate(cols):
        out[:, j] = np.bincount(ids, weights=col, minlength=int(n) + 1)[: int(n) + 1]
    return out


def plane_sums_in_boxes(
    labels: NDArray[np.int32],
    n: int,
    ids: NDArray[np.intp],
    boxes: NDArray[np.int64],
    depth_mm: NDArray[np.float32],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
) -> NDArray[np.float64]:
    """:func:`plane_sums` of the labels ``ids`` only, reading each one's box alone.

    ``boxes`` (k, 4) are the inclusive (x0, y0, x1, y1) of ``ids``, which must hold every
    pixel of the label. The rows of ``ids`` are those of ``plane_sums(..., only=...)`` to the
    last bit (the same runs, added in the same order); the others stay 0. A few supports
    among many objects cover a fraction of the frame.
    """
    return kernels_sums.plane_sums_boxes(
        np.ascontiguousarray(labels, np.int32),
        int(n),
        np.ascontiguousarray(ids, np.intp),
        np.ascontiguousarray(boxes, np.int64),
        np.ascontiguousarray(depth_mm, np.float32),
        float(fx),
        float(fy),
        float(cx),
        float(cy),
    )


def shares_beneath(
    depth_mm: NDArray[np.float32],
    step: int,
    cam: Intrinsics,
    normal: NDArray[np.float64],
    offset_mm: NDArray[np.float64],
    beneath_mm: float,
) -> NDArray[np.float64]:
    """Return the share of the sampled readings lying more than ``beneath_mm`` beneath each plane.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm); 0 where there is no reading.
    step : int
        Every ``step``-th pixel of every ``step``-th row is read.
    cam : Intrinsics
        The camera's intrinsics (px).
    normal, offset_mm : ndarray, shapes (P, 3) and (P,)
        Planes ``n . X + d = 0`` in camera coordinates (mm), ``n`` a unit normal; the signed
        distance ``n . X + d`` is positive on the camera's side.
    beneath_mm : float
        How far (mm) beyond a plane a reading must lie to count.

    Returns
    -------
    ndarray of float64, shape (P,)
        For each plane, the count of sampled readings at a signed distance below
        ``-beneath_mm`` over the count of sampled readings (0 without readings).
    """
    return kernels_sums.shares_beneath(
        np.asarray(depth_mm, np.float32), int(step), cam.fx, cam.fy, cam.cx, cam.cy,
        np.ascontiguousarray(normal, np.float64), np.ascontiguousarray(offset_mm, np.float64), float(beneath_mm),
    )  # fmt: skip


def planes_from_sums(
    sums: NDArray[np.float64], *, min_px: float = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return unit normals, offsets (mm) and pixel counts from the sums of :func:`plane_sums` (row 0 unused).

    The sums are additive, so the plane of a union of pieces comes from the sum of their rows
    without another pass over the image. Each row's normal equations (plus 1e-12 on the
    diagonal) are solved by LAPACK (``np.linalg.solve``, compiled). Rows of fewer than
    ``min_px`` pixels are not solved: their normals and offsets are NaN.
    """
    return kernels_sums.planes_from_sums(np.ascontiguousarray(sums, np.float64), float(min_px))
