"""depthgram.segmentation: depth image to salient objects (paper, section 3).

- :func:`segment`: histogram thresholding, with slicing for oblique surfaces (default), or
  region growing; returns a :class:`Segmentation`.
- :func:`region_grow`: the region-growing reference of the paper's Table 1.
- :func:`estimate_sensor`: the depth camera's :class:`SensorModel` (step and noise) from one frame.
- :func:`warm_up`: load the compiled kernels only rare frames reach, before a real-time stream.
- :func:`evaluate`: agreement of a label map with ground-truth instances (IoU, coverage,
  precision, Hoover et al. 1996 counts).
"""

from depthgram.segmentation.config import METHODS, SegmentConfig
from depthgram.segmentation.core import segment, warm_up
from depthgram.segmentation.evaluate import Evaluation, ObjectScore, evaluate
from depthgram.segmentation.noise_model import SensorModel, estimate_sensor, sensor_model
from depthgram.segmentation.objects import KINDS, Histogram, SceneObject, Segmentation
from depthgram.segmentation.region import region_grow

__all__ = [
    "KINDS",
    "METHODS",
    "Evaluation",
    "Histogram",
    "ObjectScore",
    "SceneObject",
    "SegmentConfig",
    "Segmentation",
    "SensorModel",
    "estimate_sensor",
    "evaluate",
    "region_grow",
    "segment",
    "sensor_model",
    "warm_up",
]
