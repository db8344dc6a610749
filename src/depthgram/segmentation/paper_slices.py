"""The paper's slicing method, literally: per-slice histograms joined by successive depth labels.

Section 3 of the paper partitions the image into slices perpendicular to the view direction
(bands of rows, or bands of columns), thresholds each slice's own depth histogram by the same
peak and 10 % trailing-cut rule as the global histogram, and joins slice segments with equal or
successive depth labels into a "super-object". Inside a thin slice an oblique surface has a
narrow depth range, so it makes a peak; along the slicing direction its depth label changes
steadily. Runs with a constant depth label are objects facing the sensor, and those are left to
the global histogram, so that on fronto-parallel scenes both methods agree (the paper's
"compatible with bulk histogram segmentation").

Unlike :mod:`depthgram.segmentation.slices` (the default ``slices`` method), nothing here looks at
surface normals: an object standing on a support shares the support's depth where they touch,
so the literal method may join them (measured in ``benchmarks/table1.py``).

Choices where the paper is silent
---------------------------------
- Depth label of a slice segment: the label of its mean depth on the *global* histogram's scale
  (:meth:`Bands.depth_label`), not the slice's own band index. A slice's band index counts peaks
  inside that slice only, so "successive" would compare unrelated scales between slices; the
  global scale is the grammar's ``o_Depth_label``.
- Runs: a segment is followed, in the next slice, by the touching label-compatible segment it
  shares the longest border with, when that choice is mutual. Plain connected components of the
  touching graph join every surface meeting another at the same depth (floor, end wall, walls,
  everything standing on the floor) into one group whose per-slice depth means nothing; a chain
  of best partners follows one surface. A run is *steady* when its mean depth moves the same way
  by more than one histogram bin (``bin_mm``) at every step for at least ``paper_min_slices``
  slices; steady segments of one direction and sign that touch are then joined into one
  compound object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from depthgram.frame import Intrinsics
from depthgram.segmentation.attributes import fused_stats, label_stats, make_objects
from depthgram.segmentation.config import SegmentConfig
from depthgram.segmentation.histogram import Bands, bin_index, depth_bands
from depthgram.segmentation.label import ACTIVE, BLOCK, HOLE, label_keyed, relabel
from depthgram.segmentation.objects import SceneObject, Segmentation
from depthgram.segmentation.threshold import band_image, threshold_labels

__all__ = ["SliceRuns", "paper_slices", "slice_runs", "slice_segments"]


def slice_segments(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    config: SegmentConfig,
    *,
    horizontal: bool,
    aperture: int,
) -> tuple[NDArray[np.int32], int]:
    """Segments of every slice: each slice's own histogram bands, split into connected parts.

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid.
    valid : ndarray of bool, shape (H, W)
        Pixels with a reading.
    config : SegmentConfig
        Histogram parameters (``bin_mm``, ``fraction``, ``cut_from``, ``gap_pixels``,
        ``smooth_bins``, ``min_prominence``, ``fill_holes_px``), used as for the global histogram.
    horizontal : bool
        Horizontal slices (bands of ``aperture`` rows) or vertical ones (bands of columns).
    aperture : int
        Slice thickness (px).

    Returns
    -------
    labels : ndarray of int32, shape (H, W)
        Segment id per pixel (0: none); a segment never crosses a slice border.
    n : int
        Number of segments.
    """
    length = depth_mm.shape[0 if horizontal else 1]
    slice_config = replace(config, min_prominence=config.paper_prominence)
    key = np.full(depth_mm.shape, -1.0, np.float32)
    state = np.where(valid, np.int8(BLOCK), np.int8(HOLE))
    offset = 0
    for start in range(0, length, aperture):
        band_of_slice = slice(start, start + aperture)
        sl = (band_of_slice, slice(None)) if horizontal else (slice(None), band_of_slice)
        bins, edges, counts = bin_index(depth_mm[sl], valid[sl], slice_config)
        bands = depth_bands(counts, edges, slice_config)
        if bands.n == 0:
            continue
        band = np.where(bins >= 0, bands.lut[np.maximum(bins, 0)], -1)
        on = band >= 0
        # a key per (slice, band): one labelling pass for all slices, and no join across a border
        key[sl] = np.where(on, band + offset, -1)
        state[sl][on] = ACTIVE
        offset += bands.n
    return label_keyed(key, state, tol=0.0, bridge=config.fill_holes_px)


@dataclass(frozen=True, eq=False)
class SliceRuns:
    """Slice segments of one direction with their runs.

    Attributes
    ----------
    labels : ndarray of int32, shape (H, W)
        Segment id per pixel, from :func:`slice_segments`.
    depth : ndarray of float64, shape (n + 1,)
        Mean depth (mm) per segment (index 0 unused).
    depth_label : ndarray of int64, shape (n + 1,)
        Global depth label per segment.
    slice_index : ndarray of int64, shape (n + 1,)
        Slice of each segment, 0 at the top (left) of the image.
    sign : ndarray of int8, shape (n + 1,)
        +1 when the segment is in a steady run whose depth grows with the slice index, -1 when
        it shrinks, 0 for segments facing the sensor.
    group : ndarray of int32, shape (n + 1,)
        Compound object (1..k) of each steady segment, 0 otherwise.
    """

    labels: NDArray[np.int32]
    depth: NDArray[np.float64]
    depth_label: NDArray[np.int64]
    slice_index: NDArray[np.int64]
    sign: NDArray[np.int8]
    group: NDArray[np.int32]

    @property
    def n_groups(self) -> int:
        """Number of compound objects."""
        return int(self.group.max(initial=0))


def _touching_pairs(
    labels: NDArray[np.int32], aperture: int, horizontal: bool, n: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Pairs (a in slice s, b in slice s + 1) touching across a slice border, with border length (px)."""
    lab = labels if horizontal else labels.T
    starts = np.arange(aperture, lab.shape[0], aperture)
    if starts.size == 0:
        empty = np.zeros(0, np.int64)
        return empty, empty, empty
    a = lab[starts - 1].ravel().astype(np.int64)
    b = lab[starts].ravel().astype(np.int64)
    both = (a > 0) & (b > 0)
    code, count = np.unique(a[both] * (n + 1) + b[both], return_counts=True)
    return code // (n + 1), code % (n + 1), count.astype(np.int64)


