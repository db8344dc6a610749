"""The plane functions under their former module name (kept so that existing imports work).

The plane code lives in one module per concept: :mod:`depthgram.segmentation.ransac` (dominant
planes by RANSAC), :mod:`depthgram.segmentation.plane_sums` (least-squares planes of labelled
pieces) and :mod:`depthgram.segmentation.coplanar` (coplanar pieces joined, pixels near a plane).
"""

from __future__ import annotations

from depthgram.segmentation.coplanar import class_window, coplanar_groups, join_near, near_planes
from depthgram.segmentation.plane_sums import plane_sums, plane_sums_in_boxes, planes_from_sums, shares_beneath
from depthgram.segmentation.ransac import Plane, find_planes, plane_distance_mm, plane_normal, plane_residual_mask

__all__ = [
    "Plane",
    "class_window",
    "coplanar_groups",
    "find_planes",
    "join_near",
    "near_planes",
    "plane_distance_mm",
    "plane_normal",
    "plane_residual_mask",
    "plane_sums",
    "plane_sums_in_boxes",
    "planes_from_sums",
    "shares_beneath",
]
