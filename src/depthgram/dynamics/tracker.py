"""Objects followed across frames: stable identities, radial velocity, time to collision.

The tracker keeps the state of all live tracks in numpy arrays (one row per track) so that
an update costs a fixed handful of array operations whatever the number of objects; Python
objects are only built for what is returned.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from depthgram.dynamics.config import TrackerConfig
from depthgram.dynamics.flow import fit_radial_velocity, time_to_collision
from depthgram.dynamics.match import assign, match_cost
from depthgram.errors import InputError
from depthgram.scene.tree import Motion
from depthgram.segment.objects import SceneObject

__all__ = ["STATUSES", "Track", "TrackUpdate", "Tracker"]

#: Track statuses, in the order of their integer codes.
STATUSES = ("visible", "entering", "leaving", "occluded")
_VISIBLE, _ENTERING, _LEAVING, _OCCLUDED = range(4)


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
        The last N queue entries, oldest first: (time in s, or frame number when no
        timestamps are known; mean depth in mm, or None for an invalid entry).
    """

    id: int
    hits: int
    missed: int
    confirmed: bool
    status: str
    last: SceneObject
    motion: Motion
    queue: tuple[tuple[float, float | None], ...]


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


def _features(objects: Sequence[SceneObject]) -> NDArray[np.float64]:
    """(M, 9) array: cx, cy, depth, area, label, x0, y0, x1, y1."""
    rows = [(o.center[0], o.center[1], o.depth, o.area, o.label, *o.bbox) for o in objects]
    return np.array(rows, dtype=np.float64).reshape(len(rows), 9)


