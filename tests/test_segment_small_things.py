"""A thing smaller than ``min_area`` on its facing side alone, judged with its foot (issue 28, item 5)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthgram.frame import Intrinsics
from depthgram.segmentation import evaluate, segment
from depthgram.segmentation.label import ACTIVE, BLOCK, HOLE
from depthgram.segmentation.label.stats import COUNT
from depthgram.segmentation.surfaces import surfaces_kept

JOIN = {"tol_0": 4.0, "tol_2": 0.0, "slope_per_px": 0.002}


def test_a_small_piece_no_surface_takes_back_is_kept_for_its_support_to_judge() -> None:
    h, w = 40, 80
    depth = np.full((h, w), 1000.0, np.float32)
    state = np.full((h, w), HOLE, np.int8)
    # a large surface, a crease column and, past it, a small piece continuing the surface
    state[:, :40] = ACTIVE
    state[:10, 40] = BLOCK
    state[:10, 41:45] = ACTIVE
    # an isolated small piece (a marker on a table whose readings around it are the table's),
    # ringed by its own crease band, as the concave creases along its base mark it
    depth[29:39, 59:69] = 1500.0
    state[29:39, 59:69] = BLOCK
    state[30:38, 60:68] = ACTIVE
    # a speck under the seed size
    depth[2:4, 70:72] = 2000.0
    state[2:4, 70:72] = ACTIVE
    facing = state != HOLE
    kept = {"bridge_px": 0, "min_px": 100, "max_px": 5, "seed_px": 20}
    labels, n, sums, _ = surfaces_kept(depth, state, facing, band_px=2, **kept, **JOIN)
    assert n == 2
    # the attached piece and the crease joined the large surface, as without a seed size
    assert np.all(labels[:10, 40:45] == labels[0, 0])
    # the piece is kept, and takes back the band_px steps of its crease band (corners: 2)
    assert np.all(labels[29:39, 59:69] == 2) and sums[2, COUNT] == 100
    # with the base span (no band given back) it is kept as it was cut
    labels, n, sums, _ = surfaces_kept(depth, state, facing, **kept, **JOIN)
    assert n == 2 and sums[2, COUNT] == 64 and not np.any(labels[29, 59:69])
    assert np.all(labels[2:4, 70:72] == 0)
    # without a seed size the small piece is dropped
    labels, n, _, _ = surfaces_kept(depth, state, facing, bridge_px=0, min_px=100, max_px=5, **JOIN)
    assert n == 1 and np.all(labels[29:39, 59:69] == 0)


def _marker_on_a_table(
    radius_mm: float, tilt_deg: float, seed: int, size: tuple[int, int] = (320, 240), focal_px: float = 300.0
) -> tuple[np.ndarray, np.ndarray, Intrinsics]:
    """A cylinder (a marker) lying across the view on a table 700 mm ahead, camera tilted down.

    Ray-cast at ``size`` px, 0.5 mm noise. Returns depth (mm), truth (1 the marker) and the intrinsics.
    """
    w, h = size
    cx, cy = (w - 1) / 2, (h - 1) / 2
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    ray = np.stack([(u - cx) / focal_px, (v - cy) / focal_px, np.ones((h, w))], -1)
    tilt = np.radians(tilt_deg)
    down = np.array([0.0, np.cos(tilt), np.sin(tilt)])
    to_table = np.where(ray @ down > 1e-6, 700.0 * np.sin(tilt) / np.maximum(ray @ down, 1e-9), np.inf)
    axis = np.array([0.0, 0.0, 700.0]) - radius_mm * down  # its axis runs along the camera's x
    dy, dz = ray[..., 1], ray[..., 2]
    a = dy**2 + dz**2
    b = -2.0 * (dy * axis[1] + dz * axis[2])
    c = axis[1] ** 2 + axis[2] ** 2 - radius_mm**2
    disc = b**2 - 4.0 * a * c
    to_marker = np.where(disc > 0, (-b - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * a), np.inf)
    to_marker = np.where(np.abs(to_marker * ray[..., 0]) <= 60.0, to_marker, np.inf)
    hit = to_marker < to_table
    depth = np.where(hit, to_marker, to_table) * dz
    depth += np.random.default_rng(seed).normal(0.0, 0.5, depth.shape)
    return depth.astype(np.float32), hit.astype(np.int32), Intrinsics(focal_px, focal_px, cx, cy)


@pytest.mark.parametrize("tilt_deg", [35.0, 45.0])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_marker_lying_on_a_table_is_an_object_with_or_without_intrinsics(tilt_deg: float, seed: int) -> None:
    # 364 px, 1.6 times min_area (231 px at 320 x 240); the orientation field gives its lower
    # rim and its top to the table, and its facing piece alone is under min_area: without
    # being judged with its foot it was lost (IoU 0.002)
    depth, truth, cam = _marker_on_a_table(8.0, tilt_deg, seed)
    for intrinsics in (cam, None):
        seg = segment(depth, intrinsics=intrinsics)
        score = evaluate(seg.labels, truth, valid=depth > 0, truth_ids=[1]).score(1)
        assert score.iou >= 0.8
        assert score.precision >= 0.99


def test_a_small_plate_floating_before_a_wall_with_no_support_is_dropped() -> None:
    # a piece under min_area with no support beneath to give it a foot stays no object
    depth = np.full((240, 320), 2000.0, np.float32)
    depth[100:112, 150:162] = 1500.0  # 144 px, between the seed size (57) and min_area (231)
    depth += np.random.default_rng(0).normal(0.0, 0.5, depth.shape).astype(np.float32)
    seg = segment(depth, intrinsics=Intrinsics(300.0, 300.0, 159.5, 119.5))
    assert not np.any(seg.labels[102:110, 152:160])
    assert all(o.area > 231 for o in seg.objects)


def test_a_cup_on_a_table_keeps_its_piece_with_a_structured_light_cameras_crease_span(shared_data: Path) -> None:
    # 7-Scenes frames 1 and 2 (Kinect v1): a cup on the table, 1.62-1.66 m before a table at
    # 1.69 m, about 1.2 k px. At the sensor's span (5 grid px) the crease band along its base
    # left its piece at 224 grid px, under min_area (231): it was lost. Given back the band's
    # extra width (3 steps over the base span's 2 px) it is judged at its size and kept
    from depthgram import read

    folder = shared_data / "7scenes_redkitchen_seq"
    if not folder.is_dir():
        pytest.skip("7scenes_redkitchen_seq not found under ../shared/data")
    for i, frame in enumerate(read(folder)):
        if i == 0:
            continue
        if i > 2:
            break
        seg = segment(frame, crease_span_fraction=0.0)
        cups = [o for o in seg.objects if abs(o.center_xy[0] - 399) < 15 and abs(o.center_xy[1] - 176) < 15]
        assert len(cups) == 1 and 1000 <= cups[0].area <= 1500, [(o.area, o.center_xy) for o in cups]
