"""Range flow (paper, section 5): objects tracked across frames, radial velocity, time to collision.

>>> from depthgram.dynamics import Tracker
>>> tracker = Tracker()
>>> pixels = FramePixels(frame.depth, segmentation.labels)  # optional: depth change from each core
>>> upd = tracker.update(segmentation.objects, frame.time_s, frame.size, pixels)  # doctest: +SKIP
>>> upd.motions[obj.id]  # doctest: +SKIP
Motion(track_id=1, v_radial=-410.2, ttc=1.9, status='visible', v_sigma=21.5, fps_assumed=None)
"""

from depthgram.dynamics.camera_motion import FramePixels, image_shift
from depthgram.dynamics.config import TrackerConfig
from depthgram.dynamics.core_depth import core_depth_change, warm_up
from depthgram.dynamics.evaluate import BodyScore, TrackingScore, evaluate_tracking
from depthgram.dynamics.flow import fit_radial_velocity, time_to_collision
from depthgram.dynamics.match import assign, bbox_iou, match_cost
from depthgram.dynamics.tracker import STATUSES, Track, Tracker, TrackUpdate

__all__ = [
    "STATUSES",
    "BodyScore",
    "FramePixels",
    "Track",
    "TrackUpdate",
    "Tracker",
    "TrackerConfig",
    "TrackingScore",
    "assign",
    "bbox_iou",
    "core_depth_change",
    "evaluate_tracking",
    "fit_radial_velocity",
    "image_shift",
    "match_cost",
    "time_to_collision",
    "warm_up",
]