def _first_by(key: NDArray[np.int64], count: NDArray[np.int64], size: int) -> NDArray[np.int64]:
    """For each key value, the index of its pair with the largest count (-1 when none)."""
    order = np.lexsort((-count, key))
    keys, first = np.unique(key[order], return_index=True)
    out = np.full(size, -1, np.int64)
    out[keys] = order[first]
    return out


def _steady_signs(
    chain: list[int], depth: NDArray[np.float64], spread: NDArray[np.float64], step_mm: float, min_slices: int
) -> list[int]:
    """Sign of the steady run each chain member belongs to (0: none).

    Hand-written because the rule is the paper's own idea: at each of at least
    ``min_slices - 1`` successive steps the depth moves the same way by more than one histogram
    bin and by more than half the two segments' depth ranges, so that successive segments sit in
    successive depth bands. A piece of a plateau (a wall cut across its running direction) has a
    wide range and moves less than that from slice to slice.
    """
    d = depth[chain]
    steps = np.diff(d)
    # sqrt(3) * std is half the width of a uniform spread: the ranges overlap by under half
    limit = np.maximum(step_mm, math.sqrt(3) / 2 * (spread[chain][:-1] + spread[chain][1:]))
    signs = np.where(steps > limit, 1, np.where(steps < -limit, -1, 0))
    out = [0] * len(chain)
    i = 0
    while i < signs.size:
        s = int(signs[i])
        j = i
        while j < signs.size and signs[j] == s:
            j += 1
        if s != 0 and j - i >= min_slices - 1:
            for k in range(i, j + 1):
                if out[k] == 0:
                    out[k] = s
        i = j
    return out


