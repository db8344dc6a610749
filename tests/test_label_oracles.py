"""The labellers and the statistics table against independent libraries on random images.

The other kernel tests hold each compiled pass to the numpy route it replaced; these hold the
labellers to ``scipy.ndimage.label`` and ``scipy.sparse.csgraph`` (components of an explicit
neighbour graph) and the statistics to ``skimage.measure.regionprops``, which share no code
with the package.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from depthgram.segmentation.attributes import label_stats, make_objects
from depthgram.segmentation.label import (
    ACTIVE,
    BLOCK,
    HOLE,
    label_bands_stats,
    label_keyed,
    label_keyed_stats,
    label_stats_fused,
)
from depthgram.segmentation.label.stats import (
    COUNT,
    KEY,
    SUM_X,
    SUM_XZ,
    SUM_Y,
    SUM_YZ,
    SUM_Z,
    SUM_ZZ,
    relabel_stats,
)
from depthgram.segmentation.surfaces import keep_large

measure = pytest.importorskip("skimage.measure", reason="scikit-image (dev extra) is the statistics oracle")

#: 4-connectivity for scipy.ndimage.label.
FOUR = ndimage.generate_binary_structure(2, 1)


def _raster_order(labels: np.ndarray) -> np.ndarray:
    """``labels`` (0 = none) renumbered 1..n in raster order of each label's first pixel."""
    flat = labels.ravel()
    ids, first = np.unique(flat, return_index=True)
    keep = ids > 0
    ids, first = ids[keep], first[keep]
    lut = np.zeros(int(flat.max(initial=0)) + 1, np.int64)
    lut[ids[np.argsort(first)]] = np.arange(1, ids.size + 1)
    return lut[labels]


def _per_key_components(key: np.ndarray, active: np.ndarray) -> np.ndarray:
    """4-connected components of the active pixels of each key, by scipy.ndimage.label."""
    out = np.zeros(key.shape, np.int64)
    offset = 0
    for k in np.unique(key[active]):
        lab, n = ndimage.label(active & (key == k), structure=FOUR)
        out[lab > 0] = lab[lab > 0] + offset
        offset += n
    return _raster_order(out)


def _drop_small(labels: np.ndarray, min_px: int) -> np.ndarray:
    count = np.bincount(labels.ravel())
    small = count < min_px
    small[0] = True
    return _raster_order(np.where(small[labels], 0, labels))


