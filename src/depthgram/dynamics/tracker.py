"""Objects followed across frames: stable identities, radial velocity, time to collision.

The tracker keeps the state of all live tracks in one record array (one record per track with
named fields, :data:`~depthgram.dynamics.kernels.TRACK_DTYPE`) plus two queue arrays, updated
in place by compiled kernels, so that an update costs a few calls whatever the number of
objects; Python objects are only built for what is returned.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from depthgram.dynamics.camera_motion import CameraMotion, EgoMotion, FramePixels, shift_structure, structure_shift
from depthgram.dynamics.config import NOMINAL_FPS, TrackerConfig
from depthgram.dynamics.core_depth import core_depth_change, inner_edge_shift, still_depth_change
from depthgram.dynamics.estimate import EstimateParams, estimate
from depthgram.dynamics.kernels import (
    FORBIDDEN,
    OBJECT_DTYPE,
    OBJECT_FIELDS,
    OCCLUDED,
    Status,
    StepParams,
    keep_tracks,
    mark_behind,
    new_tracks,
    predict_cost,
    step,
)
from depthgram.dynamics.match import cost_params
from depthgram.errors import InputError
from depthgram.frame import Intrinsics
from depthgram.scene.tree import Motion
from depthgram.segmentation.objects import SceneObject

__all__ = ["STATUSES", "Status", "Track", "TrackUpdate", "Tracker", "estimate_params", "step_params"]

#: Track statuses, in the order of their integer codes (:class:`Status`).
STATUSES = tuple(x.name.lower() for x in Status)


@dataclass(frozen=True)
class Track:
    """A snapshot of one track.

    Attributes
    ----------
    id : int
        Stable track id, from 1.
    hits : int
        Frames in which the track was detected.
    missed : int
        Frames since its last detection (0 when detected this frame).
    confirmed : bool
        True once ``hits >= min_hits``.
    status : str
        One of :data:`STATUSES`.
    last : SceneObject
        The object as last detected.
    motion : Motion
        The track's motion as of this frame (status ``occluded`` while missed).
    queue : tuple of (float, float or None)
        The last N queue entries, oldest first: (time in s, from the frame rate when the
        frames have no timestamps; depth in mm, or None for an invalid entry).
    center_xy : tuple of float or None
        Where the object's centre is now (px): as detected, or while occluded, predicted along
        its image velocity since its last detection.
    depth_mm : float or None
        The filter's depth now (mm; estimator ``kalman``): predicted along its radial velocity
        while occluded. None before the filter has a reading.
    depth_sigma_mm : float or None
        That depth's standard deviation (mm); it grows with every frame the track coasts.
    """

    id: int
    hits: int
    missed: int
    confirmed: bool
    status: str
    last: SceneObject
    motion: Motion
    queue: tuple[tuple[float, float | None], ...]
    center_xy: tuple[float, float] | None = None
    depth_mm: float | None = None
    depth_sigma_mm: float | None = None


@dataclass(frozen=True)
class TrackUpdate:
    """What one :meth:`Tracker.update` found.

    Attributes
    ----------
    motions : dict of int to Motion
        Motion of each of this frame's objects, keyed by ``SceneObject.id``.
    occluded : tuple of Track
        Confirmed tracks alive but not detected this frame.
    ended : tuple of Track
        Confirmed tracks that died this frame (occlusion budget exhausted).
    """

    motions: dict[int, Motion]
    occluded: tuple[Track, ...] = ()
    ended: tuple[Track, ...] = ()


def track_depth(o: SceneObject) -> float:
    """Return the depth (mm) whose change is read as radial motion.

    The mean depth (paper, eq. 13), or for a compound object (kind ``compound``) its nearest part's
    (the middle of the three nearest when they lie within 1 % of each other in depth).

    A compound (a box's front and oblique side, a table top with its front edge) shows more or
    less of its oblique surface as it moves across the view, which moves its mean depth with no
    radial motion at all; its nearest slice (the front face, the front edge) does not. Floors,
    walls and ceilings keep their mean depth: their nearest slice is wherever the view's edge
    cuts them (measured on 7-Scenes: |v| p99 1101 mm/s with their nearest slice, 995 without).
    """
    if _reads_nearest_part(o):
        d = sorted(p.depth for p in o.parts)
        # A front face cut into several slices at one depth: the middle of its three nearest
        # slices, since a sliver at the object's edge, where mixed pixels pull the depth
        # nearer, is not the face (on `crossing` such slivers read 5-9 mm nearer for a frame or
        # two: 150-270 mm/s of false motion). Parts spread in depth (a surface running away)
        # keep the nearest: on 7-Scenes the middle one there moved p99 |v| from 699 to 751 mm/s.
        if len(d) >= 3 and d[2] - d[0] <= 0.01 * d[0]:
            return d[1]
        return d[0]
    return o.depth


def _reads_nearest_part(o: SceneObject) -> bool:
    """Whether :func:`track_depth` reads ``o``'s nearest part rather than its mean depth."""
    return o.kind == "compound" and bool(o.parts)


def _features(objects: Sequence[SceneObject]) -> NDArray[np.void]:
    """Return the objects as the kernels read them: :data:`~depthgram.dynamics.kernels.OBJECT_DTYPE` records.

    ``behind`` is 1 where a nearer object (by more than 5 % of depth) touches or overlaps the
    object's box: the paper's partial occlusion (case b), whose area change is not motion and
    whose visible mean depth is biased, so the tracker leaves such frames out of the fit while
    the visible area changes. ``read_nearest`` is 1 where :func:`track_depth` read the nearest
    part of a compound, 0 where it read the mean depth.
    """
    m = len(objects)
    rows = [(*o.center_xy, track_depth(o), o.area, o.depth_label, *o.bbox_xy) for o in objects]
    flat = np.fromiter(itertools.chain.from_iterable(rows), np.float64, count=9 * m)
    # The record's fields are all float64 and its first nine those of `rows`, in their order:
    # filled as one block of floats, then seen as records.
    block = np.zeros((m, len(OBJECT_FIELDS)))
    block[:, :9] = flat.reshape(m, 9)
    f = block.view(OBJECT_DTYPE)[:, 0]
    f["read_nearest"] = [_reads_nearest_part(o) for o in objects]
    mark_behind(f)
    return f


_NO_PAIRS = np.zeros(0, np.intp)


def _some(x: tuple[float, float] | None) -> tuple[tuple[float, float], ...]:
    """``(x,)``, or ``()`` for None."""
    return () if x is None else (x,)


def _scale(z_prev: float, dz: float) -> float:
    """How much an object shrinks back into the previous frame.

    Its predicted depth now over its depth then (1 without a velocity). The prediction, not this
    frame's reading, so that a segment that gains or loses a part does not scale its core.
    """
    k = (z_prev + dz) / z_prev if z_prev > 0 and math.isfinite(dz) else 1.0
    return k if 0.5 <= k <= 2.0 else 1.0


def step_params(config: TrackerConfig) -> StepParams:
    """Return the settings of the compiled :func:`~depthgram.dynamics.kernels.step`."""
    c = config
    return StepParams(
        border_px=float(c.border_px),
        border_area_rate=float(c.border_area_rate),
        max_area_jump=float(c.max_area_jump),
        fit_border_entries=bool(c.fit_border_entries),
        min_speed=float(c.min_speed),
        min_hits=int(c.min_hits),
        max_missed=int(c.max_missed),
        max_occluded_s=float(c.max_occluded_s),
        # The filter's innovation gate judges jumps against its own uncertainty (and three in a
        # row restart it): the queue's fixed jump test would restart it on one outlier.
        max_depth_jump_rate=math.inf if c.estimator == "kalman" else float(c.max_depth_jump_rate),
        center_tau_s=float(c.center_tau_s),
        area_tau_s=float(c.area_tau_s),
    )


def estimate_params(config: TrackerConfig) -> EstimateParams:
    """Return the settings of the compiled :func:`~depthgram.dynamics.estimate.estimate`."""
    c = config
    return EstimateParams(
        kalman=c.estimator == "kalman",
        depth_sigma_mm=float(c.depth_sigma_mm),
        depth_sigma_floor_mm=float(c.depth_sigma_floor_mm),
        accel_sigma=float(c.accel_sigma),
        innovation_gate=float(c.innovation_gate),
        ttc_min_sigmas=float(c.ttc_min_sigmas),
        min_speed=float(c.min_speed),
        # The velocity uncertainty a (re)started filter begins with (mm/s).
        v_sigma0=3000.0,
        own_accel_sigma=float(c.own_accel_sigma),
        # The own velocity a track with the camera's motion known starts from is 0 (most of a view
        # stands still), with this uncertainty (mm/s): a brisk walk.
        own_v_sigma0=1500.0,
        # An object's own radial velocity counts once it is this many of its sigmas from standing
        # still (dimensionless): a significance test against the still world most of a view is,
        # made for each of a frame's 10-20 objects 30 times a second (at 2 sigmas about one
        # spurious own motion a frame).
        own_min_sigmas=3.0,
    )


def _motion(
    track_id: int, v: float, ttc: float, status: str, fps_assumed: float | None, v_sigma: float = math.nan
) -> Motion:
    """Return a Motion; NaN velocity, time to collision or v_sigma become None."""
    known = not math.isnan(v)
    return Motion(
        track_id=track_id,
        v_radial=v if known else None,
        ttc=None if math.isnan(ttc) else ttc,
        status=status,
        v_sigma=v_sigma if known and math.isfinite(v_sigma) else None,
        fps_assumed=fps_assumed,
    )


class Tracker:
    """Follow objects across frames and read their radial range flow (paper, section 5).

    Each track keeps a queue of its last N mean depths with their times; the radial
    velocity is the least-squares slope over the queue's valid entries (equation 13 for two
    entries), the time to collision the fitted depth over the closing speed. Objects are
    matched to tracks by one global assignment over a gated attribute cost.

    Parameters
    ----------
    config : TrackerConfig, optional
        Gates, queue length, occlusion budget; defaults when omitted.

    Examples
    --------
    >>> tracker = Tracker()
    >>> for seg, frame in zip(segmentations, frames):  # doctest: +SKIP
    ...     upd = tracker.update(seg.objects, frame.time_s, frame.size)
    ...     upd.motions[obj.id].v_radial
    """

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config if config is not None else TrackerConfig()
        c = self.config
        self._cost_params = cost_params(c)
        self._step_params = step_params(c)
        self._estimate_params = estimate_params(c)
        self.reset()

    def reset(self) -> None:
        """Forget every track; the next update starts a new sequence with ids from 1."""
        n = self.config.queue_length
        self._next_id = 1
        self._frame = -1
        self._t_last: float | None = None
        self._per_frame: bool | None = None
        self._dt = 1.0 / NOMINAL_FPS  # this frame's time step (s)
        self._fps_assumed: float | None = None
        self._fps_warned = False
        self._n = 0
        # The first self._n records are the live tracks (kernels.TRACK_FIELDS says what each
        # field holds), in id order; the rest is room to grow into.
        self._tracks = new_tracks(16)
        self._qt = np.zeros((16, n))  # each track's queue: times (s), oldest first
        self._qz = np.zeros((16, n))  # and depths (mm; NaN: no valid entry)
        self._last: list[SceneObject] = []
        self._motion: list[Motion] = []
        self._pixels: FramePixels | None = None  # the previous frame's, when given
        self._camera_moved = False  # whether the camera's motion was found in the last update
        self._ego = EgoMotion()
        # this frame's image motion when prepare() found it ahead of update(): (depth, camera, shift)
        self._prepared: tuple[object, CameraMotion | None, tuple[float, float] | None] | None = None
        # the last depth array read for the frame's shift and its structure, which the next
        # frame's shift reads again as its previous one
        self._structure: tuple[object, NDArray[np.float32]] | None = None

    # ------------------------------------------------------------------ public views
    @property
    def tracks(self) -> tuple[Track, ...]:
        """Snapshots of all live tracks (tentative ones included), in id order."""
        return self._snapshots(list(range(self._n)))

    def _snapshots(self, rows: list[int]) -> tuple[Track, ...]:
        """Return snapshots of the live tracks at ``rows``."""
        if not rows:
            return ()
        # One list per field: reading a record's fields one by one costs several times more.
        live = self._tracks[: self._n]
        ids, hits, missed, status = (live[name].tolist() for name in ("id", "hits", "missed", "status"))
        el = (self._t_last if self._t_last is not None else 0.0) - live["t_seen"]
        cx, cy = (live["cx"] + live["vx"] * el).tolist(), (live["cy"] + live["vy"] * el).tolist()
        kf_z, kf_pzz = live["kf_z"].tolist(), live["kf_pzz"].tolist()
        min_hits = self.config.min_hits
        return tuple(
            Track(
                id=ids[i],
                hits=hits[i],
                missed=missed[i],
                confirmed=hits[i] >= min_hits,
                status=STATUSES[status[i]],
                last=self._last[i],
                motion=self._motion[i],
                queue=tuple(
                    (float(t), None if not math.isfinite(z) else float(z))
                    for t, z in zip(self._qt[i].tolist(), self._qz[i].tolist(), strict=True)
                ),
                center_xy=(cx[i], cy[i]),
                depth_mm=kf_z[i] if math.isfinite(kf_z[i]) else None,
                depth_sigma_mm=math.sqrt(kf_pzz[i]) if math.isfinite(kf_z[i]) and kf_pzz[i] >= 0 else None,
            )
            for i in rows
        )

    # ------------------------------------------------------------------ update
    def _clock(self, time_s: float | None) -> float:
        """Advance the frame counter and return this frame's queue time."""
        self._frame += 1
        per_frame = time_s is None
        if self._per_frame is None:
            self._per_frame = per_frame
        elif self._per_frame != per_frame:
            had = "without" if self._per_frame else "with"
            raise InputError(
                f"tracker frame {self._frame}: earlier frames came {had} timestamps, this one "
                f"{'without' if per_frame else 'with'}; give time_s for every frame or for none "
                "(call reset() between sequences)"
            )
        if time_s is None:
            fps = self.config.fps
            if fps is None:
                # Said once, and only from the second frame on: a single still has no time step,
                # so no velocity rests on the assumed rate.
                if self._frame >= 1 and not self._fps_warned:
                    self._fps_warned = True
                    warnings.warn(
                        f"tracker: the frames have no timestamps and no frame rate is set; assuming "
                        f"{NOMINAL_FPS:g} frames/s for velocities (mm/s) and times to collision (s). "
                        "Give the real rate with --fps (or [tracker] fps in the config).",
                        UserWarning,
                        stacklevel=3,
                    )
                fps = NOMINAL_FPS
                self._fps_assumed = fps
            time_s = self._frame / fps
        t = float(time_s)
        if not math.isfinite(t):
            raise InputError(f"tracker frame {self._frame}: time_s must be a finite number of seconds, got {t}")
        if self._t_last is not None:
            if t <= self._t_last:
                raise InputError(
                    f"tracker frame {self._frame}: time_s {t} s is not after the previous frame's "
                    f"{self._t_last} s; timestamps must increase (call reset() between sequences)"
                )
            self._dt = t - self._t_last
        self._t_last = t
        return t

    def prepare(self, depth_mm: NDArray[np.floating], intrinsics: Intrinsics | None) -> None:
        """Find this frame's image motion from its depth alone, ahead of :meth:`update`.

        Optional: :meth:`update` finds it itself when not prepared. The camera's motion (ICP) and
        the frame's shift need only the depth, so a caller may run this beside the
        segmentation of the same frame, in another thread (the pipeline does: both release the
        GIL for most of their time). The next :meth:`update` must come with ``pixels`` holding
        this same ``depth_mm`` array; any other update discards what was prepared.

        Parameters
        ----------
        depth_mm : ndarray of float, shape (H, W)
            This frame's depth (mm), 0 or NaN where invalid.
        intrinsics : Intrinsics or None
            The camera's intrinsics (px); None reads a single shift only.
        """
        self._prepared = None
        if self.config.depth_from != "core":
            return
        prev = self._pixels
        camera = self._camera_motion(depth_mm, intrinsics)
        shift = None
        if prev is not None and np.shape(prev.depth_mm) == np.shape(depth_mm):
            shift = self._shift(prev.depth_mm, depth_mm)
        self._prepared = (depth_mm, camera, shift)

    def _shift(self, prev_depth_mm: NDArray[np.floating], depth_mm: NDArray[np.floating]) -> tuple[float, float]:
        """:func:`image_shift`, with the previous frame's structure kept from its own shift."""
        known = self._structure
        if known is not None and known[0] is prev_depth_mm:
            before = known[1]
        else:
            before = shift_structure(prev_depth_mm)
        now = shift_structure(depth_mm)
        self._structure = (depth_mm, now)
        h, w = np.shape(depth_mm)
        return structure_shift(before, now, (w, h))

    def update(
        self,
        objects: Sequence[SceneObject],
        time_s: float | None,
        frame_size: tuple[int, int],
        pixels: FramePixels | None = None,
        *,
        helper: Executor | None = None,
    ) -> TrackUpdate:
        """Match this frame's objects to the tracks and read their motion.

        Given the frame's ``pixels`` (depth and label map) on this and the previous update, and
        ``config.depth_from == "core"``, an object's depth change is read from its core, the
        pixels that stay in it (:mod:`depthgram.dynamics.core_depth`); otherwise, and for objects
        without a core, from its mean depth alone.

        Parameters
        ----------
        objects : sequence of SceneObject
            This frame's objects (top level; parts of compounds are not tracked apart).
        time_s : float or None
            Frame timestamp (s). None for every frame of a sequence: frame k is at
            ``k / config.fps``, or at the nominal 30 frames/s with one warning when no rate is
            configured (each Motion then says which rate it assumed).
        frame_size : tuple of int
            (width, height) of the image (px), as :attr:`depthgram.frame.Frame.size`.
        pixels : FramePixels, optional
            This frame's depth (mm) and label map (``SceneObject.id`` per pixel), shape
            (height, width). Ignored (not even checked) when ``config.depth_from == "mean"``.
        helper : Executor, optional
            A thread that reads about half of the objects' cores beside the caller's
            (:func:`depthgram.dynamics.core_depth.core_depth_change`): for a caller whose second
            core idles meanwhile. The update is the same with or without it.

        Returns
        -------
        TrackUpdate

        Raises
        ------
        InputError
            On a bad frame size, duplicate object ids, or timestamps that do not increase.
        """
        cfg = self.config
        try:
            width, height = (int(frame_size[0]), int(frame_size[1]))
        except (TypeError, ValueError, IndexError) as exc:
            raise InputError(f"tracker: frame_size must be (width, height) in px, got {frame_size!r}") from exc
        if width <= 0 or height <= 0:
            raise InputError(f"tracker: frame_size must be positive (width, height) px, got {frame_size!r}")
        objects = tuple(objects)
        if len({o.id for o in objects}) != len(objects):
            ids = sorted(o.id for o in objects)
            raise InputError(f"tracker frame {self._frame + 1}: duplicate SceneObject ids {ids}")
        if cfg.depth_from == "mean":
            pixels = None
        t_now = self._clock(time_s)
        fps_assumed = self._fps_assumed
        f = _features(objects)
        n, m = self._n, len(objects)
        if n + m > len(self._tracks):
            more = max(2 * len(self._tracks), n + m) - len(self._tracks)
            self._tracks = np.concatenate([self._tracks, new_tracks(more)])
            self._qt = np.concatenate([self._qt, np.zeros((more, self._qt.shape[1]))])
            self._qz = np.concatenate([self._qz, np.zeros((more, self._qz.shape[1]))])
        tracks = self._tracks
        cost = predict_cost(
            tracks, n, f, math.hypot(width, height), t_now, self._dt, self._cost_params, not self._camera_moved
        )
        if n and m:
            rows, cols = linear_sum_assignment(cost)
        else:
            rows = cols = _NO_PAIRS
        dcore, dstill = self._core_changes(objects, pixels, rows, cols, cost, (width, height), helper)
        params = self._step_params
        obj_row, v_out, ttc, dead, restarted, k, offset = step(
            tracks, self._qt, self._qz, n, f, rows, cols, cost, t_now, self._dt,
            float(width), float(height), self._frame == 0, self._next_id, params, dcore, dstill,
        )  # fmt: skip
        self._n = n + k
        self._next_id += k
        if k:  # placeholders, filled below
            self._last.extend([objects[0]] * k)
            self._motion.extend([Motion(0)] * k)
        core_row = np.full(self._n, np.nan)
        still_row = np.full(self._n, np.nan)
        core_row[obj_row] = dcore
        still_row[obj_row] = dstill
        v_out, ttc, v_sig = self._estimate(n, restarted, v_out, ttc, offset, core_row, still_row)

        # Python objects only for what is returned.
        live = tracks[: self._n]
        ids_l = live["id"].tolist()
        st_l = live["status"].tolist()
        v_l = v_out.tolist()
        ttc_l = ttc.tolist()
        sig_l = v_sig.tolist()
        motions: dict[int, Motion] = {}
        for o, i in zip(objects, obj_row.tolist(), strict=True):
            mo = _motion(ids_l[i], v_l[i], ttc_l[i], STATUSES[st_l[i]], fps_assumed, sig_l[i])
            motions[o.id] = mo
            self._motion[i] = mo
            self._last[i] = o
        missed = [i for i in range(n) if st_l[i] == OCCLUDED]
        for i in missed:
            self._motion[i] = _motion(ids_l[i], v_l[i], ttc_l[i], STATUSES[OCCLUDED], fps_assumed, sig_l[i])
        min_hits = cfg.min_hits
        hits = live["hits"]
        ended_rows = [i for i in missed if dead[i] and hits[i] >= min_hits]
        snaps = self._snapshots(ended_rows + [i for i in missed if not dead[i]])
        ended, occluded = snaps[: len(ended_rows)], snaps[len(ended_rows) :]
        if missed and dead[:n].any():
            self._drop(~dead)
        return TrackUpdate(motions=motions, occluded=occluded, ended=ended)

    def _core_changes(
        self,
        objects: tuple[SceneObject, ...],
        pixels: FramePixels | None,
        rows: NDArray[np.intp],
        cols: NDArray[np.intp],
        cost: NDArray[np.float64],
        frame_size: tuple[int, int],
        helper: Executor | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return each object's core depth change since the previous frame, and the change it would show standing still.

        Both in mm, NaN where unknown; the second only where the camera's motion is known.
        This frame's pixels are kept for the next update.
        """
        prev, self._pixels = self._pixels, pixels
        out = np.full(len(objects), np.nan)
        still = np.full(len(objects), np.nan)
        if pixels is None:
            return out, still
        shape = (frame_size[1], frame_size[0])
        if np.shape(pixels.depth_mm) != shape or np.shape(pixels.labels) != shape:
            raise InputError(
                f"tracker frame {self._frame}: pixels must be (height, width) = {shape} like frame_size, got "
                f"depth {np.shape(pixels.depth_mm)} and labels {np.shape(pixels.labels)}"
            )
        prepared, self._prepared = self._prepared, None
        if prepared is not None and prepared[0] is pixels.depth_mm:
            camera, shift = prepared[1], prepared[2]
        else:
            camera, shift = self._camera_motion(pixels.depth_mm, pixels.intrinsics), None
        self._camera_moved = camera is not None
        if prev is None:
            return out, still
        if camera is not None:
            moved = still_depth_change(pixels, {o.id: o.bbox_xy for o in objects}, camera)
            for c, o in enumerate(objects):
                still[c] = moved.get(o.id, math.nan)
        # Pairs with a track seen in the previous frame: its last object is that frame's segment.
        # The track's own image motion: its centre's move, its smoothed image velocity, which
        # holds while the outline changes (entering, leaving, partly hidden), and for an object
        # cut by the image's edge the move of its edge inside the image (px).
        dt = self._dt
        cfg_border = self.config.border_px
        pairs = {}
        # Under the camera's motion, each object's image scale from its own radial motion: its
        # predicted change less the camera's part (the still change), which the motion holds.
        own_scales: dict[int, float] = {}
        moving: set[int] = set()
        for i, c in zip(rows.tolist(), cols.tolist(), strict=True):
            t = self._tracks[i]
            if not (cost[i, c] < FORBIDDEN and t["missed"] == 0):
                continue
            o = objects[c]
            if camera is not None:
                own_scales[o.id] = _scale(t["z_fit"], t["v"] * dt - still[c])
                # its own radial velocity, the camera's part taken out, counts (estimate(): two
                # readings, three of its sigmas from standing still)
                own_v = t["own_v"]
                if t["own_n"] >= 2 and abs(own_v) > self._estimate_params.own_min_sigmas * math.sqrt(t["own_var"]):
                    moving.add(o.id)
            pairs[o.id] = (
                self._last[i].id,
                o.bbox_xy,
                (
                    (t["cx"] - o.center_xy[0], t["cy"] - o.center_xy[1]),
                    (-t["vx"] * dt, -t["vy"] * dt),
                    *_some(inner_edge_shift(self._last[i].bbox_xy, o.bbox_xy, frame_size, cfg_border)),
                ),
                _scale(t["z_fit"], t["v"] * dt),
            )
        if not pairs:
            return out, still
        if shift is None:
            shift = self._shift(prev.depth_mm, pixels.depth_mm)
        change = core_depth_change(
            prev, pixels, pairs, shift, camera=camera, helper=helper, own_scales=own_scales, moving=moving
        )
        for c, o in enumerate(objects):
            out[c] = change.get(o.id, math.nan)
        return out, still

    def _camera_motion(self, depth_mm: NDArray[np.floating], intrinsics: Intrinsics | None) -> CameraMotion | None:
        """Return the camera's motion since the previous frame, or None to use one shift.

        None without intrinsics, with ``config.image_motion == "shift"``, on the first frame and
        where the ICP fails (:meth:`EgoMotion.update`). Every frame with intrinsics goes
        through the ICP, so that the next frame finds its predecessor prepared.
        """
        if intrinsics is None or self.config.image_motion != "camera":
            self._ego.reset()
            return None
        motion = self._ego.update(depth_mm, intrinsics)
        # a still camera: the frame's shift (none, or a pan the ICP missed) moves the core
        return None if motion is None or motion.still else motion

    def _estimate(
        self,
        n: int,
        restarted: NDArray[np.bool_],
        v_queue: NDArray[np.float64],
        ttc_queue: NDArray[np.float64],
        offset: NDArray[np.float64],
        core_dz: NDArray[np.float64],
        still_dz: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Radial velocity, time to collision and v_sigma of every live row (mm/s, s, mm/s).

        See :func:`depthgram.dynamics.estimate.estimate`.
        """
        nn = self._n
        return estimate(
            self._tracks[:nn], self._qt[:nn], self._qz[:nn], n, restarted, v_queue, ttc_queue,
            self._dt, self._estimate_params, offset, core_dz, still_dz,
        )  # fmt: skip

    def _drop(self, keep: NDArray[np.bool_]) -> None:
        """Keep only the live tracks where ``keep`` is True."""
        k = keep_tracks(self._tracks, self._qt, self._qz, self._n, keep)
        idx = np.flatnonzero(keep).tolist()
        self._last = [self._last[i] for i in idx]
        self._motion = [self._motion[i] for i in idx]
        self._n = k
