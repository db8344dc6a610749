"""Wide frames segmented on a grid of their pixels (``work_width_px``), then refined per pixel:
boundaries at full resolution, attributes measured on the full label map, and the same accuracy
as segmenting every pixel on scenes with exact truth."""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.segmentation import SegmentConfig, evaluate, segment
from depthgram.segmentation.attributes import label_stats, make_objects
from depthgram.segmentation.coarse import grid_frame, grid_step, refine_labels
from depthgram.segmentation.orientation import default_intrinsics, upsample_classes


def test_grid_step_brings_the_width_under_the_work_width() -> None:
    assert [grid_step(w, 320) for w in (176, 320, 321, 640, 960, 1280, 1920)] == [1, 1, 2, 2, 3, 4, 6]
    assert grid_step(1280, 0) == 1
    with pytest.raises(InputError, match="work_width_px"):
        SegmentConfig(work_width_px=-1)


def test_the_grid_is_a_pinhole_camera_of_the_same_rays() -> None:
    depth = np.arange(48 * 64, dtype=np.float32).reshape(48, 64) + 500
    cam = default_intrinsics(depth.shape)
    gd, gok, gcam = grid_frame(depth, depth > 0, cam, 4)  # every pixel has a reading
    assert gd.shape == (12, 16) and gd[3, 5] == depth[12, 20] and gok.all()
    # sample (i, j) is pixel (4 i, 4 j): the same ray in both cameras
    assert (20 - cam.cx) / cam.fx == pytest.approx((5 - gcam.cx) / gcam.fx)
    assert (12 - cam.cy) / cam.fy == pytest.approx((3 - gcam.cy) / gcam.fy)


def _two_surfaces(step: int) -> tuple[np.ndarray, np.ndarray]:
    """A box at 800 mm in front of a wall at 1500 mm, its edges off the grid; a 1 px wire."""
    h, w = 60, 80
    depth = np.full((h, w), 1500.0, np.float32)
    truth = np.ones((h, w), np.int32)
    depth[13:38, 23:47] = 800.0  # rows 13..37, columns 23..46: no edge on a multiple of step
    truth[13:38, 23:47] = 2
    depth[:, 61] = 600.0  # a wire thinner than the grid step, between two grid columns
    truth[:, 61] = 0
    assert 61 % step and 13 % step and 23 % step
    return depth, truth


@pytest.mark.parametrize("step", [2, 3, 4])
def test_refined_labels_put_the_edges_where_the_depth_jumps(step: int) -> None:
    depth, truth = _two_surfaces(step)
    grid = np.ascontiguousarray(truth[::step, ::step])
    gd = np.ascontiguousarray(depth[::step, ::step])
    labels, sums, boxes = refine_labels(grid, gd, depth, depth > 0, step, tol_0=0.0, tol_2=4e-6, slope_per_px=0.002)
    # every pixel of both surfaces has its own label, found at full resolution; the wire,
    # which no grid sample saw, joins neither (it is on no sampled surface)
    assert np.array_equal(labels, truth)
    # the statistics gathered in the same pass are those of the new map
    want = label_stats(labels, depth, 2, metric=True)
    np.testing.assert_allclose(sums[:, 0], want.count)
    np.testing.assert_allclose(sums[:, 1], want.sz)
    np.testing.assert_allclose(sums[:, 3], want.sx)
    np.testing.assert_allclose(sums[:, 6], want.syz)
    assert boxes[2].tolist() == [23, 13, 46, 37]


@pytest.mark.parametrize(("step", "h", "w"), [(2, 48, 64), (2, 47, 63), (3, 50, 61), (4, 37, 90)])
def test_refined_labels_and_sums_are_those_of_the_pixel_by_pixel_kernel(step: int, h: int, w: int) -> None:
    from depthgram.segmentation.coarse import _refine
    from reference import refine_per_pixel

    rng = np.random.default_rng(step * 1000 + h)
    # patches of a few labels on surfaces of a few depths, with equal depths (ties between
    # samples of two labels), holes, and grid samples left out
    depth = rng.choice(np.array([800.0, 803.0, 806.0, 1500.0, 1510.0], np.float32), size=(h, w))
    depth = (depth + rng.integers(0, 3, size=(h, w))).astype(np.float32)
    valid = rng.random((h, w)) > 0.1
    depth[~valid] = 0.0
    gd, gok, _ = grid_frame(depth, valid, default_intrinsics((h, w)), step)
    grid = np.where(gok, rng.integers(1, 5, size=gok.shape), 0).astype(np.int32)
    grid[rng.random(grid.shape) < 0.1] = 0
    args = (grid, gd, depth, valid, step, np.float32(2.0), np.float32(2e-6), np.float32(0.004), int(grid.max()))
    grid_classes = rng.integers(0, 3, size=grid.shape).astype(np.int8)
    want = refine_per_pixel(*args)
    got = _refine(*args, grid_classes)
    assert np.array_equal(got[0], want[0])
    assert np.array_equal(got[1], want[1])  # the same sums to the last bit (the same additions)
    assert np.array_equal(got[2], want[2])
    assert len(np.unique(got[0])) > 3  # the case is not trivial
    # the classes repeated in the same pass are upsample_classes' map
    assert np.array_equal(got[3], upsample_classes(grid_classes, valid, step))


