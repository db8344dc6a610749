"""Configuration of the range-flow tracker (paper, section 5)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from depthgram.errors import InputError

__all__ = ["NOMINAL_FPS", "TrackerConfig"]

#: Frame rate assumed for frames without timestamps when no rate is configured (frames/s).
NOMINAL_FPS = 30.0


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
    max_occluded_s : float
        Longer budget of a confirmed track whose predicted box lies behind a nearer object
        (s): it survives without a detection while that lasts, up to this long, and gets its
        id back when the object comes out where and at the depth its prediction allows.
    fps : float or None
        Frame rate (frames/s) of frames that come without timestamps: frame k is at
        ``k / fps`` s. None: such frames are taken at :data:`NOMINAL_FPS` with a warning, and
        every Motion says which rate was assumed.
    max_center_rate : float
        Gate on the distance between an object's center and the track's predicted center, as
        a fraction of the image diagonal per second of the frame step (1/s; 3.0 is 0.1 of
        the diagonal at 30 frames/s); it grows by ``gate_growth`` per second missed.
    max_depth_rate : float
        Gate on the relative change of depth from the track's prediction,
        ``|z - z_pred| / z_pred``, per second since the track's last detection (1/s; 6.0 is
        0.2 per frame at 30 frames/s).
    max_area_ratio : float
        Gate on ``max(a / a_track, a_track / a)`` of the pixel areas (dimensionless, > 1).
        Generous by default because entering objects and splits change area fast.
    min_iou : float
        Gate on the overlap of the object's bbox with the track's predicted bbox (0..1);
        0 disables it.
    gate_growth : float
        Relative widening of the center gate per second missed (1/s; 7.5 is 25 % per frame
        at 30 frames/s), so that an object can reappear a little away from its predicted
        place after an occlusion.
    w_center, w_depth, w_area, w_iou, w_label : float
        Weights of the cost terms (dimensionless, >= 0): center distance over its gate,
        depth change over its gate, ``|log area ratio|`` over ``log max_area_ratio``,
        ``1 - IoU``, and a depth-label mismatch (0 or 1).
    border_px : int
        An object whose bbox comes within this many pixels of the image border is at the
        border: ``entering`` when its area grows, ``leaving`` when it shrinks (px).
    border_area_rate : float
        Relative change of the depth-compensated area ``A z^2`` per second above which an
        object at the border is entering or leaving (1/s; 1.5 is 5 % per frame at 30
        frames/s). The compensation keeps an object that approaches at the border from
        reading as entering.
    max_area_jump : float
        A detection whose depth-compensated area differs from the track's running area by
        more than this factor is a split or merge by segmentation; its mean depth is biased
        and is kept out of the velocity fit (dimensionless, > 1).
    max_depth_jump_rate : float
        A detection whose depth is further from the track's predicted path than this
        fraction of the predicted depth per second since the last detection restarts the
        queue: the segment now covers another surface, and fitting across the jump would
        read it as a fast motion (1/s, > 0; 0.9 is 3 % per frame at 30 frames/s; ``inf``
        disables). Only tracks that already have a velocity are tested: a new track's
        prediction is "standing still", which a fast approach leaves on every frame.
    fit_border_entries : bool
        Whether mean depths of entering or leaving frames enter the velocity fit. Off by
        default: a partly visible object's mean depth is biased by what part is seen.
    min_speed : float
        Radial speed below which an object is still and has no time to collision (mm/s).
    center_tau_s : float
        Time constant of the smoothing of each track's image velocity (s; 0.048 s weighs a
        new reading by 0.5 at 30 frames/s).
    area_tau_s : float
        Time constant of the running depth-compensated area against which splits and merges
        are judged (s; 0.094 s weighs a new reading by 0.3 at 30 frames/s).
    estimator : str
        How the radial velocity is read: ``kalman``, a constant-velocity Kalman filter on depth
        and radial velocity with an innovation gate, or ``queue``, the paper's slope over the
        last ``queue_length`` depths. Both report ``v_sigma``. The filter is the default: as
        accurate as the queue on 7-Scenes' posed truth and the simulator's scenes, with a
        ``v_sigma`` that holds the real error (and so gates the time to collision) where the
        slope's standard error understates it; ``benchmarks/bench_tracking.py --estimator``.
    depth_sigma_mm : float
        Sensor noise of an object's depth reading at 1 m (mm); it grows with the square of
        the depth (ToF and structured light). A sensor estimate can set it.
    depth_sigma_floor_mm : float
        Depth noise that does not shrink with nearness (mm), added to the above.
    accel_sigma : float
        Standard deviation of the unmodelled radial acceleration of a tracked object
        (mm/s^2), the filter's process noise: how fast it follows a change of speed.
    own_accel_sigma : float
        The same for an object's own radial acceleration where the camera's motion is known
        (``image_motion = "camera"``; mm/s^2): the camera's part of the velocity is then read
        afresh each frame and only the object's own part is filtered, so it can be slower
        than ``accel_sigma``: a person starting or stopping a walk accelerates at 1-2 m/s^2.
        Where the readings stop fitting it, the filter's noise grows up to ``accel_sigma``.
        The own part counts once it is three of its sigmas from standing still and two readings
        agree on it (``v_sigma`` covers it until then). Measured
        (``benchmarks/bench_tracking.py``): 7-Scenes within 25 % + 30 mm/s 0.846, 0.849, 0.849
        at 1000, 2000, 3000; the simulator's ``crossing`` (a still camera, but an ICP that
        slides along the floor with the person) 1.000 at each.
    innovation_gate : float
        A depth reading further from the filter's prediction than this many standard
        deviations is an outlier and is not followed (dimensionless); three outliers in a row
        restart the filter there (the object did change).
    ttc_min_sigmas : float
        A time to collision (and the warnings built on it) is given only when the closing
        speed is at least this many ``v_sigma`` (dimensionless): otherwise the velocity is
        not known well enough and ttc is None.
    depth_from : str
        Where each object's depth change between frames (mm) is read: ``core``, over the
        object's core, the pixels in it now that, moved back by the image motion, were in the
        same track's segment in the previous frame, so pixels entering or leaving its outline
        do not move it (:mod:`depthgram.dynamics.core_depth`; compare on 7-Scenes' posed truth with
        ``benchmarks/bench_tracking.py --depth core|mean``); or ``mean``, the change of the
        object's mean depth alone, as the paper. ``core`` needs each frame's depth and label
        map and costs about 5 ms per 640x480 frame, more with ``image_motion = "camera"``
        (``benchmarks/bench_tracking.py``); ``mean`` needs neither (the pipeline then does not
        hand them over), for small computers.
    image_motion : str
        How the core's pixels are moved back to the previous frame (with ``depth_from =
        "core"``): ``camera``, each pixel by the image motion of its still point under the
        camera's own motion, found by ICP on the two frames' depth
        (:class:`depthgram.dynamics.camera_motion.EgoMotion`; needs the frame's intrinsics, else it
        falls back to ``shift``), or ``shift``, one shift for the whole frame by phase
        correlation (:func:`depthgram.dynamics.camera_motion.image_shift`). Either way each tracked
        object's own image motion is tried beside it. Compare with
        ``benchmarks/bench_tracking.py --image-motion camera|shift``.
    """

    queue_length: int = 4
    min_hits: int = 3
    max_missed: int = 10
    max_occluded_s: float = 1.0
    fps: float | None = None
    max_center_rate: float = 3.0
    max_depth_rate: float = 6.0
    max_area_ratio: float = 6.0
    min_iou: float = 0.0
    gate_growth: float = 7.5
    w_center: float = 1.0
    w_depth: float = 1.0
    w_area: float = 0.5
    w_iou: float = 1.0
    w_label: float = 0.2
    border_px: int = 2
    border_area_rate: float = 1.5
    max_area_jump: float = 1.25
    max_depth_jump_rate: float = 0.9
    fit_border_entries: bool = False
    min_speed: float = 50.0
    center_tau_s: float = 0.048
    area_tau_s: float = 0.094
    estimator: str = "kalman"
    depth_sigma_mm: float = 1.0
    depth_sigma_floor_mm: float = 0.5
    accel_sigma: float = 3000.0
    own_accel_sigma: float = 2000.0
    innovation_gate: float = 4.0
    ttc_min_sigmas: float = 1.5
    depth_from: str = "core"
    image_motion: str = "camera"

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
            "max_occluded_s", "max_center_rate", "max_depth_rate", "max_area_ratio", "min_iou", "gate_growth",
            "w_center", "w_depth", "w_area", "w_iou", "w_label", "border_area_rate",
            "max_area_jump", "min_speed", "center_tau_s", "area_tau_s", "depth_sigma_mm",
            "depth_sigma_floor_mm", "accel_sigma", "own_accel_sigma", "innovation_gate", "ttc_min_sigmas",
        )  # fmt: skip
        for name in floats:
            v = getattr(self, name)
            ok = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) and v >= 0
            _check(ok, name, v, "a finite number >= 0")
        _check(self.max_center_rate > 0, "max_center_rate", self.max_center_rate, "> 0 (1/s)")
        _check(self.max_depth_rate > 0, "max_depth_rate", self.max_depth_rate, "> 0 (1/s)")
        _check(self.center_tau_s > 0, "center_tau_s", self.center_tau_s, "> 0 s")
        _check(self.estimator in ("kalman", "queue"), "estimator", self.estimator, "'kalman' or 'queue'")
        _check(self.depth_from in ("core", "mean"), "depth_from", self.depth_from, "'core' or 'mean'")
        _check(self.image_motion in ("camera", "shift"), "image_motion", self.image_motion, "'camera' or 'shift'")
        _check(self.innovation_gate > 0, "innovation_gate", self.innovation_gate, "> 0")
        _check(
            self.depth_sigma_mm + self.depth_sigma_floor_mm > 0,
            "depth_sigma_mm",
            self.depth_sigma_mm,
            "a positive noise (with depth_sigma_floor_mm)",
        )
        _check(self.area_tau_s > 0, "area_tau_s", self.area_tau_s, "> 0 s")
        f = self.fps
        ok = f is None or (
            isinstance(f, int | float) and not isinstance(f, bool) and math.isfinite(f) and 0 < f <= 100_000
        )
        _check(ok, "fps", f, "None or a frame rate in (0, 100000] frames/s")
        _check(self.max_area_ratio > 1, "max_area_ratio", self.max_area_ratio, "> 1")
        j = self.max_depth_jump_rate
        ok = isinstance(j, int | float) and not isinstance(j, bool) and not math.isnan(j) and j > 0
        _check(ok, "max_depth_jump_rate", j, "a number > 0 (1/s; inf disables)")
        _check(self.max_area_jump > 1, "max_area_jump", self.max_area_jump, "> 1")
        _check(self.min_iou <= 1, "min_iou", self.min_iou, "in [0, 1]")
        _check(isinstance(self.fit_border_entries, bool), "fit_border_entries", self.fit_border_entries, "a bool")