def slice_runs(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    bands: Bands,
    config: SegmentConfig,
    *,
    horizontal: bool,
    aperture: int,
) -> SliceRuns:
    """Slice segments of one direction, their runs, and the compound objects they form.

    Parameters
    ----------
    depth_mm, valid : ndarray, shape (H, W)
        Depth (mm) and the pixels with a reading.
    bands : Bands
        The global histogram's bands: the scale of depth labels.
    config : SegmentConfig
        Histogram parameters, ``bin_mm`` (smallest steady depth step, mm) and
        ``paper_min_slices``.
    horizontal : bool
        Bands of rows (floor, ceiling, table tops) or of columns (walls).
    aperture : int
        Slice thickness (px).
    """
    labels, n = slice_segments(depth_mm, valid, config, horizontal=horizontal, aperture=aperture)
    st = label_stats(labels, depth_mm, n)
    count = np.maximum(st.count, 1)
    depth = st.sz / count
    depth[0] = 0.0
    spread = np.sqrt(np.maximum(st.szz / count - depth * depth, 0.0))
    dl = np.asarray(bands.depth_label(depth), np.int64)
    pos = (st.sy if horizontal else st.sx) / count
    slice_index = (pos // aperture).astype(np.int64)
    a, b, c = _touching_pairs(labels, aperture, horizontal, n)
    ok = np.abs(dl[a] - dl[b]) <= 1  # the paper's "equal or successive depth labels"
    a, b, c = a[ok], b[ok], c[ok]
    # runs: mutual longest-border partners between successive slices
    best_next = _first_by(a, c, n + 1)
    best_prev = _first_by(b, c, n + 1)
    nxt = np.zeros(n + 1, np.int64)
    has_prev = np.zeros(n + 1, bool)
    for i in range(a.size):
        if best_next[a[i]] == i and best_prev[b[i]] == i:
            nxt[a[i]] = b[i]
            has_prev[b[i]] = True
    sign = np.zeros(n + 1, np.int8)
    for head in np.flatnonzero(~has_prev[1:]) + 1:
        chain = [int(head)]
        while nxt[chain[-1]]:
            chain.append(int(nxt[chain[-1]]))
        if len(chain) >= config.paper_min_slices:
            sign[chain] = _steady_signs(chain, depth, spread, config.bin_mm, config.paper_min_slices)
    # steady segments of the same sign that touch with compatible labels form one super-object
    keep = (sign[a] != 0) & (sign[a] == sign[b])
    graph = coo_matrix((np.ones(int(keep.sum())), (a[keep], b[keep])), shape=(n + 1, n + 1))
    _, comp = connected_components(graph, directed=False)
    steady = np.flatnonzero(sign)
    group = np.zeros(n + 1, np.int32)
    if steady.size:
        _, dense = np.unique(comp[steady], return_inverse=True)
        group[steady] = dense.astype(np.int32) + 1
    return SliceRuns(labels, depth, dl, slice_index, sign, group)


def _kind(
    horizontal: bool, sign: int, bbox_xy: tuple[int, int, int, int], shape: tuple[int, ...], aperture: int
) -> str:
    """Floor: depth grows upward from the bottom slice; ceiling: downward from the top slice."""
    if not horizontal:
        return "wall"
    h = shape[0]
    if sign < 0 and bbox_xy[3] > h - aperture:  # its last row within the bottom slice
        return "floor"
    if sign > 0 and bbox_xy[1] < aperture:
        return "ceiling"
    return "compound"


def paper_slices(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    intrinsics: Intrinsics | None,
    config: SegmentConfig,
) -> Segmentation:
    """Segment with the paper's slicing method (``method="paper"``).

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid (as from :func:`depthgram.segmentation.validate.check_depth`).
    valid : ndarray of bool, shape (H, W)
        Pixels with a reading.
    intrinsics : Intrinsics, optional
        When given, ``centroid_mm`` and ``area_mm2`` are filled.
    config : SegmentConfig
        ``paper_aperture`` (px when >= 1, else fraction of the image height for horizontal
        slices and of its width for vertical ones), ``slice_directions``, ``paper_min_slices``,
        ``paper_prominence`` and the histogram parameters.

    Returns
    -------
    Segmentation
        Facing objects first (kind ``object``, from the global histogram), then compound
        objects (``floor``, ``ceiling``, ``wall``, ``compound``) whose ``parts`` are their slice
        segments (kind ``part``, successive depth labels). ``bands_mm`` and
        ``aperture_px`` (rows, columns) are set.
    """
    h, w = depth_mm.shape
    band, state, bands = band_image(depth_mm, valid, config)
    min_px = config.min_pixels(depth_mm.size)
    directions = [d for d in (True, False) if config.slice_directions in ("both", "horizontal" if d else "vertical")]
    claimed = np.zeros(depth_mm.shape, bool)
    found: list[tuple[bool, int, SliceRuns, NDArray[np.int32]]] = []
    apertures: dict[str, int] = {}
    for horizontal in directions:
        ap = config.paper_step(h if horizontal else w)
        apertures["rows" if horizontal else "columns"] = ap
        runs = slice_runs(depth_mm, valid, bands, config, horizontal=horizontal, aperture=ap)
        if runs.n_groups == 0:
            continue
        gmap = runs.group[runs.labels]
        # horizontal slicing goes first: a pixel already in a floor or ceiling stays there
        gmap[claimed] = 0
        sizes = np.bincount(gmap.ravel(), minlength=runs.n_groups + 1)
        big = sizes >= min_px
        big[0] = False
        gmap[~big[gmap]] = 0
        claimed |= gmap > 0
        found.append((horizontal, ap, runs, gmap))
    # facing pixels: exactly the global histogram's bands and components
    facing_state = state.copy()
    facing_state[claimed & (state == ACTIVE)] = BLOCK
    labels, n = threshold_labels(band, facing_state, config)
    labels, stats, band_of = fused_stats(labels, n, depth_mm, band, min_px)
    if intrinsics is None:
        stats = replace(stats, sxz=None, syz=None)
    objects = make_objects(labels, stats, depth_labels=band_of.astype(np.int64), intrinsics=intrinsics)
    next_id = len(objects) + 1
    compounds: list[SceneObject] = []
    for horizontal, ap, runs, gmap in found:
        ng = runs.n_groups
        cst = label_stats(gmap, depth_mm, ng, metric=intrinsics is not None)
        # provisional ids: the group's value in the label map (groups emptied by the claim skip)
        whole = make_objects(gmap, cst, intrinsics=intrinsics, first_id=next_id)
        seg = np.where(gmap > 0, runs.labels, 0).astype(np.int32)
        nseg = runs.depth.size - 1
        pst = label_stats(seg, depth_mm, nseg, metric=intrinsics is not None)
        parts = make_objects(
            seg, pst, kinds=["part"] * (nseg + 1), depth_labels=runs.depth_label, intrinsics=intrinsics
        )
        by_group: dict[int, list[SceneObject]] = {}
        for p in parts:
            by_group.setdefault(int(runs.group[p.id]), []).append(p)
        for o in whole:
            g = o.id - next_id + 1
            ps = sorted(by_group[g], key=lambda p: p.depth)
            sign = int(runs.sign[np.flatnonzero(runs.group == g)[0]])
            kind = _kind(horizontal, sign, o.bbox_xy, depth_mm.shape, ap)
            compounds.append(replace(o, kind=kind, depth_label=min(p.depth_label for p in ps), parts=tuple(ps)))
        on = gmap > 0
        labels[on] = gmap[on] + (next_id - 1)
        next_id += ng
    # ids 1..n again: facing objects first, then compounds; parts are numbered after them all
    lut = np.zeros(next_id, np.int32)
    lut[: len(objects) + 1] = np.arange(len(objects) + 1)
    out = list(objects)
    part_id = len(objects) + len(compounds) + 1
    for new, c in enumerate(compounds, start=len(objects) + 1):
        lut[c.id] = new
        renamed = tuple(replace(p, id=part_id + i) for i, p in enumerate(c.parts))
        part_id += len(renamed)
        out.append(replace(c, id=new, parts=renamed))
    labels = relabel(labels, lut)
    return Segmentation(labels, tuple(out), bands.histogram, "paper", bands_mm=bands.limits_mm(), aperture_px=apertures)
