"""Objects as depth-continuous surfaces bounded by depth jumps and concave creases.

The paper's global histogram groups pixels by depth band, which fails on real cameras in three
ways: an object spanning several bands is cut into slabs (a person walking toward a Kinect), a
small object without a histogram peak of its own is handed to the band of the wall behind it,
and two objects touching at one depth become one. Grouping by the surface instead avoids all
three: two neighbouring pixels belong to one object when their depths differ by no more than
the sensor can resolve (:class:`~depthgram.segmentation.noise_model.SensorModel`) plus what a surface
sloping at up to ``max_slope_deg`` moves over the distance between them, and when no concave
crease (the inside corner where a mug stands against a box, or a box on a table) runs between
them. A convex edge (the corner of a box showing two faces, the rim of a cup) does not separate,
as in the convexity rule of LCCP (Stein et al., CVPR 2014): objects are convex where they bend.

The depth bands of the histogram still name each object's ``depth_label`` (the grammar's
``o_<label>``); they no longer decide which pixels belong together.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation._kernels import surfaces as kernels_surfaces
from depthgram.segmentation._kernels.surfaces import NO_BOXES, NO_SUMS, count_labels, keep_counted
from depthgram.segmentation.creases import concave_creases, crease_scale_px, crease_state, surface_state
from depthgram.segmentation.label.unionfind import resolve as _resolve
from depthgram.segmentation.openings import merge_openings
from depthgram.segmentation.order_stats import percentile32

#: ``loosen_grow``'s table of loosened surfaces and their pixels left when nothing is counted down
_NOT_COUNTED = np.zeros(1, np.int32)
_NOT_LEFT = np.zeros(1, np.int64)

__all__ = [
    "concave_creases",
    "crease_scale_px",
    "crease_state",
    "facing_halves",
    "keep_large",
    "label_surfaces",
    "loosen_small",
    "merge_openings",
    "reattach",
    "surface_state",
    "surfaces_kept",
]


@njit(cache=True, nogil=True)
def facing_halves(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], include: NDArray[np.bool_], none_mm: float
) -> tuple[NDArray[np.bool_], NDArray[np.float32], NDArray[np.bool_], float, tuple[float, float, int]]:
    """Return the facing readings and what the depth labels' histogram reads of them, in one call.

    ``valid & include``; its every 2nd row and column of depth and of the mask (as
    ``np.ascontiguousarray(depth[::2, ::2])``); the 95th percentile (``np.percentile``'s
    value) of the depths of every 4th row and column of the facing readings, or ``none_mm``
    when there are none; and the smallest and largest depth and the count of the halves' facing
    readings (``histogram.log_bin_counts``' ``span``). One compiled call for eight numpy and
    OpenCV calls on small frames. ``depth`` is C-contiguous and positive at every valid pixel
    (:func:`~depthgram.segmentation.validate.check_depth`'s).
    """
    h, w = depth.shape
    facing = np.empty((h, w), np.bool_)
    for y in range(h):
        f, v, inc = facing[y], valid[y], include[y]
        for x in range(w):
            f[x] = v[x] & inc[x]
    h2 = (h + 1) // 2
    w2 = (w + 1) // 2
    d2 = np.empty((h2, w2), np.float32)
    m2 = np.empty((h2, w2), np.bool_)
    # the range from the readings' bit patterns, which positive floats order as integers do
    # (integer minima vectorise, float ones do not)
    bits = depth.view(np.uint32)
    lo_bits = np.uint32(0xFFFFFFFF)
    hi_bits = np.uint32(0)
    n = 0
    for i in range(h2):
        drow, brow, frow, d2r, m2r = depth[2 * i], bits[2 * i], facing[2 * i], d2[i], m2[i]
        for j in range(w2):
            f = frow[2 * j]
            u = brow[2 * j]
            d2r[j] = drow[2 * j]
            m2r[j] = f
            lo_bits = min(lo_bits, u if f else np.uint32(0xFFFFFFFF))
            hi_bits = max(hi_bits, u if f else np.uint32(0))
            n += f
    pair = np.empty(2, np.uint32)
    pair[0], pair[1] = lo_bits, hi_bits
    lo_hi = pair.view(np.float32)
    lo = lo_hi[0] if n else np.float32(np.inf)
    hi = lo_hi[1] if n else np.float32(-np.inf)
    sample = np.empty(((h2 + 1) // 2) * ((w2 + 1) // 2), np.float32)
    k = 0
    for i in range(0, h2, 2):
        for j in range(0, w2, 2):
            if m2[i, j]:
                sample[k] = d2[i, j]
                k += 1
    far = percentile32(sample[:k], 95.0, True) if k else none_mm
    return facing, d2, m2, far, (float(lo), float(hi), n)


def label_surfaces(
    depth_mm: NDArray[np.float32],
    state: NDArray[np.int8],
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
    bridge_px: int,
) -> tuple[NDArray[np.int32], int]:
    """4-connected components of active pixels whose depths are continuous.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm).
    state : ndarray of int8, shape (H, W)
        :data:`~depthgram.segmentation.label.HOLE` (no reading: bridged),
        :data:`~depthgram.segmentation.label.ACTIVE` (to label) or
        :data:`~depthgram.segmentation.label.BLOCK` (never crossed).
    tol_0, tol_2 : float
        Depth tolerance ``tol_0 + tol_2 z**2`` (mm) between two readings of one surface.
    slope_per_px : float
        Depth a surface may move per pixel of distance, per mm of depth (``tan(max_slope) / f``).
    bridge_px : int
        Longest run of holes crossed along a row or column.

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
        1..n in raster order of each component's first pixel; 0 elsewhere.
    n : int
    """
    lab, parent, nxt, _ = kernels_surfaces.label_surfaces(
        np.ascontiguousarray(depth_mm, np.float32),
        np.ascontiguousarray(state, np.int8),
        float(tol_0),
        float(tol_2),
        float(slope_per_px),
        int(bridge_px),
    )
    labels, n, _, _ = _resolve(lab, parent, nxt, NO_SUMS, NO_BOXES, 0, False)
    return labels, int(n)


def surfaces_kept(
    depth_mm: NDArray[np.float32],
    state: NDArray[np.int8],
    facing: NDArray[np.bool_],
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
    bridge_px: int,
    min_px: int,
    max_px: int,
    seed_px: int | None = None,
    band_px: int = 0,
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    """Return the surfaces of ``min_px`` pixels or more once loose pixels are reattached, with statistics.

    :func:`label_surfaces`, :func:`loosen_small`, :func:`reattach` (up to ``max_px`` steps) and
    :func:`keep_large` in a row, with the same labels and statistics, in fewer passes over
    the frame: the labeller counts its pixels; one pass marks the loose pixels and the seeds
    of the growth, which works in place on the provisional labels read through their final
    ids; one pass relabels with the statistics. No pass counts labels again: the surfaces
    left after loosening all have ``min_px`` pixels or more and growth only adds to them, so
    ``keep_large`` keeps exactly those.

    With ``seed_px`` below ``min_px``, a loosened surface of ``seed_px`` pixels or more that
    no surface grew back into (a thing lying on a support, whose readings around it the
    orientation field gave to the support) is kept too, with the pixels left to it, for the
    caller to judge once it has its foot (:func:`depthgram.segmentation.core._give_feet`).
    Such a piece then takes back up to ``band_px`` steps of the loose pixels around it: the
    part of its crease band that a wider crease span than the one ``min_px`` was set with
    (a structured-light camera's, :func:`depthgram.segmentation.creases.crease_span_px`) took
    from it, so that it is judged at the size it would have had.

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
        1..n as :func:`keep_large` numbers them; 0 elsewhere.
    n : int
    sums : ndarray of float64, shape (n + 1, N_COLUMNS)
    boxes : ndarray of int64, shape (n + 1, 4)
        The statistics table and inclusive boxes of :func:`keep_large`.
    """
    z = np.ascontiguousarray(depth_mm, np.float32)
    lab, parent, nxt, pcount = kernels_surfaces.label_surfaces(
        z, np.ascontiguousarray(state, np.int8), float(tol_0), float(tol_2), float(slope_per_px), int(bridge_px)
    )
    seed = min_px if seed_px is None else min(seed_px, min_px)
    table, count, loosened, left = kernels_surfaces.kept_table(lab, parent, nxt, pcount, int(min_px), int(seed))
    facing = np.ascontiguousarray(facing, np.bool_)
    grow = (float(tol_0), float(tol_2), float(slope_per_px), int(max_px))
    kernels_surfaces.loosen_grow(lab, table, facing, z, *grow, loosened, left, table)
    keep_px = min_px
    if loosened.size > 1:
        # a piece under min_px that no surface took back (a thing lying on a support, cut from
        # it by the orientation field) is kept for the caller to judge with its foot
        kernels_surfaces.restore_unclaimed(table, loosened, count, left, int(seed))
        if band_px > 0:
            # the restored pieces alone: loosened labels (same size as table here) now kept
            restored = np.where(loosened > 0, table, 0).astype(np.int32)
            band = (*grow[:3], int(band_px))
            kernels_surfaces.loosen_grow(lab, table, facing, z, *band, _NOT_COUNTED, _NOT_LEFT, restored)
        keep_px = 1
    labels, n, sums, boxes = kernels_surfaces.keep_through(lab, table, count, int(keep_px), z)
    return labels, int(n), sums, boxes


def reattach(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    loose: NDArray[np.bool_],
    *,
    tol_0: float,
    tol_2: float,
    slope_per_px: float,
    max_px: int,
) -> NDArray[np.int32]:
    """Grow labels into loose pixels (a crease, a dropped speck) along depth-continuous paths.

    A loose pixel takes the label of a 4-neighbour that has one when their depths are
    continuous as :func:`label_surfaces` tests them, at most ``max_px`` steps from the labelled
    pixel it started from; the others stay 0. Breadth first, so each pixel goes to the nearest
    surface it continues. Returns a new array.
    """
    out = np.array(labels, dtype=np.int32, copy=True)
    if loose.any():
        # the default's growth on provisional labels, here through the identity table
        identity = np.arange(int(out.max(initial=0)) + 1, dtype=np.int32)
        kernels_surfaces.loosen_grow(
            out,
            identity,
            np.ascontiguousarray(loose, np.bool_),
            np.ascontiguousarray(depth_mm, np.float32),
            float(tol_0),
            float(tol_2),
            float(slope_per_px),
            int(max_px),
            _NOT_COUNTED,
            _NOT_LEFT,
            identity,
        )
    return out


@njit(cache=True, nogil=True)
def loosen_small(labels: NDArray[np.int32], n: int, facing: NDArray[np.bool_], min_px: int) -> NDArray[np.bool_]:
    """Facing pixels without a label or in a component under ``min_px`` pixels.

    Returned as a mask, their labels set to 0 (in place). One count and one pass for numpy's
    bincount, gather and two masked writes.
    """
    h, w = labels.shape
    count = count_labels(labels, n)
    small = count < min_px
    small[0] = True
    loose = np.zeros((h, w), np.bool_)
    for y in range(h):
        for x in range(w):
            if facing[y, x] and small[labels[y, x]]:
                loose[y, x] = True
                labels[y, x] = 0
    return loose


def keep_large(
    labels: NDArray[np.int32], n: int, min_px: int, depth: NDArray[np.float32]
) -> tuple[NDArray[np.int32], int, NDArray[np.float64], NDArray[np.int64]]:
    """Renumber the components of at least ``min_px`` pixels 1..m in order, with their statistics.

    The sums and inclusive boxes are those of
    :func:`depthgram.segmentation.label.label_stats_fused` (key 0).

    One count, then one pass that relabels and sums
    (:func:`depthgram.segmentation.label.stats.relabel_stats`), for numpy's bincount, the
    relabelling pass and the statistics pass.
    """
    out, m, sums, box = keep_counted(labels, count_labels(labels, n), min_px, depth)
    return out, int(m), sums, box
