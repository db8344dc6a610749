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


@dataclass(frozen=True)
class MotScore:
    """The field's multi-object tracking metrics of one tracker on one simulated sequence.

    CLEAR MOT and IDF1 as ``motmetrics`` computes them. Ground truth: the bodies of kind
    ``object`` showing at least ``min_area_fraction`` of the frame; hypotheses: the segments
    with the track id the tracker gave them; a pair matches where their pixel masks overlap
    with IoU >= 0.5. Segments made mostly of walls, floors and ceilings are the background,
    not tracking targets, and are left out.

    Attributes
    ----------
    scene, sensor, tracker : str
        Scene name, sensor model, tracker (``depthgram`` or ``norfair``).
    size : tuple of int
        (width, height) px.
    fps : float
        Frame rate (frames/s).
    mota, motp, idf1 : float
        Multiple object tracking accuracy, precision (mean 1 - IoU of matched pairs) and the
        identity F1 score (dimensionless).
    id_switches, false_positives, misses, objects : int
        Identity switches, unmatched hypotheses, unmatched truth, truth body-frames.
    merged : int
        Body-frames whose best segment also holds at least a quarter of another object body:
        two objects merged by segmentation where their silhouettes touch, which no tracker
        can undo.
    v_within : float
        Share of the tracked body-frames, from each track's third frame on and with a steady
        true velocity, whose ``v_radial`` is within ``v_rel`` of the truth (a missing
        velocity counts as a miss); NaN for ``norfair``, which reads no depth.
    v_covered : float
        Share of those readings with ``|v_radial - truth| <= 2 v_sigma``.
    v_readings : int
        How many body-frames ``v_within`` counts.
    """

    scene: str
    sensor: str
    tracker: str
    size: tuple[int, int]
    fps: float
    mota: float
    motp: float
    idf1: float
    id_switches: int
    false_positives: int
    misses: int
    objects: int
    merged: int
    v_within: float = float("nan")
    v_covered: float = float("nan")
    v_readings: int = 0


class _NorfairIds:
    """A plain 2-D tracker a user might pick: norfair on the segments' image centres.

    Euclidean distance on the centres (px), gated at a tenth of the image diagonal, and an
    occlusion budget of one second, as the depthgram tracker's.
    """

    def __init__(self, size: tuple[int, int], fps: float) -> None:
        from depthgram._optional import needs_extra

        with needs_extra("dev", "the norfair comparison (norfair-enough)"):
            import norfair
        self._norfair = norfair
        self._frame = 0
        self._tracker = norfair.Tracker(
            distance_function="euclidean",
            distance_threshold=0.1 * float(np.hypot(*size)),
            hit_counter_max=max(1, round(fps)),
            initialization_delay=2,
        )

    def update(self, objects: tuple[SceneObject, ...]) -> dict[int, int]:
        """Return the norfair id of each object (``SceneObject.id`` -> id) this frame."""
        nf = self._norfair
        self._frame += 1
        # norfair keeps a copy of each track's last detection: the frame tells this frame's
        dets = [nf.Detection(np.array([o.center_xy], dtype=np.float64), data=(self._frame, o.id)) for o in objects]
        out: dict[int, int] = {}
        for tob in self._tracker.update(detections=dets):
            frame, oid = tob.last_detection.data
            if tob.id is not None and frame == self._frame:
                out[int(oid)] = int(tob.id)
        return out


