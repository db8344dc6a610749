"""Which pixels lie on horizontal supports (floor, ceiling, table tops) and which on walls.

Why inverse depth: for any plane n·P = d seen through a pinhole, ``1/Z = (n_x u' + n_y v' +
n_z) / d`` with ``u' = (u - cx) / fx``, ``v' = (v - cy) / fy``. So the image gradient of 1/Z
gives the plane normal up to scale: ``n ∝ (fx ∂(1/Z)/∂u, fy ∂(1/Z)/∂v, 1/Z - ...)``. A surface
facing the sensor has a flat 1/Z, a floor or a table top changes steadily from row to row
(∂Z/∂y ≠ 0, the hint the slices exploit), a wall from column to column. The gradient is taken
over a box window of valid pixels (hole-aware), and not at occlusion edges, where a depth jump
would fake a steep surface.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics

__all__ = ["default_intrinsics", "orientation_classes", "orientation_field"]

#: Classes returned by :func:`orientation_classes`.
FACING, HORIZONTAL, VERTICAL = 0, 1, 2


def default_intrinsics(shape: tuple[int, int]) -> Intrinsics:
    """Pinhole guess for a frame without calibration: 64 degrees horizontal field of view."""
    h, w = shape
    f = 0.8 * w
    return Intrinsics(f, f, (w - 1) / 2.0, (h - 1) / 2.0)


def orientation_classes(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    intrinsics: Intrinsics,
    *,
    window_px: int = 7,
    oblique_deg: float = 35.0,
    jump_rel: float = 0.05,
) -> NDArray[np.int8]:
    """Per-pixel class: 0 facing the sensor (or unknown), 1 horizontal, 2 vertical lateral.

    See :func:`orientation_field` for the parameters.
    """
    return orientation_field(
        depth_mm, valid, intrinsics, window_px=window_px, oblique_deg=oblique_deg, jump_rel=jump_rel
    )[0]


def orientation_field(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    intrinsics: Intrinsics,
    *,
    window_px: int = 7,
    oblique_deg: float = 35.0,
    jump_rel: float = 0.05,
) -> tuple[NDArray[np.int8], NDArray[np.float32]]:
    """Per-pixel class (0 facing or unknown, 1 horizontal, 2 vertical lateral) and unit normal.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid.
    valid : ndarray of bool
        Pixels with a reading.
    intrinsics : Intrinsics
        Camera intrinsics (px).
    window_px : int
        Side of the smoothing window (px).
    oblique_deg : float
        Largest angle (degrees) between the surface normal and the image's vertical axis for a
        horizontal surface, or its horizontal axis for a wall.
    jump_rel : float
        Relative depth step between neighbours marking an occlusion edge.

    Returns
    -------
    classes : ndarray of int8, shape (H, W)
    normals : ndarray of float32, shape (H, W, 3)
        Unit surface normal in the camera frame (x right, y down, z forward), turned toward
        the sensor.
    """
    h, w = depth_mm.shape
    inv = np.zeros_like(depth_mm)
    np.divide(1000.0, depth_mm, out=inv, where=valid)  # 1/m keeps float32 well scaled
    # a 3 x 3 valid-weighted mean, then differences over `step` px: the slope of a distant floor
    # (1/Z changes by 1 / (h fy) per row) must stand above the noise of one difference
    m = valid.astype(np.float32)
    den3 = np.maximum(cv2.boxFilter(m, -1, (3, 3), normalize=False, borderType=cv2.BORDER_REPLICATE), 1e-6)
    inv3 = np.asarray(
        cv2.boxFilter(inv, -1, (3, 3), normalize=False, borderType=cv2.BORDER_REPLICATE) / den3, np.float32
    )
    # the mean is defined wherever a 3 x 3 neighbour has a reading, which bridges a sieve of
    # dropouts (registered structured light keeps one pixel in four)
    has = den3 > 0.5
    step = max(1, window_px // 2)
    gx = _one_sided(inv3, has, step)
    gy = np.ascontiguousarray(_one_sided(np.ascontiguousarray(inv3.T), np.ascontiguousarray(has.T), step).T)
    # average the gradient over valid pixels only; holes neither pull it to zero nor fake edges.
    # Pixels whose slope is steeper than 80 degrees from the line of sight are left out too: on
    # both sides of an occlusion edge (a smoothed or flying pixel) they would fake a steep plane.
    fx, fy = intrinsics.fx, intrinsics.fy
    steep = np.float32(math.tan(math.radians(80.0)))
    keep = has & (np.abs(fx * gx) <= steep * inv3) & (np.abs(fy * gy) <= steep * inv3)
    gx[~keep] = 0.0
    gy[~keep] = 0.0
    k = (window_px, window_px)
    mk = keep.astype(np.float32)
    den = np.maximum(cv2.boxFilter(mk, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE), 1e-6)
    gx = np.asarray(cv2.boxFilter(gx, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE) / den, np.float32)
    gy = np.asarray(cv2.boxFilter(gy, -1, k, normalize=False, borderType=cv2.BORDER_REPLICATE) / den, np.float32)
    fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
    a = fx * gx
    b = fy * gy
    u = ((np.arange(w, dtype=np.float32) - cx) / fx)[None, :]
    v = ((np.arange(h, dtype=np.float32) - cy) / fy)[:, None]
    c = inv3 - a * u - b * v
    norm = np.sqrt(a * a + b * b + c * c) + 1e-12
    cos_t = math.cos(math.radians(oblique_deg))
    cls = np.zeros((h, w), np.int8)
    cls[np.abs(b) >= cos_t * norm] = HORIZONTAL
    cls[np.abs(a) >= cos_t * norm] = VERTICAL
    jump = (_jumps(depth_mm, valid, jump_rel) | _jumps(depth_mm.T, valid.T, jump_rel).T).astype(np.uint8)
    cls[jump.astype(bool) | ~valid] = FACING
    # (a, b, c) . ray = 1/Z > 0 always, so its opposite is the normal turned toward the sensor
    sign = np.float32(-1.0) / norm
    normals = np.stack([a * sign, b * sign, c * sign], axis=-1).astype(np.float32)
    return cls, normals


def _jumps(z: NDArray[np.float32], valid: NDArray[np.bool_], jump_rel: float) -> NDArray[np.bool_]:
    """Pixels beside an occlusion edge along rows.

    A step is an edge when it exceeds ``jump_rel`` of the depth and is more than twice the
    steps two pixels before and after it: a floor seen at a grazing angle makes large but
    steady steps, an occlusion one isolated step (or two, with a flying pixel between).
    """
    d = np.abs(np.diff(z, axis=1))
    ok = valid[:, 1:] & valid[:, :-1]
    d[~ok] = 0.0
    big = d > jump_rel * np.maximum(z[:, 1:], z[:, :-1])
    around = np.zeros_like(d)
    around[:, 2:] = d[:, :-2]
    np.maximum(around[:, :-2], d[:, 2:], out=around[:, :-2])
    big &= d > 2.0 * around
    out = np.zeros(z.shape, bool)
    out[:, 1:] |= big
    out[:, :-1] |= big
    return out


def _one_sided(inv: NDArray[np.float32], valid: NDArray[np.bool_], step: int) -> NDArray[np.float32]:
    """Derivative along rows (per px), the smaller of the forward and backward differences.

    Beside an occlusion edge one of the two differences crosses the edge; the smaller one stays
    on the pixel's own surface, so a floor pixel next to a box keeps the floor's slope. Pixels
    whose neighbours both lack a reading get 0 (no evidence of a slope).
    """
    fwd = np.zeros_like(inv)
    fwd[:, :-step] = inv[:, step:] - inv[:, :-step]
    okf = np.zeros_like(valid)
    okf[:, :-step] = valid[:, step:] & valid[:, :-step]
    bwd = np.zeros_like(inv)
    bwd[:, step:] = fwd[:, :-step]
    okb = np.zeros_like(valid)
    okb[:, step:] = okf[:, :-step]
    big = np.float32(np.inf)
    f = np.where(okf, fwd, big)
    b = np.where(okb, bwd, big)
    g = np.where(np.abs(f) <= np.abs(b), f, b)
    g[~(okf | okb)] = 0.0
    return (g / step).astype(np.float32)
