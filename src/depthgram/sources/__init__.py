"""Depth sources: files, folders, globs, ``.npy``/``.npz`` stacks, ROS bags and the simulator.

Every source yields :class:`~depthgram.frame.Frame` objects one at a time (memory stays at
about one frame), all built by :func:`depthgram.frame.make_frame`::

    from depthgram.sources import open_source, read

    for frame in read("../shared/data/7scenes_redkitchen_seq"):
        ...
    src = open_source("TUM_depth.png", scale_mm=0.2)
    print(src.info())
"""

from depthgram.sources.base import Source, SourceInfo
from depthgram.sources.config import ENCODINGS, SourceConfig
from depthgram.sources.open import open_source, read
from depthgram.sources.sidecars import natural_key, read_timestamps

__all__ = [
    "ENCODINGS",
    "Source",
    "SourceConfig",
    "SourceInfo",
    "natural_key",
    "open_source",
    "read",
    "read_timestamps",
]