def mot_sequence(
    scene: str,
    frames: int,
    *,
    size: tuple[int, int] = (176, 132),
    fps: float = 30.0,
    sensor: str = "tof",
    seed: int = 1,
    config: TrackerConfig | None = None,
    trackers: tuple[str, ...] = ("depthgram", "norfair"),
    min_area_fraction: float = 0.002,
    v_rel: float = 0.05,
) -> tuple[MotScore, ...]:
    """Simulate and segment a scene once, track it with each tracker, score with ``motmetrics``.

    Parameters
    ----------
    scene : str
        A :data:`depthgram.sensor.SCENES` name.
    frames : int
        Frames to run.
    size : tuple of int
        (width, height) px.
    fps : float
        Frame rate (frames/s).
    sensor : str
        ``tof`` or ``structured-light``.
    seed : int
        Noise seed.
    config : TrackerConfig, optional
        The depthgram tracker's settings (the frames come with their timestamps).
    trackers : tuple of str
        ``depthgram`` (:class:`Tracker`, handed the pixels as the pipeline does) and/or
        ``norfair`` (:class:`_NorfairIds`), over the same segmentations.
    min_area_fraction : float
        Share of the frame a body must show to be ground truth (dimensionless).
    v_rel : float
        Relative velocity tolerance of ``v_within`` (dimensionless).

    Returns
    -------
    tuple of MotScore
        One per tracker, in the order given.
    """
    from depthgram._optional import needs_extra
    from depthgram.segmentation import segment
    from depthgram.sensor import simulate

    with needs_extra("dev", "tracking metrics (motmetrics)"):
        import motmetrics

    cfg = config if config is not None else TrackerConfig()
    tr = Tracker(cfg)
    nf = _NorfairIds(size, fps) if "norfair" in trackers else None
    accs = {name: motmetrics.MOTAccumulator(auto_id=True) for name in trackers}
    merged = 0
    v_ok = v_n = v_cov = 0
    age: dict[int, int] = {}
    v_hist: dict[int, list[float]] = {}
    for sf in simulate(scene, frames, size=size, fps=fps, seed=seed, sensor=sensor):
        fr = sf.frame
        seg = segment(fr.depth, valid=fr.valid, intrinsics=fr.intrinsics)
        labels, objects = seg.labels, seg.objects
        min_area = min_area_fraction * fr.depth.size
        gt = [b for b in sf.truth if b.kind == "object" and b.area >= min_area]
        inter, seg_area, body_area, back = _overlaps(
            labels, sf.instances, {b.id for b in sf.truth if b.kind != "object"}
        )
        hyp = [o for o in objects if back.get(o.id, 0) <= 0.5 * o.area]
        dist = np.full((len(gt), len(hyp)), np.nan)
        for i, b in enumerate(gt):
            for j, o in enumerate(hyp):
                c = inter.get((b.id, o.id), 0)
                iou = c / (body_area[b.id] + seg_area[o.id] - c) if c else 0.0
                if iou >= 0.5:
                    dist[i, j] = 1.0 - iou
        objs_by_id = {o.id: o for o in objects}
        for b in gt:
            best = max(((c, s) for (bb, s), c in inter.items() if bb == b.id), default=(0, 0))[1]
            if best and any(
                inter.get((other.id, best), 0) >= 0.25 * other.area
                for other in sf.truth
                if other.kind == "object" and other.id != b.id and other.area >= min_area
            ):
                merged += 1
        if "depthgram" in trackers:
            upd = tr.update(objects, fr.time_s, fr.size, FramePixels(fr.depth, labels, fr.intrinsics))
            ids = {oid: m.track_id for oid, m in upd.motions.items()}
            for m in upd.motions.values():
                age[m.track_id] = age.get(m.track_id, 0) + 1
            accs["depthgram"].update([b.id for b in gt], [ids[o.id] for o in hyp], dist)
            for i, b in enumerate(gt):
                hist = v_hist.setdefault(b.id, [])
                hist.append(b.v_radial)
                hit = np.flatnonzero(np.isfinite(dist[i]))
                if hit.size != 1 or b.touches_border or len(hist) < 3 or max(hist[-3:]) != min(hist[-3:]):
                    continue
                m = upd.motions[hyp[int(hit[0])].id]
                if age[m.track_id] < 3 or abs(b.v_radial) < 1.0:
                    continue
                v_n += 1
                if m.v_radial is not None:
                    err = abs(m.v_radial - b.v_radial)
                    v_ok += err <= v_rel * abs(b.v_radial)
                    v_cov += m.v_sigma is not None and err <= 2 * m.v_sigma
        if nf is not None:
            nids = nf.update(tuple(objs_by_id[o.id] for o in hyp))
            keep = [j for j, o in enumerate(hyp) if o.id in nids]
            accs["norfair"].update([b.id for b in gt], [nids[hyp[j].id] for j in keep], dist[:, keep])
    mh = motmetrics.metrics.create()
    names = ["mota", "motp", "idf1", "num_switches", "num_false_positives", "num_misses", "num_objects"]
    out = []
    for name in trackers:
        r = mh.compute(accs[name], metrics=names, name=name).iloc[0]
        dg = name == "depthgram"
        out.append(
            MotScore(
                scene=scene, sensor=sensor, tracker=name, size=(int(size[0]), int(size[1])), fps=float(fps),
                mota=float(r["mota"]), motp=float(r["motp"]), idf1=float(r["idf1"]),
                id_switches=int(r["num_switches"]), false_positives=int(r["num_false_positives"]),
                misses=int(r["num_misses"]), objects=int(r["num_objects"]), merged=merged,
                v_within=v_ok / v_n if dg and v_n else float("nan"),
                v_covered=v_cov / v_n if dg and v_n else float("nan"), v_readings=v_n if dg else 0,
            )
        )  # fmt: skip
    return tuple(out)


def _overlaps(
    labels: NDArray[np.integer], instances: NDArray[np.integer], background: set[int]
) -> tuple[dict[tuple[int, int], int], dict[int, int], dict[int, int], dict[int, int]]:
    """Pixel counts: (body, segment) intersections, segment areas, body areas, and each segment's background pixels."""
    lab = np.asarray(labels).astype(np.int64).ravel()
    inst = np.asarray(instances).astype(np.int64).ravel()
    seg_ids, seg_counts = np.unique(lab[lab > 0], return_counts=True)
    body_ids, body_counts = np.unique(inst[inst > 0], return_counts=True)
    both = (lab > 0) & (inst > 0)
    inter: dict[tuple[int, int], int] = {}
    back: dict[int, int] = {}
    if both.any():
        pairs, counts = np.unique(np.stack([inst[both], lab[both]]), axis=1, return_counts=True)
        for (b, s), c in zip(pairs.T.tolist(), counts.tolist(), strict=True):
            inter[(b, s)] = c
            if b in background:
                back[s] = back.get(s, 0) + c
    return (
        inter,
        dict(zip(seg_ids.tolist(), seg_counts.tolist(), strict=True)),
        dict(zip(body_ids.tolist(), body_counts.tolist(), strict=True)),
        back,
    )
