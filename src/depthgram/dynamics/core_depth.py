"""The depth change of each object read from the pixels that stay in it (issue 13, item 1).

The paper reads radial motion from the change of an object's mean depth. On a moving camera
that mean moves with what part of the object is seen: a wall cut by the image edge, a floor
uncovered by the camera's turn, a segment that gains an arm or a few pixels of floor. The
change of its *core* does not: the pixels that belong to the object in this frame and, moved
back by the image motion, belonged to the same track's segment in the previous frame. Their
mean depth difference is the radial motion of the same surface points, which is what a
radial velocity of a surface means (and what the ground truth of
:func:`depthgram.dynamics.evaluate.radial_velocity_from_poses` carries each pixel through).

The image motion comes from the camera's own motion where the frame has intrinsics: a rigid
motion per frame by a point-to-plane ICP on the two frames' depth (:class:`EgoMotion`), which
moves each pixel by the image motion of its still point (a turn moves the image alike, a step
by parallax: walls and floors seen at a slant move by different amounts across the image).
Without intrinsics, where the ICP fails or finds the camera still, it is one shift per frame,
found by phase correlation of the two frames' depth gradients (:func:`image_shift`). Each
tracked object's own image motion is tried beside it (an object moving in front of the camera).

What was measured against what: on 7-Scenes (Kinect v1, hand-held, 300 frames) the tracker's
readings against the poses' truth, per object kind, for the mean depth, the median, a 10-90 %
trimmed mean, the core without a shift, the core moved by the object's centroid motion, the
core moved by the image shift, by the poses' true median flow, by the poses' true camera
motion and by the ICP's, and a range-flow constraint fit per object; on the simulator's
``approach``, ``crossing``, ``touching`` and ``ball_wall`` scenes (a still camera) against
their exact radial velocities. ``benchmarks/bench_tracking.py --depth core`` (camera motion
and shift side by side) and ``--depth plain`` give the figures.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from concurrent.futures import Executor

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.dynamics.camera_motion import CameraMotion, FramePixels

__all__ = ["core_depth_change", "inner_edge_shift", "still_depth_change", "warm_up"]

#: A pixel pair whose depths differ by more than this fraction of the depth is taken for an
#: edge the shift did not line up (another surface), not for motion: 10 % of the depth in one
#: frame is 90 m/s at 3 m and 30 frames/s.
_EDGE_FRACTION = 0.1


#: Pixels of an object's core read per candidate motion: larger objects are read on a grid
#: of every k-th row and column (their mean change needs no more: on 7-Scenes within 25 % +
#: 30 mm/s 0.849, 0.848, 0.847 at 3000, 1500, 1000 pixels; the core reading 3.3 ms of a frame
#: at 3000, 2.0 at 1500).
_CORE_SAMPLE_PX = 1500


def _sample_step(box: tuple[int, int, int, int]) -> int:
    """Every how many rows and columns an object's box is read: about :data:`_CORE_SAMPLE_PX` pixels."""
    x0, y0, x1, y1 = box
    return max(1, math.isqrt(max((x1 - x0) * (y1 - y0), 1) // _CORE_SAMPLE_PX))


#: How much larger (fraction) the core under the frame's shift must be than under the
#: camera's motion to take the shift: on the simulator's ``ball_wall`` (a still camera, a
#: floor, a wall and a ball) the ICP slides sideways by 5 px a frame, and the ball's readings
#: within 25 % + 30 mm/s went from 0.82 to 0.94 with this test; 7-Scenes unchanged.
_SHIFT_KEEPS_MORE = 0.05


#: A candidate image motion: one shift (dx, dy) px for the whole object, or the camera's.
Candidate = tuple[float, float] | CameraMotion


@njit(cache=True, nogil=True)
def _core_sums(
    z_now: NDArray[np.floating],
    labels_now: NDArray[np.integer],
    oid: int,
    box: tuple[int, int, int, int],
    step: int,
    camera: bool,
    a: NDArray[np.float64],
    prev_z: NDArray[np.floating],
    prev_labels: NDArray[np.integer],
    pid: int,
    edge: float,
) -> tuple[int, float, float, int]:
    """Core size (sampled px), mean depth change (mm) and its spread (mm) under one image motion.

    The object ``oid``'s pixels are read in its ``box`` (x0, y0, x1, y1, half-open) on every
    ``step``-th row and column, as float32; the fourth value is how many of them have a reading
    (sampled px). ``camera``: ``a`` holds the rotation (row-major), the translation (mm), fx,
    fy, cx, cy, then the object's own image scale and its centre (px, the principal point),
    applied after the camera's motion; otherwise the shift dx, dy (px), the scale and its
    centre (px). One pass per
    object and motion: the same steps in numpy and ``cv2.remap`` cost some twenty calls, which
    made the core reading 5.9 ms of a 7-Scenes frame for 13 objects.
    """
    h, w = prev_z.shape
    x0, y0, x1, y1 = box
    n = 0
    own = 0
    s1 = 0.0
    s2 = 0.0
    for yy0 in range(y0, y1, step):
        gy = float(yy0)
        for xx0 in range(x0, x1, step):
            z32 = np.float32(z_now[yy0, xx0])
            if not (labels_now[yy0, xx0] == oid and z32 > 0):
                continue
            own += 1
            z = float(z32)
            gx = float(xx0)
            if camera:
                px = (gx - a[14]) / a[12] * z
                py = (gy - a[15]) / a[13] * z
                qx = a[0] * px + a[1] * py + a[2] * z + a[9]
                qy = a[3] * px + a[4] * py + a[5] * z + a[10]
                qz = a[6] * px + a[7] * py + a[8] * z + a[11]
                if not qz > 0:
                    continue
                x = (a[12] * qx / qz + a[14] - a[17]) * a[16] + a[17]
                y = (a[13] * qy / qz + a[15] - a[18]) * a[16] + a[18]
            else:
                x = (gx - a[3]) * a[2] + a[3] + a[0]
                y = (gy - a[4]) * a[2] + a[4] + a[1]
            if not (x > -1.0 and y > -1.0 and x < w and y < h):
                continue
            xf = math.floor(x)
            yf = math.floor(y)
            u = x - xf
            v = y - yf
            xi = int(xf)
            yi = int(yf)
            mine = 0.0
            z0 = 0.0
            for k in range(4):
                xx = xi + (k & 1)
                yy = yi + (k >> 1)
                wk = (u if k & 1 else 1.0 - u) * (v if k >> 1 else 1.0 - v)
                if wk == 0.0 or xx < 0 or yy < 0 or xx >= w or yy >= h:
                    continue
                zk = float(prev_z[yy, xx])
                z0 += wk * zk
                if prev_labels[yy, xx] == pid and zk > 0:
                    mine += wk
            # every neighbour that weighs in belongs to the track's previous segment
            d = z - z0
            if mine > 0.999 and abs(d) <= edge * z:
                n += 1
                s1 += d
                s2 += d * d
    if n == 0:
        return 0, math.nan, math.nan, own
    mean = s1 / n
    return n, mean, math.sqrt(max(s2 / n - mean * mean, 0.0)), own


def _camera_params(camera: CameraMotion) -> NDArray[np.float64]:
    """Return the camera's motion as :func:`_core_sums` reads it: rotation, translation (mm), fx, fy, cx, cy.

    Then the object's own image scale, 1, and its centre (filled per object by :class:`_Core`).
    """
    k = camera.intrinsics
    a = np.concatenate([camera.rotation.ravel(), camera.translation_mm, [k.fx, k.fy, k.cx, k.cy, 1.0, 0.0, 0.0]])
    return np.ascontiguousarray(a, dtype=np.float64)


class _Core:
    """One object's pixels this frame, read against the previous frame under candidate motions.

    Under a shift, the pixel ``p`` of this frame was at ``c + (p - c) * scale + shift`` in the
    previous one, ``c`` the box's centre: an object coming closer grows in the image about
    itself, and reading its previous depth at the same pixel would read a point further out on
    its surface. Under the camera's motion each pixel goes where its still point was (which
    holds the growth the camera's own motion causes), and then, for an object that moves in depth
    itself, by the scale of that own motion (its depth then over its depth now) about the
    principal point, where a point moving in depth alone is seen to move from: without it a
    ball closing at 600 mm/s at 2 m read 5 % fast under the camera's motion, since at a fixed
    pixel the depth of an approaching sphere changes faster than its centre's (towards its
    outline the ray meets it ever further out; 5-10 % for a ball of 100-120 mm at 1.5-2 m). The previous depth is read
    bilinearly, from four pixels that all belong to the track's previous segment: on a steep
    flank (a cylinder's side) half a pixel is tens of millimetres.
    """

    def __init__(
        self,
        prev: FramePixels,
        now: FramePixels,
        oid: int,
        pid: int,
        box: tuple[int, int, int, int],
        motions: Sequence[Candidate],
        scale: float,
        camera_params: NDArray[np.float64] | None,
        own_scale: float = 1.0,
    ) -> None:
        x0, y0, x1, y1 = box
        self.box = box
        self.step = _sample_step(box)
        #: pixels read per motion (an upper bound of the core: sharing the work out)
        self.size = len(range(y0, y1, self.step)) * len(range(x0, x1, self.step))
        self.now = now
        self.prev = prev
        self.oid = oid
        self.pid = pid
        centre = (0.5 * (x0 + x1 - 1), 0.5 * (y0 + y1 - 1))
        self.params: list[tuple[bool, NDArray[np.float64]]] = []
        for m in motions:
            if isinstance(m, CameraMotion):
                a = camera_params if camera_params is not None else _camera_params(m)
                if own_scale != 1.0:
                    a = a.copy()
                    a[16] = own_scale  # about the principal point, a[14:16]
                    a[17:19] = a[14], a[15]
                self.params.append((True, a))
            else:
                self.params.append((False, np.array([m[0], m[1], scale, *centre], dtype=np.float64)))

    def stats(self, k: int) -> tuple[int, float, float, int]:
        """:func:`_core_sums` of this object under motion ``k``: core px, mean change, spread, object px."""
        camera, a = self.params[k]
        now, prev = self.now, self.prev
        return _core_sums(
            now.depth_mm, now.labels, self.oid, self.box, self.step, camera, a,
            prev.depth_mm, prev.labels, self.pid, _EDGE_FRACTION,
        )  # fmt: skip


def inner_edge_shift(
    prev_box: tuple[int, int, int, int], box: tuple[int, int, int, int], size: tuple[int, int], border_px: int = 2
) -> tuple[float, float] | None:
    """Image motion (px) of an object cut by the image's edge, read from its edges inside the image.

    An object entering or leaving the view moves its centre by its motion plus its growth or
    shrinking at the edge; its edge inside the image moves with it alone (the simulator's person
    walking in from the side: its centre moved 2 px a frame, its inner edge 4, its true motion).
    Along an axis where the object touches one border in both frames, the other edge's move;
    along an axis where it touches neither or both, the box centre's. None where it touches no
    border in either frame (its centre's move says the same). As :func:`image_shift`'s: the point
    at ``(x, y)`` now was at ``(x + dx, y + dy)`` before.

    Parameters
    ----------
    prev_box, box : tuple of int
        The object's bbox (x0, y0, x1, y1) px, half-open, in the previous frame and now.
    size : tuple of int
        (width, height) of the image (px).
    border_px : int
        Distance from the image's edge within which a box touches it (px).
    """
    out: list[float] = []
    touched = False
    for lo, hi, n in ((0, 2, size[0]), (1, 3, size[1])):
        lo_then, lo_now = prev_box[lo] <= border_px, box[lo] <= border_px
        hi_then, hi_now = prev_box[hi] >= n - border_px, box[hi] >= n - border_px
        if lo_then and lo_now and not (hi_then or hi_now):
            out.append(float(prev_box[hi] - box[hi]))
            touched = True
        elif hi_then and hi_now and not (lo_then or lo_now):
            out.append(float(prev_box[lo] - box[lo]))
            touched = True
        else:
            out.append(0.5 * (prev_box[lo] + prev_box[hi] - box[lo] - box[hi]))
    return (out[0], out[1]) if touched else None


def core_depth_change(
    prev: FramePixels,
    now: FramePixels,
    pairs: Mapping[int, tuple[int, tuple[int, int, int, int], Sequence[tuple[float, float]], float]],
    shift: tuple[float, float],
    *,
    camera: CameraMotion | None = None,
    min_px: int = 20,
    min_share: float = 0.1,
    prefer: float = 0.8,
    helper: Executor | None = None,
    own_scales: Mapping[int, float] | None = None,
    moving: Collection[int] | None = None,
) -> dict[int, float]:
    """Mean depth change of each object's core from the previous frame (mm).

    Two kinds of image motion are tried per object: the frame's (``shift``: the camera's motion,
    which moves each pixel by its own amount, or one shift for the whole frame) and the object's
    own (its track's motion in the image). The object's own is taken only where it lines the
    core up clearly better (the spread of the depth change falls below ``prefer`` times the
    frame motion's): an object moving across a still view (the simulator's cart) needs its own,
    while a surface cut by the image edge moves its outline, and with it the centre, for reasons
    other than motion.

    Parameters
    ----------
    prev, now : FramePixels
        The previous and this frame.
    pairs : mapping
        This frame's object id to (the id the same track had in the previous frame, the
        object's bbox (x0, y0, x1, y1) px half-open, the track's own image motions to try,
        each (dx, dy) px as in :func:`image_shift`, and the object's image scale from the
        previous frame to this one, the ratio of its depths then and now).
    shift : tuple of float
        The frame's shift (dx, dy) px, from :func:`image_shift`.
    camera : CameraMotion, optional
        The camera's motion (:class:`EgoMotion`): tried first, and the shift only where it
        keeps clearly more of the object inside its previous segment.
    min_px : int
        Fewest core pixels for a reading (px).
    min_share : float
        Smallest core as a share of the object's valid pixels this frame: below it the object
        is mostly new surface and its core says little (0..1).
    prefer : float
        How much smaller the spread under the object's own motion must be to take it (0..1).
    helper : Executor, optional
        A thread that reads about half of the (object, motion) pairs while the caller reads the
        others, when the caller's second core would idle otherwise (the result is the same).
    own_scales : mapping of int to float, optional
        This frame's object id to its image scale from the previous frame under its own radial
        motion alone, the camera's part taken out (its depth then plus its own change, over its
        depth then): applied about the principal point after the ``camera``'s motion. Default
        1 (the object stands still).
    moving : collection of int, optional
        This frame's ids of objects known to move on their own: their own image motion is
        taken unless the frame's lines the core up clearly better (spread below ``prefer``
        times the own motion's), the mirror of the rule for the rest.

    Returns
    -------
    dict of int to float
        Object id (this frame) to ``mean(z_now - z_prev)`` over its core (mm); objects without
        a core of ``min_px`` pixels and ``min_share`` of their area are left out.
    """
    if np.shape(prev.labels) != np.shape(now.labels) or np.shape(prev.depth_mm) != np.shape(now.depth_mm):
        return {}
    cam = None if camera is None else _camera_params(camera)
    cores: list[tuple[int, _Core, int]] = []
    for oid, (pid, box, owns, scale) in pairs.items():
        tried: list[tuple[float, float]] = [shift]
        todo: list[Candidate] = [shift] if camera is None else [camera, shift]
        for own in owns:
            # a motion within a quarter pixel of one tried reads the same core
            if any(abs(own[0] - t[0]) + abs(own[1] - t[1]) < 0.25 for t in tried):
                continue
            tried.append(own)
            todo.append(own)
        own_scale = 1.0 if own_scales is None else own_scales.get(oid, 1.0)
        cores.append((oid, _Core(prev, now, oid, pid, box, todo, scale, cam, own_scale), len(todo)))
    read = _read_cores([(core, m) for _, core, m in cores], helper)
    out: dict[int, float] = {}
    for c, (oid, core, m) in enumerate(cores):
        n, mean, spread, sampled = read[c, 0]
        # sizes on the sampled grid, compared with the area on it
        area = sampled * core.step * core.step
        k = max(area // max(sampled, 1), 1)
        ok = n * k >= min_px and n * k >= min_share * area
        first = 1
        if camera is not None:
            # The frame's shift instead of the camera's motion where it keeps clearly more of
            # the object inside its previous segment: the ICP slid along what the still scene
            # does not pin down (a floor and a wall say nothing of a sideways move), which
            # moves a small object's core off it.
            n2, mean2, spread2, _ = read[c, 1]
            if n2 > (1.0 + _SHIFT_KEEPS_MORE) * n:
                n, mean, spread = n2, mean2, spread2
                ok = n * k >= min_px and n * k >= min_share * area
            first = 2
        # an object moving on its own: its own image motion first, the frame's only where it
        # lines the core up clearly better (the mirror of the rule for the still world)
        bar = 1.0 / prefer if moving is not None and oid in moving else prefer
        for j in range(first, m):
            n2, mean2, spread2, _ = read[c, j]
            if n2 * k >= min_px and n2 * k >= min_share * area and (not ok or spread2 < bar * spread):
                n, mean, spread, ok = n2, mean2, spread2 / prefer, True
        if ok:
            out[oid] = mean
    return out


def _read_cores(
    cores: Sequence[tuple[_Core, int]], helper: Executor | None
) -> dict[tuple[int, int], tuple[int, float, float, int]]:
    """Return :meth:`_Core.stats` of each core's first ``m`` motions, keyed by ``(core's index, motion)``.

    With a ``helper``, the (core, motion) pairs are shared out by the pixels they read (largest
    first, each to the lighter side) and the helper reads its share while this thread reads
    the other: each reading is one compiled call that releases the GIL, and its result does
    not depend on the thread that made it.
    """
    jobs = [(c, k) for c, (_, m) in enumerate(cores) for k in range(m)]

    def read(share: Sequence[tuple[int, int]]) -> list[tuple[int, float, float, int]]:
        return [cores[c][0].stats(k) for c, k in share]

    mine: list[tuple[int, int]] = jobs
    theirs: list[tuple[int, int]] = []
    if helper is not None and len(jobs) > 1:
        mine = []
        load = [0, 0]
        for c, k in sorted(jobs, key=lambda ck: -cores[ck[0]][0].size):
            side = 0 if load[0] <= load[1] else 1
            (mine if side == 0 else theirs).append((c, k))
            load[side] += cores[c][0].size + 1
    future = helper.submit(read, theirs) if helper is not None and theirs else None
    out = dict(zip(mine, read(mine), strict=True))
    if future is not None:
        out.update(zip(theirs, future.result(), strict=True))
    return out


def still_depth_change(
    now: FramePixels, boxes: Mapping[int, tuple[int, int, int, int]], camera: CameraMotion
) -> dict[int, float]:
    """Mean depth change each object would show since the previous frame if it stood still (mm).

    A still point at ``P`` in this frame's camera was at ``R P + t`` in the previous one
    (:class:`CameraMotion`), so its depth changed by ``P_z - (R P + t)_z``; this is linear in
    ``P``, and an object's mean change is that of its mean point. It is the camera's share of
    the object's radial motion: read from the whole view's ICP, it has none of the depth noise
    of the object's own pixels read twice (on 7-Scenes, against the poses' truth: |error|
    median 15 mm/s against 26 for the core's change).

    Parameters
    ----------
    now : FramePixels
        This frame's depth (mm) and label map.
    boxes : mapping of int to tuple of int
        Object id to its bbox (x0, y0, x1, y1) px, half-open.
    camera : CameraMotion
        The camera's motion from the previous frame to this one.

    Returns
    -------
    dict of int to float
        Object id to depth change (mm); objects without a valid pixel are left out.
    """
    if not boxes:
        return {}
    k = camera.intrinsics
    r, t = camera.rotation, camera.translation_mm
    ids = np.fromiter(boxes, np.int64, count=len(boxes))
    box = np.array(list(boxes.values()), np.int64).reshape(-1, 4)
    # the same sampling grid as the core's (its mean needs no more pixels)
    steps = np.array([_sample_step(b) for b in boxes.values()], np.int64)
    # one compiled pass over the objects: per object, the numpy steps cost some 40 µs
    sums = _mean_points(now.depth_mm, now.labels, ids, box, steps)
    out: dict[int, float] = {}
    for oid, (cnt, sx, sy, sz) in zip(ids.tolist(), sums.tolist(), strict=True):
        if cnt == 0:
            continue
        mx, my, mz = (sx - k.cx * sz) / k.fx / cnt, (sy - k.cy * sz) / k.fy / cnt, sz / cnt
        out[oid] = mz - (r[2, 0] * mx + r[2, 1] * my + r[2, 2] * mz + t[2])
    return out


@njit(cache=True, nogil=True)
def _mean_points(
    depth: NDArray[np.floating],
    labels: NDArray[np.integer],
    ids: NDArray[np.int64],
    boxes: NDArray[np.int64],
    steps: NDArray[np.int64],
) -> NDArray[np.float64]:
    """Per object: its sampled valid pixels' count, and the sums of ``x z``, ``y z`` and ``z`` (px mm, mm).

    Object ``j`` is read on every ``steps[j]``-th row and column of its box.
    """
    out = np.zeros((ids.shape[0], 4))
    for j in range(ids.shape[0]):
        x0, y0, x1, y1 = boxes[j, 0], boxes[j, 1], boxes[j, 2], boxes[j, 3]
        step = steps[j]
        oid = ids[j]
        n = 0
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for y in range(y0, y1, step):
            for x in range(x0, x1, step):
                z = float(depth[y, x])
                if labels[y, x] == oid and z > 0:
                    n += 1
                    sx += x * z
                    sy += y * z
                    sz += z
        out[j, 0] = n
        out[j, 1] = sx
        out[j, 2] = sy
        out[j, 3] = sz
    return out


def warm_up() -> None:
    """Load (on a fresh install: compile) the kernels that only a moving camera reaches.

    A warm-up on one still frame does not move the camera, so the camera's share of each
    object's depth change (:func:`still_depth_change`) was compiled at the first moving frame
    of a stream (249 ms on a fresh install). Called by ``Pipeline.warm_up``.
    """
    z = np.ones((2, 2), np.float32)
    one = np.ones(1, np.int64)
    _mean_points(z, np.ones((2, 2), np.int32), one, np.array([[0, 0, 2, 2]], np.int64), one)
