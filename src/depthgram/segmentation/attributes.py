"""Object attributes from a label map: area, center, mean and spread of depth, bbox, metric size.

All statistics (count, sum Z, sum Z², sum x, sum y, sum xZ, sum yZ, bounding box: the table of
:mod:`depthgram.segmentation.label.stats`) come from the labellers or from one compiled raster
pass over the label map, whatever the object count; :class:`Stats` holds its columns by name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy import ndimage

from depthgram.frame import Intrinsics
from depthgram.segmentation.label import label_stats_fused, relabel
from depthgram.segmentation.label.stats import COUNT, KEY, SUM_X, SUM_XZ, SUM_Y, SUM_YZ, SUM_Z, SUM_ZZ
from depthgram.segmentation.objects import SceneObject, new_object

__all__ = [
    "ObjectSpec",
    "Stats",
    "attribute_rows",
    "fused_stats",
    "label_stats",
    "make_objects",
    "objects_from_rows",
]


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

    @classmethod
    def from_sums(cls, sums: NDArray[np.float64], boxes: NDArray[Any] | None, *, metric: bool) -> Stats:
        """Build from the statistics table of :mod:`depthgram.segmentation.label.stats`.

        The table has one row per label; the two metric sums are kept only when ``metric``
        (intrinsics known).
        """
        return cls(
            sums[:, COUNT], sums[:, SUM_Z], sums[:, SUM_ZZ], sums[:, SUM_X], sums[:, SUM_Y],
            sums[:, SUM_XZ] if metric else None, sums[:, SUM_YZ] if metric else None, boxes,
        )  # fmt: skip


def label_stats(labels: NDArray[np.int32], depth_mm: NDArray[np.floating], n: int, *, metric: bool = False) -> Stats:
    """Return sums and boxes per label over the pixels with a label > 0, in one compiled pass.

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
    return Stats.from_sums(sums, boxes, metric=metric)


def fused_stats(
    labels: NDArray[np.int32], n: int, depth_mm: NDArray[np.float32], key: NDArray[Any], min_px: int
) -> tuple[NDArray[np.int32], Stats, NDArray[np.float64]]:
    """Drop labels under ``min_px`` pixels, renumber, and return their sums, boxes and keys."""
    sums, boxes = label_stats_fused(labels, n, depth_mm, key)
    keep = sums[:, COUNT] >= min_px
    keep[0] = False
    lut = np.zeros(n + 1, dtype=np.int32)
    lut[keep] = np.arange(1, int(keep.sum()) + 1, dtype=np.int32)
    sel = np.concatenate(([0], np.flatnonzero(keep)))
    s = sums[sel]
    stats = Stats.from_sums(s, boxes[sel], metric=True)
    out = relabel(labels, lut) if n else labels
    return out, stats, s[:, KEY]


@njit(cache=True, nogil=True)
def attribute_table(
    count: NDArray[np.float64],
    sz: NDArray[np.float64],
    szz: NDArray[np.float64],
    sx: NDArray[np.float64],
    sy: NDArray[np.float64],
    sxz: NDArray[np.float64],
    syz: NDArray[np.float64],
    fx: float,
    fy: float,
    cx: float,
    cy: float,
) -> NDArray[np.float64]:
    """Return per label 1..n: count, mean depth, depth std, center x, y, centroid X, Y (mm), area (mm²).

    The sums are those of :class:`Stats` (index 0 unused); compiled, for the callers that
    build the table inside compiled code (the slice parts of compound objects).
    """
    n = count.size - 1
    out = np.empty((max(n, 0), 8), np.float64)
    for i in range(1, n + 1):
        safe = max(count[i], 1.0)
        mean = sz[i] / safe
        row = out[i - 1]
        row[0] = count[i]
        row[1] = mean
        row[2] = math.sqrt(max(szz[i] / safe - mean * mean, 0.0))
        row[3] = sx[i] / safe
        row[4] = sy[i] / safe
        row[5] = (sxz[i] - cx * sz[i]) / fx / safe
        row[6] = (syz[i] - cy * sz[i]) / fy / safe
        row[7] = szz[i] / (fx * fy)
    return out


