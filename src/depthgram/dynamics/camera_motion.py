"""The camera's own motion between two depth frames, and the image motion it gives.

The paper reads radial motion from the change of an object's mean depth. On a moving camera
that mean moves with what part of the object is seen: a wall cut by the image edge, a floor
uncovered by the camera's turn, a segment that gains an arm or a few pixels of floor. The
change of its *core* does not: the pixels that belong to the object in this frame and, moved
back by the image motion, belonged to the same track's segment in the previous frame. Their
mean depth difference is the radial motion of the same surface points, which is what a
radial velocity of a surface means (and what the ground truth of
:func:`depthgram.dynamics.evaluate.radial_velocity_from_poses` carries each pixel through).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.noise_model import SensorModel, estimate_sensor

__all__ = ["CameraMotion", "EgoMotion", "FramePixels", "image_shift", "shift_structure", "structure_shift"]


#: Side of the grid on which the image shift is found (px of the down-sampled image).
_SHIFT_W, _SHIFT_H = 160, 120


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


#: Tiles (columns, rows) of the ICP's grid held out one at a time to test the found motion
#: (:func:`_held_out_gain`): some 20 x 20 grid pixels each at 160 x 120, wider than the
#: smoothing that makes neighbouring points' noise alike, and enough of them for their spread.
_EGO_TILES = (8, 6)


#: Frames between two estimates of the sensor's model, whose resolution weighs the ICP's pairs: a
#: camera's noise does not change from frame to frame, and an estimate costs about 0.1 ms.
_SENSOR_EVERY = 30


#: Standard errors by which the found motion must beat standing still on held-out tiles for
#: the camera to be read as moving (:func:`_held_out_gain`): one-sided, a still camera is read
#: as moving by chance on at most 1 frame in 40 (Student's t, 47 degrees of freedom; fewer,
#: since a motion fitted to noise loses on held-out tiles on average). On 7-Scenes every real
#: frame's gain is 2.56 or more (median 7.6).
_EGO_STILL_SIGMAS = 2.0


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
#: the scene does pin down it is a fraction of a percent of the data's weight. The pairs' weights
#: (a reading at 1 m counts 1, a far one less) lower the data's say in the direction a view pins
#: down least, so the same pull would bias it more than when every pair counted 1: a third of the
#: 1e-3 it was then keeps the simulator's sideways step found as well as before.
_ICP_PRIOR = 3e-4


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
    tile_ata: NDArray[np.float64],
    tile_atr: NDArray[np.float64],
    tile_n: NDArray[np.int64],
    total: NDArray[np.float64],
    tiled: bool,
    noise: NDArray[np.float64],
) -> bool:
    """Run ``iterations`` ICP steps on one pass's points, updating ``rot`` and ``t`` in place.

    Each step sums the normal equations of its matched pairs, each weighted by the inverse
    square of the sensor's resolution at its depth relative to its resolution at 1 m
    (``noise``: the step ``noise[0] + noise[1] z**2`` and the noise deviation ``noise[2] +
    noise[3] z**2``, z in m, of :meth:`SensorModel.resolution`; all zero: alike at every depth),
    solves them pulled toward standing still by ``prior`` per matched pair (so that noisier
    pairs, which say less, are pulled more), and applies the increment by Rodrigues' formula.
    Compiled with the sums: as numpy calls, the 6 x 6 solve and the 3 x 3 products cost some 50
    us a step, eleven steps a frame. False when a step matches fewer than 100 pairs.

    With ``tiled`` the sums are kept per tile of the previous frame's grid (``tile_ata``
    (T, 6, 6), ``tile_atr`` (T, 6), ``tile_n`` (T,), :data:`_EGO_TILES`; else all in the
    first) and hold the last step's on return, with ``total`` the motion (rotation vector,
    rad; translation, m) they were taken at: what :func:`_held_out_gain` needs. Only the last
    step needs its tiles (tiling every step cost 5 % of the ICP).
    """
    eye6 = np.eye(6)
    ata = np.zeros((6, 6))
    atr = np.zeros(6)
    row = np.empty(6)
    fx, fy, cx, cy = cam32[0], cam32[1], cam32[2], cam32[3]
    g = np.float32(gate)
    tx, ty = _EGO_TILES
    # a pixel's tile by a product, not two integer divisions a pair
    tile_x, tile_y = np.float32(tx / w), np.float32(ty / h)
    res_1m = max(noise[0] + noise[1], 2.0 * (noise[2] + noise[3]))
    for _ in range(iterations):
        # the step's matches and normal equations: how many pairs, J^T J and J^T r. Each point
        # s of this frame, moved by (rot, t), is projected into the previous frame's grid and
        # paired with the point there; a pair counts when both its depth gap and its
        # point-to-plane residual are under `gate` (m). J's rows are (q x n, n). One pass in
        # float32, as the numpy steps it replaced (3.2 of the ICP's 5.4 ms per 7-Scenes frame
        # were their calls and temporaries), summed in sequence: BLAS's jac.T @ jac sums in an
        # order that depends on its buffers' alignment, which moved the ICP's motion in its
        # seventh digit from run to run.
        r32 = rot.astype(np.float32)
        t32 = t.astype(np.float32)
        tile_ata[:] = 0.0
        tile_atr[:] = 0.0
        tile_n[:] = 0
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
            tile = int(v * tile_y) * tx + int(u * tile_x) if tiled else 0
            tile_n[tile] += 1
            xf, yf, zf = float(qx), float(qy), float(qz)
            af, bf, cf = float(a), float(b), float(c)
            row[0] = yf * cf - zf * bf
            row[1] = zf * af - xf * cf
            row[2] = xf * bf - yf * af
            row[3] = af
            row[4] = bf
            row[5] = cf
            # A disparity camera's resolution falls as z**2 (a 3 m wall's readings are ten times
            # coarser than a 1 m table's): counted alike, the far readings set the motion.
            wk = 1.0
            if res_1m > 0.0:
                z2 = zf * zf
                wk = (res_1m / max(noise[0] + noise[1] * z2, 2.0 * (noise[2] + noise[3] * z2))) ** 2
            rk = float(r) * wk
            for p in range(6):
                tile_atr[tile, p] += row[p] * rk
                for q in range(p, 6):
                    tile_ata[tile, p, q] += row[p] * row[q] * wk
        ata[:] = 0.0
        atr[:] = 0.0
        for k in range(tile_n.shape[0]):
            for p in range(6):
                atr[p] += tile_atr[k, p]
                for q in range(p, 6):
                    ata[p, q] += tile_ata[k, p, q]
        for p in range(6):
            for q in range(p):
                ata[p, q] = ata[q, p]
        if n < 100:
            return False
        mu = prior * n
        total[0] = 0.5 * (rot[2, 1] - rot[1, 2])
        total[1] = 0.5 * (rot[0, 2] - rot[2, 0])
        total[2] = 0.5 * (rot[1, 0] - rot[0, 1])
        total[3:] = t
        delta = -np.linalg.solve(ata + mu * eye6, atr + mu * total)
        # the increment's rotation matrix, by Rodrigues' formula
        th = math.sqrt(delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2])
        kx = np.array([[0.0, -delta[2], delta[1]], [delta[2], 0.0, -delta[0]], [-delta[1], delta[0], 0.0]])
        if th < 1e-12:
            d_rot = np.eye(3) + kx
        else:
            kx /= th
            d_rot = np.eye(3) + math.sin(th) * kx + (1.0 - math.cos(th)) * (kx @ kx)
        rot[:] = d_rot @ rot
        t[:] = d_rot @ t + delta[3:]
    return True


def _icp(
    now: _Surface, before: _Surface, cam: tuple[float, float, float, float], noise: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float] | None:
    """Point-to-plane ICP with projective matching: the 4x4 motion from ``now``'s camera to ``before``'s (m).

    Returned with its held-out gain's significance (:func:`_held_out_gain`, in standard
    errors). None when fewer than 100 points match (too little valid depth, a jump too large).
    ``noise`` sets the pairs' weights: see :func:`_icp_steps`.
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
    tiles = _EGO_TILES[0] * _EGO_TILES[1]
    tile_ata, tile_atr, tile_n = np.zeros((tiles, 6, 6)), np.zeros((tiles, 6)), np.zeros(tiles, np.int64)
    total = np.zeros(6)
    for k, (step, iterations) in enumerate(_ICP_PASSES):
        grid = now.points[:, ::step, ::step]
        mine = grid[2] > 0
        sx, sy, sz = (grid[i][mine] for i in range(3))
        last = k == len(_ICP_PASSES) - 1
        # the held-out test needs the tiles of the last step alone
        for count, tiled in ((iterations - 1, False), (1, True)) if last else ((iterations, False),):
            found = _icp_steps(
                sx, sy, sz, rot, t, cam32, px0, py0, pz0, nx0, ny0, nz0, target_ok, w, h, gate, count, _ICP_PRIOR,
                tile_ata, tile_atr, tile_n, total, tiled, noise,
            )  # fmt: skip
            if not found:
                return None
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = t
    return out, _held_out_gain(tile_ata, tile_atr, tile_n, total, _ICP_PRIOR)


