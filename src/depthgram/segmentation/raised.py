"""What lies on a support, however flat: readings standing above its plane by more than the noise.

A dish, a book, a screwdriver or a banana lying on a table rises 10-30 mm above it. Seen at an
angle, its edge is a depth step that a ToF camera's noise at a metre (several millimetres a
reading) and the surfaces' join allowance bridge, so it joins the table. One reading cannot tell
it from noise, but the table's plane, fitted over tens of thousands of readings, is known far
better than any reading, and a window of readings averages their noise down: a patch whose mean
stands above the plane by several of the sensor's sigmas over the window's root count (plus one
quantisation step) is not the table.

Only a support's readings of its own orientation class are read and fitted (a table top's
horizontal ones: a front face folded into it is not on its plane). A piece is kept when it is
large enough to be an object and the ring around it lies on the plane: the edge of a non-planar
support (a ramp, a sagging cloth) rises gradually and has no flat ring, an object lying on the
table has one.

The steps, for each support (:func:`raised_pieces`):

1. **The gate** (:func:`_block_plane`) fits the plane on block means of every few readings and
   lets a support through only when a block stands above it: on most frames nothing lies on a
   support and nothing more is read.
2. **The cut** reads every t-th reading, t the largest step at which its window of 3 x 3 samples
   fits inside the smallest piece (``min_px``, :data:`_PIECE_SAMPLES`): the cut's cost is its
   pixel count. A window stands above the plane where its mean height over the support's
   readings in it exceeds ``k_sigma`` sensor sigmas over the root of their count plus one
   quantisation step, and lies on it where its mean is within that. Holes (a structured-light
   camera's sieve of dropouts) are bridged: a window counts wherever a quarter of it has the
   support's readings and the readings closed by the window cover it.
3. **The pieces**, the standing windows' 8-connected sets, are kept when they are large enough
   and hold at most half the support's readings (more is the support itself: the plane was
   fitted on the rest, a robust fit's breakdown point), and when they look like a thing lying
   on the support, not like the support's own depth bending:

   - ``ring_share`` of the ring around them (one sample wide) lies flat on the plane, and at
     most ``ring_missing`` of it has no reading: a thing lying on a support is too low to cast
     a shadow; one standing well before it (on a counter before a wall) is seen beside its own;
   - their median height stands ``rise_steps`` quantisation steps over their ring's, and that
     ring lies at most ``ring_rise`` of their height (or a step) above the plane: a real
     camera's depth bends by a few steps over a table (lens and baseline calibration),
     smoothly, so the ring of a swell rises with it, as does that of a ball's cap taken for a
     support; a thing lying on a table steps up from a flat ring. (The rise is a difference of
     two medians of many readings: a noisy time-of-flight camera's sigma counts only by the
     root of their counts; one reading's two sigmas would hide a dish 5 sigmas high);
   - the support beyond the ring (one to two samples out) lies on the plane, its median within
     ``outer_resolutions``: a stereo or structured-light floor's streak has a trough beside its
     crest.

4. **A kept piece's pixels** are then the support's readings of its samples' cells and one cell
   around (the samples' edge is a cell off the readings') standing above half its median height
   (the window's mean reaches past its edge), when they are still ``min_px`` and the support's
   readings 4-6 px beyond them (within a sample's cell of the piece) do not lie below the plane
   by more than ``ring_trough`` of the piece's height (a stereo streak's trough beside its
   crest), and their outline, smoothed of single readings, is at most ``ring_outline`` times
   the root of their area (a stereo camera's error on a weakly textured surface is a lacy
   mosaic; a thing lying there is a solid body). The caller holds only horizontal supports'
   pieces (a table seen at an angle) to these two.

Steps 2-4 run compiled (:mod:`depthgram.segmentation._kernels.raised`: numpy's and OpenCV's
calls on a support's few thousand samples cost more than their arithmetic).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.segmentation._kernels.raised import FEW_BLOCKS, PLANE, block_gate, cut, paint
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
#: the cut's window and ring (samples), and how far (px) a support's box is grown to hold them at
#: its edge
_WINDOW, _RING, _PAD_PX = 3, 1, 9
#: samples of the smallest piece when a support is cut on every t-th reading: t is the largest
#: step at which the cut's window of 3 x 3 samples (3t px a side) still fits inside a piece of
#: ``min_px`` pixels
_PIECE_SAMPLES = 9
#: the band of the support's readings beyond a piece's pixels that ``ring_trough`` reads (px, a
#: square's distance): past the edge's mixed readings, within a stereo streak's trough
_TROUGH_BAND = (4, 6)


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
    ring_share: float = 0.6,
    rise_steps: float = 3.0,
    outer_resolutions: float = 1.0,
    ring_missing: float = 0.15,
    ring_rise: float = 0.1,
    ring_trough: float = 0.3,
    ring_outline: float = 14.0,
    refuse_corners: bool = False,
) -> tuple[NDArray[np.int32], list[int], tuple[int, int, int, int]]:
    """Find the pieces of each horizontal support that stand above its plane by more than the noise.

    The gate, the cut on every t-th reading, the pieces' tests and their pixels, as the module
    says.

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
    ring_share : float
        Least share (0..1) of the ring around a piece lying on the plane.
    rise_steps : float
        How many quantisation steps (or the noise of the two medians, when larger) the piece's
        median height must stand above its ring's.
    outer_resolutions : float
        How many resolutions the support's median height beyond the ring may lie off its plane.
    ring_missing : float
        Most share (0..1) of the ring around a piece without a reading: a thing lying on a
        support is too low to cast a shadow or leave mixed pixels at its edge; one standing
        well before it (on a counter before a wall) is seen beside its shadow.
    ring_rise : float
        Most the ring's median height may be, as a share of the piece's (or one quantisation
        step, when larger): a thing lying on a support steps up from the plane at its edge;
        the cap of a rounded surface taken for a support (a hand, a ball near the camera) has
        its ring rising with it.
    ring_trough : float
        Most the support's readings 4 to 6 px beyond a piece's pixels (and within one sample's
        cell of its samples) may lie below the plane (their median), as a share of the piece's
        median height (``inf``: not read): a stereo camera's depth error is zero-mean over its
        matching, so a streak's crest has a trough beside it; a thing lying on a support has
        the support's plane there.
    ring_outline : float
        Most a piece's outline (its pixels opened and closed by 3 x 3, against single readings'
        noise) may be over the root of its area (``inf``: not read): a thing lying on a support
        is a solid body (a disc 3.5, a book 4-5, a screwdriver 6-7); a stereo camera's error
        on a weakly textured table or carpet is a lacy mosaic of its matching's patches.
    refuse_corners : bool
        Refuse a piece with more than a third of its ring beyond the frame's edge: a piece in a
        corner of a table seen at an angle (half its ring beyond) is where a structured-light
        camera's depth bends most, and nothing of its ring is seen there; a thing partly out of
        view along one edge (a quarter of its ring beyond) is kept.

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
    # steps 2 and 3 read every t-th reading, then step 4 the pieces kept
    t = max(1, math.isqrt(min_px // _PIECE_SAMPLES))
    min_samples = max(1, math.ceil(min_px / (t * t)))
    m = sensor
    for sid, own in zip(support_ids, boxes, strict=True):
        # the support's own box (inclusive), grown by the windows and the ring: nothing else is read
        bx0, by0 = max(int(own[0]) - _PAD_PX, 0), max(int(own[1]) - _PAD_PX, 0)
        bx1, by1 = min(int(own[2]) + _PAD_PX + 1, w), min(int(own[3]) + _PAD_PX + 1, h)
        coef = _block_plane(labels, sid, classes, cls, depth_mm, (bx0, by0, bx1, by1), sensor, k_sigma, min_px)
        if coef is None:
            continue
        if coef.size == 0:
            lab, val, hor = labels[by0:by1, bx0:bx1], valid[by0:by1, bx0:bx1], classes[by0:by1, bx0:bx1] == cls
            coef = _plane_fit((lab == sid) & val & hor, depth_mm[by0:by1, bx0:bx1], sensor)
        comp, pieces, kept, halves, on, height = cut(
            labels, int(sid), valid, classes, int(cls), depth_mm, bx0, by0, bx1, by1, t, coef, _WINDOW, _RING,
            float(m.sigma_0), float(m.sigma_2), float(m.step_0), float(m.step_2), float(k_sigma), min_samples,
            float(ring_share), float(rise_steps), float(outer_resolutions), float(ring_missing), float(ring_rise),
            bool(refuse_corners),
        )  # fmt: skip
        if not kept.size:
            continue
        if out is None:
            out = np.zeros((h, w), np.int32)
        n, placed = paint(
            out, labels, int(sid), valid, classes, int(cls), depth_mm, bx0, by0, bx1, by1, t, coef, comp, pieces,
            kept, halves, on, height, int(min_px), len(of_support) + 1, float(ring_trough), *_TROUGH_BAND,
        )  # fmt: skip
        if n and math.isfinite(ring_outline):
            n, placed = _drop_lacy(out, len(of_support) + 1, placed, ring_outline)
        of_support += [sid] * n
        if n:
            x_lo, y_lo = min(x_lo, int(placed[:, 0].min())), min(y_lo, int(placed[:, 1].min()))
            x_hi, y_hi = max(x_hi, int(placed[:, 2].max())), max(y_hi, int(placed[:, 3].max()))
    if out is None or not of_support:
        # read-only zeros without a frame's memory
        return np.broadcast_to(np.int32(0), (h, w)), of_support, (0, 0, 0, 0)
    return out, of_support, (x_lo, y_lo, x_hi, y_hi)


def _drop_lacy(
    out: NDArray[np.int32], first: int, placed: NDArray[np.int64], outline: float
) -> tuple[int, NDArray[np.int64]]:
    """Erase from ``out`` the pieces ``first``, ``first + 1``, ... whose outline is lacy; renumber the rest.

    ``placed``: each piece's box (x0, y0, x1, y1, exclusive). A piece's pixels are opened and
    closed by a 3 x 3 square (single readings' noise at its half-height edge), and it is erased
    when the outline of what remains exceeds ``outline`` times the root of its area. Returns
    the pieces kept and their boxes, numbered ``first``, ``first + 1``, ... in their order.
    """
    square = np.ones((3, 3), np.uint8)
    keep: list[int] = []
    for k, (x0, y0, x1, y1) in enumerate(placed.tolist()):
        here = out[y0:y1, x0:x1]
        mine = here == first + k
        smooth = cv2.morphologyEx(
            cv2.morphologyEx(mine.view(np.uint8), cv2.MORPH_OPEN, square), cv2.MORPH_CLOSE, square
        )
        edges, _ = cv2.findContours(smooth, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
        length = sum(cv2.arcLength(e, True) for e in edges)
        area = int(np.count_nonzero(smooth))
        if area == 0 or length > outline * math.sqrt(area):
            here[mine] = 0
        else:
            if len(keep) != k:
                here[mine] = first + len(keep)
            keep.append(k)
    return len(keep), placed[keep]


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
