"""Dominant support planes of any orientation: table tops and floors seen from above at a slant.

The orientation classes of :mod:`depthgram.segmentation.orientation` are taken against the camera's
axes, which suits a level camera. A camera looking down at a table at 45 degrees sees the table
top with its normal 45 degrees from every image axis, so it comes out facing, and the table with
everything on it is one object. Any plane, however oriented, has an inverse depth exactly affine
in pixel coordinates under a pinhole camera::

    1/Z = a u + b v + c

so the dominant planes are found by a robust fit of that affine model (RANSAC over a subsample
of valid pixels, then a least-squares refit on the inliers) without any intrinsics. A plane is a
support when it is large and oblique (its depth spreads over its extent); a fronto-parallel plane
such as a back wall is a facing object in the paper's model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation._kernels.ransac import assign_planes, dilate3, search_planes

__all__ = ["Plane", "find_planes", "plane_distance_mm", "plane_normal", "plane_residual_mask", "warm_up"]


@dataclass(frozen=True)
class Plane:
    """One support plane found by :func:`find_planes`.

    Attributes
    ----------
    coef : tuple of float
        ``(a, b, c)`` of ``1000 / Z = a u + b v + c`` with ``u`` the column and ``v`` the row (px)
        and Z in mm (so the left side is in 1/m).
    inliers : ndarray of bool, shape (H, W)
        Pixels on the plane that belong to its large connected pieces.
    area : int
        Number of inlier pixels.
    spread : float
        Depth spread over the inliers: (95th - 5th percentile) / median depth.
    """

    coef: tuple[float, float, float]
    inliers: NDArray[np.bool_]
    area: int
    spread: float


def plane_normal(coef: tuple[float, float, float], cam: Intrinsics) -> NDArray[np.float64]:
    """Return the unit normal (camera frame: x right, y down, z forward) of a plane, turned toward the sensor.

    With normalised coordinates ``u' = (u - cx) / fx``: ``1/Z = a fx u' + b fy v' + (c + a cx +
    b cy)``; for a plane ``n . P = d`` this is ``-(n . ray) / d``, so ``n`` is minus that vector.
    """
    a, b, c = coef
    vec = np.array([a * cam.fx, b * cam.fy, c + a * cam.cx + b * cam.cy])
    return -vec / max(float(np.linalg.norm(vec)), 1e-15)


def plane_distance_mm(coef: tuple[float, float, float], cam: Intrinsics) -> float:
    """Distance (mm) from the camera centre to the plane: ``1000 / |(a fx, b fy, c + a cx + b cy)|``."""
    a, b, c = coef
    vec = np.array([a * cam.fx, b * cam.fy, c + a * cam.cx + b * cam.cy])
    return 1000.0 / max(float(np.linalg.norm(vec)), 1e-15)


def plane_residual_mask(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    coef: tuple[float, float, float],
    *,
    tol_mm: float,
    tol_rel: float,
    step: int = 1,
) -> NDArray[np.bool_]:
    """Return the valid pixels within ``max(tol_mm, tol_rel Z)`` of the plane's predicted depth.

    ``step`` > 1: the image is every ``step``-th pixel of every ``step``-th row of the frame the
    plane was fitted in (coefficients in full-frame pixels).
    """
    h, w = depth_mm.shape
    a, b, c = coef
    cols = np.arange(w, dtype=np.float32) * np.float32(step)
    rows = np.arange(h, dtype=np.float32) * np.float32(step)
    inv = (np.float32(a) * cols[None, :] + np.float32(b) * rows[:, None]) + np.float32(c)
    z = depth_mm
    # |Z - Zp| <= tol  <=>  |1000 - Z inv| <= tol * inv, with inv = 1000 / Zp > 0 (no division)
    tol = np.maximum(np.float32(tol_mm), np.float32(tol_rel) * z)
    out: NDArray[np.bool_] = valid & (inv > 0) & (np.abs(np.float32(1000.0) - z * inv) <= tol * inv)
    return out


def find_planes(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    *,
    min_area: float = 0.08,
    min_spread: float = 0.15,
    tol_mm: float = 8.0,
    tol_rel: float = 0.012,
    max_planes: int = 3,
    hypotheses: int = 128,
    sample_step: int | None = None,
    seed: int = 0,
    search: NDArray[np.bool_] | None = None,
) -> list[Plane]:
    """Return the dominant oblique planes of a depth image, largest first.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid.
    valid : ndarray of bool
        Pixels with a reading.
    min_area : float
        Smallest plane kept, as a fraction of the frame's pixels (0..1).
    min_spread : float
        Smallest depth spread (5th to 95th percentile over the median depth) of an oblique plane;
        flatter planes face the sensor and are left to the histogram.
    tol_mm, tol_rel : float
        A pixel lies on a plane when its depth is within ``max(tol_mm, tol_rel Z)`` mm of it.
    max_planes : int
        Most planes searched for.
    hypotheses : int
        RANSAC hypotheses (three-point samples) per plane.
    sample_step : int, optional
        The search runs on every ``sample_step``-th pixel of every ``sample_step``-th row; by
        default the step that leaves about 3000 pixels.
    seed : int
        Seed of the random samples (deterministic results).
    search : ndarray of bool, optional
        Pixels where planes are looked for (default: all valid ones); a plane found there then
        takes every valid pixel on it near its pieces.

    Returns
    -------
    list of Plane
    """
    h, w = depth_mm.shape
    min_px = max(int(min_area * h * w), 3)
    # about 3000 grid points whatever the frame size: the search costs the same at 176 x 132
    # and 640 x 480, and only the final inlier test runs at full resolution
    s = sample_step or max(1, round(math.sqrt(h * w / 3000.0)))
    z_sub = np.ascontiguousarray(depth_mm[::s, ::s], dtype=np.float32)
    min_sub = min_px / (s * s)
    t_mm, t_rel = np.float32(tol_mm), np.float32(tol_rel)
    # the searches are one compiled call (search_planes): the draws are numpy's (its
    # bounded integers from the seeded bit generator's numbers), the solves and the refit
    # LAPACK's numbers, so the planes are those of the numpy route (docs/design-notes.md, "RANSAC")
    rcond = _EPS
    raw = _raw32(seed, max(max_planes, 0) * 2 * (3 * hypotheses + 2000) + 64)
    while True:
        # the grid's own pixels only, not a full-frame `valid & search` (the search takes them out)
        left = np.ascontiguousarray(valid[::s, ::s] if search is None else valid[::s, ::s] & search[::s, ::s])
        k, coefs, pieces, spreads = search_planes(
            z_sub, left, s, t_mm, t_rel, min_sub, hypotheses, max_planes, min_spread, raw, rcond
        )
        if k >= 0:
            break
        # rejected draws (each about n / 2**32 likely) used up the numbers: more, and again
        raw = _raw32(seed, 2 * raw.size)
    if not k:
        return []
    found = [((float(c[0]), float(c[1]), float(c[2])), float(sp)) for c, sp in zip(coefs[:k], spreads[:k], strict=True)]
    # a full-resolution pixel may join a plane when its grid cell or a neighbouring one did:
    # the contact rows at the foot of an object are kept, far pixels on the plane's extension not
    allowed = dilate3(pieces[:k])
    which = assign_planes(depth_mm, valid, np.ascontiguousarray(coefs[:k]), allowed, s, float(tol_mm), float(tol_rel))
    planes: list[Plane] = []
    for j, (coef, spread) in enumerate(found, start=1):
        mask = which == j
        area = int(np.count_nonzero(mask))
        if area >= min_px:
            planes.append(Plane(coef, mask, area, spread))
    return planes


#: Machine epsilon of float64 (numpy's default ``rcond`` of a least squares is it times the
#: larger dimension), taken once: ``np.finfo`` costs 0.8 us a call.
_EPS = float(np.finfo(np.float64).eps)


#: Per seed: the first 32-bit numbers of ``np.random.default_rng(seed)``'s bit generator.
_RAW32: dict[int, NDArray[np.uint32]] = {}


def _raw32(seed: int, count: int) -> NDArray[np.uint32]:
    """Return at least ``count`` of the 32-bit numbers PCG64(``seed``) gives ``Generator.integers``.

    numpy's PCG64 hands out each 64-bit output as two 32-bit numbers, the low half first. The
    plane search draws from the seeded state at every call (the same numbers each frame), so
    they are made once per seed and read by ``_kernels.ransac.bounded`` in compiled code: numpy's
    calls for the draws, and seeding or setting back the generator, cost 10-20 us a frame.
    """
    raw = _RAW32.get(seed)
    if raw is None or raw.size < count:
        r64 = np.random.PCG64(seed).random_raw(-(-count // 2))
        raw = np.empty(2 * r64.size, np.uint32)
        raw[0::2] = (r64 & np.uint64(0xFFFFFFFF)).astype(np.uint32)
        raw[1::2] = (r64 >> np.uint64(32)).astype(np.uint32)
        _RAW32[seed] = raw
    return raw


def warm_up() -> None:
    """Load (on a fresh install: compile) the kernel that gives the pixels of the planes found.

    A 2 x 2 frame finds no plane, so a search alone does not reach it; 7-Scenes on the grid of
    a 640 px frame first found one at frame 5 (367 ms on a fresh install).
    """
    z = np.full((2, 2), 1000.0, np.float32)
    assign_planes(
        z, np.ones((2, 2), np.bool_), np.zeros((1, 3), np.float64), np.ones((1, 1, 1), np.uint8), 2, 8.0, 0.01
    )
