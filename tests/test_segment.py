"""Segmentation on synthetic scenes with known truth (paper, section 3)."""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.frame import Intrinsics
from depthgram.segmentation import SegmentConfig, evaluate, region_grow, segment
from depthgram.segmentation.histogram import bin_index, depth_bands

CAM = Intrinsics(fx=140.0, fy=140.0, cx=87.5, cy=65.5)


def fronto_scene(noise_mm: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two rectangles facing the sensor before a far wall, 176 x 132."""
    z = np.full((132, 176), 3000.0, np.float32)
    truth = np.full((132, 176), 3, np.int32)
    z[20:60, 20:70] = 1000.0
    truth[20:60, 20:70] = 1
    z[40:100, 100:150] = 1800.0
    truth[40:100, 100:150] = 2
    if noise_mm:
        z += np.random.default_rng(seed).normal(0, noise_mm, z.shape).astype(np.float32)
    return z, truth


def floor_scene(
    boxes: tuple[tuple[float, float, float, float], ...] = ((-400, 1500, 300, 400), (250, 2200, 350, 500)),
    height_mm: float = 800.0,
    far_mm: float = 6000.0,
    noise_rel: float = 0.0,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """A floor seen by a camera ``height_mm`` above it, boxes standing on it, a far wall.

    Each box is (x_left mm, depth mm, width mm, height mm), its face toward the sensor. Truth:
    1 = floor, 2 = wall, 3.. = boxes in order.
    """
    h, w = 132, 176
    v = np.arange(h, dtype=np.float64)[:, None] - CAM.cy
    u = np.arange(w, dtype=np.float64)[None, :] - CAM.cx
    z = np.full((h, w), far_mm)
    truth = np.full((h, w), 2, np.int32)
    with np.errstate(divide="ignore"):
        zf = np.where(v > 0, height_mm * CAM.fy / np.where(v > 0, v, 1), np.inf)
    floor = zf < far_mm
    z = np.where(floor, zf, z) * np.ones((1, w))
    truth[np.broadcast_to(floor, (h, w))] = 1
    for i, (x0, zb, bw, bh) in enumerate(boxes):
        rows = (v >= CAM.fy * (height_mm - bh) / zb) & (v <= CAM.fy * height_mm / zb)
        cols = (u >= CAM.fx * x0 / zb) & (u <= CAM.fx * (x0 + bw) / zb)
        m = rows & cols & (zb < z)
        z[m] = zb
        truth[m] = 3 + i
    if noise_rel:
        z = z * (1 + np.random.default_rng(seed).normal(0, noise_rel, z.shape))
    return z.astype(np.float32), truth


def test_fronto_parallel_objects_and_their_attributes() -> None:
    z, truth = fronto_scene()
    seg = segment(z, method="threshold", intrinsics=CAM)
    ev = evaluate(seg.labels, truth)
    assert ev.correct == 3 and ev.area > 0.99 and ev.precision == 1.0
    near = min(seg.objects, key=lambda o: o.depth)
    assert near.depth_label == 0 and near.kind == "object"
    assert near.area == 40 * 50 and near.area_fraction == pytest.approx(2000 / z.size)
    assert near.depth == pytest.approx(1000.0) and near.depth_std == pytest.approx(0.0, abs=1e-6)
    assert near.center_xy == pytest.approx((44.5, 39.5))
    assert near.bbox_xy == (20, 20, 70, 60)  # half-open
    assert (seg.labels[near.slice] == near.id).all() and seg.labels[near.slice].shape == (40, 50)
    # pinhole back-projection: X = (u - cx) Z / fx; area per pixel (Z / f)^2
    assert near.centroid_mm == pytest.approx(((44.5 - 87.5) * 1000 / 140, (39.5 - 65.5) * 1000 / 140, 1000.0))
    assert near.area_mm2 == pytest.approx(2000 * (1000 / 140) ** 2)
    assert [o.depth_label for o in sorted(seg.objects, key=lambda o: o.depth)] == [0, 1, 2]
    assert seg.labels.dtype == np.int32 and set(np.unique(seg.labels)) == {1, 2, 3}


def test_histogram_cuts_follow_the_10_percent_rule_both_readings() -> None:
    # 10 mm bins from 1005 mm: the near object fills bins 0..9 (peak bin 2), the far one 30..39
    shape = [5, 20, 60, 20, 5, 1, 1, 1, 1, 1]
    z = np.concatenate([np.repeat(1005.0 + 10 * np.arange(10), shape), np.repeat(1305.0 + 10 * np.arange(10), shape)])
    img = z.reshape(1, -1).astype(np.float32)
    ok = np.ones_like(img, bool)
    # peak bin 2 -> following minimum bin 10 (first empty bin); peak bin 32 -> end of histogram (39).
    # cut = peak + t (minimum - peak), t = 0.9 ("minimum" reading) or 0.1 ("peak" reading); the leading
    # cut of the second band sits t of the way back from peak 32 to minimum 10. Bands keep whole bins.
    expected = {
        # first band's leading cut: t of the way back from peak 2 to bin 0
        "minimum": ([1005 + 10 * 1, 1005 + 10 * 13], [1005 + 10 * 10, 1005 + 10 * 39]),  # 0.2, 9.2, 12.2, 38.3
        "peak": ([1005 + 10 * 2, 1005 + 10 * 30], [1005 + 10 * 3, 1005 + 10 * 33]),  # 1.8, 2.8, 29.8, 32.7
    }
    for cut_from, (lower, upper) in expected.items():
        cfg = SegmentConfig(bin_mm=10.0, smooth_bins=0.0, min_prominence=0.05, cut_from=cut_from)
        bins, edges, counts = bin_index(img, ok, cfg)
        assert counts.sum() == img.size and bins.min() == 0
        bands = depth_bands(counts, edges, cfg)
        assert bands.histogram.peaks.tolist() == pytest.approx([1030.0, 1330.0])
        assert bands.lower.tolist() == pytest.approx(lower)
        assert bands.upper.tolist() == pytest.approx(upper)
        assert bands.depth_label(np.array([1000.0, 1200.0, 1400.0])).tolist() == [0, 1, 2]


def test_sieve_of_holes_keeps_one_object_and_a_gap_keeps_two() -> None:
    z, truth = fronto_scene()
    ok = np.zeros(z.shape, bool)
    ok[::2, ::2] = True  # registered structured light: three quarters missing in a grid
    seg = segment(z, valid=ok, method="threshold", fill_holes_px=1)
    assert len(seg.objects) == 3
    assert np.all(seg.labels[~ok] == 0)
    ev = evaluate(seg.labels, truth, valid=ok)
    assert ev.correct == 3 and ev.area == pytest.approx(1.0)
    # without bridging the sieve falls apart into single pixels, all below min_area
    assert len(segment(z, valid=ok, method="threshold", fill_holes_px=0).objects) == 0
    # two objects at the same depth separated by 4 invalid columns stay two with bridging 2
    z2 = np.full((60, 80), 2000.0, np.float32)
    ok2 = np.ones(z2.shape, bool)
    z2[10:50, 10:70] = 1000.0
    ok2[10:50, 38:42] = False
    seg2 = segment(z2, valid=ok2, method="threshold", fill_holes_px=2, min_area_px=50)
    near = [o for o in seg2.objects if o.depth < 1500]
    assert len(near) == 2 and {o.area for o in near} == {40 * 28, 40 * 28}


def test_invalid_pixels_and_nan_are_background() -> None:
    z, _ = fronto_scene()
    z[0:10, :] = np.nan
    z[10:20, :] = 0
    seg = segment(z, method="threshold")
    assert np.all(seg.labels[:20] == 0)
    empty = segment(np.zeros((10, 12), np.float32))
    assert empty.objects == () and empty.labels.shape == (10, 12) and not empty.labels.any()


def test_clear_errors_for_bad_input() -> None:
    with pytest.raises(InputError, match="2-D"):
        segment(np.zeros((4, 4, 3)))
    with pytest.raises(InputError, match="dtype"):
        segment(np.zeros((4, 4), bool))
    with pytest.raises(InputError, match="shape"):
        segment(np.ones((4, 4)), valid=np.ones((4, 5), bool))
    with pytest.raises(InputError, match="fraction"):
        SegmentConfig(fraction=0.9)
    with pytest.raises(InputError, match="method"):
        SegmentConfig(method="kmeans")
    with pytest.raises(InputError, match="unknown"):
        segment(np.ones((4, 4)), colour="red")
    with pytest.raises(InputError, match="bin_mm"):
        SegmentConfig(bin_mm=-1)


def test_slicing_agrees_with_the_global_histogram_for_facing_objects() -> None:
    z, _ = fronto_scene(noise_mm=8.0)
    a = segment(z, method="threshold")
    b = segment(z, method="slices")
    np.testing.assert_array_equal(a.labels, b.labels)
    assert [(o.depth, o.area, o.kind) for o in a.objects] == [(o.depth, o.area, o.kind) for o in b.objects]


@pytest.mark.parametrize("noise_rel", [0.0, 0.01])
def test_boxes_on_the_floor_come_out_separate_from_it(noise_rel: float) -> None:
    z, truth = floor_scene(noise_rel=noise_rel)
    seg = segment(z, intrinsics=CAM)
    ev = evaluate(seg.labels, truth)
    for box in (3, 4):
        s = ev.score(box)
        assert s.iou > 0.8 and s.precision > 0.9, s
    floor = ev.score(1)
    assert floor.iou > 0.85
    fl = seg.by_id()[floor.detected]
    assert fl.kind == "floor" and len(fl.parts) >= 5
    # horizontal slices of a floor: depth grows slice by slice, labels never go down
    depths = [p.depth for p in fl.parts]
    assert depths == sorted(depths)
    labels = [p.depth_label for p in fl.parts]
    assert labels == sorted(labels) and labels[-1] > labels[0]
    assert fl.depth_label == labels[0]
    # the global histogram alone merges the boxes with the floor rows at their depth
    plain = evaluate(segment(z, method="threshold", intrinsics=CAM).labels, truth)
    assert min(plain.score(3).precision, plain.score(4).precision) < 0.9


def test_region_growing_reference() -> None:
    z, truth = fronto_scene(noise_mm=5.0)
    seg = region_grow(z, region_tol_mm=30.0, region_relative=False, min_area_px=50)
    assert seg.method == "region"
    assert evaluate(seg.labels, truth).correct == 3
    # a gentle ramp is one region (steps 5 mm < tol), a 100 mm step splits it
    ramp = np.tile(1000 + 5.0 * np.arange(100, dtype=np.float32), (30, 1))
    assert len(region_grow(ramp, region_tol_mm=10.0, region_relative=False, min_area_px=1).objects) == 1
    ramp[:, 50:] += 100
    assert len(region_grow(ramp, region_tol_mm=10.0, region_relative=False, min_area_px=1).objects) == 2
    assert segment(ramp, method="region", region_tol_mm=10, region_relative=False, min_area_px=1).method == "region"


def test_gap_pixels_between_bands_are_background_only_on_request() -> None:
    # two flat objects whose depth spreads overlap thinly: a few pixels fall between the bands
    z = np.full((40, 60), 1000.0, np.float32)
    z[:, 30:] = 1400.0
    # a seam at 1025 mm: 10 mm bins from 1000, peak 0 at bin 0, following minimum bin 1 (first
    # empty), band 0 ends at 0 + 0.9 * 1 -> bin 0, band 1 starts at 40 - 0.9 * 39 = 4.9 -> bin 5:
    # bins 1..4 are the gap
    z[:, 28:30] = 1025.0
    keep = segment(z, method="threshold", min_area_px=1, smooth_bins=0.0, min_prominence=0.05)
    drop = segment(z, method="threshold", min_area_px=1, smooth_bins=0.0, min_prominence=0.05, gap_pixels="background")
    assert not drop.labels[:, 28:30].any() and drop.labels[:, :28].all() and drop.labels[:, 30:].all()
    assert keep.labels[:, 28:30].all()
    assert drop.bands_mm is not None
    lower, upper = drop.bands_mm.T
    assert upper[0] < 1025 < lower[1]


def test_segmentation_carries_typed_fields_per_method() -> None:
    # Segmentation.extras was an untyped dict; its entries are now fields.
    z, _ = floor_scene()
    for method in ("threshold", "slices", "paper"):
        seg = segment(z, method=method, intrinsics=CAM)
        assert seg.bands_mm is not None and seg.bands_mm.ndim == 2 and seg.bands_mm.shape[1] == 2
        lower, upper = seg.bands_mm.T
        assert (lower <= upper).all() and (upper[:-1] <= lower[1:]).all()  # nearest first, disjoint
        for o in seg.objects:
            if o.kind == "object":  # a facing object lies in the band its depth label names
                assert lower[o.depth_label] <= o.depth <= upper[o.depth_label], (method, o)
    slices = segment(z, method="slices", intrinsics=CAM)
    assert slices.classes is not None and slices.classes.shape == z.shape
    assert set(np.unique(slices.classes).tolist()) <= {0, 1, 2} and (slices.classes == 1).any()  # the floor
    paper = segment(z, method="paper", intrinsics=CAM)
    assert paper.aperture_px is not None and set(paper.aperture_px) == {"rows", "columns"}
    region = segment(z, method="region", intrinsics=CAM)
    assert region.bands_mm is None and region.classes is None and region.aperture_px is None


def test_depth_dependent_bins_widen_with_depth() -> None:
    cfg = SegmentConfig(bin_mm=10.0, depth_dependent_bins=True, ref_depth_mm=1000.0)
    z = np.array([[500.0, 1000.0, 4000.0]], np.float32)
    _, edges, _ = bin_index(z, np.ones(z.shape, bool), cfg)
    widths = np.diff(edges)
    # geometric edges: width proportional to depth, 10 mm at 1 m
    near, far = widths[0], widths[-1]
    assert near == pytest.approx(5.0, rel=0.02) and far == pytest.approx(40.0, rel=0.02)


def test_overrides_are_checked_every_time_even_when_cached() -> None:
    from depthgram.segmentation.config import SegmentConfig

    cfg = SegmentConfig()
    first = cfg.with_overrides(method="threshold", fill_holes_px=3)
    assert first is cfg.with_overrides(fill_holes_px=3, method="threshold")  # cached, order-free
    assert first.method == "threshold" and first.fill_holes_px == 3 and cfg.method == "surfaces"
    # 3.0 == 3 and hashes alike, but only an integer is a pixel count
    with pytest.raises(InputError, match="fill_holes_px"):
        cfg.with_overrides(fill_holes_px=3.0)
    with pytest.raises(InputError, match="unknown option"):
        cfg.with_overrides(bogus=1)
    with pytest.raises(InputError, match="min_area"):
        cfg.with_overrides(min_area=[1])  # unhashable: not cached, still checked


def test_min_area_is_two_explicit_limits_and_the_old_spelling_still_works() -> None:
    from depthgram.segmentation.config import SegmentConfig

    cfg = SegmentConfig(min_area_fraction=0.01, min_area_px=500)
    assert cfg.min_pixels(100 * 100) == 500 and cfg.min_pixels(1000 * 1000) == 10_000
    with pytest.warns(DeprecationWarning, match="min_area_px"):
        old = SegmentConfig(min_area=50)
    assert old.min_pixels(1000 * 1000) == 50
    with pytest.warns(DeprecationWarning):
        assert SegmentConfig(min_area=0.01).min_pixels(100 * 100) == 100
    with pytest.raises(InputError, match="min_area_px"):
        SegmentConfig(min_area_px=0)


def test_new_object_is_the_dataclasss_own_object() -> None:
    import copy
    import dataclasses
    import pickle

    from depthgram.segmentation.objects import SceneObject, new_object

    part = SceneObject(9, "part", 2, 1200.0, 3.5, 40, 0.01, (3.0, 4.0), (1, 2, 5, 6))
    values = (3, "compound", 1, 1234.5, 7.25, 812, 0.035, (51.5, 60.25), (10, 20, 90, 100))
    metric = ((-12.5, 40.0, 1234.5), 5.5e5, (part,))
    for extra in ((None, None), metric):
        got = new_object(*values, *extra)
        want = SceneObject(*values, *extra)
        # the same fields in the same order, so equality, hash, repr and pickling agree
        assert list(vars(got).items()) == list(vars(want).items())
        assert [f.name for f in dataclasses.fields(SceneObject)] == list(vars(got))
        assert got == want and hash(got) == hash(want) and repr(got) == repr(want)
        assert pickle.loads(pickle.dumps(got)) == want and copy.deepcopy(got) == want
        assert dataclasses.replace(got, id=4) == dataclasses.replace(want, id=4)
        with pytest.raises(dataclasses.FrozenInstanceError):
            got.id = 5  # type: ignore[misc]
