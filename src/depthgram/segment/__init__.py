"""depthgram.segment: depth image to salient objects (paper, section 3).

- :func:`segment`: histogram thresholding, with slicing for oblique surfaces (default), or
  region growing; returns a :class:`Segmentation`.
- :func:`region_grow`: the region-growing reference of the paper's Table 1.
- :func:`evaluate`: agreement of a label map with ground-truth instances (IoU, coverage,
  precision, Hoover et al. 1996 counts).
"""

import sys
import types
from typing import Any

from depthgram.segment.config import METHODS, SegmentConfig
from depthgram.segment.core import segment
from depthgram.segment.evaluate import Evaluation, ObjectScore, evaluate
from depthgram.segment.objects import KINDS, Histogram, SceneObject, Segmentation
from depthgram.segment.region import region_grow

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


class _CallableModule(types.ModuleType):
    """This package, callable as :func:`segment`.

    ``depthgram.segment(depth_mm)`` is the public name users write, and ``depthgram.segment`` is
    also this package: once any code has imported it, the package attribute is the module, not
    the function, so the module itself forwards calls to the function.
    """

    def __call__(self, *args: Any, **kwargs: Any) -> Segmentation:
        return segment(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
