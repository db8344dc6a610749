"""Correspondence of tracks and this frame's objects: a gated cost and one global assignment.

The paper keeps identity through the object's attributes (depth label, mean depth, area and
center). Each pair gets a cost that sums normalised attribute differences; pairs beyond a
gate are forbidden; then ``scipy.optimize.linear_sum_assignment`` picks the cheapest
one-to-one matching over all pairs, so no object steals a track just by coming first.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from depthgram.dynamics.config import TrackerConfig
from depthgram.dynamics.kernels import FORBIDDEN, OBJECT_DTYPE, PREDICTION_DTYPE, CostParams, cost_kernel

__all__ = ["FORBIDDEN", "CostParams", "assign", "bbox_iou", "cost_kernel", "cost_params", "match_cost"]


def bbox_iou(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Intersection over union of every pair of half-open pixel boxes.

    Parameters
    ----------
    a : ndarray, shape (T, 4)
        Boxes (x0, y0, x1, y1) in pixels, half-open (x1, y1 exclusive), as ``SceneObject.bbox_xy``.
    b : ndarray, shape (M, 4)
        Boxes likewise.

    Returns
    -------
    ndarray of float, shape (T, M)
        IoU in 0..1.
    """
    ix = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    iy = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = np.clip(ix, 0, None) * np.clip(iy, 0, None)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return np.asarray(inter / np.maximum(union, 1.0), dtype=np.float64)


def cost_params(config: TrackerConfig) -> CostParams:
    """Return the gates and weights of ``config`` that :func:`cost_kernel` reads."""
    c = config
    return CostParams(
        max_center_rate=float(c.max_center_rate), gate_growth=float(c.gate_growth),
        max_depth_rate=float(c.max_depth_rate), log_max_area_ratio=math.log(c.max_area_ratio),
        min_iou=float(c.min_iou), w_center=float(c.w_center), w_depth=float(c.w_depth),
        w_area=float(c.w_area), w_iou=float(c.w_iou), w_label=float(c.w_label),
        accel_sigma=float(c.accel_sigma), innovation_gate=float(c.innovation_gate),
    )  # fmt: skip


def match_cost(
    track_center: ArrayLike,
    track_depth: ArrayLike,
    track_area: ArrayLike,
    track_bbox: ArrayLike,
    track_label: ArrayLike,
    track_elapsed_s: ArrayLike,
    obj_center: ArrayLike,
    obj_depth: ArrayLike,
    obj_area: ArrayLike,
    obj_bbox: ArrayLike,
    obj_label: ArrayLike,
    diagonal_px: float,
    dt_s: float,
    config: TrackerConfig,
) -> NDArray[np.float64]:
    """Cost of matching each track (predicted state) to each object, gates applied.

    The cost sums, with the weights of ``config``: center distance over the center gate,
    depth change over the depth gate, ``|log area ratio|`` over ``log max_area_ratio``,
    ``1 - IoU`` of the boxes, and ``w_label`` when the depth labels differ. A pair is
    allowed only when each of the first three is <= 1 and IoU >= ``min_iou``. The gates are
    rates: the center gate is ``max_center_rate * dt_s`` of the diagonal, widened by
    ``gate_growth`` per second missed, the depth gate ``max_depth_rate`` times the time since
    the track's last detection, so that the same physical motion passes at any frame rate.
    (The tracker's own tracks with a Kalman filter widen the depth gate while they coast only
    as far as the filter's predicted depth may stray, :func:`cost_kernel`.)

    Parameters
    ----------
    track_center : array_like, shape (T, 2)
        Predicted image center (x, y) of each track this frame (px).
    track_depth : array_like, shape (T,)
        Predicted mean depth (mm).
    track_area : array_like, shape (T,)
        Last seen area (px).
    track_bbox : array_like, shape (T, 4)
        Predicted bbox (px, half-open).
    track_label : array_like, shape (T,)
        Last depth label.
    track_elapsed_s : array_like, shape (T,)
        Time since each track's last detection (s): ``dt_s`` for a track seen last frame.
    obj_center, obj_depth, obj_area, obj_bbox, obj_label : array_like
        The same attributes of this frame's M objects.
    diagonal_px : float
        Image diagonal (px), the scale of the center gate.
    dt_s : float
        This frame's time step (s).
    config : TrackerConfig
        Gates and weights.

    Returns
    -------
    ndarray of float, shape (T, M)
        Costs; :data:`FORBIDDEN` where a gate is exceeded.
    """

    def f(a: ArrayLike, shape: tuple[int, ...]) -> NDArray[np.float64]:
        return np.asarray(a, dtype=np.float64).reshape(shape)

    nt = np.asarray(track_depth).size
    no = np.asarray(obj_depth).size
    pred = np.zeros(nt, PREDICTION_DTYPE)
    center = f(track_center, (nt, 2))
    pred["cx"], pred["cy"] = center[:, 0], center[:, 1]
    pred["sx"], pred["sy"] = center[:, 0], center[:, 1]
    pred["x0"], pred["y0"], pred["x1"], pred["y1"] = f(track_bbox, (nt, 4)).T
    pred["z"], pred["area"] = f(track_depth, (nt,)), f(track_area, (nt,))
    pred["label"], pred["elapsed"] = f(track_label, (nt,)), f(track_elapsed_s, (nt,))
    pred["zs"] = np.nan  # no filter: the depth gate widens at max_depth_rate
    objs = np.zeros(no, OBJECT_DTYPE)
    center = f(obj_center, (no, 2))
    objs["cx"], objs["cy"] = center[:, 0], center[:, 1]
    objs["x0"], objs["y0"], objs["x1"], objs["y1"] = f(obj_bbox, (no, 4)).T
    objs["z"], objs["area"], objs["label"] = f(obj_depth, (no,)), f(obj_area, (no,)), f(obj_label, (no,))
    return cost_kernel(pred, objs, float(diagonal_px), float(dt_s), cost_params(config))


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
