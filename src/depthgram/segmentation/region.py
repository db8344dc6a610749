"""Region growing, the paper's reference segmentation (Table 1).

Neighbouring valid pixels join while their depth difference stays under a tolerance (optionally
growing with depth, since sensor noise does). This is unseeded region growing done with one
union-find pass over the 4-neighbour graph (:func:`depthgram.segmentation.label.label_keyed_stats`), so the
comparison with thresholding measures the method, not an interpreter loop.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.attributes import Stats, make_objects
from depthgram.segmentation.label import ACTIVE, HOLE, label_keyed_stats
from depthgram.segmentation.objects import Segmentation
from depthgram.segmentation.validate import check_depth

__all__ = ["region_grow"]


def region_grow(
    depth_mm: NDArray[np.floating],
    *,
    valid: NDArray[np.bool_] | None = None,
    tol_mm: float = 20.0,
    relative: bool = True,
    min_area: float = 0.005,
    fill_holes_px: int = 2,
    intrinsics: Intrinsics | None = None,
) -> Segmentation:
    """Segment by region growing on depth continuity.

    Parameters
    ----------
    depth_mm : ndarray, shape (H, W)
        Depth (mm); 0 or NaN where invalid.
    valid : ndarray of bool, optional
        Pixels with a reading; finite and > 0 by default.
    tol_mm : float
        Largest depth step (mm) between joined neighbours; per metre of depth when ``relative``.
    relative : bool
        Scale the tolerance with depth (``tol_mm * Z / 1000``).
    min_area : float
        Smallest region kept: pixels when >= 1, fraction of the frame when < 1.
    fill_holes_px : int
        Longest run of invalid pixels (px) bridged along a row or a column.
    intrinsics : Intrinsics, optional
        For metric centroids and areas.

    Returns
    -------
    Segmentation
        ``method="region"``; every region is an object of kind ``object`` with label 0 (region
        growing has no depth bands).
    """
    depth, ok = check_depth(depth_mm, valid)
    state = np.where(ok, np.int8(ACTIVE), np.int8(HOLE))
    min_px = int(np.ceil(min_area)) if min_area >= 1 else max(1, int(np.ceil(min_area * depth.size)))
    # one labelling pass gathers every region's sums; regions under min_px are dropped and the
    # rest renumbered in the same relabelling pass (no separate statistics passes)
    tol, rel = (0.0, tol_mm / 1000.0) if relative else (tol_mm, 0.0)
    labels, _, sums, boxes = label_keyed_stats(
        depth, state, depth, tol=tol, rel=rel, bridge=fill_holes_px, min_px=min_px
    )
    stats = Stats.from_sums(sums, boxes, metric=intrinsics is not None)
    objects = make_objects(labels, stats, intrinsics=intrinsics)
    return Segmentation(labels=labels, objects=tuple(objects), histogram=None, method="region")
