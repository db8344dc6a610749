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

The cost is kept to what a default can pay: a compiled gate fits the plane on block means of
every few readings and lets a support through only when a block stands above it; the cut then
reads every t-th reading, t the largest step at which its window of 3 x 3 samples fits inside
the smallest piece (``min_px``, :data:`_PIECE_SAMPLES`), and only the pieces it keeps are read
at full resolution.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.segmentation._kernels.raised import FEW_BLOCKS, PLANE, block_gate
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
#: samples of the smallest piece when a support is cut on every t-th reading
#: (:func:`_sampled_pieces`): t is the largest step at which the cut's window of 3 x 3 samples
#: (3t px a side) still fits inside a piece of ``min_px`` pixels
_PIECE_SAMPLES = 9


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

    A support passes the gate first (:func:`_block_plane`); it is then cut at full resolution
    when ``min_px`` is small (under :data:`_PIECE_SAMPLES` x 4 pixels), on every t-th reading
    otherwise (:func:`_sampled_pieces`).

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
        Side of the window (px) whose readings are averaged at full resolution (3 x 3 samples
        on every t-th reading).
    ring_share : float
        Least share (0..1) of the ring around a piece lying on the plane.
    step_resolutions : float
        How many of the sensor's resolutions (:meth:`SensorModel.resolution`) the piece's median
        height must stand above its ring's.

    Returns
    -------
    pieces : ndarray of int32, shape (H, W)
        0, or the piece 1..k of each pixel (pixels with a reading only); read-only when there
        is no piece.
    of_support : list of int
        The support id each piece was cut from (``of_support[j - 1]`` for piece ``j``).
    """
    h, w = depth_mm.shape
    out: NDArray[np.int32] | None = None  # most frames cut nothing: no frame-sized map then
    of_support: list[int] = []
    pad = window_px + 4
    for sid, box in zip(support_ids, boxes, strict=True):
        # the support's own box (inclusive), grown by the windows and the ring: nothing else is read
        bx0, by0 = max(int(box[0]) - pad, 0), max(int(box[1]) - pad, 0)
        bx1, by1 = min(int(box[2]) + pad + 1, w), min(int(box[3]) + pad + 1, h)
        lab, z_box = labels[by0:by1, bx0:bx1], depth_mm[by0:by1, bx0:bx1]
        val, hor = valid[by0:by1, bx0:bx1], horizontal[by0:by1, bx0:bx1]
        coef = _block_plane(labels, sid, horizontal, depth_mm, (bx0, by0, bx1, by1), sensor, k_sigma, min_px)
        if coef is None:
            continue
        if coef.size == 0:
            coef = _plane_fit((lab == sid) & val & hor, z_box, sensor)
        t = max(1, math.isqrt(min_px // _PIECE_SAMPLES))
        if t > 1:
            # cut on every t-th reading (the cut's cost is its pixel count), the pieces' pixels
            # then taken at full resolution (:func:`_sampled_pieces`)
            found = _sampled_pieces(
                lab, sid, val, hor, z_box, coef, t, sensor, min_px=min_px, k_sigma=k_sigma,
                ring_share=ring_share, step_resolutions=step_resolutions,
            )  # fmt: skip
        else:
            on = (lab == sid) & val & hor
            height = _height_over(on, z_box, coef, (0, 0), lab.shape)
            got = _pieces(
                on, z_box, height, sensor, min_px=min_px, k_sigma=k_sigma, window_px=window_px,
                ring_share=ring_share, step_resolutions=step_resolutions,
            )  # fmt: skip
            found = [(where, mine) for where, mine, _ in got]
        for (py, px), mine in found:
            of_support.append(sid)
            if out is None:
                out = np.zeros((h, w), np.int32)
            out[by0 + py.start : by0 + py.stop, bx0 + px.start : bx0 + px.stop][mine] = len(of_support)
    if out is None:
        # read-only zeros without a frame's memory
        return np.broadcast_to(np.int32(0), (h, w)), of_support
    return out, of_support


def _sampled_pieces(
    lab: NDArray[np.int32],
    sid: int,
    val: NDArray[np.bool_],
    hor: NDArray[np.bool_],
    z_box: NDArray[np.float32],
    coef: NDArray[np.float64],
    t: int,
    sensor: SensorModel,
    *,
    min_px: int,
    k_sigma: float,
    ring_share: float,
    step_resolutions: float,
) -> list[tuple[tuple[slice, slice], NDArray[np.bool_]]]:
    """Return the pieces of a support found on every ``t``-th reading of its box, with their full-resolution pixels.

    The cut of :func:`_pieces` on the samples, in windows of 3 x 3 samples (which bridge a
    structured-light camera's dropouts as the full resolution's 5 x 5 do) and a ring one
    sample wide; a piece's pixels are then the support's readings of its samples' cells (and
    one cell around: the samples' edge is a cell off the readings') standing above half its
    median height. ``lab``, ``val``, ``hor``: the labels (the support's are ``sid``), the readings and the
    horizontal class in its box; the other parameters are :func:`raised_pieces`'.
    """
    h, w = lab.shape
    sub = (slice(None, None, t), slice(None, None, t))
    on_t = (lab[sub] == sid) & val[sub] & hor[sub]
    z_t = z_box[sub]
    height_t = _height_over(on_t, z_t, coef, (0, 0), (h, w), step=t)
    got = _pieces(
        on_t, z_t, height_t, sensor, min_px=max(1, math.ceil(min_px / (t * t))), k_sigma=k_sigma, window_px=3,
        ring_share=ring_share, step_resolutions=step_resolutions, ring_px=1, open_px=1,
    )  # fmt: skip
    found = []
    cell = np.ones((2 * t + 1, 2 * t + 1), np.uint8)
    for (py, px), mine_t, half in got:
        y0, y1 = max(py.start * t - t, 0), min(py.stop * t + t, h)
        x0, x1 = max(px.start * t - t, 0), min(px.stop * t + t, w)
        cells = np.zeros((y1 - y0, x1 - x0), np.uint8)
        grid = np.repeat(np.repeat(mine_t.view(np.uint8), t, axis=0), t, axis=1)
        oy, ox = py.start * t - y0, px.start * t - x0
        gh, gw = min(grid.shape[0], cells.shape[0] - oy), min(grid.shape[1], cells.shape[1] - ox)
        cells[oy : oy + gh, ox : ox + gw] = grid[:gh, :gw]
        here = (slice(y0, y1), slice(x0, x1))
        on = (lab[here] == sid) & val[here] & hor[here]
        height = _height_over(on, z_box[here], coef, (x0, y0), (h, w))
        mine = cv2.dilate(cells, cell).view(bool) & on & (height > half)
        if int(np.count_nonzero(mine)) >= min_px:
            found.append((here, mine))
    return found


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
    ring_px: int = 3,
    open_px: int = 3,
) -> list[tuple[tuple[slice, slice], NDArray[np.bool_], float]]:
    """Return the pieces of ``on`` standing above the plane: each one's box (slices), mask in it and half height (mm).

    ``height``: each reading's height (mm) over the support's plane; ``ring_px``: the ring's
    width (px); ``open_px``: the side of the opening that drops slivers of the windows' test
    (1: none); the other parameters are :func:`raised_pieces`'.
    """
    found: list[tuple[tuple[slice, slice], NDArray[np.bool_], float]] = []
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
    high = (area & (mean > limit)).view(np.uint8)
    if open_px > 1:
        high = np.asarray(cv2.morphologyEx(high, cv2.MORPH_OPEN, np.ones((open_px, open_px), np.uint8)), np.uint8)
    k, comp, stats, _ = cv2.connectedComponentsWithStats(high, connectivity=8)
    if k <= 1:
        return found
    flat = area & (np.abs(mean) <= limit)
    n_on = np.count_nonzero(on)
    hh, ww = on.shape
    ring_kernel = np.ones((2 * ring_px + 1, 2 * ring_px + 1), np.uint8)
    grow = ring_px + 1
    big = np.flatnonzero(stats[1:k, cv2.CC_STAT_AREA] >= min_px) + 1
    for j, where in zip(big.tolist(), stats[big, :4].tolist(), strict=True):
        x, y, bw, bh = (int(v) for v in where)
        # the piece's box grown by the ring's width: the ring is read there only
        x0, y0, x1, y1 = max(x - grow, 0), max(y - grow, 0), min(x + bw + grow, ww), min(y + bh + grow, hh)
        piece = comp[y0:y1, x0:x1] == j
        ring = cv2.dilate(piece.view(np.uint8), ring_kernel).view(bool) & ~piece
        if np.count_nonzero(flat[y0:y1, x0:x1] & ring) < ring_share * max(int(np.count_nonzero(ring)), 1):
            continue
        on_here = on[y0:y1, x0:x1]
        inside_height = height[y0:y1, x0:x1]
        # its edge where the readings pass half its height: the window's mean reaches past it
        half = 0.5 * _median(inside_height[piece & on_here])
        mine = piece & on_here & (inside_height > half)
        n_mine = np.count_nonzero(mine)
        # more than half of the support standing above its plane is the support: the plane was
        # fitted on the rest (a robust fit's breakdown point), nothing lies on it
        if n_mine < min_px or 2 * n_mine > n_on:
            continue
        # a step over the ring, not a swell of the surface: a real camera's depth bends by a
        # few resolutions over a table (lens and baseline calibration), smoothly, so that the
        # ring of a swell rises with it; an object lying on the table steps up from a flat ring
        near = ring & on_here
        around = _median(inside_height[near]) if near.any() else 0.0
        z_piece = _median(z_box[y0:y1, x0:x1][mine])
        if _median(inside_height[mine]) - around < step_resolutions * float(sensor.resolution(z_piece)):
            continue
        found.append(((slice(y0, y1), slice(x0, x1)), mine, half))
    return found


def _block_plane(
    labels: NDArray[np.int32],
    sid: int,
    horizontal: NDArray[np.bool_],
    depth_mm: NDArray[np.float32],
    box: tuple[int, int, int, int],
    sensor: SensorModel,
    k_sigma: float,
    min_px: int,
) -> NDArray[np.float64] | None:
    """Return the support's plane (``1000/Z = a u + b v + c``, box-centred), or None when nothing stands above it.

    ``box``: (x0, y0, x1, y1, exclusive) of the support ``sid``'s pixels, grown by the windows
    and the ring. Every s-th pixel of it is read (about :data:`_GATE_SAMPLES`): None when too few
    are the support's horizontal readings, an empty plane when they make too few blocks (the
    caller fits the readings themselves). They are averaged over square blocks (about
    :data:`_GATE_BLOCKS`), of which those wholly on the support are read: a plane is linear in
    inverse depth, so such a block's mean inverse depth is the plane's at its centre, and noise
    averages down by the root of its count. A block standing above the blocks' least-squares
    plane by ``k_sigma`` of its mean's noise plus one quantisation step, and by one of the
    sensor's resolutions, says something may lie on the support (a piece is kept when it
    stands three resolutions over its ring, :func:`raised_pieces`, so a block half covered by
    one stands out). What lies on the support pulls that fit up by its share of it, less than
    its height: when no block stands out nothing does (None, and no reading is looked at
    again, as on most frames). Otherwise the plane is fitted again on the blocks within 2.5
    MADs of it (one-sided: nothing on a support lies below it, and what lies on it, a quarter
    of a table seen from above in dishes and books, tilts a fit toward itself; a symmetric cut
    of a tilted fit drops the support's own far side as well), then on those within their
    noise; None when no block stands above that plane either. The loops are compiled
    (:func:`depthgram.segmentation._kernels.raised.block_gate`): numpy's calls on a few hundred
    blocks cost more than their arithmetic.
    """
    x0, y0, x1, y1 = box
    s = max(1, round(math.sqrt((x1 - x0) * (y1 - y0) / _GATE_SAMPLES)))
    status, coef = block_gate(
        labels, int(sid), horizontal, depth_mm, x0, y0, x1, y1, s, float(_GATE_BLOCKS),
        float(max(_MIN_SUPPORT_PX, min_px)), float(sensor.sigma_0), float(sensor.sigma_2), float(sensor.step_0),
        float(sensor.step_2), float(k_sigma), _ROUNDS,
    )  # fmt: skip
    if status == PLANE:
        return coef
    return np.zeros(0) if status == FEW_BLOCKS else None


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
    step: int = 1,
) -> NDArray[np.float32]:
    """Depth (mm) by which each reading of ``on`` lies nearer than the plane ``coef`` (0 elsewhere).

    ``on`` and ``z_box`` are every ``step``-th pixel of a part of the support's box of ``shape``
    starting at its pixel ``origin`` (x, y): the plane is centred on the box.
    """
    cu, cv = (shape[1] - 1) / 2.0 - origin[0], (shape[0] - 1) / 2.0 - origin[1]
    u = (np.arange(0, on.shape[1] * step, step, dtype=np.float32) - np.float32(cu))[None, :]
    v = (np.arange(0, on.shape[0] * step, step, dtype=np.float32) - np.float32(cv))[:, None]
    plane = np.float32(coef[0]) * u + np.float32(coef[1]) * v + np.float32(coef[2])
    with np.errstate(divide="ignore", invalid="ignore"):
        height = np.float32(1000.0) / plane - z_box
    return np.where(on & (plane > 0), height, np.float32(0.0)).astype(np.float32)


def _median(x: NDArray[np.float32]) -> float:
    """Return the median of ``x`` (non-empty) by one partition: numpy's median call costs more than its work here."""
    k = x.size // 2
    if x.size % 2:
        return float(np.partition(x, k)[k])
    p = np.partition(x, (k - 1, k))
    return 0.5 * (float(p[k - 1]) + float(p[k]))
