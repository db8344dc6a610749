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
from collections.abc import Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.frame import Intrinsics

__all__ = [
    "CameraMotion",
    "EgoMotion",
    "FramePixels",
    "core_depth_change",
    "image_shift",
    "inner_edge_shift",
    "still_depth_change",
]

#: Side of the grid on which the image shift is found (px of the down-sampled image).
_SHIFT_W, _SHIFT_H = 160, 120
#: A pixel pair whose depths differ by more than this fraction of the depth is taken for an
#: edge the shift did not line up (another surface), not for motion: 10 % of the depth in one
#: frame is 90 m/s at 3 m and 30 frames/s.
_EDGE_FRACTION = 0.1


#: Peak of the phase correlation below which the image shift is taken as none.
_MIN_RESPONSE = 0.5


@dataclass(frozen=True, eq=False)
class FramePixels:
    """One frame's depth and label map, as handed to :meth:`depthgram.dynamics.Tracker.update`.

    Attributes
    ----------
    depth_mm : ndarray of float, shape (H, W)
        Depth (mm); 0 or NaN where invalid.
    labels : ndarray of int, shape (H, W)
        Object id (``SceneObject.id``) per pixel, 0 for none.
    intrinsics : Intrinsics or None
        The camera's pinhole intrinsics (px), as :attr:`depthgram.frame.Frame.intrinsics`;
        with them the camera's own motion gives each pixel its image motion
        (:class:`EgoMotion`), without them one shift per frame does (:func:`image_shift`).
    """

    depth_mm: NDArray[np.floating]
    labels: NDArray[np.integer]
    intrinsics: Intrinsics | None = None