def attribute_rows(sums: NDArray[np.float64], intrinsics: Intrinsics) -> NDArray[np.float64]:
    """Return the attributes :func:`make_objects` gives each label of a statistics table.

    ``sums`` has the columns of :mod:`depthgram.segmentation.label.stats` (the first
    :data:`~depthgram.segmentation.label.stats.N_SUMS` at least), row 0 unused. Row ``i - 1``
    of the result is label ``i``'s pixel count, mean depth and its standard deviation (mm),
    center x and y (px), centroid X and Y (mm) and metric area (mm²), the same numbers
    make_objects puts in its objects (0 pixels: no object).
    """
    return _table_attributes(sums, intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy)


@njit(cache=True, nogil=True)
def _table_attributes(sums: NDArray[np.float64], fx: float, fy: float, cx: float, cy: float) -> NDArray[np.float64]:
    # attribute_table of the table's columns: one array to pass instead of seven
    return attribute_table(
        sums[:, COUNT], sums[:, SUM_Z], sums[:, SUM_ZZ], sums[:, SUM_X], sums[:, SUM_Y],
        sums[:, SUM_XZ], sums[:, SUM_YZ], fx, fy, cx, cy,
    )  # fmt: skip


class ObjectSpec(NamedTuple):
    """What an object is before its pixel attributes are measured: id, kind, depth label, parts."""

    id: int
    kind: str
    depth_label: int
    parts: tuple[SceneObject, ...]


def objects_from_rows(
    specs: list[ObjectSpec], rows: list[list[float]], boxes: list[list[int]], total: int, *, metric: bool
) -> list[SceneObject]:
    """Return the objects of ``specs``, their attributes from a table of :func:`attribute_rows`.

    Object ``i`` takes row ``i - 1`` of ``rows`` (as lists, ``.tolist()``) and the inclusive
    box ``boxes[i]``; ``total`` is the frame's pixel count, ``metric`` keeps the centroid and
    metric area. The same objects as :func:`make_objects` builds from the same sums.
    """
    out = []
    for oid, kind, label, parts in specs:
        c, mean, std, cx, cy, gx, gy, amm = rows[oid - 1]
        x0, y0, x1, y1 = boxes[oid]
        out.append(
            new_object(
                oid,
                kind,
                label,
                mean,
                std,
                int(c),
                c / total,
                (cx, cy),
                (x0, y0, x1 + 1, y1 + 1),
                (gx, gy, mean) if metric else None,
                amm if metric else None,
                parts,
            )
        )
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
    if n <= 0:
        return []
    metric = intrinsics is not None and stats.sxz is not None and stats.syz is not None
    cam = (1.0, 1.0, 0.0, 0.0)
    if intrinsics is not None:
        cam = (intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy)
    # every attribute of every label in one compiled call, turned into Python numbers by one
    # .tolist(): per-column numpy calls and per-object numpy scalars cost more than the
    # statistics pass on small frames
    sxz = stats.sxz if metric and stats.sxz is not None else stats.sz
    syz = stats.syz if metric and stats.syz is not None else stats.sz
    table = attribute_table(
        stats.count, stats.sz, stats.szz, stats.sx, stats.sy, sxz, syz, *cam,
    ).tolist()  # fmt: skip
    if stats.boxes is not None:
        # the kernels keep inclusive boxes (last column and row); objects carry half-open ones
        x0, y0, x1, y1 = (stats.boxes[1:] + np.array([0, 0, 1, 1])).T.tolist()
        present = [row[0] > 0 for row in table]
    else:
        found = ndimage.find_objects(labels, max_label=n)
        present = [(row[0] > 0 and f is not None) for row, f in zip(table, found, strict=True)]
        x0 = [f[1].start if f is not None else 0 for f in found]
        y0 = [f[0].start if f is not None else 0 for f in found]
        x1 = [f[1].stop if f is not None else 0 for f in found]
        y1 = [f[0].stop if f is not None else 0 for f in found]
    id_l = ids[1:].tolist() if ids is not None else list(range(first_id, first_id + n))
    lab_l = depth_labels[1:].tolist() if depth_labels is not None else [0] * n
    out: list[SceneObject] = []
    for j in range(n):
        if not present[j]:
            continue
        c, mean, std, cx, cy, gx, gy, amm = table[j]
        out.append(
            new_object(
                int(id_l[j]),
                kinds[j + 1] if kinds is not None else "object",
                int(lab_l[j]),
                mean,
                std,
                int(c),
                c / total,
                (cx, cy),
                (int(x0[j]), int(y0[j]), int(x1[j]), int(y1[j])),
                (gx, gy, mean) if metric else None,
                amm if metric else None,
            )
        )
    return out