def test_pixels_without_a_reading_or_off_every_sampled_surface_get_no_label() -> None:
    depth, truth = _two_surfaces(2)
    valid = depth > 0
    valid[20, 30] = False
    grid = np.ascontiguousarray(truth[::2, ::2])
    gd = np.ascontiguousarray(depth[::2, ::2])
    grid[8:11, 13:16] = 0  # grid samples the segmentation left out (too small, say)
    labels, _, _ = refine_labels(grid, gd, depth, valid, 2, tol_0=0.0, tol_2=4e-6, slope_per_px=0.002)
    assert labels[20, 30] == 0
    assert labels[18, 28] == 0  # all four samples around it left out
    assert labels[16, 30] == 2  # a left-out sample's pixel still takes its surface from the others


def test_a_grid_sample_without_a_reading_is_taken_from_its_own_cell() -> None:
    # structured light's interleaved holes: every even column of a row has no reading
    depth = np.full((40, 60), 1200.0, np.float32)
    valid = np.ones(depth.shape, np.bool_)
    valid[22, ::2] = False
    cam = default_intrinsics(depth.shape)
    gd, gok, _ = grid_frame(np.where(valid, depth, 0), valid, cam, 2)
    assert gok.all() and np.all(gd == 1200.0)
    valid[22:24, 10:12] = False  # a whole cell without a reading stays a hole
    gd, gok, _ = grid_frame(np.where(valid, depth, 0), valid, cam, 2)
    assert not gok[11, 5] and gok.sum() == gok.size - 1


@pytest.mark.parametrize(("step", "h", "w"), [(2, 40, 60), (2, 41, 59), (3, 31, 50), (4, 30, 45)])
def test_grid_samples_are_each_cells_first_reading(step: int, h: int, w: int) -> None:
    from reference import grid_first_reading

    rng = np.random.default_rng(h * w)
    depth = (rng.random((h, w)) * 3000 + 500).astype(np.float32)
    valid = rng.random((h, w)) > 0.6  # many cells without a reading at their corner
    valid[: step * 3] = rng.random((step * 3, w)) > 0.99  # and rows of cells without any
    depth[~valid] = 0.0
    gd, gok, _ = grid_frame(depth, valid, default_intrinsics((h, w)), step)
    want_z, want_ok = grid_first_reading(depth, valid, step)
    assert np.array_equal(gok, want_ok) and np.array_equal(gd, want_z)
    assert 0 < gok.sum() < gok.size and not valid[::step, ::step].all()  # both kinds of cell occur


def test_the_default_on_a_wide_frame_matches_every_pixel_on_the_truth() -> None:
    from depthgram.sensor import simulate

    for scene in ("table", "touching", "ball_wall"):
        sf = next(iter(simulate(scene, 1, size=(640, 480), seed=0, sensor="sl")))
        f = sf.frame
        truth = np.where(f.valid, sf.instances, 0)
        grid = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics)
        full = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics, work_width_px=0)
        eg, ef = evaluate(grid.labels, truth), evaluate(full.labels, truth)
        assert eg.area_assigned >= ef.area_assigned - 0.01, (scene, eg.area_assigned, ef.area_assigned)
        assert eg.precision_assigned >= ef.precision_assigned - 0.01, scene
        assert eg.found_share >= ef.found_share, scene
        assert grid.classes is not None and grid.classes.shape == f.depth.shape


def test_attributes_are_measured_on_the_full_label_map() -> None:
    from depthgram.sensor import simulate

    f = next(iter(simulate("table", 1, size=(640, 480), seed=0))).frame
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics)
    n = max(o.id for o in seg.objects)
    again = {
        o.id: o
        for o in make_objects(seg.labels, label_stats(seg.labels, f.depth, n, metric=True), intrinsics=f.intrinsics)
    }
    assert seg.objects and all(o.area > 0 for o in seg.objects)
    for o in seg.objects:
        a = again[o.id]
        assert (o.area, o.bbox_xy) == (a.area, a.bbox_xy)
        assert o.center_xy == pytest.approx(a.center_xy) and o.depth == pytest.approx(a.depth)
        assert o.centroid_mm == pytest.approx(a.centroid_mm) and o.area_mm2 == pytest.approx(a.area_mm2)
        assert np.all(seg.labels[o.slice][seg.labels[o.slice] > 0] >= 1)
        for p in o.parts:  # slice parts are scaled from the grid: inside the frame and their object's box
            x0, y0, x1, y1 = p.bbox_xy
            assert 0 <= x0 < x1 <= 640 and 0 <= y0 < y1 <= 480
