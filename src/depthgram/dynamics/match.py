"""Correspondence of tracks and this frame's objects: a gated cost and one global assignment.

The paper keeps identity through the object's attributes (depth label, mean depth, area and
center). Each pair gets a cost that sums normalised attribute differences; pairs beyond a
gate are forbidden; then ``scipy.optimize.linear_sum_assignment`` picks the cheapest
one-to-one matching over all pairs, so no object steals a track just by coming first.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from depthgram.dynamics.config import TrackerConfig

__all__ = ["FORBIDDEN", "assign", "bbox_iou", "match_cost"]

#: Cost of a gated (forbidden) pair. Finite, because linear_sum_assignment rejects
#: matrices where a row has no finite entry; pairs at this cost are dropped afterwards.
FORBIDDEN = 1e9


def bbox_iou(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Intersection over union of every pair of inclusive pixel boxes.

    Parameters
    ----------
    a : ndarray, shape (T, 4)
        Boxes (x0, y0, x1, y1), inclusive pixel coordinates.
    b : ndarray, shape (M, 4)
        Boxes likewise.

    Returns
    -------
    ndarray of float, shape (T, M)
        IoU in 0..1.
    """
    ix = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]) + 1
    iy = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]) + 1
    inter = np.clip(ix, 0, None) * np.clip(iy, 0, None)
    area_a = (a[:, 2] - a[:, 0] + 1) * (a[:, 3] - a[:, 1] + 1)
    area_b = (b[:, 2] - b[:, 0] + 1) * (b[:, 3] - b[:, 1] + 1)
    union = area_a[:, None] + area_b[None, :] - inter
    return np.asarray(inter / np.maximum(union, 1.0), dtype=np.float64)


def match_cost(
    track_center: NDArray[np.float64],
    track_depth: NDArray[np.float64],
    track_area: NDArray[np.float64],
    track_bbox: NDArray[np.float64],
    track_label: NDArray[np.int64],
    track_missed: NDArray[np.int64],
    obj_center: NDArray[np.float64],
    obj_depth: NDArray[np.float64],
    obj_area: NDArray[np.float64],
    obj_bbox: NDArray[np.float64],
    obj_label: NDArray[np.int64],
    diagonal_px: float,
    config: TrackerConfig,
) -> NDArray[np.float64]:
    """Cost of matching each track (predicted state) to each object, gates applied.

    Parameters
    ----------
    track_center : ndarray, shape (T, 2)
        Predicted image center (x, y) of each track this frame (px).
    track_depth : ndarray, shape (T,)
        Predicted mean depth (mm).
    track_area : ndarray, shape (T,)
        Last seen area (px).
    track_bbox : ndarray, shape (T, 4)
        Predicted bbox (px, inclusive).
    track_label : ndarray, shape (T,)
        Last depth label.
    track_missed : ndarray, shape (T,)
        Frames since the last detection before this one; gates widen with it.
    obj_center, obj_depth, obj_area, obj_bbox, obj_label : ndarray
        The same attributes of this frame's M objects.
    diagonal_px : float
        Image diagonal (px), the scale of the center gate.
    config : TrackerConfig
        Gates and weights.

    Returns
    -------
    ndarray of float, shape (T, M)
        Costs; :data:`FORBIDDEN` where a gate is exceeded.
    """
    c = config
    grow = 1.0 + track_missed.astype(np.float64)
    r_center = c.max_center_frac * diagonal_px * (1.0 + c.gate_growth * track_missed)
    d = np.hypot(
        track_center[:, None, 0] - obj_center[None, :, 0], track_center[:, None, 1] - obj_center[None, :, 1]
    )
    dc = d / r_center[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        dz = np.abs(obj_depth[None, :] - track_depth[:, None]) / (track_depth[:, None] * c.max_depth_change)
        dz /= grow[:, None]
        la = np.abs(np.log(np.maximum(obj_area[None, :], 1.0) / np.maximum(track_area[:, None], 1.0)))
    da = la / np.log(c.max_area_ratio)
    iou = bbox_iou(track_bbox, obj_bbox)
    cost = (
        c.w_center * dc
        + c.w_depth * dz
        + c.w_area * da
        + c.w_iou * (1.0 - iou)
        + c.w_label * (track_label[:, None] != obj_label[None, :])
    )
    # NaN depth (no valid pixel) fails the depth gate by comparison with NaN.
    allowed = (dc <= 1.0) & (dz <= 1.0) & (da <= 1.0) & (iou >= c.min_iou)
    return np.where(allowed, cost, FORBIDDEN)


def assign(cost: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """One global minimum-cost matching; forbidden pairs are dropped.

    Parameters
    ----------
    cost : ndarray, shape (T, M)
        From :func:`match_cost`.

    Returns
    -------
    rows, cols : ndarray of int
        Matched track rows and object columns, same length.
    """
    if cost.size == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    rows, cols = linear_sum_assignment(cost)
    keep = cost[rows, cols] < FORBIDDEN
    return rows[keep], cols[keep]
