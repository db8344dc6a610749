"""Connected-component labelling of depth images, with per-component statistics.

The modules, by responsibility:

- :mod:`~depthgram.segmentation.label.keyed`: the keyed labeller (4-neighbours join when their
  keys agree within a tolerance; holes of invalid pixels bridged), with or without statistics,
  and for the pixels of two classes in one pass;
  the pixel states :data:`HOLE`, :data:`ACTIVE`, :data:`BLOCK`.
- :mod:`~depthgram.segmentation.label.bands`: the run-based labeller of depth bands straight
  from the histogram bins.
- :mod:`~depthgram.segmentation.label.stats`: the per-label statistics table (its named
  columns) and the one-pass statistics of a label map.
- :mod:`~depthgram.segmentation.label.unionfind`: union-find and the second pass the
  labellers share.
- :mod:`~depthgram.segmentation.label.renumber`: ``lut[labels]`` in one pass.

The public names are re-exported here.
"""

from __future__ import annotations

from depthgram.segmentation.label.bands import label_bands_stats
from depthgram.segmentation.label.keyed import (
    ACTIVE,
    BLOCK,
    HOLE,
    label_keyed,
    label_keyed_planes,
    label_keyed_stats,
    label_two_classes,
)
from depthgram.segmentation.label.renumber import relabel
from depthgram.segmentation.label.stats import label_stats_fused

__all__ = [
    "ACTIVE",
    "BLOCK",
    "HOLE",
    "label_bands_stats",
    "label_keyed",
    "label_keyed_planes",
    "label_keyed_stats",
    "label_stats_fused",
    "label_two_classes",
    "relabel",
]
