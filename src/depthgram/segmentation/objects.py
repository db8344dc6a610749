"""What segmentation produces: objects with their attributes, and the label map.

These are plain frozen dataclasses so that every later stage (grammar, tracker, actions,
sound, views) can take them without knowing how they were found.
"""

from __future__ import annotations

import builtins
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["KINDS", "Histogram", "SceneObject", "Segmentation", "new_object"]

#: Object kinds. ``object``: a segment facing the sensor; ``floor``, ``wall``, ``ceiling``:
#: oblique surfaces found by slicing; ``compound``: other runs of successive depth labels
#: joined into one super-object; ``part``: one slice segment of a compound object.
KINDS = ("object", "floor", "wall", "ceiling", "compound", "part")


@dataclass(frozen=True)
class SceneObject:
    """One salient object of a depth frame (a terminal ``o_<label>`` of the grammar).

    Attributes
    ----------
    id : int
        Object id, >= 1; the value of its pixels in :attr:`Segmentation.labels`.
    kind : str
        One of :data:`KINDS`.
    depth_label : int
        Depth label: index of the histogram band (peak) the object belongs to, from 0 nearest.
        For a compound object, the label of its nearest part.
    depth : float
        Mean depth (mm) over the object's valid pixels.
    depth_std : float
        Standard deviation of depth (mm) over those pixels.
    area : int
        Area in pixels (valid pixels only).
    area_fraction : float
        ``area`` as a fraction of the frame's pixel count.
    center_xy : tuple of float
        Image center (x, y) in pixels: the mean column and row.
    bbox_xy : tuple of int
        Bounding box (x0, y0, x1, y1) in pixels, half-open: columns ``x0 <= x < x1`` and rows
        ``y0 <= y < y1``, so ``labels[y0:y1, x0:x1]`` is the object's box and ``x1 - x0`` its
        width. :attr:`slice` gives the same box as a numpy index.
    centroid_mm : tuple of float or None
        3-D centroid (X, Y, Z) in mm in the camera frame, when intrinsics are known.
    area_mm2 : float or None
        Metric area (mm^2) of the surface seen, when intrinsics are known: each pixel counts
        ``(Z / fx) * (Z / fy)``.
    parts : tuple of SceneObject
        For compound objects, the slice segments it was joined from (kind ``part``), with
        successive depth labels; empty otherwise.
    """

    id: int
    kind: str
    depth_label: int
    depth: float
    depth_std: float
    area: int
    area_fraction: float
    center_xy: tuple[float, float]
    bbox_xy: tuple[int, int, int, int]
    centroid_mm: tuple[float, float, float] | None = None
    area_mm2: float | None = None
    parts: tuple[SceneObject, ...] = ()

    @property
    def slice(self) -> tuple[builtins.slice, builtins.slice]:
        """The bounding box as a numpy index ``(rows, columns)``, like scikit-image's ``regionprops.slice``.

        ``labels[o.slice] == o.id`` marks the object's pixels inside its box.
        """
        x0, y0, x1, y1 = self.bbox_xy
        return (slice(y0, y1), slice(x0, x1))


_new = object.__new__


def new_object(
    oid: int,
    kind: str,
    depth_label: int,
    depth: float,
    depth_std: float,
    area: int,
    area_fraction: float,
    center_xy: tuple[float, float],
    bbox_xy: tuple[int, int, int, int],
    centroid_mm: tuple[float, float, float] | None,
    area_mm2: float | None,
    parts: tuple[SceneObject, ...] = (),
) -> SceneObject:
    """Return ``SceneObject(oid, kind, ...)``, the same object, built at a third of the cost.

    A frozen dataclass's ``__init__`` sets each of the twelve fields through
    ``object.__setattr__``; the segmentation builds some forty objects a frame (objects, slice
    parts), where that was a visible share of a small frame. The fields go into the instance's
    dictionary in one step instead (no validation is skipped: the class has none).
    """
    o = _new(SceneObject)
    o.__dict__.update(
        id=oid,
        kind=kind,
        depth_label=depth_label,
        depth=depth,
        depth_std=depth_std,
        area=area,
        area_fraction=area_fraction,
        center_xy=center_xy,
        bbox_xy=bbox_xy,
        centroid_mm=centroid_mm,
        area_mm2=area_mm2,
        parts=parts,
    )
    return o


@dataclass(frozen=True, eq=False)
class Histogram:
    """The global depth histogram with its peaks and cuts, kept for plots and reports.

    Attributes
    ----------
    edges : ndarray of float, shape (B + 1,)
        Bin edges (mm).
    counts : ndarray of int, shape (B,)
        Pixel counts per bin.
    peaks : ndarray of float
        Depth (mm) of each peak, nearest first.
    cuts : ndarray of float
        Depth (mm) of each threshold: band ``k`` spans ``cuts[k-1] .. cuts[k]``.
    """

    edges: NDArray[np.float64]
    counts: NDArray[np.int64]
    peaks: NDArray[np.float64]
    cuts: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Segmentation:
    """Result of segmenting one frame.

    Attributes
    ----------
    labels : ndarray of int32, shape (H, W)
        Object id per pixel; 0 = background, too small, or invalid.
    objects : tuple of SceneObject
        The objects, in id order.
    histogram : Histogram or None
        The global histogram used, for plots.
    method : str
        Which method produced it (``threshold``, ``slices``, ``paper``, ``region``, ...).
    bands_mm : ndarray of float, shape (K, 2), or None
        Leading and trailing cut (mm) of each depth band, nearest first; ``depth_label`` ``k``
        spans ``bands_mm[k]``. None for methods without bands (``region``).
    classes : ndarray of int8, shape (H, W), or None
        Orientation class per pixel for the slicing methods that estimate it: 0 facing the
        sensor, 1 horizontal support (floor, table top), 2 vertical (wall); None otherwise.
    aperture_px : dict of str to int, or None
        Slice thickness (px) used by the ``paper`` method per direction (``"rows"``,
        ``"columns"``); None for the other methods.
    beyond_far_px : int
        Readings at or beyond the config's ``far_mm`` (+inf included), left out as invalid.
    """

    labels: NDArray[np.int32]
    objects: tuple[SceneObject, ...]
    histogram: Histogram | None = None
    method: str = "threshold"
    bands_mm: NDArray[np.float64] | None = None
    classes: NDArray[np.int8] | None = None
    aperture_px: dict[str, int] | None = None
    beyond_far_px: int = 0

    def by_id(self) -> dict[int, SceneObject]:
        """Objects keyed by id."""
        return {o.id: o for o in self.objects}
