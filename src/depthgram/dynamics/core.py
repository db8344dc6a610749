"""The camera's motion and each object's core depth change under their former module name.

The code lives in :mod:`depthgram.dynamics.camera_motion` (the camera's own motion by ICP, the
image shift by phase correlation) and :mod:`depthgram.dynamics.core_depth` (each object's depth
change from its core pixels, and the change it would show standing still); this module keeps
existing imports working.
"""

from __future__ import annotations

from depthgram.dynamics.camera_motion import (
    CameraMotion,
    EgoMotion,
    FramePixels,
    image_shift,
    shift_structure,
    structure_shift,
)
from depthgram.dynamics.core_depth import core_depth_change, inner_edge_shift, still_depth_change
from depthgram.dynamics.core_depth import warm_up as load_rare_kernels

__all__ = [
    "CameraMotion",
    "EgoMotion",
    "FramePixels",
    "core_depth_change",
    "image_shift",
    "inner_edge_shift",
    "load_rare_kernels",
    "shift_structure",
    "still_depth_change",
    "structure_shift",
]
