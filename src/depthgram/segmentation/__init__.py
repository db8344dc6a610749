"""depthgram.segmentation: depth image to salient objects (paper, section 3).

- :func:`segment`: histogram thresholding, with slicing for oblique surfaces (default), or
  region growing; returns a :class:`Segmentation`.
- :func:`region_grow`: the region-growing reference of the paper's Table 1.
- :func:`evaluate`: agreement of a label map with ground-truth instances (IoU, coverage,
  precision, Hoover et al. 1996 counts).
"""

from depthgram.segmentation.config import METHODS, SegmentConfig
from depthgram.segmentation.core import segment
from depthgram.segmentation.evaluate import Evaluation, ObjectScore, evaluate
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
    "evaluate",
    "region_grow",
    "segment",
]