@njit(cache=True, nogil=True)
def _held_out_gain(
    tile_ata: NDArray[np.float64],
    tile_atr: NDArray[np.float64],
    tile_n: NDArray[np.int64],
    total: NDArray[np.float64],
    prior: float,
) -> float:
    """How many standard errors a motion found on the rest of the image beats standing still on each tile.

    For each tile of the grid the ICP's last step is solved again without the tile's pairs
    (``tile_ata``, ``tile_atr``: its weighted sums of J^T J and J^T r, ``tile_n`` pairs, at the
    motion ``total``: rotation vector, rad, and translation, m; ``prior`` as in :func:`_icp_steps`),
    and the tile's sum of squared point-to-plane residuals under that motion is compared with
    the one under no motion (m^2, both to first order about ``total``): the gain is positive
    where the motion the others see carries the tile's points closer to the previous surface
    than standing still does. Returns the tiles' mean gain over its standard error (their
    spread / sqrt(number of tiles with pairs)); 0 when fewer than two tiles have pairs or no
    tile gains anything, +inf when every tile gains the same positive amount.

    A motion fitted to noise, or to an object moving on its own, fits the pairs it was found
    on, but not held-out ones: there the gain is zero or negative on average, however large the
    motion looks. Tiles, not points, are held out, because neighbouring points share their
    noise (the 3 x 3 and 5 x 5 smoothing of :class:`_Surface`, a sensor's correlated noise).
    """
    count = tile_n.shape[0]
    ata = np.zeros((6, 6))
    atr = np.zeros(6)
    n = 0
    for k in range(count):
        n += tile_n[k]
        for p in range(6):
            atr[p] += tile_atr[k, p]
            for q in range(p, 6):
                ata[p, q] += tile_ata[k, p, q]
                ata[q, p] = ata[p, q]
    gains = np.empty(count)
    m = 0
    a = np.empty((6, 6))
    rest = np.empty((6, 6))
    rhs = np.empty(6)
    for k in range(count):
        if tile_n[k] == 0:
            continue
        mu = prior * (n - tile_n[k])
        for p in range(6):
            for q in range(p, 6):
                a[p, q] = a[q, p] = tile_ata[k, p, q]
                rest[p, q] = rest[q, p] = ata[p, q] - a[p, q]
            rest[p, p] += mu
            rhs[p] = -(atr[p] - tile_atr[k, p] + mu * total[p])
        # the last step's increment, found without this tile
        step = np.linalg.solve(rest, rhs)
        # ||r + J d||^2 for d = -total (no motion) less for d = step (the others' motion)
        gain = 0.0
        for p in range(6):
            gain += 2.0 * tile_atr[k, p] * (-total[p] - step[p])
            for q in range(6):
                gain += a[p, q] * (total[p] * total[q] - step[p] * step[q])
        gains[m] = gain
        m += 1
    if m < 2:
        return 0.0
    mean = 0.0
    for k in range(m):
        mean += gains[k]
    mean /= m
    var = 0.0
    for k in range(m):
        var += (gains[k] - mean) ** 2
    spread = math.sqrt(var / (m - 1))
    if spread == 0.0:
        return math.inf if mean > 0 else 0.0
    return mean / spread * math.sqrt(m)


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

    Each pair of the ICP counts by the inverse square of the sensor's resolution at its depth
    (:meth:`SensorModel.resolution`): a structured-light or stereo camera reads a 3 m wall ten
    times coarser than a 1 m table, and counted alike the far readings, the most numerous, set
    the motion; a time-of-flight camera's resolution changes little with depth, and its readings
    count nearly alike.

    Call :meth:`update` once per frame, in order.

    Parameters
    ----------
    sensor : SensorModel, optional
        The camera's step and noise. By default estimated from the frames
        (:func:`~depthgram.segmentation.estimate_sensor`, every :data:`_SENSOR_EVERY` frames).
    """

    def __init__(self, sensor: SensorModel | None = None) -> None:
        self._given = sensor
        self._noise = np.zeros(4) if sensor is None else _noise_terms(sensor)
        self._since_estimate = -1  # frames since the sensor was last estimated (-1: never)
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
            (:attr:`CameraMotion.still`) where the motion does not beat standing still on
            held-out parts of the view by :data:`_EGO_STILL_SIGMAS` standard errors
            (:func:`_held_out_gain`).
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
        self._update_sensor(depth_mm)
        step = self._step
        o = step // 2
        z = np.asarray(depth_mm, dtype=np.float32)[o::step, o::step] * np.float32(0.001)
        z = np.nan_to_num(z, nan=0.0, posinf=0.0, neginf=0.0)
        z = np.ascontiguousarray(np.where((z > 0) & (z < _EGO_MAX_DEPTH_M), z, 0.0), dtype=np.float32)
        now = _Surface(z, self._cam)
        before, self._prev = self._prev, now
        if before is None:
            return None
        found = _icp(now, before, self._cam, self._noise)
        if found is None or not np.isfinite(found[0]).all():
            return None
        back, gain = found
        cam32 = np.array(self._cam, dtype=np.float32)
        r32, t32 = back[:3, :3].astype(np.float32), back[:3, 3].astype(np.float32)
        share = _motion_checks(z, before.z, r32, t32, cam32, _EGO_MAX_DEPTH_DIFF_M)
        if share < _EGO_MIN_INLIERS:
            return None
        if not gain > _EGO_STILL_SIGMAS:
            # The motion does not carry held-out parts of the view onto the previous surface
            # better than standing still: it is the ICP's jitter on the sensor's noise (on a
            # still 640 x 480 simulator scene 0.4-1.2 px, over the old fixed threshold of
            # 0.3 px) or the pull of an object moving on its own. Read as still, so that the
            # frame's shift (none) moves no pixel.
            return CameraMotion(np.eye(3), np.zeros(3), intrinsics)
        return CameraMotion(back[:3, :3].copy(), back[:3, 3] * 1000.0, intrinsics)

    def _update_sensor(self, depth_mm: NDArray[np.floating]) -> None:
        """Estimate the sensor's model from ``depth_mm`` on the first frame and every :data:`_SENSOR_EVERY`."""
        if self._given is not None:
            return
        self._since_estimate += 1
        if 0 < self._since_estimate < _SENSOR_EVERY:
            return
        self._since_estimate = 0
        z = np.nan_to_num(np.asarray(depth_mm, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
        valid = z > 0
        if valid.any():
            self._noise = _noise_terms(estimate_sensor(z, valid))


def _noise_terms(sensor: SensorModel) -> NDArray[np.float64]:
    """Return ``sensor``'s (step_0, step_2, sigma_0, sigma_2) for depths in metres (mm, mm/m^2)."""
    return np.array([sensor.step_0, sensor.step_2 * 1e6, sensor.sigma_0, sensor.sigma_2 * 1e6])


@njit(cache=True, nogil=True)
def _motion_checks(
    z: NDArray[np.float32],
    z_prev: NDArray[np.float32],
    r32: NDArray[np.float32],
    t32: NDArray[np.float32],
    cam32: NDArray[np.float32],
    gate: float,
) -> float:
    """How well a camera motion carries ``z``'s points onto ``z_prev``'s surface.

    ``z``, ``z_prev`` are the grid's depths (m), ``(r32, t32)`` the motion from this camera to the
    previous one (m), ``cam32`` the grid's (fx, fy, cx, cy) px. Returns the share of the points
    carried onto a valid pixel (the nearest) whose depth there is within ``gate`` (m) of the
    carried point's (0..1; pixels carried out of the view or onto a hole say nothing either
    way). One pass in float32, as the numpy steps and ``cv2.remap`` it replaced (about 1 ms of
    the ICP's frame).
    """
    h, w = z.shape
    fx, fy, cx, cy = cam32[0], cam32[1], cam32[2], cam32[3]
    g = np.float32(gate)
    landed = 0
    fit = 0
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
    return fit / landed if landed else 0.0
