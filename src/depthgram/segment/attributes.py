"""Object attributes from a label map: area, center, mean and spread of depth, bbox, metric size.

All statistics (count, sum Z, sum Z², sum x, sum y, sum xZ, sum yZ, bounding box) come from one
compiled raster pass over the label map, whatever the object count. The plain-numpy route
(seven weighted ``np.bincount`` passes plus ``scipy.ndimage.find_objects``) is kept as
:func:`label_stats_bincount`; it gives the same numbers and was measured about 3x slower.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from depthgram.frame import Intrinsics
from depthgram.segment.label import label_stats_fused
from depthgram.segment.objects import SceneObject

__all__ = ["Stats", "fused_stats", "label_stats", "label_stats_bincount", "make_objects", "relabel_small"]


@dataclass(frozen=True, eq=False)
class Stats:
    """Per-label sums over valid labelled pixels; index ``i`` is label ``i`` (0 unused).

    Attributes
    ----------
    count, sz, szz, sx, sy : ndarray of float64
        Pixel count, sum of depth (mm), of depth squared (mm²), of column and of row (px).
    sxz, syz : ndarray of float64 or None
        Sums of column x depth and row x depth, kept when intrinsics are wanted.
    boxes : ndarray of int64, shape (n + 1, 4) or None
        Inclusive (x0, y0, x1, y1) per label when already known; else taken from the labels.
    """

    count: NDArray[Any]
    sz: NDArray[Any]
    szz: NDArray[Any]
    sx: NDArray[Any]
    sy: NDArray[Any]
    sxz: NDArray[Any] | None
    syz: NDArray[Any] | None
    boxes: NDArray[np.int64] | None = None


def label_stats(labels: NDArray[np.int32], depth_mm: NDArray[np.floating], n: int, *, metric: bool = False) -> Stats:
    """Sums and boxes per label over the pixels with a label > 0, in one compiled pass.

    Parameters
    ----------
    labels : ndarray of int32, shape (H, W)
        Label map, 0 = none; only pixels with a reading may carry a label.
    depth_mm : ndarray, shape (H, W)
        Depth (mm).
    n : int
        Largest label.
    metric : bool
        Keep the sums of x·Z and y·Z (for 3-D centroids).
    """
    sums, boxes = label_stats_fused(labels, n, np.asarray(depth_mm, np.float32), labels)
    return Stats(
        sums[:, 0],
        sums[:, 1],
        sums[:, 2],
        sums[:, 3],
        sums[:, 4],
        sums[:, 5] if metric else None,
        sums[:, 6] if metric else None,
        boxes,
    )


def label_stats_bincount(
    labels: NDArray[np.int32], depth_mm: NDArray[np.floating], n: int, *, metric: bool = False
) -> Stats:
    """The same sums with weighted ``np.bincount`` passes (reference; about 3x slower at 640 x 480)."""
    flat = labels.ravel()
    idx = np.flatnonzero(flat)
    lab = flat[idx]
    z = depth_mm.ravel()[idx].astype(np.float64)
    ys, xs = np.divmod(idx, labels.shape[1])
    m = n + 1
    count = np.bincount(lab, minlength=m).astype(np.float64)
    sz = np.bincount(lab, weights=z, minlength=m)
    szz = np.bincount(lab, weights=z * z, minlength=m)
    sx = np.bincount(lab, weights=xs, minlength=m)
    sy = np.bincount(lab, weights=ys, minlength=m)
    sxz = np.bincount(lab, weights=xs * z, minlength=m) if metric else None
    syz = np.bincount(lab, weights=ys * z, minlength=m) if metric else None
    return Stats(count, sz, szz, sx, sy, sxz, syz)


def fused_stats(
    labels: NDArray[np.int32], n: int, depth_mm: NDArray[np.float32], key: NDArray[Any], min_px: int
) -> tuple[NDArray[np.int32], Stats, NDArray[np.float64]]:
    """Drop labels under ``min_px`` pixels, renumber, and return their sums, boxes and keys."""
    sums, boxes = label_stats_fused(labels, n, depth_mm, key)
    keep = sums[:, 0] >= min_px
    keep[0] = False
    lut = np.zeros(n + 1, dtype=np.int32)
    lut[keep] = np.arange(1, int(keep.sum()) + 1, dtype=np.int32)
    sel = np.concatenate(([0], np.flatnonzero(keep)))
    s = sums[sel]
    stats = Stats(s[:, 0], s[:, 1], s[:, 2], s[:, 3], s[:, 4], s[:, 5], s[:, 6], boxes[sel])
    out: NDArray[np.int32] = lut[labels] if n else labels
    return out, stats, s[:, 7]


def relabel_small(labels: NDArray[np.int32], count: NDArray[np.float64], min_px: int) -> NDArray[np.int32]:
    """Drop labels with fewer than ``min_px`` pixels and renumber the rest 1..k in order."""
    keep = count >= min_px
    keep[0] = False
    lut = np.zeros(count.size, dtype=np.int32)
    lut[keep] = np.arange(1, int(keep.sum()) + 1, dtype=np.int32)
    out: NDArray[np.int32] = lut[labels]
    return out


def make_objects(
    labels: NDArray[np.int32],
    stats: Stats,
    *,
    kinds: list[str] | None = None,
    depth_labels: NDArray[np.integer] | None = None,
    intrinsics: Intrinsics | None = None,
    first_id: int = 1,
    ids: NDArray[np.integer] | None = None,
) -> list[SceneObject]:
    """One :class:`SceneObject` per label 1..n of ``labels`` with its attributes.

    Parameters
    ----------
    labels : ndarray of int32
        Label map the statistics were taken from (used for bounding boxes).
    stats : Stats
        From :func:`label_stats`.
    kinds : list of str, optional
        Kind per label (index 0 unused); ``object`` by default.
    depth_labels : ndarray of int, optional
        Depth label (band index) per label (index 0 unused); 0 by default.
    intrinsics : Intrinsics, optional
        When given, ``centroid_mm`` and ``area_mm2`` are filled.
    ids : ndarray of int, optional
        Object id per label (index 0 unused); the label itself by default.
    """
    n = stats.count.size - 1
    total = labels.size
    if stats.boxes is not None:
        b = stats.boxes
        boxes = [(slice(b[i, 1], b[i, 3] + 1), slice(b[i, 0], b[i, 2] + 1)) for i in range(1, n + 1)]
    else:
        boxes = ndimage.find_objects(labels, max_label=n)
    out: list[SceneObject] = []
    for i in range(1, n + 1):
        c = stats.count[i]
        box = boxes[i - 1]
        if c <= 0 or box is None:
            continue
        mean = stats.sz[i] / c
        var = max(stats.szz[i] / c - mean * mean, 0.0)
        centroid = None
        area_mm2 = None
        if intrinsics is not None and stats.sxz is not None and stats.syz is not None:
            fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
            centroid = (
                float((stats.sxz[i] - cx * stats.sz[i]) / fx / c),
                float((stats.syz[i] - cy * stats.sz[i]) / fy / c),
                float(mean),
            )
            area_mm2 = float(stats.szz[i] / (fx * fy))
        ys, xs = box
        out.append(
            SceneObject(
                id=int(ids[i]) if ids is not None else first_id + i - 1,
                kind=kinds[i] if kinds is not None else "object",
                label=int(depth_labels[i]) if depth_labels is not None else 0,
                depth=float(mean),
                depth_std=float(np.sqrt(var)),
                area=int(c),
                area_fraction=float(c / total),
                center=(float(stats.sx[i] / c), float(stats.sy[i] / c)),
                bbox=(int(xs.start), int(ys.start), int(xs.stop - 1), int(ys.stop - 1)),
                centroid_mm=centroid,
                area_mm2=area_mm2,
            )
        )
    return out
