"""Tracking quality against simulated ground truth: velocity error, identity switches, losses.

Each truth body is followed through its *primary* segment: the segmented object holding
most of its visible pixels. Scores only count bodies of kind ``object`` (hands, people,
carts), whose motion matters; walls and floors are split and re-joined by whatever passes in
front of them, so their fragments' identities say little about the tracker.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from depthgram.dynamics.camera_motion import FramePixels
from depthgram.dynamics.config import TrackerConfig
from depthgram.dynamics.tracker import Tracker
from depthgram.segmentation.objects import SceneObject

__all__ = [
    "BodyScore",
    "TrackingScore",
    "evaluate_tracking",
    "objects_from_labels",
    "primary_segments",
    "radial_velocity_from_poses",
]


@dataclass(frozen=True)
class BodyScore:
    """How one truth body was tracked.

    Attributes
    ----------
    name : str
        Truth body name.
    visible_frames : int
        Frames where the body shows at least ``min_area`` valid pixels.
    tracked_frames : int
        Of those, frames where a segment made mostly of it (its primary segment) carried a
        track id.
    track_ids : tuple of int
        The primary segment's track ids, in order of first appearance.
    id_switches : int
        Changes of the primary track id between successive tracked frames (also across a
        gap where the body was hidden).
    v_errors : tuple of float
        ``v_radial - truth`` (mm/s) over frames where the track had at least ``settle``
        earlier valid frames and reported a velocity while the body was fully visible.
    v_truth : tuple of float
        The true radial velocities (mm/s) at those frames.
    id_by_frame : tuple of (int, int)
        (frame index, primary track id) for every tracked frame.
    """

    name: str
    visible_frames: int
    tracked_frames: int
    track_ids: tuple[int, ...]
    id_switches: int
    v_errors: tuple[float, ...]
    v_truth: tuple[float, ...]
    id_by_frame: tuple[tuple[int, int], ...] = ()


@dataclass(frozen=True)
class TrackingScore:
    """Scores of one simulated sequence.

    Attributes
    ----------
    scene : str
        Scene name.
    frames : int
        Frames run.
    bodies : tuple of BodyScore
        One per truth body of kind ``object``.
    """

    scene: str
    frames: int
    bodies: tuple[BodyScore, ...] = field(default=())

    @property
    def id_switches(self) -> int:
        """Identity switches over all bodies."""
        return sum(b.id_switches for b in self.bodies)

    @property
    def lost_frames(self) -> int:
        """Visible frames without a track, over all bodies."""
        return sum(b.visible_frames - b.tracked_frames for b in self.bodies)

    def within(self, rel: float = 0.05, abs_mm_s: float = 60.0) -> float:
        """Share of velocity readings within ``max(rel * |truth|, abs_mm_s)`` of the truth."""
        err = np.array([e for b in self.bodies for e in b.v_errors])
        tru = np.array([t for b in self.bodies for t in b.v_truth])
        if err.size == 0:
            return float("nan")
        return float(np.mean(np.abs(err) <= np.maximum(rel * np.abs(tru), abs_mm_s)))

    def v_error_percentiles(self, q: Iterable[float] = (50, 95)) -> tuple[float, ...]:
        """Percentiles of |v_radial - truth| (mm/s) over all readings."""
        err = np.abs([e for b in self.bodies for e in b.v_errors])
        if err.size == 0:
            return tuple(float("nan") for _ in q)
        return tuple(float(np.percentile(err, x)) for x in q)


def primary_segments(labels: NDArray[np.integer], instances: NDArray[np.integer]) -> dict[int, tuple[int, int]]:
    """For each truth instance, the segment holding most of its pixels.

    Parameters
    ----------
    labels : ndarray of int, shape (H, W)
        Segment id per pixel (0 none).
    instances : ndarray of int, shape (H, W)
        Truth body id per pixel (0 none).

    Returns
    -------
    dict
        ``instance id -> (segment id, shared pixels)``.
    """
    both = (labels > 0) & (instances > 0)
    if not both.any():
        return {}
    pairs = np.stack([instances[both].astype(np.int64), labels[both].astype(np.int64)])
    uniq, counts = np.unique(pairs, axis=1, return_counts=True)
    out: dict[int, tuple[int, int]] = {}
    for (inst, seg), c in zip(uniq.T.tolist(), counts.tolist(), strict=True):
        if c > out.get(inst, (0, 0))[1]:
            out[inst] = (seg, c)
    return out


def objects_from_labels(
    labels: NDArray[np.integer], depth_mm: NDArray[np.floating], kinds: dict[int, str] | None = None
) -> tuple[SceneObject, ...]:
    """SceneObjects of a label map: a perfect segmentation, to score the tracker alone.

    Parameters
    ----------
    labels : ndarray of int, shape (H, W)
        Object id per pixel, 0 none (truth instances masked by validity).
    depth_mm : ndarray of float, shape (H, W)
        Measured depth (mm).
    kinds : dict, optional
        Kind per id; default ``object``.

    Returns
    -------
    tuple of SceneObject
        One per id present, label 0, in id order.
    """
    lab = np.asarray(labels).astype(np.int64)
    h, w = lab.shape
    n = int(lab.max(initial=0)) + 1
    flat = lab.ravel()
    ys, xs = np.indices((h, w))
    z = np.asarray(depth_mm, dtype=np.float64).ravel()
    area = np.bincount(flat, minlength=n)
    sx = np.bincount(flat, xs.ravel(), minlength=n)
    sy = np.bincount(flat, ys.ravel(), minlength=n)
    sz = np.bincount(flat, z, minlength=n)
    szz = np.bincount(flat, z * z, minlength=n)
    boxes = ndimage.find_objects(lab)
    out = []
    for i in range(1, n):
        sl = boxes[i - 1]
        if area[i] == 0 or sl is None:
            continue
        mean = sz[i] / area[i]
        std = float(np.sqrt(max(szz[i] / area[i] - mean * mean, 0.0)))
        bbox = (sl[1].start, sl[0].start, sl[1].stop, sl[0].stop)
        kind = (kinds or {}).get(i, "object")
        center = (float(sx[i] / area[i]), float(sy[i] / area[i]))
        out.append(SceneObject(i, kind, 0, float(mean), std, int(area[i]), area[i] / (h * w), center, bbox))
    return tuple(out)


def evaluate_tracking(
    scene: str,
    frames: int,
    *,
    size: tuple[int, int] = (176, 132),
    fps: float = 30.0,
    seed: int = 0,
    config: TrackerConfig | None = None,
    min_area: int = 100,
    settle: int = 3,
    segmenter: str = "segment",
    core: bool = True,
) -> TrackingScore:
    """Simulate, segment and track a scene, and score the tracker against the truth.

    Parameters
    ----------
    scene : str
        A :data:`depthgram.sensor.SCENES` name (``approach``, ``crossing``, ...).
    frames : int
        Frames to run.
    size : tuple of int
        (width, height) px.
    fps : float
        Frame rate (Hz).
    seed : int
        Noise seed.
    config : TrackerConfig, optional
        Tracker settings.
    min_area : int
        Pixels a body must show to count as visible (px).
    settle : int
        Frames of constant true velocity, and valid queue entries of the track, before its
        velocity is scored: the brief's "after 3 frames" (a turn of the simulated hand is
        a step in velocity no fit over past frames can follow at once).
    segmenter : str
        ``segment``: :func:`depthgram.segmentation.segment`, the real pipeline; ``truth``: the
        simulator's instance map, a perfect segmentation, to score the tracker alone; a
        segmentation method's name (``slices``, ...): that method.
    core : bool
        Hand the tracker each frame's pixels, as the pipeline does, so that it reads each
        object's depth change from its core (:mod:`depthgram.dynamics.core_depth`); False: from
        the objects' depths alone.

    Returns
    -------
    TrackingScore
    """
    from depthgram.segmentation import segment
    from depthgram.sensor import simulate

    tracker = Tracker(config)
    recs: dict[int, _Record] = {}
    n = 0
    for sf in simulate(scene, frames, size=size, fps=fps, seed=seed):
        n += 1
        fr = sf.frame
        if segmenter == "truth":
            labels = np.where(fr.valid, sf.instances, 0)
            objects = objects_from_labels(labels, fr.depth, {b.id: b.kind for b in sf.truth})
        else:
            method: dict[str, Any] = {} if segmenter == "segment" else {"method": segmenter}
            seg = segment(fr.depth, valid=fr.valid, intrinsics=fr.intrinsics, **method)
            labels, objects = seg.labels, seg.objects
        upd = tracker.update(
            objects, fr.time_s, fr.size, FramePixels(fr.depth, labels, fr.intrinsics) if core else None
        )
        prim = primary_segments(labels, sf.instances)
        seg_area = {o.id: o.area for o in objects}
        queues = {t.last.id: t.queue for t in tracker.tracks if t.missed == 0}
        for body in sf.truth:
            if body.kind != "object":
                continue
            rec = recs.setdefault(body.id, _Record(body.name))
            if body.area < min_area:
                continue
            rec.visible += 1
            rec.v_hist.append(body.v_radial)
            seg_id, shared = prim.get(body.id, (0, 0))
            motion = upd.motions.get(seg_id)
            # A segment that is mostly something else (the body swallowed by the wall) is a
            # segmentation miss, not a track of this body.
            if motion is None or shared < 0.5 * seg_area.get(seg_id, 0):
                continue
            rec.tracked += 1
            rec.ids.append(motion.track_id)
            rec.frames.append(fr.index)
            n_valid = sum(z is not None for _, z in queues.get(seg_id, ()))
            steady = len(rec.v_hist) > settle and max(rec.v_hist[-settle - 1 :]) == min(rec.v_hist[-settle - 1 :])
            if motion.status == "visible" and motion.v_radial is not None and n_valid >= settle and steady:
                rec.err.append(motion.v_radial - body.v_radial)
                rec.tru.append(body.v_radial)
    bodies = tuple(r.score() for r in recs.values())
    return TrackingScore(scene=scene, frames=n, bodies=bodies)


@dataclass
class _Record:
    name: str
    visible: int = 0
    tracked: int = 0
    ids: list[int] = field(default_factory=list)
    err: list[float] = field(default_factory=list)
    tru: list[float] = field(default_factory=list)
    v_hist: list[float] = field(default_factory=list)
    frames: list[int] = field(default_factory=list)

    def score(self) -> BodyScore:
        switches = sum(a != b for a, b in zip(self.ids, self.ids[1:], strict=False))
        return BodyScore(
            name=self.name,
            visible_frames=self.visible,
            tracked_frames=self.tracked,
            track_ids=tuple(dict.fromkeys(self.ids)),
            id_switches=switches,
            v_errors=tuple(self.err),
            v_truth=tuple(self.tru),
            id_by_frame=tuple(zip(self.frames, self.ids, strict=True)),
        )


def radial_velocity_from_poses(
    depth_mm: NDArray[np.floating],
    labels: NDArray[np.integer],
    ids: Iterable[int],
    intrinsics: tuple[float, float, float, float],
    pose_prev: NDArray[np.floating],
    pose_next: NDArray[np.floating],
    dt_s: float,
) -> dict[int, float]:
    """Return the true radial velocity of static objects seen by a moving camera, from its poses.

    Each valid pixel of an object is carried to 3-D with the intrinsics, into the world with
    the camera pose of this frame's neighbours, and into the camera of the previous and the
    next frame; the object's true radial velocity is the mean change of those points' depth
    per second (a central difference, ``(z_next - z_prev) / dt_s``): the rate of change of
    its mean depth, which is what the tracker reads, with the scene held still.

    Parameters
    ----------
    depth_mm : ndarray of float, shape (H, W)
        This frame's depth (mm), 0 or NaN where invalid.
    labels : ndarray of int, shape (H, W)
        Object id per pixel.
    ids : iterable of int
        The objects to score.
    intrinsics : tuple of float
        (fx, fy, cx, cy) in px.
    pose_prev, pose_next : ndarray, shape (4, 4)
        Camera-to-world poses of the previous and next frames, each relative to this frame's
        camera (``inv(T_this) @ T_other`` for world poses); translation in mm.
    dt_s : float
        Time between the previous and the next frame (s).

    Returns
    -------
    dict of int to float
        Object id to true radial velocity (mm/s); objects without a valid pixel are left out.
    """
    fx, fy, cx, cy = intrinsics
    z = np.asarray(depth_mm, dtype=np.float64)
    lab = np.asarray(labels)
    to_prev = np.linalg.inv(np.asarray(pose_prev, dtype=np.float64))
    to_next = np.linalg.inv(np.asarray(pose_next, dtype=np.float64))
    out: dict[int, float] = {}
    for oid in ids:
        ys, xs = np.nonzero((lab == oid) & (z > 0) & np.isfinite(z))
        if xs.size == 0:
            continue
        zz = z[ys, xs]
        pts = np.stack([(xs - cx) * zz / fx, (ys - cy) * zz / fy, zz, np.ones_like(zz)])
        z_prev = (to_prev[2] @ pts).mean()
        z_next = (to_next[2] @ pts).mean()
        out[int(oid)] = float((z_next - z_prev) / dt_s)
    return out
