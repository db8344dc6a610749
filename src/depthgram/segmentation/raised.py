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

from depthgram.segmentation._kernels.raised import FEW_BLOCKS, PLANE, block_gate, component_test, window_test
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
    classes: NDArray[np.int8],
    cls: int,
    support_ids: list[int],
    boxes: NDArray[np.int64],
    sensor: SensorModel,
    *,
    min_px: int,
    k_sigma: float = 4.0,
    window_px: int = 5,
    ring_share: float = 0.6,
    step_resolutions: float = 3.0,
) -> tuple[NDArray[np.int32], list[int], tuple[int, int, int, int]]:
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
    classes : ndarray of int8, shape (H, W)
        Each pixel's orientation class.
    cls : int
        The supports' class (horizontal, or facing for a table seen from above): a support's
        plane is fitted on its readings of this class, and only they are cut.
    support_ids : list of int
        The supports' ids in ``labels``.
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
    box : tuple of int
        (x0, y0, x1, y1, exclusive) holding every piece's pixels: the caller reads no more of
        ``pieces`` (an empty box when there is no piece).
    """
    h, w = depth_mm.shape
    x_lo, y_lo, x_hi, y_hi = w, h, 0, 0
    out: NDArray[np.int32] | None = None  # most frames cut nothing: no frame-sized map then
    of_support: list[int] = []
    pad = window_px + 4
    for sid, own in zip(support_ids, boxes, strict=True):
        # the support's own box (inclusive), grown by the windows and the ring: nothing else is read
        bx0, by0 = max(int(own[0]) - pad, 0), max(int(own[1]) - pad, 0)
        bx1, by1 = min(int(own[2]) + pad + 1, w), min(int(own[3]) + pad + 1, h)
        coef = _block_plane(labels, sid, classes, cls, depth_mm, (bx0, by0, bx1, by1), sensor, k_sigma, min_px)
        if coef is None:
            continue
        if coef.size == 0:
            lab, val, hor = labels[by0:by1, bx0:bx1], valid[by0:by1, bx0:bx1], classes[by0:by1, bx0:bx1] == cls
            coef = _plane_fit((lab == sid) & val & hor, depth_mm[by0:by1, bx0:bx1], sensor)
        box = (bx0, by0, bx1, by1)
        t = max(1, math.isqrt(min_px // _PIECE_SAMPLES))
        if t > 1:
            # cut on every t-th reading (the cut's cost is its pixel count), the pieces' pixels
            # then taken at full resolution (:func:`_sampled_pieces`)
            found = _sampled_pieces(
                labels, sid, valid, classes, cls, depth_mm, box, coef, t, sensor, min_px=min_px, k_sigma=k_sigma,
                ring_share=ring_share, step_resolutions=step_resolutions,
            )  # fmt: skip
        else:
            got = _pieces(
                labels, sid, valid, classes, cls, depth_mm, box, coef, 1, sensor, min_px=min_px, k_sigma=k_sigma,
                window_px=window_px, ring_share=ring_share, step_resolutions=step_resolutions,
            )  # fmt: skip
            found = [(where, mine) for where, mine, _ in got]
        for (py, px), mine in found:
            of_support.append(sid)
            if out is None:
                out = np.zeros((h, w), np.int32)
            out[by0 + py.start : by0 + py.stop, bx0 + px.start : bx0 + px.stop][mine] = len(of_support)
            x_lo, y_lo = min(x_lo, bx0 + px.start), min(y_lo, by0 + py.start)
            x_hi, y_hi = max(x_hi, bx0 + px.stop), max(y_hi, by0 + py.stop)
    if out is None:
        # read-only zeros without a frame's memory
        return np.broadcast_to(np.int32(0), (h, w)), of_support, (0, 0, 0, 0)
    return out, of_support, (x_lo, y_lo, x_hi, y_hi)


def _sampled_pieces(
    labels: NDArray[np.int32],
    sid: int,
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    depth_mm: NDArray[np.float32],
    box: tuple[int, int, int, int],
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
    median height. ``box``: (x0, y0, x1, y1, exclusive) of the support's pixels grown by the
    windows and the ring, on which ``coef`` is centred; slices of the returned pieces are in
    it. The other parameters are :func:`raised_pieces`'.
    """
    bx0, by0, bx1, by1 = box
    h, w = by1 - by0, bx1 - bx0
    got = _pieces(
        labels, sid, valid, classes, cls, depth_mm, box, coef, t, sensor, min_px=max(1, math.ceil(min_px / (t * t))),
        k_sigma=k_sigma, window_px=3, ring_share=ring_share, step_resolutions=step_resolutions, ring_px=1, open_px=1,
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
        here = (slice(by0 + y0, by0 + y1), slice(bx0 + x0, bx0 + x1))
        on = (labels[here] == sid) & valid[here] & (classes[here] == cls)
        height = _height_over(on, depth_mm[here], coef, (x0, y0), (h, w))
        mine = cv2.dilate(cells, cell).view(bool) & on & (height > half)
        if int(np.count_nonzero(mine)) >= min_px:
            found.append(((slice(y0, y1), slice(x0, x1)), mine))
    return found


def _pieces(
    labels: NDArray[np.int32],
    sid: int,
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    depth_mm: NDArray[np.float32],
    box: tuple[int, int, int, int],
    coef: NDArray[np.float64],
    t: int,
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
    """Return the pieces of the support ``sid`` standing above its plane, on every ``t``-th reading of ``box``.

    Each piece as its box (slices of the sampled grid), mask in it and half height (mm). A
    window of ``window_px`` samples stands above the plane where its mean height over the
    support's readings in it exceeds ``k_sigma`` sensor sigmas over the root of their count
    plus one quantisation step, and lies on it where its mean is within that; holes (a
    structured-light camera's sieve of dropouts) are bridged: a window counts wherever a
    quarter of it has the support's readings and the readings closed by the window cover
    it. The standing windows' connected pieces of at least ``min_px`` samples are kept when
    ``ring_share`` of the ring around them (``ring_px`` wide) lies flat on the plane, when
    they hold at most half the support's readings (more is the support itself: the plane was
    fitted on the rest, a robust fit's breakdown point), and when their median height stands
    ``step_resolutions`` of the sensor's resolutions over their ring's: a real camera's depth
    bends by a few resolutions over a table (lens and baseline calibration), smoothly, so that
    the ring of a swell rises with it; an object lying on the table steps up from a flat ring.
    A piece's edge is where the readings pass half its median height (the window's mean
    reaches past it). ``open_px``: the side of the opening that drops slivers of the windows'
    test (1: none). The window and piece tests are compiled
    (:func:`depthgram.segmentation._kernels.raised.window_test`, ``component_test``: numpy
    and OpenCV's calls on a support's few thousand samples cost more than their
    arithmetic); the pieces are OpenCV's connected components.
    """
    x0, y0, x1, y1 = box
    m = sensor
    on, height, z, high, flat = window_test(
        labels, int(sid), valid, classes, int(cls), depth_mm, x0, y0, x1, y1, int(t), np.asarray(coef, np.float64),
        int(window_px), float(m.sigma_0), float(m.sigma_2), float(m.step_0), float(m.step_2), float(k_sigma),
    )  # fmt: skip
    if open_px > 1:
        high = np.asarray(cv2.morphologyEx(high, cv2.MORPH_OPEN, np.ones((open_px, open_px), np.uint8)), np.uint8)
    k, cv_comp, cv_stats, _ = cv2.connectedComponentsWithStats(high, connectivity=8)
    if k <= 1:
        return []
    comp, stats = np.asarray(cv_comp, np.int32), np.asarray(cv_stats, np.int32)
    kept, halves = component_test(
        comp, stats, on, flat, height, z, int(min_px), int(ring_px), float(ring_share), float(step_resolutions),
        float(m.sigma_0), float(m.sigma_2), float(m.step_0), float(m.step_2),
    )  # fmt: skip
    found: list[tuple[tuple[slice, slice], NDArray[np.bool_], float]] = []
    hh, ww = comp.shape
    grow = ring_px + 1
    for j, half in zip(kept.tolist(), halves.tolist(), strict=True):
        x, y, bw, bh = (int(v) for v in stats[j, :4])
        where = (slice(max(y - grow, 0), min(y + bh + grow, hh)), slice(max(x - grow, 0), min(x + bw + grow, ww)))
        found.append((where, (comp[where] == j) & on[where] & (height[where] > half), half))
    return found


def _block_plane(
    labels: NDArray[np.int32],
    sid: int,
    classes: NDArray[np.int8],
    cls: int,
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
        labels, int(sid), classes, int(cls), depth_mm, x0, y0, x1, y1, s, float(_GATE_BLOCKS),
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
