"""Slicing for oblique surfaces: floor, ceiling, table tops and walls as compound objects.

The paper cuts the image into slices perpendicular to an oblique surface's running direction:
inside a thin slice the surface has one depth, and successive slices give successive depth
labels, joined into one super-object. Here the surface's running direction is read from the
local orientation (:mod:`depthgram.segment.orientation`): horizontal surfaces are cut into
horizontal slices (rows), walls into vertical slices (columns). Pixels of one orientation class
join while depth stays continuous between neighbours, which is exactly "runs of slice segments
with successive depth labels"; each slice of such a run is a ``part``. Objects standing on a
support keep their own (facing) class, so they come out separate from it even where their base
touches it at the same depth.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segment.attributes import label_stats, make_objects
from depthgram.segment.label import ACTIVE, BLOCK, HOLE, label_keyed
from depthgram.segment.objects import SceneObject
from depthgram.segment.orientation import HORIZONTAL, VERTICAL

__all__ = ["slice_parts", "support_components"]


def support_components(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    *,
    jump_rel: float,
    bridge: int,
) -> tuple[NDArray[np.int32], int]:
    """Depth-continuous components of the pixels of one orientation class."""
    state = np.where(valid, np.int8(BLOCK), np.int8(HOLE))
    state[classes == cls] = ACTIVE
    return label_keyed(depth_mm, state, tol=0.0, rel=jump_rel, bridge=bridge)


def slice_parts(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    obj: SceneObject,
    *,
    horizontal: bool,
    aperture: float,
    depth_label: object,
    intrinsics: Intrinsics | None,
    first_id: int,
) -> tuple[SceneObject, ...]:
    """The slice segments of one compound object, nearest first, as ``part`` objects.

    Parameters
    ----------
    labels : ndarray of int32
        Label map holding ``obj.id``.
    horizontal : bool
        Horizontal slices (rows; floor, ceiling, table tops) or vertical slices (columns; walls).
    aperture : float
        Slice thickness: px when >= 1, else fraction of the object's extent across the slices.
    depth_label : callable
        Depth (mm) -> global depth label.
    first_id : int
        Id of the first part (parts are not in the label map; ids only name them).
    """
    x0, y0, x1, y1 = obj.bbox
    sub = labels[y0 : y1 + 1, x0 : x1 + 1] == obj.id
    extent = (y1 - y0 + 1) if horizontal else (x1 - x0 + 1)
    step = int(aperture) if aperture >= 1 else max(1, math.ceil(aperture * extent))
    n_slices = (extent + step - 1) // step
    hh, ww = sub.shape
    idx = (np.arange(hh) // step)[:, None] if horizontal else (np.arange(ww) // step)[None, :]
    part_map = np.where(sub, np.broadcast_to(idx + 1, sub.shape), 0).astype(np.int32)
    z = np.ascontiguousarray(depth_mm[y0 : y1 + 1, x0 : x1 + 1])
    stats = label_stats(part_map, z, n_slices, metric=intrinsics is not None)
    shifted = None
    if intrinsics is not None:
        shifted = Intrinsics(intrinsics.fx, intrinsics.fy, intrinsics.cx - x0, intrinsics.cy - y0)
    parts = make_objects(part_map, stats, intrinsics=shifted)
    parts.sort(key=lambda p: p.depth)
    fn = depth_label  # callable, typed loosely to keep this module free of Bands
    out = []
    for j, p in enumerate(parts):
        cx, cy = p.center
        bx0, by0, bx1, by1 = p.bbox
        out.append(
            SceneObject(
                id=first_id + j,
                kind="part",
                label=int(fn(p.depth)),  # type: ignore[operator]
                depth=p.depth,
                depth_std=p.depth_std,
                area=p.area,
                area_fraction=p.area / labels.size,
                center=(cx + x0, cy + y0),
                bbox=(bx0 + x0, by0 + y0, bx1 + x0, by1 + y0),
                centroid_mm=p.centroid_mm,
                area_mm2=p.area_mm2,
            )
        )
    return tuple(out)


def support_kind(cls: int, centroid_y_mm: float, is_lowest: bool) -> str:
    """Kind of a support component: ``wall``; ``floor`` (lowest horizontal below the camera);
    ``ceiling`` (horizontal above it); ``compound`` (other horizontal supports: table tops)."""
    if cls == VERTICAL:
        return "wall"
    if cls == HORIZONTAL and centroid_y_mm < 0:
        return "ceiling"
    return "floor" if is_lowest else "compound"