def _random_image(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integer keys (a few values, so that components are large), states and depth (mm)."""
    h, w = (int(v) for v in rng.integers(1, 40, 2))
    # blocks of a few pixels of one key, so that components span rows and columns
    cell = int(rng.integers(1, 5))
    key = rng.integers(0, 3, (h // cell + 1, w // cell + 1)).repeat(cell, 0).repeat(cell, 1)[:h, :w]
    state = rng.choice(np.array([HOLE, ACTIVE, BLOCK], np.int8), (h, w), p=[0.2, 0.7, 0.1])
    depth = np.where(state != HOLE, rng.random((h, w)) * 3000 + 300, 0).astype(np.float32)
    return key.astype(np.float32), state, depth


def _bridged_graph_components(key: np.ndarray, state: np.ndarray, bridge: int) -> np.ndarray:
    """Components of the labeller's neighbour graph, by scipy.sparse.csgraph.

    An active pixel is joined to the nearest pixel with a reading (active or blocking) to its
    left in its row and above it in its column, when that pixel is active, has the same key
    and lies at most ``bridge + 1`` px away (only holes between them).
    """
    h, w = key.shape
    idx = np.arange(h * w).reshape(h, w)
    rows: list[int] = []
    cols: list[int] = []
    for img_key, img_state, img_idx in ((key, state, idx), (key.T, state.T, idx.T)):
        for r in range(img_state.shape[0]):
            last = -1
            for c in range(img_state.shape[1]):
                s = img_state[r, c]
                if s == HOLE:
                    continue
                if (
                    s == ACTIVE
                    and last >= 0
                    and img_state[r, last] == ACTIVE
                    and c - last <= bridge + 1
                    and img_key[r, last] == img_key[r, c]
                ):
                    rows.append(int(img_idx[r, last]))
                    cols.append(int(img_idx[r, c]))
                last = c
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(h * w, h * w))
    _, comp = connected_components(graph, directed=False)
    active = state == ACTIVE
    # csgraph numbers every pixel; keep the active ones, 1-based
    return _raster_order(np.where(active, comp.reshape(h, w) + 1, 0))


def test_keyed_labeller_without_bridges_equals_scipy_label_per_key() -> None:
    rng = np.random.default_rng(2026)
    for _ in range(150):
        key, state, _ = _random_image(rng)
        labels, n = label_keyed(key, state)
        want = _per_key_components(key, state == ACTIVE)
        np.testing.assert_array_equal(labels, want)
        assert n == int(want.max(initial=0))


def test_keyed_labeller_with_bridges_equals_the_graph_components() -> None:
    rng = np.random.default_rng(17)
    for _ in range(100):
        key, state, _ = _random_image(rng)
        bridge = int(rng.integers(0, 4))
        labels, n = label_keyed(key, state, bridge=bridge)
        want = _bridged_graph_components(key, state, bridge)
        np.testing.assert_array_equal(labels, want)
        assert n == int(want.max(initial=0))


def test_graph_oracle_bridges_holes_and_not_blocking_pixels() -> None:
    # the oracle itself on a case worked out by hand: one hole is bridged, a blocking pixel is not
    key = np.zeros((1, 5), np.float32)
    state = np.array([[ACTIVE, HOLE, ACTIVE, BLOCK, ACTIVE]], np.int8)
    np.testing.assert_array_equal(_bridged_graph_components(key, state, 1), [[1, 0, 1, 0, 2]])
    np.testing.assert_array_equal(_bridged_graph_components(key, state, 0), [[1, 0, 2, 0, 3]])


def _assert_stats_match_regionprops(
    labels: np.ndarray, n: int, depth: np.ndarray, sums: np.ndarray, boxes: np.ndarray
) -> None:
    props = measure.regionprops(labels.astype(np.int64), intensity_image=depth.astype(np.float64))
    assert [p.label for p in props] == list(range(1, n + 1))
    for p in props:
        i = p.label
        row = sums[i]
        assert row[COUNT] == p.area
        # bbox: (min_row, min_col, max_row + 1, max_col + 1); the table's boxes are inclusive
        r0, c0, r1, c1 = p.bbox
        assert tuple(boxes[i]) == (c0, r0, c1 - 1, r1 - 1)
        cy, cx = p.centroid
        assert row[SUM_X] / row[COUNT] == pytest.approx(cx, rel=1e-12)
        assert row[SUM_Y] / row[COUNT] == pytest.approx(cy, rel=1e-12)
        mean = row[SUM_Z] / row[COUNT]
        assert mean == pytest.approx(p.intensity_mean, rel=1e-9)
        var = row[SUM_ZZ] / row[COUNT] - mean * mean
        assert np.sqrt(max(var, 0.0)) == pytest.approx(p.intensity_std, rel=1e-6, abs=1e-6 * mean)
        wy, wx = p.centroid_weighted  # sum(x Z) / sum(Z), sum(y Z) / sum(Z)
        assert row[SUM_XZ] / row[SUM_Z] == pytest.approx(wx, rel=1e-9)
        assert row[SUM_YZ] / row[SUM_Z] == pytest.approx(wy, rel=1e-9)


def test_statistics_pass_equals_regionprops() -> None:
    rng = np.random.default_rng(5)
    for _ in range(60):
        key, state, depth = _random_image(rng)
        labels = _per_key_components(key, state == ACTIVE).astype(np.int32)
        n = int(labels.max(initial=0))
        band = rng.integers(0, 9, labels.shape).astype(np.float32)
        sums, boxes = label_stats_fused(labels, n, depth, band)
        _assert_stats_match_regionprops(labels, n, depth, sums, boxes)
        for i in range(1, n + 1):  # the key column holds the last pixel's key in raster order
            assert sums[i, KEY] == band[labels == i][-1]


def test_labellers_with_statistics_equal_scipy_and_regionprops() -> None:
    rng = np.random.default_rng(9)
    for _ in range(60):
        key, state, depth = _random_image(rng)
        min_px = int(rng.integers(1, 6))
        labels, n, sums, boxes = label_keyed_stats(key, state, depth, min_px=min_px)
        want = _drop_small(_per_key_components(key, state == ACTIVE), min_px)
        np.testing.assert_array_equal(labels, want)
        _assert_stats_match_regionprops(labels, n, depth, sums, boxes)
        for i in range(1, n + 1):
            assert sums[i, KEY] == key[labels == i][0]


def test_band_labeller_equals_scipy_label_per_band_and_regionprops() -> None:
    rng = np.random.default_rng(23)
    for _ in range(60):
        h, w = (int(v) for v in rng.integers(1, 40, 2))
        nb = int(rng.integers(1, 8))
        valid = rng.random((h, w)) < 0.85
        bins = np.where(valid, rng.integers(0, nb, (h, w)), -1).astype(np.int32)
        lut = rng.integers(-1, 3, nb).astype(np.int32)  # bin -> band, -1 outside every band
        depth = np.where(valid, rng.random((h, w)) * 3000 + 300, 0).astype(np.float32)
        labels, n, sums, boxes = label_bands_stats(bins, lut, valid, None, depth, min_px=2)
        band = np.where(bins >= 0, lut[np.maximum(bins, 0)], -1)
        want = _drop_small(_per_key_components(band, valid & (band >= 0)), 2)
        np.testing.assert_array_equal(labels, want)
        _assert_stats_match_regionprops(labels, n, depth, sums, boxes)
        for i in range(1, n + 1):
            assert sums[i, KEY] == band[labels == i][0]


def test_objects_carry_regionprops_attributes() -> None:
    rng = np.random.default_rng(31)
    key, state, depth = _random_image(rng)
    while int(_per_key_components(key, state == ACTIVE).max(initial=0)) < 3:
        key, state, depth = _random_image(rng)
    labels = _per_key_components(key, state == ACTIVE).astype(np.int32)
    n = int(labels.max())
    objects = make_objects(labels, label_stats(labels, depth, n))
    props = measure.regionprops(labels, intensity_image=depth.astype(np.float64))
    assert [o.id for o in objects] == [p.label for p in props]
    for o, p in zip(objects, props, strict=True):
        r0, c0, r1, c1 = p.bbox
        assert o.bbox_xy == (c0, r0, c1, r1)  # both half-open
        assert o.slice == p.slice
        assert o.area == p.area
        assert o.center_xy == pytest.approx((p.centroid[1], p.centroid[0]), rel=1e-12)
        assert o.depth == pytest.approx(p.intensity_mean, rel=1e-9)
        assert o.depth_std == pytest.approx(p.intensity_std, rel=1e-6, abs=1e-6 * o.depth)


def test_relabel_with_statistics_equals_dropping_small_components_then_regionprops() -> None:
    rng = np.random.default_rng(41)
    for _ in range(60):
        key, state, depth = _random_image(rng)
        labels = _per_key_components(key, state == ACTIVE).astype(np.int32)
        n = int(labels.max(initial=0))
        min_px = int(rng.integers(1, 6))
        out, m, sums, boxes = keep_large(labels, n, min_px, depth)
        want = _drop_small(labels, min_px)
        np.testing.assert_array_equal(out, want)
        assert m == int(want.max(initial=0))
        _assert_stats_match_regionprops(out, m, depth, sums, boxes)
        assert not sums[:, KEY].any()  # keep_large leaves the key to its caller
        # the same pass through an explicit table: labels renumbered, sums of the result
        lut = np.zeros(n + 1, np.int32)
        lut[1:] = rng.integers(0, 4, n)
        got, gsums, gboxes = relabel_stats(labels, lut, 3, depth)
        np.testing.assert_array_equal(got, lut[labels])
        fsums, fboxes = label_stats_fused(got, 3, depth, np.zeros_like(depth))
        np.testing.assert_array_equal(gsums, fsums)
        np.testing.assert_array_equal(gboxes, fboxes)
