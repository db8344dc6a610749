"""Range flow (paper, section 5): objects tracked across frames, radial velocity, time to collision.

>>> from depthgram.dynamics import Tracker
>>> tracker = Tracker()
>>> upd = tracker.update(segmentation.objects, frame.time_s, frame.size)  # doctest: +SKIP
>>> upd.motions[obj.id]  # doctest: +SKIP
Motion(track_id=1, v_radial=-410.2, ttc=1.9, status='visible', v_sigma=21.5, fps_assumed=None)
"""

from depthgram.dynamics.config import TrackerConfig
from depthgram.dynamics.evaluate import BodyScore, TrackingScore, evaluate_tracking
from depthgram.dynamics.flow import fit_radial_velocity, time_to_collision
from depthgram.dynamics.match import assign, bbox_iou, match_cost
from depthgram.dynamics.tracker import STATUSES, Track, Tracker, TrackUpdate

__all__ = [
    "STATUSES",
    "BodyScore",
    "Track",
    "TrackUpdate",
    "Tracker",
    "TrackerConfig",
    "TrackingScore",
    "assign",
    "bbox_iou",
    "evaluate_tracking",
    "fit_radial_velocity",
    "match_cost",
    "time_to_collision",
]