def shift_structure(depth_mm: NDArray[np.floating]) -> NDArray[np.float32]:
    """Down-sampled depth gradient magnitude (mm/px), clipped.

    The scene's edges, whose place moves with the image while their depth offset (the radial motion)
    does not matter.
    """
    z = np.asarray(depth_mm, dtype=np.float32)
    if not math.isfinite(float(np.sum(z, dtype=np.float64))):
        # a frame from depthgram's sources has 0 where invalid; nan_to_num's copy is a third of
        # this function's time, so it is paid only where a NaN or inf is there to replace
        z = np.nan_to_num(z, nan=0.0)
    small = cv2.resize(z, (_SHIFT_W, _SHIFT_H), interpolation=cv2.INTER_AREA)
    gx = cv2.Sobel(small, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(small, cv2.CV_32F, 0, 1)
    return np.asarray(np.clip(cv2.magnitude(gx, gy), 0.0, 200.0), dtype=np.float32)


def image_shift(prev_depth_mm: NDArray[np.floating], depth_mm: NDArray[np.floating]) -> tuple[float, float]:
    """Return the image motion from the previous frame to this one, one shift for the whole frame.

    Parameters
    ----------
    prev_depth_mm, depth_mm : ndarray of float, shape (H, W)
        The two frames' depth (mm), 0 or NaN where invalid.

    Returns
    -------
    (dx, dy) : tuple of float
        Shift (px, full resolution) such that the scene point at ``(x, y)`` in this frame was
        at ``(x + dx, y + dy)`` in the previous one.
    """
    h, w = np.shape(depth_mm)
    return structure_shift(shift_structure(prev_depth_mm), shift_structure(depth_mm), (w, h))


def structure_shift(
    prev_structure: NDArray[np.float32], structure: NDArray[np.float32], size: tuple[int, int]
) -> tuple[float, float]:
    """:func:`image_shift` from the two frames' :func:`shift_structure` (a caller keeps the last one).

    ``size`` is the frames' (width, height) in px.
    """
    w, h = size
    win = cv2.createHanningWindow((_SHIFT_W, _SHIFT_H), cv2.CV_32F)
    # copies: OpenCV's phaseCorrelate windows its inputs in place, and a caller keeps them
    (sx, sy), response = cv2.phaseCorrelate(prev_structure.copy(), structure.copy(), win)
    if not response >= _MIN_RESPONSE:
        # No clear peak: a still view of smooth surfaces (the simulator's), whose gradients
        # are mostly noise. Most of such an image does not move.
        return 0.0, 0.0
    # To 1/1024 px: OpenCV's phase correlation varies in its last bits from run to run (by some
    # 1e-9 px) when it runs in a thread beside the segmentation, and the tracker's readings
    # should not.
    return round(-float(sx) * w / _SHIFT_W * 1024) / 1024, round(-float(sy) * h / _SHIFT_H * 1024) / 1024


#: Width of the grid on which the camera's motion is found (px): every k-th pixel of each
#: k-th row, k the whole ratio of the frame's width to it.
_EGO_W = 160
#: Depths beyond which the odometry ignores a pixel (m): beyond 8 m consumer depth cameras
#: read tens of centimetres of noise.
_EGO_MAX_DEPTH_M = 8.0
#: Pixel pairs further apart in depth than this are not the same surface to the ICP (m): at
#: 7 cm (OpenCV's odometry's default) a moving object or an occluding edge pulls the fit (flow
#: error against 7-Scenes' poses, OpenCV's ICP: median 0.43 px at 7 cm, 0.39 px at 3 cm).
_EGO_MAX_DEPTH_DIFF_M = 0.03
#: Least share of the grid's pixels whose still point, carried back by the found motion, lands
#: on the previous frame's surface within the depth gate above; below it the ICP has locked
#: onto something else than the still scene (on 7-Scenes a share under 0.8 came with flow
#: errors of 3 px and more) and one shift per frame is used instead.
_EGO_MIN_INLIERS = 0.8
#: Mean image motion (px, full resolution) below which the camera is taken as still.
_EGO_STILL_PX = 0.3


@dataclass(frozen=True, eq=False)
class CameraMotion:
    """The camera's rigid motion from the previous frame to this one.

    A still point at ``P`` (mm) in this frame's camera coordinates was at
    ``rotation @ P + translation_mm`` in the previous frame's.

    Attributes
    ----------
    rotation : ndarray of float, shape (3, 3)
        Rotation (dimensionless).
    translation_mm : ndarray of float, shape (3,)
        Translation (mm).
    intrinsics : Intrinsics
        The camera's intrinsics at the frames' full size (px).
    """

    rotation: NDArray[np.float64]
    translation_mm: NDArray[np.float64]
    intrinsics: Intrinsics

    @property
    def still(self) -> bool:
        """Whether this is no motion at all (the identity)."""
        return bool(np.array_equal(self.rotation, np.eye(3)) and not np.any(self.translation_mm))

    def previous_xy(
        self, xs: NDArray[np.floating], ys: NDArray[np.floating], depth_mm: NDArray[np.floating]
    ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """Where the still points seen at pixels ``(xs, ys)`` and ``depth_mm`` were in the previous frame.

        Parameters
        ----------
        xs, ys : ndarray of float
            Pixel coordinates (px) in this frame, broadcast against ``depth_mm``.
        depth_mm : ndarray of float
            Their depth (mm); pixels without one (0, NaN) get a place far outside the image.

        Returns
        -------
        (x, y) : tuple of ndarray of float32
            Pixel coordinates (px) in the previous frame, shape of ``depth_mm``.
        """
        k = self.intrinsics
        # float32 is a ten-thousandth of a pixel here, and halves the cost
        z = np.asarray(depth_mm, dtype=np.float32)
        px = (np.asarray(xs, dtype=np.float32) - np.float32(k.cx)) * np.float32(1.0 / k.fx) * z
        py = (np.asarray(ys, dtype=np.float32) - np.float32(k.cy)) * np.float32(1.0 / k.fy) * z
        r, t = self.rotation.astype(np.float32), self.translation_mm.astype(np.float32)
        qx = r[0, 0] * px + r[0, 1] * py + r[0, 2] * z + t[0]
        qy = r[1, 0] * px + r[1, 1] * py + r[1, 2] * z + t[1]
        qz = r[2, 0] * px + r[2, 1] * py + r[2, 2] * z + t[2]
        ok = (z > 0) & (qz > 0)
        safe = np.where(ok, qz, np.float32(1.0))
        x = np.where(ok, np.float32(k.fx) * qx / safe + np.float32(k.cx), np.float32(-1e6))
        y = np.where(ok, np.float32(k.fy) * qy / safe + np.float32(k.cy), np.float32(-1e6))
        return x.astype(np.float32), y.astype(np.float32)

    def image_motion(self, shape: tuple[int, int], depth_mm: NDArray[np.floating]) -> NDArray[np.float32]:
        """Each pixel's image motion back to the previous frame (px), shape (H, W, 2).

        ``[y, x]`` holds ``(dx, dy)`` such that the point at ``(x, y)`` was at
        ``(x + dx, y + dy)``, as :func:`image_shift`'s; NaN where the depth is invalid.
        """
        h, w = shape
        ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
        x, y = self.previous_xy(xs, ys, depth_mm)
        bad = x < -1e5
        out = np.stack([x - xs, y - ys], axis=-1).astype(np.float32)
        out[bad] = np.nan
        return out


class _Surface:
    """One frame's grid of points (m) with their normals, as the ICP's target.

    The points come from the depth smoothed over 3 x 3 pixels and the normals from it smoothed
    over 5 x 5 (on 7-Scenes' quantised Kinect depth: flow error median 0.39 px against 0.56 px
    unsmoothed); a normal needs its four neighbours within 5 % of its depth (no normal across an
    edge).
    """

    def __init__(self, z: NDArray[np.float32], cam: tuple[float, float, float, float]) -> None:
        self.z = z
        fx, fy, cx, cy = (np.float32(c) for c in cam)
        # points and normals as (3, H, W): the ICP reads each coordinate as one flat array
        self.points, self.normals, self.ok = _surface_arrays(z, _smooth(z, 3), _smooth(z, 5), fx, fy, cx, cy)


@njit(cache=True, nogil=True)
def _surface_arrays(
    z: NDArray[np.float32],
    z3: NDArray[np.float32],
    z5: NDArray[np.float32],
    fx: np.float32,
    fy: np.float32,
    cx: np.float32,
    cy: np.float32,
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.bool_]]:
    """Points of ``z3``, unit normals of ``z5`` and where a normal holds, each (3, H, W) or (H, W).

    A normal is the cross product of the central differences of ``z5``'s points along the row
    and the column, where the pixel and its four neighbours have a depth within 5 % of its own.
    One pass in float32, as the numpy steps it replaced (some twenty frame-sized temporaries,
    1.3 ms of the ICP's frame).
    """
    h, w = z.shape
    pts = np.empty((3, h, w), np.float32)
    nrm = np.zeros((3, h, w), np.float32)
    ok = np.zeros((h, w), np.bool_)
    for y in range(h):
        ry = (np.float32(y) - cy) / fy
        for x in range(w):
            d = z3[y, x]
            pts[0, y, x] = (np.float32(x) - cx) / fx * d
            pts[1, y, x] = ry * d
            pts[2, y, x] = d
    for y in range(1, h - 1):
        for x in range(1, w - 1):
            zc = z[y, x]
            if not zc > 0:
                continue
            lim = np.float32(0.05) * zc
            good = True
            for yy, xx in ((y, x + 1), (y, x - 1), (y + 1, x), (y - 1, x)):
                q = z[yy, xx]
                if not (q > 0 and abs(q - zc) < lim):
                    good = False
            if not good:
                continue
            # central differences of the 5 x 5-smoothed points along the row (u) and column (v)
            dr, dl, dd, dup = z5[y, x + 1], z5[y, x - 1], z5[y + 1, x], z5[y - 1, x]
            ry = (np.float32(y) - cy) / fy
            rx = (np.float32(x) - cx) / fx
            rxr = (np.float32(x + 1) - cx) / fx
            rxl = (np.float32(x - 1) - cx) / fx
            ryd = (np.float32(y + 1) - cy) / fy
            ryu = (np.float32(y - 1) - cy) / fy
            ux, uy, uz = rxr * dr - rxl * dl, ry * dr - ry * dl, dr - dl
            vx, vy, vz = rx * dd - rx * dup, ryd * dd - ryu * dup, dd - dup
            nx = uy * vz - uz * vy
            ny = uz * vx - ux * vz
            nz = ux * vy - uy * vx
            norm = np.sqrt(nx * nx + ny * ny + nz * nz)
            if norm > 0:
                ok[y, x] = True
                nrm[0, y, x] = nx / norm
                nrm[1, y, x] = ny / norm
                nrm[2, y, x] = nz / norm
    return pts, nrm, ok


def _smooth(z: NDArray[np.float32], k: int) -> NDArray[np.float32]:
    """Mean of the valid depths in a ``k`` x ``k`` window, at valid pixels (0 elsewhere)."""
    valid = (z > 0).astype(np.float32)
    total = cv2.blur(z * valid, (k, k))
    count = cv2.blur(valid, (k, k))
    return np.where((z > 0) & (count > 0), total / np.maximum(count, 1e-6), 0.0).astype(np.float32)


#: The ICP's passes: every k-th point of this frame's grid, and the iterations on it.
_ICP_PASSES = ((4, 6), (2, 3), (1, 2))
#: Weight of the ICP's pull toward standing still, per matched point (m^2 of residual per unit
#: of motion, rad or m): a motion along which the still scene says little (sliding along a floor
#: and a wall) stays near none instead of following noise or a moving object; along a direction
#: the scene does pin down it is a fraction of a percent of the data's weight.
_ICP_PRIOR = 1e-3


@njit(cache=True, nogil=True)
def _icp_sums(
    sx: NDArray[np.float32],
    sy: NDArray[np.float32],
    sz: NDArray[np.float32],
    r32: NDArray[np.float32],
    t32: NDArray[np.float32],
    cam32: NDArray[np.float32],
    px0: NDArray[np.float32],
    py0: NDArray[np.float32],
    pz0: NDArray[np.float32],
    nx0: NDArray[np.float32],
    ny0: NDArray[np.float32],
    nz0: NDArray[np.float32],
    target_ok: NDArray[np.bool_],
    w: int,
    h: int,
    gate: float,
) -> tuple[int, NDArray[np.float64], NDArray[np.float64]]:
    """One ICP step's matches and normal equations: how many pairs, ``J^T J`` and ``J^T r``.

    Each point ``s`` of this frame, moved by ``(r32, t32)``, is projected into the previous
    frame's grid (intrinsics ``cam32`` = fx, fy, cx, cy of the grid) and paired with the point
    there; a pair counts when both its depth gap and its point-to-plane residual are under
    ``gate`` (m). J's rows are ``(q x n, n)``. One compiled pass in float32, as the numpy steps it
    replaces (3.2 of the ICP's 5.4 ms per 7-Scenes frame were their calls and temporaries), and
    summed in sequence: BLAS's ``jac.T @ jac`` sums in an order that depends on its buffers'
    alignment, which moved the ICP's motion in its seventh digit from run to run.
    """
    ata = np.zeros((6, 6))
    atr = np.zeros(6)
    row = np.empty(6)
    fx, fy, cx, cy = cam32[0], cam32[1], cam32[2], cam32[3]
    g = np.float32(gate)
    n = 0
    for k in range(sx.shape[0]):
        x0, y0, z0 = sx[k], sy[k], sz[k]
        qx = r32[0, 0] * x0 + r32[0, 1] * y0 + r32[0, 2] * z0 + t32[0]
        qy = r32[1, 0] * x0 + r32[1, 1] * y0 + r32[1, 2] * z0 + t32[1]
        qz = r32[2, 0] * x0 + r32[2, 1] * y0 + r32[2, 2] * z0 + t32[2]
        if not qz > np.float32(1e-6):
            continue
        u = np.rint(fx * qx / qz + cx)
        v = np.rint(fy * qy / qz + cy)
        if not (u >= 0 and u < w and v >= 0 and v < h):
            continue
        i = int(v) * w + int(u)
        if not target_ok[i]:
            continue
        a, b, c = nx0[i], ny0[i], nz0[i]
        dz = qz - pz0[i]
        r = (qx - px0[i]) * a + (qy - py0[i]) * b + dz * c
        if not (abs(dz) < g and abs(r) < g):
            continue
        n += 1
        xf, yf, zf = float(qx), float(qy), float(qz)
        af, bf, cf = float(a), float(b), float(c)
        row[0] = yf * cf - zf * bf
        row[1] = zf * af - xf * cf
        row[2] = xf * bf - yf * af
        row[3] = af
        row[4] = bf
        row[5] = cf
        rk = float(r)
        for p in range(6):
            atr[p] += row[p] * rk
            for q in range(p, 6):
                ata[p, q] += row[p] * row[q]
    for p in range(6):
        for q in range(p):
            ata[p, q] = ata[q, p]
    return n, ata, atr


@njit(cache=True, nogil=True)
def _icp_steps(
    sx: NDArray[np.float32],
    sy: NDArray[np.float32],
    sz: NDArray[np.float32],
    rot: NDArray[np.float64],
    t: NDArray[np.float64],
    cam32: NDArray[np.float32],
    px0: NDArray[np.float32],
    py0: NDArray[np.float32],
    pz0: NDArray[np.float32],
    nx0: NDArray[np.float32],
    ny0: NDArray[np.float32],
    nz0: NDArray[np.float32],
    target_ok: NDArray[np.bool_],
    w: int,
    h: int,
    gate: float,
    iterations: int,
    prior: float,
) -> bool:
    """Run ``iterations`` ICP steps on one pass's points, updating ``rot`` and ``t`` in place.

    Each step solves the normal equations of :func:`_icp_sums`, pulled toward standing still
    by ``prior`` per matched pair, and applies the increment by Rodrigues' formula. Compiled
    with the sums: as numpy calls, the 6 x 6 solve and the 3 x 3 products cost some 50 us a
    step, eleven steps a frame. False when a step matches fewer than 100 pairs.
    """
    eye6 = np.eye(6)
    total = np.empty(6)
    for _ in range(iterations):
        n, ata, atr = _icp_sums(
            sx, sy, sz, rot.astype(np.float32), t.astype(np.float32), cam32,
            px0, py0, pz0, nx0, ny0, nz0, target_ok, w, h, gate,
        )  # fmt: skip
        if n < 100:
            return False
        mu = prior * n
        total[0] = 0.5 * (rot[2, 1] - rot[1, 2])
        total[1] = 0.5 * (rot[0, 2] - rot[2, 0])
        total[2] = 0.5 * (rot[1, 0] - rot[0, 1])
        total[3:] = t
        delta = -np.linalg.solve(ata + mu * eye6, atr + mu * total)
        d_rot = _rodrigues(delta[0], delta[1], delta[2])
        rot[:] = d_rot @ rot
        t[:] = d_rot @ t + delta[3:]
    return True


@njit(cache=True, nogil=True)
def _rodrigues(w0: float, w1: float, w2: float) -> NDArray[np.float64]:
    """Return the rotation matrix of the rotation vector ``(w0, w1, w2)`` (rad), by Rodrigues' formula."""
    th = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    k: NDArray[np.float64] = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])
    if th < 1e-12:
        small: NDArray[np.float64] = np.eye(3) + k
        return small
    k /= th
    rot: NDArray[np.float64] = np.eye(3) + math.sin(th) * k + (1.0 - math.cos(th)) * (k @ k)
    return rot