class Tracker:
    """Follow objects across frames and read their radial range flow (paper, section 5).

    Parameters
    ----------
    config : TrackerConfig, optional
        Gates, queue length, occlusion budget; defaults when omitted.

    Examples
    --------
    >>> tracker = Tracker()
    >>> for seg, t in zip(segmentations, times):  # doctest: +SKIP
    ...     upd = tracker.update(seg.objects, t, frame.size)
    ...     upd.motions[obj.id].v_radial
    """

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config if config is not None else TrackerConfig()
        self.reset()

    def reset(self) -> None:
        """Forget every track; the next update starts a new sequence with ids from 1."""
        n = self.config.queue_length
        self._next_id = 1
        self._frame = -1
        self._t_last: float | None = None
        self._per_frame: bool | None = None
        self._dt = 1.0  # running frame period (s, or 1 frame), to predict depth per frame
        self._ids = np.zeros(0, np.int64)
        self._hits = np.zeros(0, np.int64)
        self._missed = np.zeros(0, np.int64)
        self._status = np.zeros(0, np.int64)
        self._center = np.zeros((0, 2))
        self._cvel = np.zeros((0, 2))  # image velocity (px/frame), to predict across misses
        self._bbox = np.zeros((0, 4))
        self._depth = np.zeros(0)  # last finite mean depth (mm)
        self._zfit = np.zeros(0)  # fitted depth at the last detection (mm), bias-free reference
        self._area = np.zeros(0)
        self._marea = np.zeros(0)  # running depth-compensated area A z^2, for split/merge
        self._label = np.zeros(0, np.int64)
        self._v = np.zeros(0)  # last finite fitted velocity, held through occlusion
        self._qt = np.zeros((0, n))
        self._qz = np.zeros((0, n))
        self._last: list[SceneObject] = []
        self._motion: list[Motion] = []

    # ------------------------------------------------------------------ public views
    @property
    def tracks(self) -> tuple[Track, ...]:
        """Snapshots of all live tracks (tentative ones included), in id order."""
        return tuple(self._snapshot(i) for i in range(len(self._ids)))

    def _snapshot(self, i: int) -> Track:
        queue = tuple(
            (float(t), None if not math.isfinite(z) else float(z))
            for t, z in zip(self._qt[i], self._qz[i], strict=True)
        )
        return Track(
            id=int(self._ids[i]),
            hits=int(self._hits[i]),
            missed=int(self._missed[i]),
            confirmed=bool(self._hits[i] >= self.config.min_hits),
            status=STATUSES[int(self._status[i])],
            last=self._last[i],
            motion=self._motion[i],
            queue=queue,
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
            return float(self._frame)
        t = float(time_s)
        if not math.isfinite(t):
            raise InputError(f"tracker frame {self._frame}: time_s must be a finite number of seconds, got {t}")
        if self._t_last is not None:
            if t <= self._t_last:
                raise InputError(
                    f"tracker frame {self._frame}: time_s {t} s is not after the previous frame's "
                    f"{self._t_last} s; timestamps must increase (call reset() between sequences)"
                )
            dt = t - self._t_last
            self._dt = dt if self._frame == 1 else 0.8 * self._dt + 0.2 * dt
        self._t_last = t
        return t

    def update(
        self, objects: Sequence[SceneObject], time_s: float | None, frame_size: tuple[int, int]
    ) -> TrackUpdate:
        """Match this frame's objects to the tracks and read their motion.

        Parameters
        ----------
        objects : sequence of SceneObject
            This frame's objects (top level; parts of compounds are not tracked apart).
        time_s : float or None
            Frame timestamp (s). None for every frame of a sequence gives velocities in
            mm/frame and times to collision in frames.
        frame_size : tuple of int
            (width, height) of the image (px), as :attr:`depthgram.frame.Frame.size`.

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
        ids = [o.id for o in objects]
        if len(set(ids)) != len(ids):
            raise InputError(f"tracker frame {self._frame + 1}: duplicate SceneObject ids {sorted(ids)}")
        t_now = self._clock(time_s)
        first = self._frame == 0

        f = _features(objects)
        o_center, o_depth, o_area = f[:, 0:2], f[:, 2], f[:, 3]
        o_label, o_bbox = f[:, 4].astype(np.int64), f[:, 5:9]
        n_old = len(self._ids)

        # Predict each track forward by the frames since its last detection.
        steps = (self._missed + 1).astype(np.float64)
        shift = self._cvel * steps[:, None]
        p_center = self._center + shift
        p_bbox = self._bbox + np.concatenate([shift, shift], axis=1)
        v_frame = np.nan_to_num(self._v) * (1.0 if self._per_frame else self._dt)
        p_depth = self._zfit + v_frame * steps

        cost = match_cost(
            p_center, p_depth, self._area, p_bbox, self._label, self._missed,
            o_center, o_depth, o_area, o_bbox, o_label,
            math.hypot(width, height), cfg,
        )  # fmt: skip
        rows, cols = assign(cost)

        # Every track's queue advances one slot; detections fill the newest one below.
        self._qt = np.roll(self._qt, -1, axis=1)
        self._qz = np.roll(self._qz, -1, axis=1)
        self._qt[:, -1] = t_now
        self._qz[:, -1] = np.nan
        self._missed += 1

        # Matched tracks.
        zo = o_depth[cols]
        z_ok = np.isfinite(zo) & (zo > 0)
        z_new = np.where(z_ok, zo, self._depth[rows])
        # Areas compared at the track's fitted depth, not this frame's mean depth: the area
        # change of an approaching object is then not read as entering, and the biased mean
        # depth of a partly visible object does not hide its area change either.
        z_ref = np.where(np.isfinite(p_depth[rows]), p_depth[rows], z_new)
        marea_new = o_area[cols] * z_ref**2
        marea_old = self._area[rows] * self._zfit[rows] ** 2
        b = cfg.border_px
        at_border = (
            (o_bbox[cols, 0] <= b)
            | (o_bbox[cols, 1] <= b)
            | (o_bbox[cols, 2] >= width - 1 - b)
            | (o_bbox[cols, 3] >= height - 1 - b)
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            change = marea_new / marea_old - 1.0
            jump = np.maximum(marea_new / self._marea[rows], self._marea[rows] / marea_new)
        prev = self._status[rows]
        thr = cfg.border_area_change
        # Hysteresis: an object keeps entering (leaving) while its area does not reverse,
        # so slow entries are not cut into entering/visible flicker.
        entering = at_border & ((change > thr) | ((prev == _ENTERING) & (change >= 0)))
        leaving = at_border & ~entering & ((change < -thr) | ((prev == _LEAVING) & (change <= 0)))
        status = np.where(entering, _ENTERING, np.where(leaving, _LEAVING, _VISIBLE))
        valid = z_ok & ~(jump > cfg.max_area_jump)
        if not cfg.fit_border_entries:
            valid &= status == _VISIBLE
        self._qz[rows, -1] = np.where(valid, zo, np.nan)

        gap = self._missed[rows].astype(np.float64)  # frames since previous detection
        dc = (o_center[cols] - self._center[rows]) / gap[:, None]
        seen_before = self._hits[rows] >= 2
        self._cvel[rows] = np.where(seen_before[:, None], 0.5 * self._cvel[rows] + 0.5 * dc, dc)
        self._center[rows] = o_center[cols]
        self._bbox[rows] = o_bbox[cols]
        self._depth[rows] = z_new
        self._area[rows] = o_area[cols]
        # The running area follows entering/leaving objects at once (their area change is
        # real), others slowly so that a one-frame split or merge stands out.
        border_move = status != _VISIBLE
        self._marea[rows] = np.where(
            border_move | ~np.isfinite(self._marea[rows]), marea_new, 0.7 * self._marea[rows] + 0.3 * marea_new
        )
        self._label[rows] = o_label[cols]
        self._status[rows] = status
        self._hits[rows] += 1
        self._missed[rows] = 0
        for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
            self._last[r] = objects[c]

        # Unmatched objects start tracks.
        new_cols = np.setdiff1d(np.arange(len(objects)), cols, assume_unique=True)
        k = len(new_cols)
        if k:
            n = cfg.queue_length
            nz = o_depth[new_cols]
            nz_ok = np.isfinite(nz) & (nz > 0)
            nb = o_bbox[new_cols]
            n_border = (nb[:, 0] <= b) | (nb[:, 1] <= b) | (nb[:, 2] >= width - 1 - b) | (nb[:, 3] >= height - 1 - b)
            n_status = np.where(n_border & (not first), _ENTERING, _VISIBLE)
            qz = np.full((k, n), np.nan)
            n_valid = nz_ok & ((n_status == _VISIBLE) | cfg.fit_border_entries)
            qz[:, -1] = np.where(n_valid, nz, np.nan)
            qt = np.full((k, n), np.nan)
            qt[:, -1] = t_now
            self._ids = np.concatenate([self._ids, np.arange(self._next_id, self._next_id + k)])
            self._next_id += k
            self._hits = np.concatenate([self._hits, np.ones(k, np.int64)])
            self._missed = np.concatenate([self._missed, np.zeros(k, np.int64)])
            self._status = np.concatenate([self._status, n_status])
            self._center = np.concatenate([self._center, o_center[new_cols]])
            self._cvel = np.concatenate([self._cvel, np.zeros((k, 2))])
            self._bbox = np.concatenate([self._bbox, nb])
            self._depth = np.concatenate([self._depth, np.where(nz_ok, nz, np.nan)])
            self._zfit = np.concatenate([self._zfit, np.where(nz_ok, nz, np.nan)])
            self._area = np.concatenate([self._area, o_area[new_cols]])
            self._marea = np.concatenate([self._marea, o_area[new_cols] * nz**2])
            self._label = np.concatenate([self._label, o_label[new_cols]])
            self._v = np.concatenate([self._v, np.full(k, np.nan)])
            self._qt = np.concatenate([self._qt, qt])
            self._qz = np.concatenate([self._qz, qz])
            self._last.extend(objects[c] for c in new_cols.tolist())
            self._motion.extend([Motion(0)] * k)  # placeholders, written below

        # Range flow for every track at once.
        v, z_now = fit_radial_velocity(self._qt, self._qz, t_now)
        have_v = np.isfinite(v)
        self._zfit[rows] = np.where(np.isfinite(z_now[rows]), z_now[rows], z_ref)
        self._v = np.where(have_v, v, self._v)
        per_frame = bool(self._per_frame)
        min_speed = cfg.min_speed_per_frame if per_frame else cfg.min_speed
        detected = self._missed == 0
        # Occluded tracks coast on their held velocity; their depth is predicted from it.
        z_pred = np.where(detected, z_now, self._depth + np.nan_to_num(self._v) * (t_now - self._t_seen()))
        v_out = np.where(detected, v, self._v)
        ttc = time_to_collision(z_pred, v_out, min_speed)
        self._status[~detected] = _OCCLUDED

        # Python objects only for what is returned.
        motions: dict[int, Motion] = {}
        idx_of_col = np.empty(len(objects), np.int64)
        idx_of_col[cols] = rows
        idx_of_col[new_cols] = np.arange(n_old, n_old + k)
        ids_l = self._ids.tolist()
        st_l = self._status.tolist()
        v_l = v_out.tolist()
        ttc_l = ttc.tolist()
        for c, i in enumerate(idx_of_col.tolist()):
            vi, ti = v_l[i], ttc_l[i]
            m = Motion(
                track_id=ids_l[i],
                v_radial=None if vi != vi else vi,  # NaN test without a call
                ttc=None if ti != ti else ti,
                status=STATUSES[st_l[i]],
                per_frame=per_frame,
            )
            motions[objects[c].id] = m
            self._motion[i] = m

        missed_idx = np.flatnonzero(~detected)
        confirmed = self._hits >= cfg.min_hits
        occluded: list[Track] = []
        for i in missed_idx.tolist():
            vi, ti = v_l[i], ttc_l[i]
            self._motion[i] = Motion(
                track_id=ids_l[i],
                v_radial=None if vi != vi else vi,
                ttc=None if ti != ti else ti,
                status="occluded",
                per_frame=per_frame,
            )
        dead = ~detected & (~confirmed | (self._missed > cfg.max_missed))
        ended = tuple(self._snapshot(i) for i in np.flatnonzero(dead & confirmed).tolist())
        occluded = [self._snapshot(i) for i in missed_idx.tolist() if not dead[i]]
        if dead.any():
            self._drop(~dead)
        return TrackUpdate(motions=motions, occluded=tuple(occluded), ended=ended)

    def _t_seen(self) -> NDArray[np.float64]:
        """Queue time of each track's last detection (for coasting depth)."""
        per = 1.0 if self._per_frame else self._dt
        now = self._t_last if self._t_last is not None else float(self._frame)
        return np.asarray(now - self._missed * per, dtype=np.float64)

    def _drop(self, keep: NDArray[np.bool_]) -> None:
        """Keep only the rows where ``keep`` is True."""
        for name in (
            "_ids", "_hits", "_missed", "_status", "_center", "_cvel", "_bbox", "_depth", "_zfit",
            "_area", "_marea", "_label", "_v", "_qt", "_qz",
        ):  # fmt: skip
            setattr(self, name, getattr(self, name)[keep])
        idx = np.flatnonzero(keep).tolist()
        self._last = [self._last[i] for i in idx]
        self._motion = [self._motion[i] for i in idx]
