"""Configuration of the range-flow tracker (paper, section 5)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from depthgram.errors import InputError

__all__ = ["TrackerConfig"]


def _check(ok: bool, what: str, value: object, expected: str) -> None:
    if not ok:
        raise InputError(f"TrackerConfig.{what}: expected {expected}, got {value!r}")


@dataclass(frozen=True)
class TrackerConfig:
    """How objects are followed across frames and how their radial velocity is read.

    Attributes
    ----------
    queue_length : int
        N, the number of most recent frames whose mean depths are kept per track and fitted
        for the radial velocity (frames, >= 2). The paper: two at least, three or more for
        robustness at the cost of latency.
    min_hits : int
        Detections after which a track is confirmed (frames). Tentative tracks die at their
        first miss, so a one-frame segmentation splinter never becomes an occluded track.
    max_missed : int
        Occlusion budget: frames a confirmed track survives without a detection.
    max_center_frac : float
        Gate on the distance between an object's center and the track's predicted center, as
        a fraction of the image diagonal (dimensionless, per frame missed it grows by
        ``gate_growth``).
    max_depth_change : float
        Gate on the relative change of mean depth, ``|z - z_track| / z_track`` per frame
        (dimensionless); grows linearly with the frames missed.
    max_area_ratio : float
        Gate on ``max(a / a_track, a_track / a)`` of the pixel areas (dimensionless, > 1).
        Generous by default because entering objects and splits change area fast.
    min_iou : float
        Gate on the overlap of the object's bbox with the track's predicted bbox (0..1);
        0 disables it.
    gate_growth : float
        Relative widening of the center gate per frame missed (dimensionless), so that an
        object can reappear a little away from its predicted place after an occlusion.
    w_center, w_depth, w_area, w_iou, w_label : float
        Weights of the cost terms (dimensionless, >= 0): center distance over its gate,
        depth change over its gate, ``|log area ratio|`` over ``log max_area_ratio``,
        ``1 - IoU``, and a depth-label mismatch (0 or 1).
    border_px : int
        An object whose bbox comes within this many pixels of the image border is at the
        border: ``entering`` when its area grows, ``leaving`` when it shrinks (px).
    border_area_change : float
        Relative change of the depth-compensated area ``A z^2`` between two frames above
        which an object at the border is entering or leaving (dimensionless). The
        compensation keeps an object that approaches at the border from reading as
        entering.
    max_area_jump : float
        A detection whose depth-compensated area differs from the track's running area by
        more than this factor is a split or merge by segmentation; its mean depth is biased
        and is kept out of the velocity fit (dimensionless, > 1).
    max_depth_jump : float
        A detection whose mean depth is further than this fraction of the predicted depth
        from the track's predicted path (per frame since the last detection) restarts the
        queue: the segment now covers another surface, and fitting across the jump would
        read it as a fast motion (dimensionless, > 0; ``inf`` disables).
    fit_border_entries : bool
        Whether mean depths of entering or leaving frames enter the velocity fit. Off by
        default: a partly visible object's mean depth is biased by what part is seen.
    min_speed : float
        Radial speed below which an object is still and has no time to collision (mm/s,
        used when timestamps are known).
    min_speed_per_frame : float
        The same threshold when no timestamps are known (mm/frame).
    """

    queue_length: int = 4
    min_hits: int = 3
    max_missed: int = 10
    max_center_frac: float = 0.1
    max_depth_change: float = 0.2
    max_area_ratio: float = 6.0
    min_iou: float = 0.0
    gate_growth: float = 0.25
    w_center: float = 1.0
    w_depth: float = 1.0
    w_area: float = 0.5
    w_iou: float = 1.0
    w_label: float = 0.2
    border_px: int = 2
    border_area_change: float = 0.05
    max_area_jump: float = 1.25
    max_depth_jump: float = 0.03
    fit_border_entries: bool = False
    min_speed: float = 50.0
    min_speed_per_frame: float = 2.0

    def __post_init__(self) -> None:
        for name in ("queue_length", "min_hits", "max_missed", "border_px"):
            v = getattr(self, name)
            _check(isinstance(v, int) and not isinstance(v, bool), name, v, "an integer")
        _check(self.queue_length >= 2, "queue_length", self.queue_length, "at least 2 frames")
        _check(self.queue_length <= 1000, "queue_length", self.queue_length, "at most 1000 frames")
        _check(self.min_hits >= 1, "min_hits", self.min_hits, "at least 1")
        _check(self.max_missed >= 0, "max_missed", self.max_missed, "0 or more frames")
        _check(self.border_px >= 0, "border_px", self.border_px, "0 or more pixels")
        floats = (
            "max_center_frac", "max_depth_change", "max_area_ratio", "min_iou", "gate_growth",
            "w_center", "w_depth", "w_area", "w_iou", "w_label", "border_area_change",
            "max_area_jump", "min_speed", "min_speed_per_frame",
        )  # fmt: skip
        for name in floats:
            v = getattr(self, name)
            ok = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) and v >= 0
            _check(ok, name, v, "a finite number >= 0")
        _check(0 < self.max_center_frac <= 2, "max_center_frac", self.max_center_frac, "in (0, 2]")
        _check(self.max_depth_change > 0, "max_depth_change", self.max_depth_change, "> 0")
        _check(self.max_area_ratio > 1, "max_area_ratio", self.max_area_ratio, "> 1")
        j = self.max_depth_jump
        ok = isinstance(j, int | float) and not isinstance(j, bool) and not math.isnan(j) and j > 0
        _check(ok, "max_depth_jump", j, "a number > 0 (inf disables)")
        _check(self.max_area_jump > 1, "max_area_jump", self.max_area_jump, "> 1")
        _check(self.min_iou <= 1, "min_iou", self.min_iou, "in [0, 1]")
        _check(isinstance(self.fit_border_entries, bool), "fit_border_entries", self.fit_border_entries, "a bool")