def _icp(now: _Surface, before: _Surface, cam: tuple[float, float, float, float]) -> NDArray[np.float64] | None:
    """Point-to-plane ICP with projective matching: the 4x4 motion from ``now``'s camera to ``before``'s (m).

    None when fewer than 100 points match (too little valid depth, a jump too large).
    """
    h, w = before.z.shape
    # one flat array per coordinate: picking rows of an (N, 3) array is several times slower
    px0, py0, pz0 = (before.points[i].ravel() for i in range(3))
    nx0, ny0, nz0 = (before.normals[i].ravel() for i in range(3))
    target_ok = before.ok.ravel()
    rot = np.eye(3)
    t = np.zeros(3)
    gate = _EGO_MAX_DEPTH_DIFF_M
    cam32 = np.array(cam, dtype=np.float32)
    for step, iterations in _ICP_PASSES:
        grid = now.points[:, ::step, ::step]
        mine = grid[2] > 0
        sx, sy, sz = (grid[i][mine] for i in range(3))
        found = _icp_steps(
            sx, sy, sz, rot, t, cam32, px0, py0, pz0, nx0, ny0, nz0, target_ok, w, h, gate, iterations, _ICP_PRIOR
        )
        if not found:
            return None
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = t
    return out


class EgoMotion:
    """The camera's motion between successive frames, by ICP on their depth.

    A hand-held or head-worn camera turns and moves, and each still point's image motion then
    depends on its place and depth (rotation moves the image alike, translation by parallax):
    walls and floors seen at a slant move by different amounts across the image. The rigid
    motion is found once per frame by point-to-plane ICP with projective matching (as
    KinectFusion's) on a grid of every k-th pixel (:data:`_EGO_W` columns), coarse to fine,
    each frame's points and normals prepared once and kept as the next pair's target. Objects
    moving on their own are outliers to it: its depth gate drops their pairs, its pull toward
    standing still holds what the still scene does not pin down, and their own image motion is
    tried beside the camera's (:func:`core_depth_change`).

    Hand-written in numpy rather than OpenCV's ``cv2.Odometry``, which was as accurate on
    7-Scenes' poses (flow error median 0.39 px at 160 px) but sums in threads in a varying
    order, so that its result changed from run to run on weakly constrained scenes, and the
    only way to stop that, ``cv2.setNumThreads``, is process-wide and left forked worker
    processes (``depthgram batch``) hanging.

    Call :meth:`update` once per frame, in order.
    """

    def __init__(self) -> None:
        self._key: tuple[int, int, Intrinsics] | None = None
        self._prev: _Surface | None = None
        self._cam = (1.0, 1.0, 0.0, 0.0)
        self._step = 1

    def reset(self) -> None:
        """Forget the previous frame."""
        self._prev = None

    def update(self, depth_mm: NDArray[np.floating], intrinsics: Intrinsics) -> CameraMotion | None:
        """Return the camera's motion from the previous frame to this one.

        Parameters
        ----------
        depth_mm : ndarray of float, shape (H, W)
            This frame's depth (mm), 0 or NaN where invalid.
        intrinsics : Intrinsics
            The camera's intrinsics (px).

        Returns
        -------
        CameraMotion or None
            None on the first frame, after a change of size or intrinsics, where the ICP
            finds too few matches, and where its motion carries fewer than
            :data:`_EGO_MIN_INLIERS` of the points onto the previous surface. The identity
            (:attr:`CameraMotion.still`) where the motion moves the image by less than
            :data:`_EGO_STILL_PX` on average.
        """
        h, w = np.shape(depth_mm)
        key = (h, w, intrinsics)
        if key != self._key:
            step = max(1, round(w / _EGO_W))
            # The grid's pixel i is the frame's pixel o + step * i.
            o = step // 2
            self._cam = (
                intrinsics.fx / step,
                intrinsics.fy / step,
                (intrinsics.cx - o) / step,
                (intrinsics.cy - o) / step,
            )
            self._step = step
            self._key = key
            self._prev = None
        step = self._step
        o = step // 2
        z = np.asarray(depth_mm, dtype=np.float32)[o::step, o::step] * np.float32(0.001)
        z = np.nan_to_num(z, nan=0.0, posinf=0.0, neginf=0.0)
        z = np.ascontiguousarray(np.where((z > 0) & (z < _EGO_MAX_DEPTH_M), z, 0.0), dtype=np.float32)
        now = _Surface(z, self._cam)
        before, self._prev = self._prev, now
        if before is None:
            return None
        back = _icp(now, before, self._cam)
        if back is None or not np.isfinite(back).all():
            return None
        cam32 = np.array(self._cam, dtype=np.float32)
        r32, t32 = back[:3, :3].astype(np.float32), back[:3, 3].astype(np.float32)
        share, flow = _motion_checks(z, before.z, r32, t32, cam32, _EGO_MAX_DEPTH_DIFF_M)
        if share < _EGO_MIN_INLIERS:
            return None
        if flow * step < _EGO_STILL_PX:
            # Within the ICP's own jitter of standing still (on the simulator's still scenes
            # 0.1-0.3 px): read as still, so that the frame's shift (none) moves no pixel.
            return CameraMotion(np.eye(3), np.zeros(3), intrinsics)
        return CameraMotion(back[:3, :3].copy(), back[:3, 3] * 1000.0, intrinsics)


