"""The compiled kernels of segmentation against plain-numpy references and hand-made scenes.

Each fused or compiled pass replaced a chain of numpy operations; these tests hold it to the
numpy route (kept here or in the package as the reference) on random images with holes,
blocking pixels and bridges, and to values worked out by hand on tiny images.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from depthgram.frame import Intrinsics
from depthgram.segmentation.attributes import label_stats
from depthgram.segmentation.binning import band_state, bin_pixels, depth_range
from depthgram.segmentation.contacts import front_faces
from depthgram.segmentation.coplanar import near_planes
from depthgram.segmentation.label import (
    ACTIVE,
    BLOCK,
    HOLE,
    label_bands_stats,
    label_keyed,
    label_keyed_planes,
    label_keyed_stats,
)
from depthgram.segmentation.label.keyed import label_two_classes
from depthgram.segmentation.objects import SceneObject
from depthgram.segmentation.orientation import upsample_classes
from depthgram.segmentation.plane_sums import plane_sums, planes_from_sums
from depthgram.segmentation.slices import slice_parts, support_pieces
from depthgram.segmentation.validate import check_depth
from reference import (
    _jumps,
    _jumps_cols,
    _one_sided,
    _one_sided_cols,
    label_stats_bincount,
    merge_coplanar,
    on_support_planes,
    plane_fits,
    relabel_small,
    sensor_samples,
    support_components,
)


def _random_keyed(rng: np.random.Generator, smooth: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    h, w = (int(v) for v in rng.integers(1, 24, 2))
    if smooth:  # bands of a few columns, like a depth ramp
        key = (np.arange(w)[None, :] * 3 // max(w, 1) + 0 * np.arange(h)[:, None]).astype(np.float32)
    else:
        key = rng.integers(0, 3, (h, w)).astype(np.float32)
    state = rng.choice(np.array([HOLE, ACTIVE, BLOCK], np.int8), (h, w), p=[0.25, 0.65, 0.10])
    depth = (rng.random((h, w)) * 1000 + 500).astype(np.float32)
    return key, state, depth


def test_keyed_stats_equal_label_then_bincount_reference() -> None:
    rng = np.random.default_rng(7)
    for t in range(200):
        key, state, depth = _random_keyed(rng, smooth=t % 2 == 0)
        bridge = int(rng.integers(0, 4))
        min_px = int(rng.integers(1, 5))
        ref, n_ref = label_keyed(key, state, bridge=bridge)
        ref = relabel_small(ref, np.bincount(ref.ravel(), minlength=n_ref + 1).astype(float), min_px)
        want = label_stats_bincount(ref, depth, int(ref.max(initial=0)), metric=True)
        labels, n, sums, boxes = label_keyed_stats(key, state, depth, bridge=bridge, min_px=min_px)
        np.testing.assert_array_equal(labels, ref)
        assert n == int(ref.max(initial=0))
        for col, arr in enumerate((want.count, want.sz, want.szz, want.sx, want.sy, want.sxz, want.syz)):
            assert arr is not None
            np.testing.assert_allclose(sums[:, col], arr, rtol=1e-12)
        for i in range(1, n + 1):
            ys, xs = np.nonzero(labels == i)
            assert tuple(boxes[i]) == (xs.min(), ys.min(), xs.max(), ys.max())
            assert sums[i, 7] == key[ys[0], xs[0]]  # the key of the component


def test_keyed_planes_equal_keyed_stats_then_plane_sums() -> None:
    # the fused route gives the labels and statistics of the two passes it replaces to the
    # last bit, and the plane sums of the readable route (bincounts) within rounding
    rng = np.random.default_rng(11)
    for t in range(200):
        key, state, depth = _random_keyed(rng, smooth=t % 2 == 0)
        if t % 3 == 0:  # depth as its own key with a relative tolerance, as the supports use it
            key = depth.copy()
        bridge = int(rng.integers(0, 4))
        min_px = int(rng.integers(1, 5))
        fx, fy = (float(v) for v in rng.random(2) * 500 + 100)
        cx, cy = float(rng.random() * key.shape[1]), float(rng.random() * key.shape[0])
        want = label_keyed_stats(key, state, depth, rel=0.05, bridge=bridge, min_px=min_px)
        planes_want = plane_sums(want[0], want[1], depth, fx, fy, cx, cy)
        labels, n, sums, boxes, planes = label_keyed_planes(
            key, state, depth, fx, fy, cx, cy, rel=0.05, bridge=bridge, min_px=min_px
        )
        np.testing.assert_array_equal(labels, want[0])
        assert n == want[1]
        np.testing.assert_array_equal(sums, want[2])
        np.testing.assert_array_equal(boxes, want[3])
        np.testing.assert_allclose(planes, planes_want, rtol=1e-11, atol=1e-12)
        assert planes.shape == (n + 1, 9)


def test_keyed_planes_in_a_window_holding_every_active_pixel_equal_the_whole_frame() -> None:
    # a support labelled again reads only a window around its pixels: the same labels, numbers,
    # sums, boxes and plane sums to the last bit, whatever the state outside the window
    rng = np.random.default_rng(12)
    for t in range(200):
        key, state, depth = _random_keyed(rng, smooth=t % 2 == 0)
        h, w = key.shape
        # the active pixels inside a random window, random other states around them
        y0, y1 = sorted(int(v) for v in rng.integers(0, h + 1, 2))
        x0, x1 = sorted(int(v) for v in rng.integers(0, w + 1, 2))
        inside = np.zeros((h, w), bool)
        inside[y0:y1, x0:x1] = True
        state = np.where(inside | (state != ACTIVE), state, np.int8(BLOCK)).astype(np.int8)
        if t % 3 == 0:
            key = depth.copy()
        bridge = int(rng.integers(0, 4))
        fx, fy = (float(v) for v in rng.random(2) * 500 + 100)
        cx, cy = float(rng.random() * w), float(rng.random() * h)
        want = label_keyed_planes(key, state, depth, fx, fy, cx, cy, rel=0.05, bridge=bridge)
        garbage = np.where(inside, state, rng.integers(0, 3, (h, w))).astype(np.int8)
        got = label_keyed_planes(key, garbage, depth, fx, fy, cx, cy, rel=0.05, bridge=bridge, window=(y0, y1, x0, x1))
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)


def test_two_classes_in_one_pass_equal_one_labelling_per_class_exactly() -> None:
    # the supports' first labelling takes horizontal and vertical pixels in one pass: each
    # class's labels, sums, boxes and plane sums must be those of its own pass to the last bit
    rng = np.random.default_rng(13)
    for t in range(300):
        h, w = (int(v) for v in rng.integers(1, 30, 2))
        valid = rng.random((h, w)) > (0.1 if t % 2 else 0.35)
        if t % 3 == 0:  # smooth depth: long runs and components crossing bridges
            depth = (1000 + 20 * np.arange(w)[None, :] + 5 * np.arange(h)[:, None]).astype(np.float32)
            depth += rng.random((h, w)).astype(np.float32) * 30
        else:
            depth = (rng.random((h, w)) * 1000 + 500).astype(np.float32)
        depth[~valid] = 0
        # blocks of one class with specks of the others, so runs of one class cross the other
        classes = np.repeat(np.repeat(rng.integers(0, 3, (h // 3 + 1, w // 4 + 1)), 3, 0), 4, 1)[:h, :w]
        specks = rng.random((h, w)) < 0.15
        classes = np.where(specks, rng.integers(0, 3, (h, w)), classes).astype(np.int8)
        bridge = int(rng.integers(0, 4))
        rel = float(rng.choice([0.02, 0.05, 0.3]))
        fx, fy = (float(v) for v in rng.random(2) * 500 + 100)
        cx, cy = float(rng.random() * w), float(rng.random() * h)
        lab, na, nb, sums, boxes, planes = label_two_classes(
            depth, valid, classes, 1, 2, fx, fy, cx, cy, rel=rel, bridge=bridge
        )
        for cls, base, n in ((1, 0, na), (2, na, nb)):
            state = np.where(valid, np.where(classes == cls, ACTIVE, BLOCK), HOLE).astype(np.int8)
            want = label_keyed_planes(depth, state, depth, fx, fy, cx, cy, rel=rel, bridge=bridge)
            rows = np.r_[0, base + 1 : base + n + 1]
            mine = (lab > base) & (lab <= base + n)
            np.testing.assert_array_equal(np.where(mine, lab - base, 0), want[0])
            assert n == want[1]
            np.testing.assert_array_equal(sums[rows], want[2])
            np.testing.assert_array_equal(boxes[rows], want[3])
            np.testing.assert_array_equal(planes[rows], want[4])
        assert not lab[~valid].any() and not lab[(classes != 1) & (classes != 2)].any()


def test_plane_sums_in_boxes_equal_plane_sums_of_the_wanted_labels() -> None:
    # reading each wanted label's box alone gives the rows of the readable route (bincounts)
    from depthgram.segmentation.plane_sums import plane_sums_in_boxes

    rng = np.random.default_rng(12)
    for t in range(60):
        key, state, depth = _random_keyed(rng, smooth=t % 2 == 0)
        labels, n, _, boxes = label_keyed_stats(key, state, depth, bridge=1)
        if n == 0:
            continue
        ids = np.flatnonzero(rng.random(n + 1) < 0.4)
        ids = ids[ids > 0]
        want = np.zeros(n + 1, np.bool_)
        want[ids] = True
        fx, fy = (float(v) for v in rng.random(2) * 500 + 100)
        cx, cy = float(rng.random() * key.shape[1]), float(rng.random() * key.shape[0])
        ref = plane_sums(labels, n, depth, fx, fy, cx, cy, only=want)
        got = plane_sums_in_boxes(labels, n, ids, boxes[ids], depth, fx, fy, cx, cy)
        np.testing.assert_allclose(got, ref, rtol=1e-11, atol=1e-12)
        assert got[ids, 5].sum() == np.isin(labels, ids).sum()


def test_shares_beneath_equal_numpy() -> None:
    # the table of camera coordinates and one product per plane it replaced, as numpy gives them
    from depthgram.segmentation.plane_sums import shares_beneath

    rng = np.random.default_rng(13)
    depth = (rng.random((37, 53)) * 3000 + 400).astype(np.float32)
    depth[rng.random(depth.shape) < 0.2] = 0.0
    cam = Intrinsics(61.5, 59.0, 26.3, 17.9)
    normal = rng.normal(size=(5, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    off = rng.random(5) * 2000.0
    for step in (1, 3, 4):
        z = depth[::step, ::step]
        v, u = np.nonzero(z > 0)
        zz = z[v, u].astype(np.float64)
        pts = np.stack(((u * step - cam.cx) / cam.fx * zz, (v * step - cam.cy) / cam.fy * zz, zz))
        ref = [np.count_nonzero(normal[j] @ pts + off[j] < -150.0) / pts.shape[1] for j in range(5)]
        got = shares_beneath(depth, step, cam, normal, off, 150.0)
        np.testing.assert_array_equal(got, ref)
        assert 0.0 < got.max() < 1.0  # the planes cut through the readings
    assert shares_beneath(np.zeros((4, 4), np.float32), 1, cam, normal, off, 150.0).tolist() == [0.0] * 5


def test_shares_beneath_by_hand() -> None:
    # a wall 1 m away seen by a camera whose rows v lie at y = 10 v mm; the floor 500 mm below
    # the camera (n = (0, -1, 0), d = 500): the rows with y > 650 mm lie more than 150 mm beneath it
    from depthgram.segmentation.plane_sums import shares_beneath

    depth = np.full((100, 7), 1000.0, np.float32)
    cam = Intrinsics(100.0, 100.0, 3.0, 0.0)
    got = shares_beneath(depth, 1, cam, np.array([[0.0, -1.0, 0.0]]), np.array([500.0]), 150.0)
    assert got.tolist() == [34 / 100]  # rows 66..99


def test_keyed_labels_by_hand() -> None:
    # row 0: two runs of key 1 split by a hole (bridged with bridge=1) and a run of key 2;
    # row 1: a blocking pixel under the hole, key 1 below the first run
    key = np.array([[1, 1, 0, 1, 2], [1, 0, 0, 0, 2]], np.float32)
    state = np.array([[ACTIVE, ACTIVE, HOLE, ACTIVE, ACTIVE], [ACTIVE, BLOCK, HOLE, HOLE, ACTIVE]], np.int8)
    depth = np.array([[100, 200, 0, 300, 400], [500, 0, 0, 0, 600]], np.float32)
    labels, n, sums, boxes = label_keyed_stats(key, state, depth, bridge=1)
    assert n == 2
    np.testing.assert_array_equal(labels, [[1, 1, 0, 1, 2], [1, 0, 0, 0, 2]])
    # component 1: pixels (0,0) (1,0) (3,0) (0,1): count 4, sum Z 1100, sum x 4, sum y 1
    assert tuple(sums[1, :5]) == (4.0, 1100.0, 100**2 + 200**2 + 300**2 + 500**2, 4.0, 1.0)
    assert tuple(sums[1, 5:7]) == (0 * 100 + 1 * 200 + 3 * 300 + 0 * 500, 500.0)
    assert tuple(boxes[1]) == (0, 0, 3, 1)
    # without the bridge the hole splits row 0, and the first run is joined only from below
    labels0, n0, _, _ = label_keyed_stats(key, state, depth, bridge=0)
    np.testing.assert_array_equal(labels0, [[1, 1, 0, 2, 3], [1, 0, 0, 0, 3]])
    assert n0 == 3


def test_relative_tolerance_joins_a_ramp_but_not_a_step() -> None:
    depth = np.array([[1000, 1008, 1016, 1200, 1208]], np.float32)  # 0.8 % steps, then 18 %
    state = np.full(depth.shape, ACTIVE, np.int8)
    labels, n, sums, _ = label_keyed_stats(depth, state, depth, rel=0.01)
    np.testing.assert_array_equal(labels, [[1, 1, 1, 2, 2]])
    assert n == 2 and sums[1, 0] == 3 and sums[2, 1] == 2408.0


def test_band_labeller_equals_keyed_labeller_on_band_images() -> None:
    rng = np.random.default_rng(11)
    for t in range(200):
        h, w = (int(v) for v in rng.integers(1, 24, 2))
        nb = int(rng.integers(1, 6))
        valid = rng.random((h, w)) < rng.choice([0.5, 0.9, 1.0])
        bins = np.where(valid, rng.integers(0, nb, (h, w)), -1).astype(np.int32)
        lut = rng.integers(-1, 3, nb).astype(np.int32)
        include = rng.random((h, w)) < 0.8 if t % 2 else None
        if include is not None:  # bin_index bins only the pixels of the histogram mask
            bins = np.where(valid & include, bins, -1).astype(np.int32)
        depth = np.where(valid, rng.random((h, w)) * 1000 + 500, 0).astype(np.float32)
        bridge = int(rng.integers(0, 4))
        band, state = band_state(bins, lut, valid, include)
        want = label_keyed_stats(band, state, depth, bridge=bridge, min_px=2)
        got = label_bands_stats(bins, lut, valid, include, depth, bridge=bridge, min_px=2)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1] == want[1]
        np.testing.assert_allclose(got[2], want[2], rtol=1e-12)
        np.testing.assert_array_equal(got[3], want[3])


def test_depth_range_from_bit_patterns() -> None:
    rng = np.random.default_rng(3)
    depth = (rng.random((30, 40)) * 4000 + 0.5).astype(np.float32)
    depth[rng.random(depth.shape) < 0.3] = 0
    ok = depth > 0
    lo, hi, n = depth_range(depth, ok, zero_outside=True)
    assert (lo, hi, n) == (float(depth[ok].min()), float(depth[ok].max()), int(ok.sum()))
    assert depth_range(depth, ok) == (lo, hi, n)
    assert depth_range(np.zeros((2, 2), np.float32), np.zeros((2, 2), bool), zero_outside=True)[2] == 0


def test_bins_and_counts_match_numpy() -> None:
    rng = np.random.default_rng(5)
    depth = (rng.random((20, 30)) * 3000 + 400).astype(np.float32)
    valid = rng.random(depth.shape) < 0.8
    lo = float(depth[valid].min())
    nb = int((float(depth[valid].max()) - lo) / 10.0) + 1
    bins, counts = bin_pixels(depth, valid, lo, 10.0, False, nb)
    want = np.minimum(((depth.astype(np.float64) - lo) * (1 / 10.0)).astype(np.int64), nb - 1)
    np.testing.assert_array_equal(bins, np.where(valid, want, -1))
    np.testing.assert_array_equal(counts, np.bincount(want[valid], minlength=nb))
    lbins, _ = bin_pixels(depth, valid, math.log(lo), 0.01, True, 400)
    wlog = np.minimum(((np.log(depth.astype(np.float64)) - math.log(lo)) / 0.01).astype(np.int64), 399)
    np.testing.assert_array_equal(lbins, np.where(valid, wlog, -1))


def test_check_depth_rejects_nan_inf_negative_and_masked() -> None:
    d = np.array([[np.nan, 0, 5, -1, np.inf, 3]], np.float32)
    depth, ok = check_depth(d, None)
    np.testing.assert_array_equal(ok, [[False, False, True, False, False, True]])
    np.testing.assert_array_equal(depth, [[0, 0, 5, 0, 0, 3]])
    depth, ok = check_depth(d, np.array([[1, 1, 1, 1, 1, 0]], bool))
    np.testing.assert_array_equal(depth, [[0, 0, 5, 0, 0, 0]])
    clean = np.array([[1, 2]], np.uint16)
    depth, ok = check_depth(clean, None)
    assert depth.dtype == np.float32 and ok.all()


def _jumps_numpy(z: np.ndarray, valid: np.ndarray, jump_rel: float) -> np.ndarray:
    d = np.abs(np.diff(z, axis=1))
    d[~(valid[:, 1:] & valid[:, :-1])] = 0.0
    big = d > jump_rel * np.maximum(z[:, 1:], z[:, :-1])
    around = np.zeros_like(d)
    around[:, 2:] = d[:, :-2]
    np.maximum(around[:, :-2], d[:, 2:], out=around[:, :-2])
    big &= d > 2.0 * around
    out = np.zeros(z.shape, bool)
    out[:, 1:] |= big
    out[:, :-1] |= big
    return out


def _one_sided_numpy(inv: np.ndarray, valid: np.ndarray, step: int) -> np.ndarray:
    fwd = np.zeros_like(inv)
    fwd[:, :-step] = inv[:, step:] - inv[:, :-step]
    okf = np.zeros_like(valid)
    okf[:, :-step] = valid[:, step:] & valid[:, :-step]
    bwd = np.zeros_like(inv)
    bwd[:, step:] = fwd[:, :-step]
    okb = np.zeros_like(valid)
    okb[:, step:] = okf[:, :-step]
    f = np.where(okf, fwd, np.float32(np.inf))
    b = np.where(okb, bwd, np.float32(np.inf))
    g = np.where(np.abs(f) <= np.abs(b), f, b)
    g[~(okf | okb)] = 0.0
    return (g / step).astype(np.float32)


def test_orientation_passes_match_numpy() -> None:
    rng = np.random.default_rng(9)
    z = (1000 + np.cumsum(rng.normal(0, 20, (16, 40)), axis=1)).astype(np.float32)
    z[:, 20:] += 300  # an occlusion edge
    valid = rng.random(z.shape) < 0.9
    z[~valid] = 0
    np.testing.assert_array_equal(_jumps(z, valid, 0.05), _jumps_numpy(z, valid, 0.05))
    assert _jumps(z, valid, 0.05)[:, 19:21].any()  # the edge is found
    inv = np.zeros_like(z)
    np.divide(1000.0, z, out=inv, where=valid)
    for step in (1, 3):
        np.testing.assert_array_equal(_one_sided(inv, valid, step), _one_sided_numpy(inv, valid, step))


@pytest.mark.parametrize("shape", [(16, 40), (1, 5), (2, 7), (3, 4), (5, 1), (7, 6), (23, 17)])
def test_one_sided_rows_match_numpy_at_every_border(shape: tuple[int, int]) -> None:
    # the compiled pass splits each row into the border columns and a branch-free interior;
    # steps as wide as the frame and wider leave no interior
    rng = np.random.default_rng(shape[0] * 31 + shape[1])
    valid = rng.random(shape) < 0.8
    inv = np.where(valid, rng.uniform(0.2, 2.0, shape), 0.0).astype(np.float32)
    for step in (1, 2, 3, 5, 8):
        np.testing.assert_array_equal(_one_sided(inv, valid, step), _one_sided_numpy(inv, valid, step))


def test_orientation_classes_match_numpy() -> None:
    # the per-pixel class from the window-mean slopes against the float32 numpy expression it
    # replaced
    from depthgram.segmentation.orientation import FACING, HORIZONTAL, VERTICAL, _classify

    rng = np.random.default_rng(4)
    h, w = 37, 53
    f32 = np.float32
    fx, fy, cx, cy = f32(60.0), f32(58.0), f32(26.0), f32(18.0)
    sgx = rng.normal(0, 0.02, (h, w)).astype(f32)
    sgy = rng.normal(0, 0.02, (h, w)).astype(f32)
    den = np.maximum(rng.integers(0, 50, (h, w)).astype(f32), f32(1e-6))
    inv3 = rng.uniform(0.2, 2.0, (h, w)).astype(f32)
    valid = rng.random((h, w)) < 0.9
    jump = rng.random((h, w)) < 0.1
    cos_t = f32(math.cos(math.radians(35.0)))
    u = ((np.arange(w, dtype=f32) - cx) / fx)[None, :]
    v = ((np.arange(h, dtype=f32) - cy) / fy)[:, None]
    a = fx * (sgx / den)
    b = fy * (sgy / den)
    c = inv3 - a * u - b * v
    t = cos_t * (np.sqrt(a * a + b * b + c * c) + f32(1e-12))
    ref = np.where(np.abs(a) >= t, VERTICAL, np.where(np.abs(b) >= t, HORIZONTAL, FACING)).astype(np.int8)
    ref[jump | ~valid] = FACING
    # the window counts as the box filter gives them (0 where no slope was kept): _classify
    # takes them at least 1e-6 as np.maximum did; the row and column jumps come joined
    raw = np.where(den > 1e-3, den, f32(0.0))
    # the window sums come as the channels of one image
    sums = np.stack([raw, sgx, sgy], axis=-1)
    got = _classify(sums, inv3, valid, jump, fx, fy, cx, cy, cos_t)
    np.testing.assert_array_equal(got, ref)
    assert len(np.unique(got)) == 3


def test_slopes_match_the_passes_they_replaced() -> None:
    # one compiled call for the 3 x 3 mean (OpenCV's box filter and numpy's division), both
    # one-sided slopes, the slopes kept under 80 degrees (numpy's float32 expression) and the
    # occlusion edges along rows or columns
    import cv2

    from depthgram.segmentation._kernels.creases import inverse_depth as _inverse
    from depthgram.segmentation.orientation import _slopes

    f32 = np.float32
    fx, fy = f32(60.0), f32(58.0)
    steep = f32(math.tan(math.radians(80.0)))
    for seed, shape in enumerate([(37, 53), (1, 9), (9, 1), (2, 2), (6, 40)]):
        rng = np.random.default_rng(seed)
        z = (1500 + np.cumsum(rng.normal(0, 30, shape), axis=1)).astype(f32)
        z[rng.random(shape) < 0.15] += 400  # occlusion steps
        valid = rng.random(shape) < 0.8
        z[~valid] = 0
        inverse = _inverse(z, valid)
        for step in (1, 3):
            inv3, planes, edge, _ = _slopes(inverse, z, valid, step, fx, fy, steep, f32(0.05))
            kept = np.moveaxis(planes, 0, -1)  # the channel planes
            both = cv2.merge([inverse[0], inverse[1]])  # the two planes as channels of one image
            box = cv2.boxFilter(both, -1, (3, 3), normalize=False, borderType=cv2.BORDER_REPLICATE)
            den3 = np.maximum(box[:, :, 1], f32(1e-6))
            np.testing.assert_array_equal(inv3, np.asarray(box[:, :, 0] / den3, f32))
            has = den3 > 0.5
            gx, gy = _one_sided(inv3, has, step), _one_sided_cols(inv3, has, step)
            lim = steep * inv3
            keep = has & (np.abs(fx * gx) <= lim) & (np.abs(fy * gy) <= lim)
            assert kept.shape == (*shape, 3) and kept.dtype == f32
            np.testing.assert_array_equal(kept[:, :, 0], keep.astype(f32))
            np.testing.assert_array_equal(kept[:, :, 1], np.where(keep, gx, f32(0.0)))
            np.testing.assert_array_equal(kept[:, :, 2], np.where(keep, gy, f32(0.0)))
            np.testing.assert_array_equal(edge, _jumps(z, valid, 0.05) | _jumps_cols(z, valid, f32(0.05)))
            if shape == (37, 53):
                assert 0 < keep.sum() < keep.size and 0 < edge.sum() < edge.size


def test_box3_mean_equals_opencvs_box_filter() -> None:
    # the 3 x 3 sums computed as OpenCV computes a float32 image (float64 running sums): the
    # same values to the last bit, also where float64 rounds (values over 40 decades)
    import cv2

    from depthgram.segmentation.orientation import _box3_mean

    rng = np.random.default_rng(5)
    for t in range(150):
        h, w = (int(v) for v in rng.integers(1, 70, 2))
        if t % 3 == 0:
            img = (10.0 ** rng.uniform(-20, 20, (h, w, 2))).astype(np.float32)
        else:
            img = (rng.normal(0, 1, (h, w, 2)) * float(rng.choice([1e-3, 1.0, 1e3]))).astype(np.float32)
        img[rng.random((h, w, 2)) < 0.3] = 0.0
        box = cv2.boxFilter(img, -1, (3, 3), normalize=False, borderType=cv2.BORDER_REPLICATE)
        den = np.maximum(box[:, :, 1], np.float32(1e-6))
        inv3, has = _box3_mean(np.ascontiguousarray(np.moveaxis(img, -1, 0)))  # as two planes
        np.testing.assert_array_equal(inv3, np.asarray(box[:, :, 0] / den, np.float32))
        np.testing.assert_array_equal(has, den > 0.5)


def test_box_filter_of_channels_equals_one_filter_per_channel() -> None:
    # the orientation field sums its kept slopes and their count as the channels of one image
    # (three running sums side by side): each channel's sums must be those of a one-channel
    # filter to the last bit, the values the field had before
    import cv2

    rng = np.random.default_rng(21)
    for t in range(120):
        h, w = (int(v) for v in rng.integers(1, 90, 2))
        cn = 3 if t % 2 else 2  # the slopes (3), 1/Z and the readings (2)
        img = (rng.normal(0, 1, (h, w, cn)) * float(rng.choice([1e-3, 0.05, 1.0, 1e3]))).astype(np.float32)
        img[rng.random((h, w, cn)) < 0.3] = 0.0
        k = int(rng.choice([3, 5, 7, 9]))
        border = cv2.BORDER_REPLICATE if t % 4 < 2 else cv2.BORDER_CONSTANT
        three = cv2.boxFilter(img, -1, (k, k), normalize=False, borderType=border)
        for c in range(cn):
            one = cv2.boxFilter(np.ascontiguousarray(img[:, :, c]), -1, (k, k), normalize=False, borderType=border)
            np.testing.assert_array_equal(three[:, :, c], one)


def test_orientation_inverse_and_mean_match_numpy() -> None:
    # 1000 / Z with the readings as 1 / 0, and the 3 x 3 mean, against OpenCV's window sums and
    # the float32 numpy expressions they replaced
    import cv2

    from depthgram.segmentation._kernels.creases import inverse_depth as _inverse
    from depthgram.segmentation.orientation import _box3_mean

    rng = np.random.default_rng(16)
    z = rng.uniform(300, 6000, (41, 57)).astype(np.float32)
    valid = rng.random(z.shape) < 0.15  # sparse: some 3 x 3 windows without a reading
    z[~valid] = 0
    inv_ref = np.zeros_like(z)
    np.divide(1000.0, z, out=inv_ref, where=valid)
    both = _inverse(z, valid)  # the two as planes
    assert both.shape == (2, *z.shape) and both.dtype == np.float32
    inv, m = both[0], both[1]
    np.testing.assert_array_equal(inv, inv_ref)
    np.testing.assert_array_equal(m, valid.astype(np.float32))
    box = {"ddepth": -1, "ksize": (3, 3), "normalize": False, "borderType": cv2.BORDER_REPLICATE}
    s_inv, s_m = cv2.boxFilter(np.ascontiguousarray(inv), **box), cv2.boxFilter(np.ascontiguousarray(m), **box)
    den3 = np.maximum(s_m, 1e-6)
    inv3, has = _box3_mean(both)
    np.testing.assert_array_equal(inv3, np.asarray(s_inv / den3, np.float32))
    np.testing.assert_array_equal(has, den3 > 0.5)
    assert 0 < has.sum() < has.size


@pytest.mark.parametrize("shape", [(16, 40), (40, 16), (1, 5), (2, 7), (3, 4), (5, 1), (23, 17)])
def test_column_passes_equal_row_passes_on_the_transpose(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    z = (1000 + np.cumsum(rng.normal(0, 20, shape), axis=0)).astype(np.float32)
    z[rng.random(shape) < 0.2] += 300  # occlusion steps
    valid = rng.random(shape) < 0.85
    z[~valid] = 0
    np.testing.assert_array_equal(_jumps_cols(z, valid, np.float32(0.05)), _jumps(z.T, valid.T, 0.05).T)
    inv = np.zeros_like(z)
    np.divide(1000.0, z, out=inv, where=valid)
    for step in (1, 3):
        np.testing.assert_array_equal(_one_sided_cols(inv, valid, step), _one_sided(inv.T, valid.T, step).T)


@pytest.mark.parametrize("k", [2, 4])
def test_upsample_classes_repeats_and_clears_holes(k: int) -> None:
    rng = np.random.default_rng(k)
    valid = rng.random((19, 23)) < 0.8
    cls = rng.integers(0, 3, (-(-19 // k), -(-23 // k))).astype(np.int8)
    want = np.repeat(np.repeat(cls, k, axis=0), k, axis=1)[:19, :23]
    want[~valid] = 0
    np.testing.assert_array_equal(upsample_classes(cls, valid, k), want)


def test_front_face_folds_only_without_a_depth_jump() -> None:
    # support 3 (a table top, rows 0-1) above facing object 1 (its front, rows 2-3) at the
    # same depth; facing object 2 below it is 50 % farther (an object behind, not a face)
    labels = np.zeros((4, 8), np.int32)
    labels[0:2, 0:8] = 3
    labels[2:4, 0:4] = 1
    labels[2:4, 4:8] = 2
    depth = np.full(labels.shape, 1000, np.float32)
    depth[2:4, 4:8] = 1500
    widths = np.array([0, 4, 4], np.float64)
    fronts = front_faces(labels, depth, widths, np.array([3], np.int32), jump_rel=0.05)
    assert fronts == {1: 3}


@pytest.mark.parametrize("seed", range(4))
def test_contacts_inside_the_supports_boxes_equal_the_whole_frame(seed: int) -> None:
    # facing ids 1..n_facing, supports after them; the counts read inside the supports' boxes
    # are the whole frame's, above-below and side by side (support left or right)
    from depthgram.segmentation.contacts import _contacts_in_boxes

    rng = np.random.default_rng(seed)
    h, w, n_facing, n_sup = 29, 41, 6, 4
    labels = np.kron(rng.integers(0, n_facing + n_sup + 1, (h // 3 + 1, w // 3 + 1)), np.ones((3, 3), np.int32))
    labels = np.ascontiguousarray(labels[:h, :w]).astype(np.int32)
    labels[rng.random((h, w)) < 0.1] = 0
    depth = (1000.0 + rng.normal(0, 30.0, (h, w))).astype(np.float32)
    ids = np.flatnonzero(rng.random(n_sup) < 0.8) + n_facing + 1
    boxes = np.array(
        [(xs.min(), ys.min(), xs.max(), ys.max()) for ys, xs in (np.nonzero(labels == i) for i in ids)], np.int64
    ).reshape(-1, 4)
    n_ids = n_facing + n_sup + 1
    is_support = np.zeros(n_ids, np.bool_)
    is_support[ids] = True
    for side in (False, True):
        # the whole frame in numpy: (facing, support) neighbour pairs without a depth jump, a
        # support above a face, or side by side either way round
        ref = np.zeros((n_facing + 1, n_ids), np.int64)
        la, lb = (labels[:, :-1], labels[:, 1:]) if side else (labels[:-1], labels[1:])
        za, zb = (depth[:, :-1], depth[:, 1:]) if side else (depth[:-1], depth[1:])
        near = np.abs(za - zb) <= np.float32(0.02) * np.maximum(za, zb)
        pairs = [(lb, la)] + ([(la, lb)] if side else [])
        for f, sp in pairs:
            on = near & (f > 0) & (f <= n_facing) & is_support[sp]
            np.add.at(ref, (f[on], sp[on]), 1)
        got = _contacts_in_boxes(labels, depth, ids.astype(np.intp), boxes, n_ids, n_facing, np.float32(0.02), side)
        np.testing.assert_array_equal(got, ref)
        assert ref.sum() > 0


def _floor_scene() -> tuple[np.ndarray, np.ndarray, Intrinsics]:
    # a floor plane 1 m below the camera (y down), seen from row 20 of 40; a box in front of it
    cam = Intrinsics(40.0, 40.0, 19.5, 19.5)
    v = (np.arange(40) - cam.cy) / cam.fy
    z = np.where(v > 0.05, 1000.0 / np.maximum(v, 1e-9), 0)[:, None] * np.ones((1, 40))
    depth = np.clip(z, 0, 8000).astype(np.float32)
    depth[depth >= 8000] = 0
    depth[25:33, 10:18] = 1500.0  # the box, facing the sensor
    return depth, depth > 0, cam


def test_support_pieces_equal_label_merge_then_stats() -> None:
    depth, ok, cam = _floor_scene()
    classes = np.zeros(depth.shape, np.int8)
    classes[ok & (depth != 1500.0)] = 1
    # far rows of a floor step by up to 20 % of their depth: a loose jump limit keeps it whole
    lab_ref, n_ref = support_components(depth, ok, classes, 1, jump_rel=0.25, bridge=2)
    lab_ref, n_ref = merge_coplanar(lab_ref, n_ref, depth, cam, min_fit_px=10)
    st = label_stats(lab_ref, depth, n_ref, metric=True)
    lab, n, sums, boxes, planes = support_pieces(depth, ok, classes, 1, cam, jump_rel=0.25, bridge=2, min_fit_px=10)
    np.testing.assert_array_equal(lab, lab_ref)
    assert n == n_ref >= 1
    np.testing.assert_allclose(sums[:, 0], st.count)
    np.testing.assert_allclose(sums[:, 1], st.sz, rtol=1e-12)
    normal, off, _ = plane_fits(lab, n, depth, cam)
    merged_normal, merged_off, _ = planes_from_sums(planes)  # pieces' sums added, no new pass
    np.testing.assert_allclose(merged_normal, normal, atol=1e-9)
    np.testing.assert_allclose(merged_off, off, rtol=1e-9)
    floor = int(np.argmax(sums[:, 0]))
    # the floor's fitted plane: normal (0, -1, 0) toward the camera, 1000 mm away
    assert normal[floor] == pytest.approx([0.0, -1.0, 0.0], abs=1e-4)
    assert off[floor] == pytest.approx(1000.0, rel=1e-4)
    cand = ok & (classes == 0)
    cand[30:34, 0:5] = True  # floor pixels wrongly taken as facing
    want = on_support_planes(lab, n, depth, cand, cam, min_px=10, tol_rel=0.025)
    got = near_planes(normal, off, sums[:, 0], boxes, depth, cand, cam, min_px=10, tol_rel=0.025)
    np.testing.assert_array_equal(got, want)
    assert got[30:34, 0:5][ok[30:34, 0:5]].all()  # the floor pixels go back to the floor
    assert not got[25:33, 10:18].any()  # the box does not


def test_slice_parts_match_per_slice_numpy_sums() -> None:
    rng = np.random.default_rng(4)
    labels = np.zeros((30, 40), np.int32)
    labels[5:25, 3:37] = 7
    labels[rng.random(labels.shape) < 0.2] = 0  # dropouts inside the object
    depth = (rng.random(labels.shape) * 500 + 1000).astype(np.float32)
    obj_mask = labels == 7
    ys, xs = np.nonzero(obj_mask)
    obj = SceneObject(
        7,
        "floor",
        0,
        0.0,
        0.0,
        int(ys.size),
        0.0,
        (0.0, 0.0),
        (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1),
    )
    for horizontal in (True, False):
        parts = slice_parts(
            labels,
            depth,
            obj.id,
            obj.bbox_xy,
            horizontal=horizontal,
            step_of=lambda extent: 4,
            depth_label=lambda z: 0,
            intrinsics=None,
            first_id=1,
        )
        coord = ys - obj.bbox_xy[1] if horizontal else xs - obj.bbox_xy[0]
        want = []
        for j in np.unique(coord // 4):
            sel = coord // 4 == j
            z = depth[ys[sel], xs[sel]].astype(np.float64)
            want.append((float(z.mean()), int(sel.sum()), float(xs[sel].mean()), float(ys[sel].mean())))
        want.sort()  # parts come nearest first
        assert len(parts) == len(want)
        for p, (mean, area, cx, cy) in zip(parts, want, strict=True):
            assert p.area == area
            assert p.depth == pytest.approx(mean, rel=1e-12)
            assert p.center_xy == pytest.approx((cx, cy), rel=1e-12)


def test_parts_of_several_compounds_in_one_call_and_scaled_from_a_grid() -> None:
    from depthgram.segmentation.slices import compound_parts

    rng = np.random.default_rng(5)
    labels = np.zeros((30, 40), np.int32)
    labels[2:14, 3:37] = 4  # a floor, sliced in rows
    labels[16:29, 5:20] = 6  # a wall, sliced in columns
    labels[rng.random(labels.shape) < 0.2] = 0
    depth = (rng.random(labels.shape) * 500 + 1000).astype(np.float32)
    cam = Intrinsics(50.0, 50.0, 19.5, 14.5)
    objs = [(4, (3, 2, 37, 14), True), (6, (5, 16, 20, 29), False)]
    kw = {"step_of": lambda extent: 3, "depth_label": lambda z: (z > 1250).astype(int), "intrinsics": cam}
    both = compound_parts(labels, depth, objs, first_id=10, **kw)
    first = slice_parts(labels, depth, 4, (3, 2, 37, 14), horizontal=True, first_id=10, **kw)
    second = slice_parts(labels, depth, 6, (5, 16, 20, 29), horizontal=False, first_id=10 + len(first), **kw)
    assert both == [first, second] and len(first) == 4 and len(second) == 5
    # on the grid of a 2x wider frame (73 x 57 px: the last column and row clipped): the parts
    # as they were scaled after being built, area times 4, center and box times 2
    scaled = compound_parts(labels, depth, objs, first_id=10, scale=(2, 73, 57), **kw)
    for grid_part, part in zip(first + second, scaled[0] + scaled[1], strict=True):
        x0, y0, x1, y1 = grid_part.bbox_xy
        cx, cy = grid_part.center_xy
        want = dataclasses.replace(
            grid_part,
            area=grid_part.area * 4,
            center_xy=(cx * 2, cy * 2),
            bbox_xy=(x0 * 2, y0 * 2, min(x1 * 2, 73), min(y1 * 2, 57)),
        )
        assert part == want
    assert max(p.bbox_xy[2] for p in scaled[0]) == 73 and max(p.bbox_xy[3] for p in scaled[1]) == 57


@pytest.mark.parametrize(("h", "w"), [(132, 176), (31, 45), (1, 1), (6, 3)])
def test_facing_halves_are_numpys_slices_and_percentile(h: int, w: int) -> None:
    from depthgram.segmentation.surfaces import facing_halves

    rng = np.random.default_rng(h * w)
    depth = (rng.random((h, w)) * 4000 + 300).astype(np.float32)
    valid = rng.random((h, w)) > 0.2
    include = rng.random((h, w)) > 0.3
    facing, d2, m2, far, span = facing_halves(depth, valid, include, 2500.0)
    want_facing = valid & include
    sample = depth[::2, ::2][::2, ::2][want_facing[::2, ::2][::2, ::2]]
    assert np.array_equal(facing, want_facing)
    assert np.array_equal(d2, depth[::2, ::2]) and np.array_equal(m2, want_facing[::2, ::2])
    assert far == (float(np.percentile(sample, 95.0)) if sample.size else 2500.0)
    # the halves' range, as the histogram's depth_range reads it
    assert span == depth_range(np.ascontiguousarray(d2), np.ascontiguousarray(m2))
    # no facing reading among the samples: the given depth, and an empty range
    none = facing_halves(depth, valid, np.zeros_like(include), 2500.0)
    assert none[3] == 2500.0 and none[4] == (math.inf, -math.inf, 0)


def test_relabel_equals_numpy_fancy_indexing() -> None:
    from depthgram.segmentation.label import relabel

    rng = np.random.default_rng(8)
    labels = rng.integers(0, 40, (37, 53)).astype(np.int32)
    lut = rng.integers(0, 9, 40).astype(np.int32)
    out = relabel(labels, lut)
    assert out.dtype == np.int32
    np.testing.assert_array_equal(out, lut[labels])
    np.testing.assert_array_equal(relabel(labels[:, ::2], lut), lut[labels[:, ::2]])  # a strided view


@pytest.mark.parametrize("sigma", [0.6, 1.0, 2.5])
def test_histogram_smoothing_gives_scipys_numbers(sigma: float) -> None:
    # the compiled smoothing must equal gaussian_filter1d exactly (peak positions and cuts
    # depend on comparisons of neighbouring bins), edges reflected, tiny histograms too
    from scipy.ndimage import gaussian_filter1d

    from depthgram.segmentation.histogram import _gaussian_weights, _smooth_padded

    rng = np.random.default_rng(int(sigma * 10))
    for _ in range(200):
        n = int(rng.integers(1, 300))
        counts = rng.integers(0, int(rng.choice([3, 100, 50_000])), n).astype(np.int64)
        padded = _smooth_padded(counts, _gaussian_weights(sigma))
        np.testing.assert_array_equal(padded[1:-1], gaussian_filter1d(counts.astype(np.float64), sigma))
        assert padded[0] == 0.0 and padded[-1] == 0.0


def test_sensor_estimate_keeps_tied_depths_in_raster_order() -> None:
    # which of the pixels tied at a depth range's boundary fall on each side changes the
    # estimate; numpy's default sort left that to the CPU's SIMD level (three different models
    # on one frame with AVX-512, AVX2 and without). The estimate is the one with ties in raster
    # order, computed here from the same steps with numpy's stable sort.
    from depthgram.segmentation.noise_model import estimate_sensor
    from depthgram.sensor import simulate
    from reference import sensor_ranges

    f = next(iter(simulate("table", 1, size=(176, 132), seed=0))).frame
    z, _, _ = sensor_samples(f.depth, f.valid, 1)
    assert np.unique(z).size < z.size // 10  # millimetre depths: ties everywhere
    fit = sensor_ranges(f.depth, f.valid, 1)
    fit = fit[fit[:, 3] > 0]
    x = fit[:, 0] ** 2
    want = []
    for y in (fit[:, 1], fit[:, 2]):
        a, b = np.linalg.lstsq(np.stack([np.ones_like(x), x], axis=1), y, rcond=None)[0]
        if a < 0:
            a, b = 0.0, max(np.dot(x, y) / np.dot(x, x), 0.0)
        elif b < 0:
            a, b = float(np.mean(y)), 0.0
        want += [a, b]
    got = estimate_sensor(f.depth, f.valid)
    np.testing.assert_allclose([got.step_0, got.step_2, got.sigma_0, got.sigma_2], want, rtol=1e-9, atol=1e-15)


def _surfaces_reference(
    depth: np.ndarray, state: np.ndarray, t0: float, t2: float, sl: float, bridge: int
) -> np.ndarray:
    # the definition: union of every row and column pair of active pixels with only holes (at
    # most `bridge`) between them and continuous depths; components numbered in raster order
    h, w = depth.shape
    parent = list(range(h * w))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    def pair(a: tuple[int, int], b: tuple[int, int], gap: int) -> None:
        za, zb = depth[a], depth[b]
        zm = min(za, zb)
        if abs(za - zb) <= t0 + t2 * zm * zm + gap * sl * zm:
            ra, rb = root(a[0] * w + a[1]), root(b[0] * w + b[1])
            parent[max(ra, rb)] = min(ra, rb)

    for lines in (((y, x) for x in range(w)) for y in range(h)), (((y, x) for y in range(h)) for x in range(w)):
        for line in lines:
            last, k_last = None, -1
            for k, p in enumerate(line):
                if state[p] == ACTIVE:
                    if last is not None and k - k_last - 1 <= bridge:
                        pair(last, p, k - k_last)
                    last, k_last = p, k
                elif state[p] == BLOCK:
                    last = None
    out = np.zeros((h, w), np.int32)
    ids: dict[int, int] = {}
    for y in range(h):
        for x in range(w):
            if state[y, x] == ACTIVE:
                out[y, x] = ids.setdefault(root(y * w + x), len(ids) + 1)
    return out


@pytest.mark.parametrize("seed", range(5))
def test_label_surfaces_equals_pairwise_definition(seed: int) -> None:
    from depthgram.segmentation.surfaces import label_surfaces

    rng = np.random.default_rng(seed)
    h, w = 23, 31
    # steps between a few planes, noise, holes and blocking pixels
    depth = (1000.0 + 300.0 * (rng.integers(0, 3, (h, w)) if seed % 2 else (np.arange(w) // 8)[None, :] % 3)
             + rng.normal(0, 3.0, (h, w))).astype(np.float32)  # fmt: skip
    state = np.full((h, w), ACTIVE, np.int8)
    state[rng.random((h, w)) < 0.15] = HOLE
    state[rng.random((h, w)) < 0.05] = BLOCK
    args = (4.0, 1e-6, 0.002, 2)
    labels, n = label_surfaces(depth, state, tol_0=args[0], tol_2=args[1], slope_per_px=args[2], bridge_px=args[3])
    ref = _surfaces_reference(depth, state, *args)
    assert n == ref.max() > 1
    assert np.array_equal(labels, ref)


@pytest.mark.parametrize("seed", range(4))
def test_creases_compiled_equal_numpy(seed: int) -> None:
    # the compiled crease pass against the numpy one it replaced, on a tilted, bent surface with
    # noise, steps and holes, under a structured-light, a ToF and an estimated sensor model
    from depthgram.segmentation._kernels.creases import inverse_depth as _inverse
    from depthgram.segmentation.creases import _creases_numpy
    from depthgram.segmentation.noise_model import PROFILES, SensorModel
    from depthgram.segmentation.surfaces import concave_creases

    rng = np.random.default_rng(seed)
    h, w = 60, 80
    x = np.arange(w)[None, :]
    y = np.arange(h)[:, None]
    depth = (900.0 + 4.0 * np.abs(x - 40) + 2.0 * y + 150.0 * (x > 60) + rng.normal(0, 1.5, (h, w))).astype(np.float32)
    valid = rng.random((h, w)) > 0.1
    depth[~valid] = 0.0
    sensors = (PROFILES["kinect-v1"], PROFILES["tof"], SensorModel("auto", 1.3, 8e-7, 2.9, 2.1e-6))
    for sensor in sensors:
        for r in (2, 3):
            k = 2 * (r // 2) + 1
            geom = np.float32(r * math.tan(math.radians(10.0)) / 500.0)
            ref = _creases_numpy(depth, valid, sensor, r, k, geom, np.float32(math.sqrt(6.0) / (0.7 * k)))
            got = concave_creases(depth, valid, sensor, scale_px=r, min_angle_deg=10.0, focal_px=500.0)
            assert ref.any()
            assert np.array_equal(got, ref)
            # with the orientation field's 1/Z and readings handed over
            inverse = _inverse(depth, valid)
            got = concave_creases(depth, valid, sensor, scale_px=r, min_angle_deg=10.0, focal_px=500.0, inverse=inverse)
            assert np.array_equal(got, ref)


@pytest.mark.parametrize("seed", range(4))
def test_coplanar_groups_are_the_components_of_the_coplanar_pairs(seed: int) -> None:
    # the definition: large pieces i, j join when their normals agree within the angle and
    # their offsets within the share; groups are the connected components of those pairs,
    # numbered 1..m by their smallest piece; small pieces stay alone
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from depthgram.segmentation.coplanar import coplanar_groups

    rng = np.random.default_rng(seed)
    for _ in range(50):
        n = int(rng.integers(2, 60))
        base = rng.normal(0, 1, (4, 3))
        base /= np.linalg.norm(base, axis=1)[:, None]
        normal = base[rng.integers(0, 4, n + 1)] + rng.normal(0, 0.05, (n + 1, 3))
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        off = rng.choice([800.0, 1500.0, 2500.0], n + 1) * (1 + rng.normal(0, 0.03, n + 1))
        count = rng.integers(0, 200, n + 1).astype(np.float64)
        lut, m = coplanar_groups(normal, off, count, min_fit_px=50)
        big = (count >= 50) & (np.arange(n + 1) > 0)
        pairs = [
            (i, j)
            for i in range(1, n + 1)
            for j in range(i + 1, n + 1)
            if big[i]
            and big[j]
            and normal[i] @ normal[j] > math.cos(math.radians(10.0))
            and abs(off[i] - off[j]) <= 0.08 * max(off[i], off[j])
        ]
        rows, cols = (list(v) for v in zip(*pairs, strict=True)) if pairs else ([], [])
        graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n + 1, n + 1))
        _, comp = connected_components(graph, directed=False)
        first = {c: int(np.flatnonzero(comp == c)[0]) for c in np.unique(comp)}
        order = sorted(first.values())
        want = np.array([order.index(first[c]) for c in comp], np.int32)
        np.testing.assert_array_equal(lut, want)
        assert m == len(order) - 1 and lut.dtype == np.int32


def test_coplanar_tables_are_numpys_grouped_reductions() -> None:
    # the joined pieces' rows: each group's rows added in piece order and its boxes' union, as
    # np.add.reduceat / np.minimum.reduceat / np.maximum.reduceat give them on the rows sorted
    # stably by group, to the last bit; the groups are coplanar_groups'
    from depthgram.segmentation.coplanar import coplanar_groups, coplanar_tables

    rng = np.random.default_rng(15)
    joined = 0
    for _ in range(200):
        n = int(rng.integers(2, 60))
        base = rng.normal(0, 1, (3, 3))
        base /= np.linalg.norm(base, axis=1)[:, None]
        normal = base[rng.integers(0, 3, n + 1)] + rng.normal(0, 0.03, (n + 1, 3))
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        off = rng.choice([800.0, 1500.0], n + 1) * (1 + rng.normal(0, 0.02, n + 1))
        count = rng.integers(0, 200, n + 1).astype(np.float64)
        sums = rng.normal(0, 1e3, (n + 1, 10)) * rng.choice([1e-9, 1.0, 1e9], (n + 1, 10))
        planes = rng.normal(0, 1, (n + 1, 9)) * rng.choice([1e-9, 1.0, 1e9], (n + 1, 9))
        x0, y0 = rng.integers(0, 100, (2, n + 1))
        boxes = np.stack([x0, y0, x0 + rng.integers(0, 50, n + 1), y0 + rng.integers(0, 50, n + 1)], axis=1)
        lut, m, tables = coplanar_tables(normal, off, count, (sums, planes, boxes), min_fit_px=50)
        want_lut, want_m = coplanar_groups(normal, off, count, min_fit_px=50)
        np.testing.assert_array_equal(lut, want_lut)
        assert m == want_m
        if m == n:
            assert tables is None
            continue
        joined += 1
        assert tables is not None
        order = np.argsort(lut, kind="stable")
        starts = np.searchsorted(lut[order], np.arange(m + 1))
        grouped = boxes[order]
        want_boxes = np.concatenate(
            [np.minimum.reduceat(grouped[:, :2], starts), np.maximum.reduceat(grouped[:, 2:], starts)], axis=1
        )
        np.testing.assert_array_equal(tables[0], np.add.reduceat(sums[order], starts))
        np.testing.assert_array_equal(tables[1], np.add.reduceat(planes[order], starts))
        np.testing.assert_array_equal(tables[2], want_boxes)
    assert joined > 50


def test_join_near_is_near_planes_then_the_class_written() -> None:
    # the supports take the facing pixels on their planes straight into the class map: the
    # classes of near_planes on the facing candidates followed by a masked write
    from depthgram.segmentation.coplanar import join_near

    rng = np.random.default_rng(8)
    for t in range(40):
        depth, ok, cam = _floor_scene()
        if t % 2:
            depth = depth + rng.normal(0, 8, depth.shape).astype(np.float32) * ok
        ok = ok & (rng.random(depth.shape) > 0.1)
        classes = rng.choice(np.array([0, 1, 2], np.int8), depth.shape, p=[0.5, 0.4, 0.1])
        _, _, _, boxes, planes = support_pieces(depth, ok, classes, 1, cam, jump_rel=0.25, bridge=2, min_fit_px=5)
        normal, off, count = planes_from_sums(planes)
        tol = float(rng.choice([0.01, 0.025, 0.1]))
        min_px = int(rng.integers(1, 40))
        near = near_planes(normal, off, count, boxes, depth, ok & (classes == 0), cam, min_px=min_px, tol_rel=tol)
        want = classes.copy()
        want[near] = 1
        got = classes.copy()
        assert join_near(got, ok, 1, 0, normal, off, count, boxes, depth, cam, min_px=min_px, tol_rel=tol) == near.sum()
        np.testing.assert_array_equal(got, want)


def test_support_labelled_again_in_its_window_equals_the_whole_frame() -> None:
    # after join_near a class is labelled again inside class_window alone: its pixels all lie
    # there, and the pieces, tables and joined supports are those of the whole frame's pass
    from depthgram.segmentation.coplanar import class_window, join_near
    from depthgram.segmentation.slices import support_pieces_lazy

    rng = np.random.default_rng(9)
    smaller = 0
    for _ in range(40):
        depth, ok, cam = _floor_scene()
        depth = depth + rng.normal(0, 8, depth.shape).astype(np.float32) * ok
        ok = ok & (rng.random(depth.shape) > 0.1)
        classes = np.zeros(depth.shape, np.int8)
        # the class in a random block (and specks of a third class), so that the window is
        # smaller than the frame
        y0, x0 = (int(v) for v in rng.integers(0, 25, 2))
        classes[y0 : y0 + 15, x0 : x0 + 15] = rng.choice(np.array([0, 1], np.int8), (15, 15), p=[0.3, 0.7])[
            : 40 - y0, : 40 - x0
        ]
        classes[rng.random(depth.shape) < 0.05] = 2
        kw = {"jump_rel": 0.25, "bridge": int(rng.integers(0, 3)), "min_fit_px": 5}
        _, _, _, _, boxes, planes, fit = support_pieces_lazy(depth, ok, classes, 1, cam, **kw)
        normal, off, count = fit if fit is not None else planes_from_sums(planes)
        min_px = int(rng.integers(1, 40))
        join_near(classes, ok, 1, 0, normal, off, count, boxes, depth, cam, min_px=min_px, tol_rel=0.05)
        win = class_window(boxes, count, depth.shape, min_px=min_px)
        smaller += (win[1] - win[0]) * (win[3] - win[2]) < depth.size
        ys, xs = np.nonzero((classes == 1) & ok)
        if ys.size:
            assert win[0] <= ys.min() and ys.max() < win[1] and win[2] <= xs.min() and xs.max() < win[3]
        want = support_pieces_lazy(depth, ok, classes, 1, cam, **kw)
        got = support_pieces_lazy(depth, ok, classes, 1, cam, **kw, window=win)
        for a, b in zip(got[:6], want[:6], strict=True):
            if a is None or b is None:
                assert a is b
            else:
                np.testing.assert_array_equal(a, b)
        assert (got[6] is None) == (want[6] is None)
        if got[6] is not None and want[6] is not None:
            for a, b in zip(got[6], want[6], strict=True):
                np.testing.assert_array_equal(a, b)
    assert smaller > 20  # the windows read less than the frame


def test_dropping_through_the_joined_table_is_joining_then_dropping() -> None:
    # _support_class reads a class's pieces through one table piece -> support -> kept support:
    # the dropped supports' pixels go back to the facing class inside their boxes only, and the
    # kept ones join the objects' label map inside theirs. The same classes and labels as
    # joining the pieces, then dropping, over the whole frame; another class's pieces (values
    # outside base + 1 .. base + n) are left alone.
    from depthgram.segmentation.label import relabel
    from depthgram.segmentation.slices import add_through, drop_classes

    rng = np.random.default_rng(6)
    for _ in range(40):
        n = int(rng.integers(2, 30))
        m = int(rng.integers(1, n + 1))
        base = int(rng.integers(0, 5))
        merge = np.concatenate(([0], rng.integers(1, m + 1, n))).astype(np.int32)
        keep = np.concatenate(([0], rng.integers(0, 2, m))).astype(bool)
        lut = np.zeros(m + 1, np.int32)
        lut[keep] = np.arange(1, int(keep.sum()) + 1, dtype=np.int32)
        labels = rng.integers(0, base + n + 4, (17, 23)).astype(np.int32)
        classes = rng.integers(0, 3, labels.shape).astype(np.int8)
        mine = (labels > base) & (labels <= base + n)
        support = relabel(np.where(mine, labels - base, 0), merge)
        kept = lut[support]
        want_classes = np.where(mine & (kept == 0), np.int8(0), classes)
        # the supports' inclusive boxes (x0, y0, x1, y1) from their pixels
        boxes = np.zeros((m + 1, 4), np.int64)
        for g in range(1, m + 1):
            ys, xs = np.nonzero(support == g)
            boxes[g] = (xs.min(), ys.min(), xs.max(), ys.max()) if ys.size else (23, 17, -1, -1)
        through = lut[merge]
        got_classes = classes.copy()
        drop_classes(labels, through, base, got_classes, 0, boxes[1:][~keep[1:]])
        np.testing.assert_array_equal(got_classes, want_classes)
        table = np.zeros(base + n + 4, np.int32)
        table[base + 1 : base + n + 1] = np.where(through[1:] > 0, through[1:] + 7, 0)
        out = np.full(labels.shape, -1, np.int32)
        add_through(out, labels, table, boxes[1:][keep[1:]])
        np.testing.assert_array_equal(out, np.where(kept > 0, kept + 7, -1))


def test_load_rare_kernels_loads_the_kernels_of_the_rare_branches() -> None:
    # a stream's first frames may take none of these branches; a real-time caller loads their
    # kernels before the stream. With the very argument types of segment's calls: a frame that
    # takes the branches afterwards compiles no new signature
    from depthgram.segmentation import segment
    from depthgram.segmentation._kernels.coplanar import coplanar_join
    from depthgram.segmentation._kernels.feet import feet, take_back
    from depthgram.segmentation._kernels.plane_sums import planes_from_sums as planes_from_sums_kernel
    from depthgram.segmentation._kernels.ransac import assign_planes, search_planes
    from depthgram.segmentation._kernels.surfaces import restore_unclaimed
    from depthgram.segmentation.core import load_rare_kernels
    from depthgram.segmentation.label import keyed, stats
    from depthgram.segmentation.slices import _class_state, _drop_classes
    from depthgram.sensor import simulate

    load_rare_kernels()
    kernels = (
        keyed._label_runs,
        keyed._relabel_planes,
        _class_state,
        _drop_classes,
        stats._stats,
        search_planes,
        planes_from_sums_kernel,
        coplanar_join,
        assign_planes,
        feet,
        restore_unclaimed,
        take_back,
    )
    before = [len(k.signatures) for k in kernels]
    assert all(before)
    for scene in ("table", "corridor"):
        f = next(iter(simulate(scene, 1, size=(176, 132), seed=0))).frame
        segment(f)  # a support labelled again after its near pixels joined it (both scenes)
    assert [len(k.signatures) for k in kernels] == before


def test_percentile32_is_numpys_percentile_to_the_last_bit() -> None:
    # numpy interpolates in float32 for a Python-number percentile and in float64 for a
    # sequence of them; the compiled route reproduces both (the frame's far depth, the spread
    # of a candidate plane)
    from depthgram.segmentation.order_stats import percentile32

    rng = np.random.default_rng(14)
    for t in range(3000):
        n = int(rng.integers(1, 300 if t % 2 else 2500))
        kind = t % 4
        if kind == 0:
            a = np.round(rng.random(n) * 3000 + 300).astype(np.float32)  # millimetres: ties
        elif kind == 1:
            a = (rng.random(n) * 3000 + 300).astype(np.float32)
        elif kind == 2:
            a = (np.round(rng.random(n) * 20) * 11.76 + 500).astype(np.float32)  # 8-bit depth steps
        else:
            a = rng.normal(1000, 300, n).astype(np.float32)
        for q in (5, 20, 50, 95):
            assert percentile32(a.copy(), float(q), True) == float(np.percentile(a, q))
        b = a.copy()
        got = [percentile32(b, q, False) for q in (5.0, 50.0, 95.0)]
        np.testing.assert_array_equal(got, np.percentile(a, (5, 50, 95)))


def test_bin_counts_equal_bin_index_counts() -> None:
    # the surfaces' histogram counts whole depths value by value (one logarithm per distinct
    # depth); the same edges and counts as binning every pixel, also for depths that are not
    # whole or span too much to count (the per-pixel route)
    from depthgram.segmentation.config import SegmentConfig
    from depthgram.segmentation.histogram import bin_counts, bin_index

    rng = np.random.default_rng(15)
    for t in range(400):
        h, w = (int(v) for v in rng.integers(1, 60, 2))
        lo = float(rng.choice([1, 200, 400, 2000]))
        span = float(rng.choice([3, 100, 3000, 20000, 100_000]))
        depth = np.round(rng.random((h, w)) * span + lo).astype(np.float32)
        if t % 5 == 0:
            depth += np.float32(0.5) * (rng.random((h, w)) < 0.01)
        valid = rng.random((h, w)) > 0.2
        cfg = SegmentConfig(
            depth_dependent_bins=True,
            ref_depth_mm=float(rng.choice([500.0, 2000.0])),
            bin_mm=float(rng.choice([5.0, 12.0, 40.0])),
        )
        edges, counts = bin_counts(depth, valid, cfg)
        _, want_edges, want_counts = bin_index(depth, valid, cfg)
        np.testing.assert_array_equal(edges, want_edges)
        np.testing.assert_array_equal(counts, want_counts)


def test_planes_from_sums_is_the_numpy_route_within_the_conditioning() -> None:
    # the compiled normals, offsets and counts of every piece's plane are those of numpy's
    # batched solve and norm, on the plane sums of labelled floors with and without noise,
    # within what each system's conditioning allows
    from reference import planes_from_sums_numpy

    rng = np.random.default_rng(12)
    n_rows = 0
    for t in range(20):
        depth, ok, cam = _floor_scene()
        if t % 2:
            depth = depth + rng.normal(0, 8, depth.shape).astype(np.float32) * ok
        classes = rng.choice(np.array([0, 1, 2], np.int8), depth.shape, p=[0.3, 0.6, 0.1])
        _, _, _, _, planes = support_pieces(depth, ok, classes, 1, cam, jump_rel=0.25, bridge=2, min_fit_px=5)
        normal, offset, count = planes_from_sums(planes)
        want_normal, want_offset, want_count = planes_from_sums_numpy(planes)
        s = planes
        ata = np.stack([s[:, [0, 1, 2]], s[:, [1, 3, 4]], s[:, [2, 4, 5]]], axis=1) + np.eye(3) * 1e-12
        ata[0] = np.eye(3)
        cond = np.maximum(np.linalg.cond(ata), 1.0)
        tol = 64 * np.finfo(np.float64).eps * cond
        np.testing.assert_array_less(np.abs(normal - want_normal).max(axis=1), tol)
        np.testing.assert_array_less(np.abs(offset - want_offset) / want_offset, tol)
        np.testing.assert_array_equal(count, want_count)  # a copied sum, not computed
        n_rows += planes.shape[0]
    assert n_rows > 100


def test_planes_from_sums_leaves_the_small_pieces_unsolved() -> None:
    # the supports read the planes of pieces of min_px pixels or more alone: those rows are the
    # full solve's to the last bit, the others NaN, and the counts are every row's
    rng = np.random.default_rng(13)
    for t in range(10):
        depth, ok, cam = _floor_scene()
        if t % 2:
            depth = depth + rng.normal(0, 8, depth.shape).astype(np.float32) * ok
        classes = rng.choice(np.array([0, 1, 2], np.int8), depth.shape, p=[0.3, 0.6, 0.1])
        _, _, _, _, planes = support_pieces(depth, ok, classes, 1, cam, jump_rel=0.25, bridge=2, min_fit_px=5)
        normal, offset, count = planes_from_sums(planes)
        min_px = float(rng.choice([1.0, 5.0, 20.0]))
        got_normal, got_offset, got_count = planes_from_sums(planes, min_px=min_px)
        solved = count >= min_px
        solved[0] = True
        np.testing.assert_array_equal(got_count, count)
        np.testing.assert_array_equal(got_normal[solved], normal[solved])
        np.testing.assert_array_equal(got_offset[solved], offset[solved])
        assert np.isnan(got_normal[~solved]).all() and np.isnan(got_offset[~solved]).all()


def test_small_supports_are_numpys_test() -> None:
    # too few pixels or too flat for their depth: numpy's test on the statistics table, rows
    # of every kind (empty, flat, spread, exactly at the limits)
    from depthgram.segmentation.label.stats import COUNT, N_COLUMNS, SUM_Z, SUM_ZZ
    from depthgram.segmentation.slices import small_supports

    rng = np.random.default_rng(14)
    for _ in range(200):
        n = int(rng.integers(1, 40))
        sums = np.zeros((n + 1, N_COLUMNS))
        count = rng.integers(0, 300, n + 1).astype(np.float64)
        mean = rng.uniform(500.0, 4000.0, n + 1)
        std = mean * rng.choice([0.0, 0.01, 0.05, 0.2], n + 1)
        sums[:, COUNT] = count
        sums[:, SUM_Z] = count * mean
        sums[:, SUM_ZZ] = count * (std * std + mean * mean)
        min_px = int(rng.integers(1, 200))
        spread = float(rng.choice([0.0, 0.01, 0.05]))
        c = sums[:, COUNT]
        m = sums[:, SUM_Z] / np.maximum(c, 1)
        s = np.sqrt(np.maximum(sums[:, SUM_ZZ] / np.maximum(c, 1) - m * m, 0))
        want = (c < min_px) | (s < spread * m)
        want[0] = False
        got, k = small_supports(sums, min_px, spread)
        np.testing.assert_array_equal(got, want)
        assert k == want.sum()


def test_large_pieces_are_opencvs_8_connected_pieces() -> None:
    # the pieces of a found plane on the search grid: 8-connected (diagonal touches join),
    # those under the size dropped; OpenCV's labelling gives the same pixels
    from depthgram.segmentation._kernels.ransac import large_pieces as _large_pieces
    from reference import large_pieces_opencv

    rng = np.random.default_rng(15)
    for _ in range(300):
        h, w = (int(v) for v in rng.integers(1, 70, 2))
        mask = rng.random((h, w)) < rng.uniform(0.05, 0.8)
        min_px = int(rng.integers(1, 30))
        np.testing.assert_array_equal(_large_pieces(mask, min_px), large_pieces_opencv(mask, min_px))
    diagonal = np.eye(5, dtype=bool)  # one piece through corners only
    assert _large_pieces(diagonal, 5).sum() == 5 and not _large_pieces(diagonal, 6).any()


def test_prominent_peaks_are_scipys_find_peaks() -> None:
    # the histogram's peaks: flat tops (their middle sample, rounded down), peaks at the ends
    # of the padding, ties between the two sides, every prominence floor
    from scipy.signal import find_peaks

    from depthgram.segmentation.histogram import prominent_peaks

    rng = np.random.default_rng(16)
    for t in range(600):
        n = int(rng.integers(0, 300))
        x = rng.integers(0, 6 if t % 2 else 1000, n).astype(np.float64)  # few levels: plateaus
        if t % 3 == 0:
            x = np.concatenate(([0.0], x, [0.0]))
        floor = float(rng.choice([1e-9, 0.5, 1.0, 3.0, 50.0, 400.0]))
        want = find_peaks(x, prominence=floor)[0]
        got = prominent_peaks(x, floor)
        np.testing.assert_array_equal(got, want)
        assert got.dtype == want.dtype


def _raster_sums(labels: np.ndarray, n: int, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The statistics table's sums (key 0) and inclusive boxes, each pixel added in raster order.

    ``np.add.at`` adds one element after the other in index order: the float64 additions, in
    the order the statistics pass promises, without its runs.
    """
    h, w = labels.shape
    ys, xs = np.mgrid[0:h, 0:w]
    lab = labels.ravel()
    z = depth.ravel().astype(np.float64)
    x = xs.ravel().astype(np.float64)
    y = ys.ravel().astype(np.float64)
    sums = np.zeros((n + 1, 8), np.float64)
    for col, v in enumerate((np.ones_like(z), z, z * z, x, y, x * z, y * z)):
        np.add.at(sums[:, col], lab, v)
    sums[0] = 0.0
    boxes = np.empty((n + 1, 4), np.int64)
    boxes[:] = (w, h, -1, -1)
    for i in range(1, n + 1):
        r, c = np.nonzero(labels == i)
        if r.size:
            boxes[i] = (c.min(), r.min(), c.max(), r.max())
    return sums, boxes


