"""An object's foot: the readings where it meets the support it stands on, given back to it.

The orientation field (:mod:`depthgram.segmentation.orientation`) takes each reading's slope over
a window; at the concave corner where a box or a mug stands on a table, the windows of the
object's lowest readings reach over the corner onto the table and read its slope, so a band of
the object's face as wide as the window's reach is classed horizontal and joins the table. On
a tabletop seen at an angle that band is a few percent of every object's area.

Which side of the corner a reading of that band lies on is a question of two surfaces, not of
slopes: the reading belongs to the object when it stands above the support's plane by more than
the sensor's noise and the object's own surface, continued to it, explains its depth better than
the support's plane does. Both are fitted in inverse depth over pixel coordinates (``1/Z = a u +
b v + c`` holds for any plane whatever the intrinsics): the support's plane over its readings
around the object (a real table bends by a few millimetres over its width), the object's surface
per short run of its outline, over its readings within the reach of that run. Where the two surfaces meet (the contact
line) both explain a reading equally well, so the band is cut there, whichever way the camera's
correlation window has smoothed the corner.

The readings are grown from the object's outline through the support's readings, no further
than the orientation window's reach; a reading that fails stops the growth through it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.segmentation._kernels.feet import feet
from depthgram.segmentation.noise_model import SensorModel

__all__ = ["feet_reach", "give_feet"]

#: sensor sigmas (plus one quantisation step) a foot's reading stands above the support's plane
K_SIGMA = 3.0


def feet_reach(normal_window_px: int) -> int:
    """Return how far (px) from an object its foot may lie: the orientation field's reach.

    The field averages slopes over a window of ``normal_window_px`` taken as differences over
    half of it, from a 3 x 3 mean (:func:`depthgram.segmentation.orientation.orientation_classes`).
    """
    half = normal_window_px // 2
    return half + max(1, half) + 1


def give_feet(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    supports: list[int],
    n_objects: int,
    sensor: SensorModel,
    sums: NDArray[np.float64],
    boxes: NDArray[np.int64],
    *,
    reach: int,
    min_px: int,
) -> int:
    """Give each object the readings of its foot that a support holds (in place).

    Parameters
    ----------
    labels : ndarray of int32, shape (H, W)
        Objects ``1..n_objects``, then the supports.
    depth : ndarray of float32, shape (H, W)
        Depth (mm).
    ok : ndarray of bool, shape (H, W)
        Readings.
    supports : list of int
        Ids of the supports whose readings may be given (horizontal ones: a table top).
    n_objects : int
        Ids ``1..n_objects`` are objects that may stand on them.
    sensor : SensorModel
        The frame's noise and quantisation step (mm).
    sums, boxes : ndarray
        The statistics table's sums (:mod:`depthgram.segmentation.label.stats`) and inclusive
        boxes per id, updated with the readings moved.
    reach : int
        Farthest a foot's reading lies from its object (px), :func:`feet_reach`.
    min_px : int
        Smallest object read (px).

    Returns
    -------
    moved : int
        Readings given to objects.
    """
    if not supports or n_objects < 1:
        return 0
    noise = (sensor.sigma_0, sensor.sigma_2, sensor.step_0, sensor.step_2, K_SIGMA)
    ids = np.asarray(supports, np.int32)
    moved = feet(labels, depth, ok, ids, n_objects, float(min_px), reach, reach, noise, sums, boxes)
    return int(moved)