@njit(cache=True, nogil=True)
def _motion_checks(
    z: NDArray[np.float32],
    z_prev: NDArray[np.float32],
    r32: NDArray[np.float32],
    t32: NDArray[np.float32],
    cam32: NDArray[np.float32],
    gate: float,
) -> tuple[float, float]:
    """How well a camera motion carries ``z``'s points onto ``z_prev``'s surface, and how far.

    ``z``, ``z_prev`` are the grid's depths (m), ``(r32, t32)`` the motion from this camera to the
    previous one (m), ``cam32`` the grid's (fx, fy, cx, cy) px. Returns the share of the points
    carried onto a valid pixel (the nearest) whose depth there is within ``gate`` (m) of the
    carried point's (0..1; pixels carried out of the view or onto a hole say nothing either
    way), and the mean image motion of the valid points (px of the grid). One pass in float32,
    as the numpy steps and ``cv2.remap`` it replaced (about 1 ms of the ICP's frame).
    """
    h, w = z.shape
    fx, fy, cx, cy = cam32[0], cam32[1], cam32[2], cam32[3]
    g = np.float32(gate)
    landed = 0
    fit = 0
    moved = 0
    flow = 0.0
    for y in range(h):
        for x in range(w):
            d = z[y, x]
            if not d > 0:
                continue
            px = (np.float32(x) - cx) / fx * d
            py = (np.float32(y) - cy) / fy * d
            qx = r32[0, 0] * px + r32[0, 1] * py + r32[0, 2] * d + t32[0]
            qy = r32[1, 0] * px + r32[1, 1] * py + r32[1, 2] * d + t32[1]
            qz = r32[2, 0] * px + r32[2, 1] * py + r32[2, 2] * d + t32[2]
            if not qz > 0:
                continue
            mx = fx * qx / qz + cx
            my = fy * qy / qz + cy
            moved += 1
            flow += math.hypot(float(mx) - x, float(my) - y)
            u = int(np.rint(mx))
            v = int(np.rint(my))
            if u < 0 or v < 0 or u >= w or v >= h:
                continue
            z0 = z_prev[v, u]
            if not z0 > 0:
                continue
            landed += 1
            if abs(z0 - qz) < g:
                fit += 1
    share = fit / landed if landed else 0.0
    return share, (flow / moved if moved else 0.0)


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
    (sampled px). ``camera``: ``a`` holds the rotation (row-major), the translation (mm) and fx,
    fy, cx, cy; otherwise the shift dx, dy (px), the scale and its centre (px). One pass per
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
                x = a[12] * qx / qz + a[14]
                y = a[13] * qy / qz + a[15]
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
    """Return the camera's motion as :func:`_core_sums` reads it: rotation, translation (mm), fx, fy, cx, cy."""
    k = camera.intrinsics
    a = np.concatenate([camera.rotation.ravel(), camera.translation_mm, [k.fx, k.fy, k.cx, k.cy]])
    return np.ascontiguousarray(a, dtype=np.float64)