@pytest.mark.parametrize("seed", range(6))
def test_statistics_pass_adds_in_raster_order(seed: int) -> None:
    # the runs' counts and sums of x and y are taken from their ends: the same numbers to the
    # last bit as adding every pixel in raster order (depths of very different magnitudes, so
    # that the order of the other sums shows)
    from depthgram.segmentation.label import label_stats_fused
    from depthgram.segmentation.label.stats import relabel_stats

    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(1, 60, 2))
    cell = int(rng.integers(1, 6))
    labels = rng.integers(0, 6, (h // cell + 1, w // cell + 1)).repeat(cell, 0).repeat(cell, 1)[:h, :w]
    labels = labels.astype(np.int32)
    depth = (rng.random((h, w)) * 10.0 ** rng.integers(-2, 5, (h, w))).astype(np.float32)
    lut = rng.integers(0, 4, 6).astype(np.int32)
    lut[0] = 0
    want = _raster_sums(lut[labels], 3, depth)
    got_labels, sums, boxes = relabel_stats(labels, lut, 3, depth)
    np.testing.assert_array_equal(got_labels, lut[labels])
    np.testing.assert_array_equal(sums, want[0])
    np.testing.assert_array_equal(boxes, want[1])
    key = rng.integers(0, 9, (h, w)).astype(np.float32)
    sums, boxes = label_stats_fused(labels, 5, depth, key)
    want = _raster_sums(labels, 5, depth)
    np.testing.assert_array_equal(sums[:, :7], want[0][:, :7])
    np.testing.assert_array_equal(boxes, want[1])
    for i in range(1, 6):  # the key column: the last pixel's key in raster order
        if (labels == i).any():
            assert sums[i, 7] == key[labels == i][-1]


def test_sensor_ranges_and_fit_equal_the_readable_route() -> None:
    # _range_fit (the counted range estimates and both least squares) against the readable
    # route and numpy's least squares: whole-millimetre depths (counting route), tenths of a
    # millimetre (readable route), holes, too few samples
    from depthgram.segmentation.noise_model import _range_fit
    from depthgram.sensor import simulate
    from reference import sensor_ranges

    f = next(iter(simulate("table", 1, size=(176, 132), seed=0))).frame
    rng = np.random.default_rng(3)
    tenths = f.depth * np.float32(1.0) + rng.integers(0, 10, f.depth.shape).astype(np.float32) / np.float32(10.0)
    holes = f.valid & (rng.random(f.depth.shape) > 0.2)
    for depth, valid, rows in (
        (f.depth, f.valid, 1),
        (f.depth, f.valid, 3),
        (f.depth, holes, 1),
        (np.where(f.valid, tenths, 0).astype(np.float32), f.valid, 2),
        (f.depth[:3], f.valid[:3], 1),
    ):
        z, _, _ = sensor_samples(depth, valid, rows)
        fit, sol = _range_fit(depth, valid, rows)
        if z.size < 200:
            assert fit.shape == (0, 4) and not sol.any()
            continue
        want = sensor_ranges(depth, valid, rows)
        want = want[want[:, 3] > 0]
        np.testing.assert_allclose(fit, want, rtol=1e-12)
        assert want.shape[0] > 1
        a = np.stack([np.ones(want.shape[0]), want[:, 0] ** 2], axis=1)
        want_sol = [*np.linalg.lstsq(a, want[:, 1], rcond=None)[0], *np.linalg.lstsq(a, want[:, 2], rcond=None)[0]]
        np.testing.assert_allclose(sol, want_sol, rtol=1e-9, atol=1e-15)


def _part_sums_by_pixel(
    labels: np.ndarray, depth: np.ndarray, oid: int, box: tuple[int, int, int, int], step: int, horizontal: bool, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """The slices' sums as the kernel promises them, pixel by pixel in plain Python.

    Each run of the object inside one slice summed from 0 in column order (count, Z, Z², x, xZ),
    then added to its slice's row, runs in raster order; inclusive boxes in box coordinates.
    """
    x0, y0, x1, y1 = box
    sums = np.zeros((n + 1, 7), np.float64)
    boxes = np.array([[x1 - x0 + 1, y1 - y0 + 1, -1, -1]] * (n + 1), np.int64)
    for y in range(y0, y1 + 1):
        yy = y - y0
        x = x0
        while x <= x1:
            if labels[y, x] != oid:
                x += 1
                continue
            start = x - x0
            j = (yy // step if horizontal else start // step) + 1
            stop = x1 if horizontal else min(x1, x0 + j * step - 1)
            c = sz = szz = sx = sxz = 0.0
            while x <= stop and labels[y, x] == oid:
                z = float(depth[y, x])
                c += 1.0
                sz += z
                szz += z * z
                sx += x - x0
                sxz += (x - x0) * z
                x += 1
            sums[j] += (c, sz, szz, sx, c * yy, sxz, sz * yy)
            boxes[j] = (min(boxes[j, 0], start), min(boxes[j, 1], yy), max(boxes[j, 2], x - 1 - x0), yy)
    return sums, boxes


@pytest.mark.parametrize("seed", range(8))
def test_slice_sums_are_the_runs_added_pixel_by_pixel(seed: int) -> None:
    # the runs' counts and sums of x come from their ends: the same numbers to the last bit
    from depthgram.segmentation.slices import _part_sums

    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(1, 40, 2))
    labels = np.where(rng.random((h, w)) < 0.15, 2, 1).astype(np.int32)
    depth = (rng.random((h, w)) * 10.0 ** rng.integers(-2, 5, (h, w))).astype(np.float32)
    x0, x1 = sorted(int(v) for v in rng.integers(0, w, 2))
    y0, y1 = sorted(int(v) for v in rng.integers(0, h, 2))
    step = int(rng.integers(1, 6))
    for horizontal in (True, False):
        n = ((y1 - y0 + 1) if horizontal else (x1 - x0 + 1)) // step + 1
        sums, boxes = _part_sums(labels, depth, 1, x0, y0, x1, y1, step, horizontal, n)
        want_sums, want_boxes = _part_sums_by_pixel(labels, depth, 1, (x0, y0, x1, y1), step, horizontal, n)
        np.testing.assert_array_equal(sums, want_sums)
        np.testing.assert_array_equal(boxes, want_boxes)


def test_valid_pixels_equal_the_float64_tests() -> None:
    # the validity pass compares float32 depths with a float32 bound for the far limit: the
    # same mask, "dirty" flag and far count as the float64 comparisons, for limits between two
    # float32 values, on one, beyond float32's range, and depths of every kind
    from depthgram.segmentation.validate import _far_bound, _valid_pixels

    rng = np.random.default_rng(5)
    special = np.array([0.0, -0.0, -1.0, np.nan, np.inf, -np.inf, 1e-45, 3.4e38], np.float32)
    for t in range(120):
        h, w = (int(v) for v in rng.integers(1, 40, 2))
        depth = (rng.random((h, w)) * 4000).astype(np.float32)
        if t % 2:
            depth = np.round(depth)
        depth[rng.random((h, w)) < 0.2] = 0.0  # holes
        pick = rng.random((h, w)) < 0.15
        depth[pick] = rng.choice(special, int(pick.sum()))
        valid = rng.random((h, w)) > 0.1
        z = float(rng.choice(depth.ravel()))
        far = float(
            rng.choice(
                [
                    2000.0,
                    np.nextafter(np.float32(1234.5), np.float32(0)) + 1e-5,  # between two float32 values
                    z if np.isfinite(z) else 1000.0,  # on a depth
                    z + 1e-9 if np.isfinite(z) else 1000.0,
                    1e39,  # beyond float32
                    np.inf,
                ]
            )
        )
        for use_valid in (True, False):
            seen = depth > 0
            if use_valid:
                seen &= valid
            z64 = depth.astype(np.float64)
            good = seen & (z64 < far)
            want_far = int((seen & (z64 >= far)).sum())
            want_dirty = bool(((~good) & (depth != 0)).any())
            mask = valid if use_valid else np.zeros((1, 1), np.bool_)
            ok, dirty, n_far = _valid_pixels(depth, mask, use_valid, _far_bound(far))
            np.testing.assert_array_equal(ok, good)
            assert dirty == want_dirty and n_far == want_far


def test_sensor_estimate_holds_python_floats() -> None:
    # the estimated model's coefficients are Python floats, as the compiled solve returned
    # them before the fit moved into one call (numpy scalars once sent the creases to their
    # numpy route: the same numbers, 0.35 ms slower at 176 x 132)
    from depthgram.segmentation.noise_model import estimate_sensor
    from depthgram.sensor import simulate

    f = next(iter(simulate("table", 1, size=(176, 132), seed=0))).frame
    m = estimate_sensor(f.depth, f.valid)
    assert m.name == "auto"
    assert all(type(v) is float for v in (m.step_0, m.step_2, m.sigma_0, m.sigma_2))


def test_creases_of_an_estimated_model_take_the_compiled_route(monkeypatch: pytest.MonkeyPatch) -> None:
    # estimate_sensor's coefficients are numpy float64 scalars: the compiled route must take
    # them as the floats they hold (the numpy route, about 0.5 ms at 176 x 132, was taken for
    # every frame of the default method when the estimate began returning numpy scalars)
    import depthgram.segmentation.creases as surfaces
    from depthgram.segmentation.noise_model import SensorModel, estimate_sensor
    from depthgram.sensor import simulate

    frame = next(iter(simulate("table", 1, size=(176, 132), seed=0))).frame
    est = estimate_sensor(frame.depth, frame.valid)
    coefs = (est.step_0, est.step_2, est.sigma_0, est.sigma_2)
    as_floats = SensorModel("auto", *(float(c) for c in coefs))
    numpy64 = SensorModel("auto", *(np.float64(c) for c in coefs))
    kw = {"scale_px": 2, "min_angle_deg": 10.0, "focal_px": 150.0}
    want = surfaces.concave_creases(frame.depth, frame.valid, as_floats, **kw)
    k = 3
    geom = np.float32(2 * math.tan(math.radians(10.0)) / 150.0)
    ref = surfaces._creases_numpy(
        frame.depth, frame.valid, as_floats, 2, k, geom, np.float32(math.sqrt(6.0) / (0.7 * k))
    )
    assert want.any()
    assert np.array_equal(want, ref)

    def refused(*args: object) -> None:
        raise AssertionError("numpy route taken")

    monkeypatch.setattr(surfaces, "_creases_numpy", refused)
    for sensor in (est, numpy64):
        assert np.array_equal(surfaces.concave_creases(frame.depth, frame.valid, sensor, **kw), want)


@pytest.mark.parametrize("seed", range(3))
def test_crease_state_is_surface_state_of_the_creases(seed: int) -> None:
    # the fused call against the two it replaced, on frames narrow and wide (the wide one
    # takes the half-resolution route), spans 1-4 and frames narrower than the span
    from depthgram.segmentation._kernels.creases import inverse_depth as _inverse
    from depthgram.segmentation.noise_model import PROFILES
    from depthgram.segmentation.surfaces import concave_creases, crease_state, surface_state

    rng = np.random.default_rng(seed)
    for h, w, r in ((60, 80, 2), (61, 79, 3), (40, 400, 4), (5, 3, 2), (3, 9, 4), (30, 50, 1)):
        x = np.arange(w)[None, :]
        y = np.arange(h)[:, None]
        depth = 900.0 + 4.0 * np.abs(x - w // 2) + 2.0 * y + 150.0 * (x > 3 * w // 4) + rng.normal(0, 1.5, (h, w))
        depth = depth.astype(np.float32)
        valid = rng.random((h, w)) > 0.1
        depth[~valid] = 0.0
        facing = valid & (rng.random((h, w)) > 0.2)
        for sensor in (PROFILES["kinect-v1"], PROFILES["tof"]):
            kw = {"scale_px": r, "min_angle_deg": 10.0, "focal_px": 500.0}
            creases = concave_creases(depth, valid, sensor, **kw)
            want = surface_state(valid, facing, creases)
            np.testing.assert_array_equal(crease_state(depth, valid, facing, sensor, **kw), want)
            inverse = _inverse(depth, valid)
            got = crease_state(depth, valid, facing, sensor, inverse=inverse, **kw)
            np.testing.assert_array_equal(got, want)


def test_sensor_model_holds_python_floats_whatever_it_is_given() -> None:
    # estimate_sensor's least squares come out of a compiled call as numpy float64; the
    # creases' compiled route takes Python numbers only, and numpy promotes a float32 frame
    # by a numpy float64 scalar but not by a Python float
    from depthgram.segmentation.noise_model import SensorModel, estimate_sensor
    from depthgram.sensor import simulate

    m = SensorModel("x", np.float64(1.5), np.float64(2e-6), 3, np.float64(1e-6))
    assert [type(v) for v in (m.step_0, m.step_2, m.sigma_0, m.sigma_2)] == [float] * 4
    assert (m.step_0, m.step_2, m.sigma_0, m.sigma_2) == (1.5, 2e-6, 3.0, 1e-6)
    f = next(iter(simulate("table", 1, size=(176, 132), seed=0))).frame
    est = estimate_sensor(f.depth, f.valid)
    assert all(type(v) is float for v in (est.step_0, est.step_2, est.sigma_0, est.sigma_2))
