"""Openings: the inside of a cup, bowl or open box joined to the object around it."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.segmentation._kernels import openings as kernels_openings

__all__ = ["merge_openings"]


def merge_openings(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    boxes: NDArray[np.int64],
    z_mean: NDArray[np.float64],
    *,
    focal_px: float,
    ring_px: int,
    jump_mm: NDArray[np.float32] | float,
    min_share: float = 0.3,
) -> NDArray[np.int32] | None:
    """Join the inside of a cup, bowl or open box to the object around it.

    Seen from above, the inside of a cup is a surface of its own: the near rim hides its lower
    part behind a depth step, and a structured-light camera loses the thin rim itself. It is
    recognised by how it borders the rest of the frame: a surface R is the inside of a nearer
    surface A when

    - at least ``min_share`` of R's border ring (``ring_px`` wide, valid pixels) lies on A,
      and A is nearer there (R is seen past A's edge);
    - little of the rest of the ring (at most 15 %) lies at R's depth: R borders other things
      only across depth steps (it occludes them or they occlude it), so it does not rest on
      or continue into anything but A;
    - R lies within A's columns, and no deeper behind A than A is wide (an opening is inside
      its object).

    An object standing behind A and narrower than it, no farther behind it than A is wide and
    visible only above it, would pass the same tests; the tabletop recordings show none.

    Parameters
    ----------
    labels : ndarray of int32, shape (H, W)
        Surfaces 1..n.
    depth_mm : ndarray of float32
        Depth (mm), 0 where invalid.
    boxes : ndarray of int, shape (n + 1, 4)
        Inclusive (x0, y0, x1, y1) of each label; row 0 unused.
    z_mean : ndarray of float, shape (n + 1,)
        Mean depth (mm) of each label.
    focal_px : float
        Focal length (px), for the metric width of A.
    ring_px : int
        Width (px) of the border ring read around R.
    jump_mm : float
        Depth difference (mm) beyond which a ring pixel is across a step from R.
    min_share : float
        Share of R's ring that must lie on A.

    Returns
    -------
    ndarray of int32 or None
        Lookup table old label -> new label (1..m), or None when nothing joins.
    """
    n = z_mean.size - 1
    if n < 2:
        return None
    jump = float(np.max(jump_mm)) if np.ndim(jump_mm) else float(jump_mm)
    table = kernels_openings.openings_table(
        labels,
        depth_mm,
        np.ascontiguousarray(boxes, np.int64),
        np.ascontiguousarray(z_mean, np.float64),
        float(focal_px),
        int(ring_px),
        jump,
        float(min_share),
    )
    return table if table.size else None