class _Core:
    """One object's pixels this frame, read against the previous frame under candidate motions.

    Under a shift, the pixel ``p`` of this frame was at ``c + (p - c) * scale + shift`` in the
    previous one, ``c`` the box's centre: an object coming closer grows in the image about
    itself, and reading its previous depth at the same pixel would read a point further out on
    its surface. Under the camera's motion each pixel goes where its still point was (which
    holds the growth already). The previous depth is read bilinearly, from four pixels that all
    belong to the track's previous segment: on a steep flank (a cylinder's side) half a pixel is
    tens of millimetres.
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
                self.params.append((True, camera_params if camera_params is not None else _camera_params(m)))
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
        cores.append((oid, _Core(prev, now, oid, pid, box, todo, scale, cam), len(todo)))
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
        for j in range(first, m):
            n2, mean2, spread2, _ = read[c, j]
            if n2 * k >= min_px and n2 * k >= min_share * area and (not ok or spread2 < prefer * spread):
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


def load_rare_kernels() -> None:
    """Load (on a fresh install: compile) the kernels that only a moving camera reaches.

    A warm-up on one still frame does not move the camera, so the camera's share of each
    object's depth change (:func:`still_depth_change`) was compiled at the first moving frame
    of a stream (249 ms on a fresh install). Called by ``Pipeline.warm_up``.
    """
    z = np.ones((2, 2), np.float32)
    one = np.ones(1, np.int64)
    _mean_points(z, np.ones((2, 2), np.int32), one, np.array([[0, 0, 2, 2]], np.int64), one)
