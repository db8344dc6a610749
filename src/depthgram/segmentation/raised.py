"""What lies on a support, however flat: readings standing above its plane by more than the noise.

A dish, a book, a screwdriver or a banana lying on a table rises 10-30 mm above it. Seen at an
angle, its edge is a depth step that a ToF camera's noise at a metre (several millimetres a
reading) and the surfaces' join allowance bridge, so it joins the table. One reading cannot tell
it from noise, but the table's plane, fitted over tens of thousands of readings, is known far
better than any reading, and a window of readings averages their noise down: a patch whose mean
stands above the plane by several of the sensor's sigmas over the window's root count (plus one
quantisation step) is not the table.

Only a support's horizontal readings are read and fitted (a folded front face is not on its
plane). A piece is kept when it is large enough to be an object and the ring around it lies on
the plane: the edge of a non-planar support (a ramp, a sagging cloth) rises gradually and has no
flat ring, an object lying on the table has one.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.segmentation.noise_model import SensorModel

__all__ = ["raised_pieces"]

#: readings a support needs before its plane says anything
_MIN_SUPPORT_PX = 500
#: rounds of the plane fit: two robust ones (median and MAD), then ones at the sensor's noise
_ROUNDS = 4
#: readings the plane is fitted on, spread over the support
_FIT_READINGS = 1000
#: samples (every s-th reading) and blocks of them the plane and the gate read (:func:`_block_plane`)
_GATE_SAMPLES = 2500
_GATE_BLOCKS = 300


def raised_pieces(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    horizontal: NDArray[np.bool_],
    support_ids: list[int],
    boxes: NDArray[np.int64],
    sensor: SensorModel,
    *,
    min_px: int,
    k_sigma: float = 4.0,
    window_px: int = 5,
    ring_share: float = 0.6,
    step_resolutions: float = 3.0,
) -> tuple[NDArray[np.int32], list[int]]:
    """Find the pieces of each horizontal support that stand above its plane by more than the noise.

    Parameters
    ----------
    labels : ndarray of int32, shape (H, W)
        Label map holding the supports' ids.
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm).
    valid : ndarray of bool, shape (H, W)
        Pixels with a reading.
    horizontal : ndarray of bool, shape (H, W)
        Pixels of the horizontal orientation class: a support's plane is fitted on these.
    support_ids : list of int
        The horizontal supports' ids in ``labels``.
    boxes : ndarray of int, shape (len(support_ids), 4)
        Each support's box (x0, y0, x1, y1, inclusive), holding all its pixels: nothing outside
        is read.
    sensor : SensorModel
        The camera's depth noise and quantisation step against depth.
    min_px : int
        Fewest pixels of a piece.
    k_sigma : float
        How many of the window mean's noise sigmas a piece must stand above the plane.
    window_px : int
        Side of the window (px) whose readings are averaged.
    ring_share : float
        Least share (0..1) of the ring around a piece lying on the plane.
    step_resolutions : float
        How many of the sensor's resolutions (:meth:`SensorModel.resolution`) the piece's median
        height must stand above its ring's.

    Returns
    -------
    pieces : ndarray of int32, shape (H, W)
        0, or the piece 1..k of each pixel (pixels with a reading only).
    of_support : list of int
        The support id each piece was cut from (``of_support[j - 1]`` for piece ``j``).
    """
    h, w = depth_mm.shape
    out = np.zeros((h, w), np.int32)
    of_support: list[int] = []
    pad = window_px + 4
    for sid, box in zip(support_ids, boxes, strict=True):
        # the support's own box (inclusive), grown by the windows and the ring: nothing else is read
        bx0, by0 = max(int(box[0]) - pad, 0), max(int(box[1]) - pad, 0)
        bx1, by1 = min(int(box[2]) + pad + 1, w), min(int(box[3]) + pad + 1, h)
        lab, z_box = labels[by0:by1, bx0:bx1], depth_mm[by0:by1, bx0:bx1]
        val, hor = valid[by0:by1, bx0:bx1], horizontal[by0:by1, bx0:bx1]
        # the plane and whether anything may stand above it, from blocks of every s-th reading:
        # a frame whose supports are bare (most) costs a few calls on a few thousand samples
        s = max(1, round(math.sqrt(lab.size / _GATE_SAMPLES)))
        # a horizontal pixel has a reading (the orientation classes are facing without one)
        ons = (lab[::s, ::s] == sid) & hor[::s, ::s]
        if int(np.count_nonzero(ons)) * s * s < max(_MIN_SUPPORT_PX, min_px):
            continue
        fit = _block_plane(ons, z_box[::s, ::s], s, lab.shape, sensor, k_sigma, margin_px=2 * window_px + 4)
        if fit is None:
            continue
        coef, regions = fit
        if coef.size == 0:
            coef = _plane_fit((lab == sid) & val & hor, z_box, sensor)
        for x0, y0, x1, y1 in regions:
            sub = (slice(y0, y1), slice(x0, x1))
            on = (lab[sub] == sid) & val[sub] & hor[sub]
            height = _height_over(on, z_box[sub], coef, (x0, y0), lab.shape)
            for (py, px), mine in _pieces(
                on, z_box[sub], height, sensor, min_px=min_px, k_sigma=k_sigma, window_px=window_px,
                ring_share=ring_share, step_resolutions=step_resolutions,
            ):  # fmt: skip
                of_support.append(sid)
                out[by0 + y0 + py.start : by0 + y0 + py.stop, bx0 + x0 + px.start : bx0 + x0 + px.stop][mine] = len(
                    of_support
                )
    return out, of_support


def _pieces(
    on: NDArray[np.bool_],
    z_box: NDArray[np.float32],
    height: NDArray[np.float32],
    sensor: SensorModel,
    *,
    min_px: int,
    k_sigma: float,
    window_px: int,
    ring_share: float,
    step_resolutions: float,
) -> list[tuple[tuple[slice, slice], NDArray[np.bool_]]]:
    """Return the pieces of ``on`` standing above the plane, each as its box (slices) and mask in it.

    ``height``: each reading's height (mm) over the support's plane; the parameters are
    :func:`raised_pieces`'.
    """
    found: list[tuple[tuple[slice, slice], NDArray[np.bool_]]] = []
    win = (window_px, window_px)
    square = np.ones(win, np.uint8)
    # each window's mean height and depth over the support's readings in it
    count = cv2.boxFilter(on.astype(np.float32), -1, win, normalize=False)
    n = np.maximum(count, 1.0)
    mean = cv2.boxFilter(height, -1, win, normalize=False) / n
    zmean = cv2.boxFilter(np.where(on, z_box, 0).astype(np.float32), -1, win, normalize=False) / n
    limit = k_sigma * sensor.sigma(zmean) / np.sqrt(n) + sensor.step(zmean)
    # holes (a structured-light camera's sieve of dropouts) are bridged: a window counts
    # wherever a quarter of it has the support's readings
    area = cv2.morphologyEx(on.astype(np.uint8), cv2.MORPH_CLOSE, square).astype(bool)
    area &= count >= window_px * window_px / 4
    high = cv2.morphologyEx((area & (mean > limit)).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    k, comp, stats, _ = cv2.connectedComponentsWithStats(high, connectivity=8)
    if k <= 1:
        return found
    flat = area & (np.abs(mean) <= limit)
    hh, ww = on.shape
    ring_kernel = np.ones((7, 7), np.uint8)
    for j in range(1, k):
        if stats[j, cv2.CC_STAT_AREA] < min_px:
            continue
        x, y, bw, bh = (int(v) for v in stats[j, :4])
        # the piece's box grown by the ring's width: the ring is read there only
        x0, y0, x1, y1 = max(x - 4, 0), max(y - 4, 0), min(x + bw + 4, ww), min(y + bh + 4, hh)
        piece = comp[y0:y1, x0:x1] == j
        ring = cv2.dilate(piece.astype(np.uint8), ring_kernel).astype(bool) & ~piece
        if flat[y0:y1, x0:x1][ring].sum() < ring_share * max(int(ring.sum()), 1):
            continue
        on_here = on[y0:y1, x0:x1]
        inside_height = height[y0:y1, x0:x1]
        # its edge where the readings pass half its height: the window's mean reaches past it
        half = 0.5 * float(np.median(inside_height[piece & on_here]))
        mine = piece & on_here & (inside_height > half)
        if int(mine.sum()) < min_px:
            continue
        # a step over the ring, not a swell of the surface: a real camera's depth bends by a
        # few resolutions over a table (lens and baseline calibration), smoothly, so that the
        # ring of a swell rises with it; an object lying on the table steps up from a flat ring
        near = ring & on_here
        around = float(np.median(inside_height[near])) if near.any() else 0.0
        z_piece = float(np.median(z_box[y0:y1, x0:x1][mine]))
        if float(np.median(inside_height[mine])) - around < step_resolutions * float(sensor.resolution(z_piece)):
            continue
        found.append(((slice(y0, y1), slice(x0, x1)), mine))
    return found


def _block_plane(
    ons: NDArray[np.bool_],
    zs: NDArray[np.float32],
    s: int,
    shape: tuple[int, int],
    sensor: SensorModel,
    k_sigma: float,
    margin_px: int,
) -> tuple[NDArray[np.float64], list[tuple[int, int, int, int]]] | None:
    """Return the support's plane (``1000/Z = a u + b v + c``, box-centred) and where to look, or None.

    ``ons`` and ``zs``: the support's readings and depths of every ``s``-th pixel of its box of
    ``shape`` (about :data:`_GATE_SAMPLES`); an empty plane when they make too few blocks. They
    are averaged over square blocks (about :data:`_GATE_BLOCKS`; OpenCV's area resize), of
    which those wholly on the support are read: a plane is linear in inverse depth, so such a
    block's mean inverse depth is the plane's at its centre, and noise averages down by the
    root of its count. A block standing above the blocks' least-squares plane by ``k_sigma``
    of its mean's noise plus one quantisation step, and by one of the sensor's resolutions,
    says something may lie on the support (a piece is kept when it stands three resolutions
    over its ring, :func:`raised_pieces`, so a block half covered by one stands out). What lies
    on the support pulls that fit up by its share of it, less than its height: when no block
    stands out nothing does (None, and no reading is looked at again, as on most frames).
    Otherwise the plane is fitted again on the blocks within 2.5 MADs of it, then on those
    within their noise, and only the boxes around the blocks standing above that plane
    (:func:`_regions`, box pixels) are read at full resolution: None when there are none.
    """
    h, w = shape
    gh0, gw0 = ons.shape
    b = max(2, round(math.sqrt(gh0 * gw0 / _GATE_BLOCKS)))
    gh, gw = gh0 // b, gw0 // b
    if gh * gw < 12:
        return np.zeros(0), [(0, 0, w, h)]  # too few blocks: the caller fits the readings themselves
    m = ons[: gh * b, : gw * b].astype(np.float32)
    q = np.float32(1000.0) / np.maximum(zs[: gh * b, : gw * b], np.float32(1.0))
    merged = cv2.merge([m, np.multiply(m, q, dtype=np.float32)])
    means = np.asarray(cv2.resize(merged, (gw, gh), interpolation=cv2.INTER_AREA), np.float32)
    full = means[:, :, 0] >= np.float32(0.999)
    rows, cols = np.nonzero(full)
    if rows.size < 6:
        return None
    mq = means[rows, cols, 1].astype(np.float64)
    centre = s * (b - 1) / 2.0
    mu = cols * float(s * b) + (centre - (w - 1) / 2.0)
    mv = rows * float(s * b) + (centre - (h - 1) / 2.0)
    z = 1000.0 / mq
    # the sensor's sigma and step at each block's depth (SensorModel.sigma, .step and
    # .resolution written out: their calls cost more than the arithmetic on a few hundred blocks)
    z2 = z * z
    sigma = sensor.sigma_0 + sensor.sigma_2 * z2
    limit = (k_sigma / b) * sigma + (sensor.step_0 + sensor.step_2 * z2)
    gate = np.maximum(limit, 2.0 * sigma)  # the resolution: the larger of a step and two sigmas
    design = np.stack([mu, mv, np.ones_like(mu)], axis=1)
    coef = _solve3(design.T @ design, design.T @ mq)
    above = 1000.0 / np.maximum(design @ coef, 1e-12) - z
    if not bool((above > gate).any()):
        return None
    mid = _middle(above)
    spread = 1.4826 * _middle(np.abs(above - mid))
    # one-sided: nothing on a support lies below it, and what lies on it (a quarter of a table
    # seen from above may be dishes and books) tilts a fit toward itself; a symmetric cut of a
    # tilted fit drops the support's own far side as well
    keep = above - mid < np.maximum(2.5 * spread, limit)
    for _ in range(_ROUNDS):
        if int(keep.sum()) < 3:
            break
        d = design[keep]
        coef = _solve3(d.T @ d, d.T @ mq[keep])
        above = 1000.0 / np.maximum(design @ coef, 1e-12) - z
        keep = above < limit
    regions = _regions(means, coef, b, s, shape, sensor, k_sigma, margin_px)
    return (coef, regions) if regions else None


def _regions(
    means: NDArray[np.float32],
    coef: NDArray[np.float64],
    b: int,
    s: int,
    shape: tuple[int, int],
    sensor: SensorModel,
    k_sigma: float,
    margin_px: int,
) -> list[tuple[int, int, int, int]]:
    """Return the boxes (x0, y0, x1, y1, exclusive, box pixels) around the blocks standing above the plane.

    ``means``: each block's share of samples on the support and its mean of ``share * 1000/Z``
    (:func:`_block_plane`), blocks of ``b`` x ``b`` samples every ``s`` pixels. A block with a
    quarter of its samples on the support stands above the plane when its mean does by its
    noise (``k_sigma`` of its mean's sigma plus one step) and by one resolution; the blocks
    next to one are read too (a piece covering part of them), and ``margin_px`` around (the
    windows and the ring). Overlapping boxes are merged, so that a piece is read whole once.
    """
    h, w = shape
    gh, gw = means.shape[:2]
    share = means[:, :, 0]
    part = share >= np.float32(0.25)
    cell = float(s * b)
    centre = s * (b - 1) / 2.0
    mu = (np.arange(gw) * cell + (centre - (w - 1) / 2.0))[None, :]
    mv = (np.arange(gh) * cell + (centre - (h - 1) / 2.0))[:, None]
    mq = means[:, :, 1] / np.maximum(share, np.float32(1e-6))
    z = 1000.0 / np.maximum(mq, 1e-12)
    z2 = z * z
    sigma = sensor.sigma_0 + sensor.sigma_2 * z2
    n = np.maximum(share * (b * b), 1.0)
    limit = k_sigma * sigma / np.sqrt(n) + (sensor.step_0 + sensor.step_2 * z2)
    gate = np.maximum(limit, 2.0 * sigma)
    plane = coef[0] * mu + coef[1] * mv + coef[2]
    above = 1000.0 / np.maximum(plane, 1e-12) - z
    stands = (part & (above > gate)).astype(np.uint8)
    if not stands.any():
        return []
    stands = cv2.dilate(stands, np.ones((3, 3), np.uint8))
    k, _, stats, _ = cv2.connectedComponentsWithStats(stands, connectivity=8)
    boxes = []
    for c0, r0, bw, bh in stats[1:k, :4].tolist():
        # the samples' grid leaves the box's last pixels out of the blocks: a block at the end
        # reaches the box's end
        x1 = w if c0 + bw >= gw else (c0 + bw) * s * b + margin_px
        y1 = h if r0 + bh >= gh else (r0 + bh) * s * b + margin_px
        boxes.append([max(c0 * s * b - margin_px, 0), max(r0 * s * b - margin_px, 0), min(x1, w), min(y1, h)])
    return _merged(boxes)


def _merged(boxes: list[list[int]]) -> list[tuple[int, int, int, int]]:
    """Return the boxes (x0, y0, x1, y1, exclusive) with overlapping ones merged into their union's box."""
    merged = True
    while merged and len(boxes) > 1:
        merged = False
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                a, c = boxes[i], boxes[j]
                if a[0] < c[2] and c[0] < a[2] and a[1] < c[3] and c[1] < a[3]:
                    boxes[i] = [min(a[0], c[0]), min(a[1], c[1]), max(a[2], c[2]), max(a[3], c[3])]
                    del boxes[j]
                    merged = True
                    break
            if merged:
                break
    return [(a[0], a[1], a[2], a[3]) for a in boxes]


def _plane_fit(on: NDArray[np.bool_], z_box: NDArray[np.float32], sensor: SensorModel) -> NDArray[np.float64]:
    """Return the support's plane fitted on its readings, for a support too small for blocks.

    The plane is linear in inverse depth over pixels, ``1000/Z = a u + b v + c``, whatever the
    intrinsics; it is fitted robustly, first against the readings' own spread (what lies on the
    support pulls a least-squares fit up), then against the sensor's noise, on about a thousand
    readings spread over the support on a grid (the plane has three numbers).
    """
    n_on = int(np.count_nonzero(on))
    every = max(1, int(np.sqrt(n_on / _FIT_READINGS)))
    rows, cols = np.nonzero(on[::every, ::every])
    z = z_box[::every, ::every][rows, cols].astype(np.float64)
    cu, cv = (on.shape[1] - 1) / 2.0, (on.shape[0] - 1) / 2.0
    design = np.stack([cols * float(every) - cu, rows * float(every) - cv, np.ones_like(z)], axis=1)
    q = 1000.0 / z
    noise = 3.0 * sensor.sigma(z) + sensor.step(z)
    keep = np.ones(z.size, bool)
    coef = np.zeros(3)
    for r in range(_ROUNDS):
        d = design[keep]
        coef = np.linalg.solve(d.T @ d + np.eye(3) * 1e-9, d.T @ q[keep])
        plane_q = design @ coef
        above = np.where(plane_q > 0, 1000.0 / np.maximum(plane_q, 1e-12) - z, 0.0)
        if r < _ROUNDS // 2:
            res = above[keep]
            mid = float(np.median(res))
            spread = 1.4826 * float(np.median(np.abs(res - mid)))
            new_keep = above - mid < np.maximum(2.5 * spread, noise)  # one-sided, as in _block_plane
        else:
            new_keep = above < noise
        if int(new_keep.sum()) < 3:
            break
        keep = new_keep
    return coef


def _height_over(
    on: NDArray[np.bool_],
    z_box: NDArray[np.float32],
    coef: NDArray[np.float64],
    origin: tuple[int, int],
    shape: tuple[int, int],
) -> NDArray[np.float32]:
    """Depth (mm) by which each reading of ``on`` lies nearer than the plane ``coef`` (0 elsewhere).

    ``on`` and ``z_box`` are a part of the support's box of ``shape`` starting at its pixel
    ``origin`` (x, y): the plane is centred on the box.
    """
    cu, cv = (shape[1] - 1) / 2.0 - origin[0], (shape[0] - 1) / 2.0 - origin[1]
    u = (np.arange(on.shape[1], dtype=np.float32) - np.float32(cu))[None, :]
    v = (np.arange(on.shape[0], dtype=np.float32) - np.float32(cv))[:, None]
    plane = np.float32(coef[0]) * u + np.float32(coef[1]) * v + np.float32(coef[2])
    with np.errstate(divide="ignore", invalid="ignore"):
        height = np.float32(1000.0) / plane - z_box
    return np.where(on & (plane > 0), height, np.float32(0.0)).astype(np.float32)


def _middle(x: NDArray[np.float64]) -> float:
    """Return the upper median of ``x`` (one partition: numpy's median call costs more than its work here)."""
    k = x.size // 2
    return float(np.partition(x, k)[k])


def _solve3(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Solve the 3 x 3 system ``a x = b`` by Cramer's rule (numpy's solve costs more than its work here)."""
    (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = a.tolist()
    y0, y1, y2 = b.tolist()
    det = a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0)
    if abs(det) < 1e-300:
        return np.zeros(3)
    x0 = y0 * (b1 * c2 - b2 * c1) - a1 * (y1 * c2 - b2 * y2) + a2 * (y1 * c1 - b1 * y2)
    x1 = a0 * (y1 * c2 - b2 * y2) - y0 * (b0 * c2 - b2 * c0) + a2 * (b0 * y2 - y1 * c0)
    x2 = a0 * (b1 * y2 - y1 * c1) - a1 * (b0 * y2 - y1 * c0) + y0 * (b0 * c1 - b1 * c0)
    return np.array([x0 / det, x1 / det, x2 / det])
