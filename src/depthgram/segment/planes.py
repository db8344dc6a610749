"""Dominant support planes of any orientation: table tops and floors seen from above at a slant.

The orientation classes of :mod:`depthgram.segment.orientation` are taken against the camera's
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

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics

__all__ = ["Plane", "find_planes", "plane_distance_mm", "plane_normal", "plane_residual_mask"]


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
    """Unit normal (camera frame: x right, y down, z forward) of a plane, turned toward the sensor.

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
) -> NDArray[np.bool_]:
    """Valid pixels within ``max(tol_mm, tol_rel Z)`` of the plane's predicted depth."""
    h, w = depth_mm.shape
    a, b, c = coef
    inv = (a * np.arange(w, dtype=np.float32)[None, :] + b * np.arange(h, dtype=np.float32)[:, None]) + np.float32(c)
    z = depth_mm
    # |Z - Zp| <= tol  <=>  |1000 - Z inv| <= tol * inv, with inv = 1000 / Zp > 0 (no division)
    tol = np.maximum(np.float32(tol_mm), np.float32(tol_rel) * z)
    out: NDArray[np.bool_] = valid & (inv > 0) & (np.abs(np.float32(1000.0) - z * inv) <= tol * inv)
    return out


def _fit(u: NDArray[np.float64], v: NDArray[np.float64], inv: NDArray[np.float64]) -> tuple[float, float, float]:
    a = np.stack([u, v, np.ones_like(u)], axis=1)
    coef = np.linalg.lstsq(a, inv, rcond=None)[0]
    return float(coef[0]), float(coef[1]), float(coef[2])


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
    sample_step: int = 6,
    seed: int = 0,
) -> list[Plane]:
    """The dominant oblique planes of a depth image, largest first.

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
    sample_step : int
        Hypotheses are scored on every ``sample_step``-th pixel of every ``sample_step``-th row.
    seed : int
        Seed of the random samples (deterministic results).

    Returns
    -------
    list of Plane
    """
    h, w = depth_mm.shape
    min_px = max(int(min_area * h * w), 3)
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:h:sample_step, 0:w:sample_step]
    sub_ok = valid[::sample_step, ::sample_step]
    su = xs[sub_ok].astype(np.float64)
    sv = ys[sub_ok].astype(np.float64)
    sz = depth_mm[::sample_step, ::sample_step][sub_ok].astype(np.float64)
    sinv = 1000.0 / np.maximum(sz, 1e-6)
    stol = np.maximum(tol_mm, tol_rel * sz)
    left = np.ones(su.size, bool)
    remaining = valid.copy()
    planes: list[Plane] = []
    min_sub = min_px / (sample_step * sample_step)
    for _ in range(max_planes * 2):
        if len(planes) >= max_planes:
            break
        idx = np.flatnonzero(left)
        if idx.size < max(min_sub, 3):
            break
        coef = _ransac(su[idx], sv[idx], sinv[idx], sz[idx], stol[idx], hypotheses, rng)
        if coef is None:
            break
        on = _on(su[idx], sv[idx], sz[idx], stol[idx], coef)
        if on.sum() < min_sub:
            break
        coef = _fit(su[idx[on]], sv[idx[on]], sinv[idx[on]])
        on = _on(su[idx], sv[idx], sz[idx], stol[idx], coef)
        left[idx[on]] = False
        # area and spread are judged on the subsample first: the full-resolution pass is paid
        # only for planes that are kept
        p5, p50, p95 = np.percentile(sz[idx[on]], (5, 50, 95))
        spread = float((p95 - p5) / max(p50, 1e-6))
        if on.sum() < min_sub or spread < min_spread:
            continue  # a fronto-parallel plane (a back wall) is a facing object, not a support
        mask = plane_residual_mask(depth_mm, remaining, coef, tol_mm=tol_mm, tol_rel=tol_rel)
        mask = _large_pieces(mask, max(min_px // 4, 1))
        area = int(np.count_nonzero(mask))
        if area < min_px:
            continue
        remaining &= ~mask
        planes.append(Plane(coef, mask, area, spread))
    return planes


def _on(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    z: NDArray[np.float64],
    tol: NDArray[np.float64],
    coef: tuple[float, float, float],
) -> NDArray[np.bool_]:
    inv = coef[0] * u + coef[1] * v + coef[2]
    out: NDArray[np.bool_] = (inv > 0) & (np.abs(1000.0 - z * inv) <= tol * inv)
    return out


def _ransac(
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    inv: NDArray[np.float64],
    z: NDArray[np.float64],
    tol: NDArray[np.float64],
    hypotheses: int,
    rng: np.random.Generator,
) -> tuple[float, float, float] | None:
    """Best three-point hypothesis of ``1/Z = a u + b v + c``; all hypotheses scored in one product."""
    n = u.size
    pick = rng.integers(0, n, size=(hypotheses, 3))
    a = np.stack([u[pick], v[pick], np.ones((hypotheses, 3))], axis=2)
    det = np.linalg.det(a)
    good = np.abs(det) > 1e-6
    if not good.any():
        return None
    coef = np.linalg.solve(a[good], inv[pick[good]][..., None])[..., 0]
    # scoring on a fixed subsample keeps the (hypotheses x points) product a few MB
    m = min(n, 1500)
    ev = rng.integers(0, n, size=m) if n > m else np.arange(n)
    pred = coef[:, 0:1] * u[ev][None, :] + coef[:, 1:2] * v[ev][None, :] + coef[:, 2:3]
    score = ((pred > 0) & (np.abs(1000.0 - z[ev][None, :] * pred) <= tol[ev][None, :] * pred)).sum(axis=1)
    best = coef[int(np.argmax(score))]
    return float(best[0]), float(best[1]), float(best[2])


def _large_pieces(mask: NDArray[np.bool_], min_px: int) -> NDArray[np.bool_]:
    """Pixels of the 8-connected pieces of ``mask`` of at least ``min_px`` pixels.

    A far object that happens to cross the plane's extension makes small pieces; the support
    itself is large even when the objects standing on it cut it apart.
    """
    _, lab, stats, _ = cv2.connectedComponentsWithStats(mask.view(np.uint8), connectivity=8)
    keep = stats[:, cv2.CC_STAT_AREA] >= min_px
    keep[0] = False
    out: NDArray[np.bool_] = keep[lab]
    return out
