"""Region growing, the paper's reference segmentation (Table 1).

Neighbouring valid pixels join while their depth difference stays under a tolerance (optionally
growing with depth, since sensor noise does). This is unseeded region growing done with one
union-find pass over the 4-neighbour graph (:func:`depthgram.segmentation.label.label_keyed_stats`), so the
comparison with thresholding measures the method, not an interpreter loop.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.attributes import Stats, make_objects
from depthgram.segmentation.config import SegmentConfig
from depthgram.segmentation.label import ACTIVE, HOLE, label_keyed_stats
from depthgram.segmentation.objects import Segmentation
from depthgram.segmentation.validate import check_depth

__all__ = ["region_grow"]


def region_grow(
    depth_mm: NDArray[np.floating],
    *,
    valid: NDArray[np.bool_] | None = None,
    intrinsics: Intrinsics | None = None,
    config: SegmentConfig | None = None,
    **overrides: Any,
) -> Segmentation:
    """Segment by region growing on depth continuity.

    Parameters
    ----------
    depth_mm : ndarray, shape (H, W)
        Depth (mm); 0 or NaN where invalid.
    valid : ndarray of bool, optional
        Pixels with a reading; finite and > 0 by default.
    intrinsics : Intrinsics, optional
        For metric centroids and areas.
    config : SegmentConfig, optional
        Its ``region_tol_mm`` (largest depth step between joined neighbours, mm; per metre of
        depth when ``region_relative``), ``min_area_px`` / ``min_area_fraction`` and
        ``fill_holes_px`` are used; defaults when omitted, so that the defaults live in one
        place.
    **overrides
        Fields of :class:`SegmentConfig` to change, e.g. ``region_tol_mm=30.0``.

    Returns
    -------
    Segmentation
        ``method="region"``; every region is an object of kind ``object`` with label 0 (region
        growing has no depth bands).
    """
    cfg = (config or SegmentConfig()).with_overrides(**overrides)
    depth, ok = check_depth(depth_mm, valid)
    state = np.where(ok, np.int8(ACTIVE), np.int8(HOLE))
    min_px = cfg.min_pixels(depth.size)
    tol_mm, relative, fill_holes_px = cfg.region_tol_mm, cfg.region_relative, cfg.fill_holes_px
    # one labelling pass gathers every region's sums; regions under min_px are dropped and the
    # rest renumbered in the same relabelling pass (no separate statistics passes)
    tol, rel = (0.0, tol_mm / 1000.0) if relative else (tol_mm, 0.0)
    labels, _, sums, boxes = label_keyed_stats(
        depth, state, depth, tol=tol, rel=rel, bridge=fill_holes_px, min_px=min_px
    )
    stats = Stats.from_sums(sums, boxes, metric=intrinsics is not None)
    objects = make_objects(labels, stats, intrinsics=intrinsics)
    return Segmentation(labels=labels, objects=tuple(objects), histogram=None, method="region")
