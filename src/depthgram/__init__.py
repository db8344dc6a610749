"""depthgram: depth-camera frames to a compact scene description.

The public API, loaded lazily so that ``import depthgram`` stays light:

- :func:`read` (from :mod:`depthgram.sources`): frames from any source, one at a time;
- :func:`segment` (from :mod:`depthgram.segmentation`, the stage's package): one depth image to objects and a label map;
- :func:`describe`: one depth image to its scene (objects, tree, sentence, plan);
- :class:`Pipeline` and :class:`Config` (from :mod:`depthgram.pipeline`): frame in, scene out;
- :class:`Frame`, :class:`Intrinsics` and :func:`make_frame` (from :mod:`depthgram.frame`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

__all__ = ["Config", "Frame", "Intrinsics", "Pipeline", "describe", "make_frame", "read", "segment"]

_LAZY = {
    "read": "depthgram.sources",
    "segment": "depthgram.segmentation",
    "Pipeline": "depthgram.pipeline",
    "Config": "depthgram.pipeline",
    "describe": "depthgram.pipeline",
    "Frame": "depthgram.frame",
    "Intrinsics": "depthgram.frame",
    "make_frame": "depthgram.frame",
}

if TYPE_CHECKING:
    from depthgram.frame import Frame, Intrinsics, make_frame
    from depthgram.pipeline import Config, Pipeline, describe
    from depthgram.segmentation import segment
    from depthgram.sources import read


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'depthgram' has no attribute {name!r}")
