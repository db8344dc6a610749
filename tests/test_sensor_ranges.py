"""The sensor estimate's depth ranges from counts (``noise_model._range_estimates_counted``).

Held to the route it replaced (``reference.sensor_ranges``: the samples, their stable order and
the range estimates one by one) to the last bit, on frames that take the counting route (whole
millimetres: ties across range boundaries, a single depth, holes, sparse rows) and on frames that
fall back to the old route (tenths of a millimetre, whole numbers off by a half, zero or huge
depths, spans too wide to count).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthgram.segmentation.noise_model import _range_estimates_counted, _range_fit
from reference import sensor_ranges


def _counted(depth: np.ndarray, valid: np.ndarray, rows: int) -> bool:
    """Whether the frame takes the counting route (not the readable one)."""
    z = depth[::rows][valid[::rows]]
    whole = bool(np.all((z >= 1) & (z < 2**24) & (np.floor(z) == z)))
    lo, hi = (float(z.min()), float(z.max())) if z.size else (0.0, 0.0)
    return whole and hi - lo < 1 << 20 and 0.05 * hi <= 8192


def _same(depth: np.ndarray, valid: np.ndarray, rows: int) -> None:
    want = sensor_ranges(depth, valid, rows)
    got = _range_estimates_counted(depth, valid, rows)
    np.testing.assert_array_equal(got, want)


def _frame(rng: np.random.Generator, h: int, w: int, kind: str) -> tuple[np.ndarray, np.ndarray]:
    # a tilted plane plus noise, with few distinct depths (many ties), optional holes
    yy, xx = np.mgrid[0:h, 0:w]
    base = float(rng.uniform(300, 4000))
    depth = base + float(rng.uniform(-8, 8)) * yy + float(rng.uniform(-3, 3)) * xx
    depth = depth + rng.normal(0, float(rng.choice([0.3, 2.0, 15.0])), (h, w))
    if kind == "coarse":  # few depths: thousands of ties at every range boundary
        depth = np.round(depth / 25.0) * 25.0
    depth = np.clip(np.round(depth), 1, None).astype(np.float32)
    valid = rng.random((h, w)) > float(rng.choice([0.0, 0.1, 0.6]))
    return np.where(valid, depth, np.float32(0)), valid


@pytest.mark.parametrize("seed", range(6))
def test_counted_ranges_equal_the_ordered_route_on_whole_depths(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for t in range(40):
        h = int(rng.integers(1, 60))
        w = int(rng.integers(3, 200))
        depth, valid = _frame(rng, h, w, "coarse" if t % 2 else "fine")
        rows = int(rng.integers(1, 4))
        assert _counted(depth, valid, rows)
        _same(depth, valid, rows)


def test_counted_ranges_single_depth_and_boundaries() -> None:
    # one depth for every pixel: each range boundary splits that depth's pixels in raster order;
    # two depths whose counts straddle several boundaries; sizes around the 200-sample floor
    for h, w in ((1, 202), (1, 203), (2, 103), (10, 100), (50, 170)):
        depth = np.full((h, w), 1234.0, np.float32)
        valid = np.ones((h, w), bool)
        assert _counted(depth, valid, 1)
        _same(depth, valid, 1)
        two = depth.copy()
        two[:, ::3] = 1300.0
        _same(two, valid, 1)
    rng = np.random.default_rng(7)
    depth = (1000.0 + rng.integers(0, 3, (40, 120)) * 40.0 + rng.integers(0, 2, (40, 120))).astype(np.float32)
    _same(depth, np.ones(depth.shape, bool), 1)
    assert sensor_ranges(depth, np.ones(depth.shape, bool), 1)[:, 3].sum() > 1  # ranges with estimates


def test_counted_ranges_fall_back_where_counts_cannot_hold_them() -> None:
    rng = np.random.default_rng(11)
    depth, valid = _frame(rng, 40, 120, "fine")
    tenths = np.where(valid, depth + np.float32(0.1), 0).astype(np.float32)
    halves = np.where(valid, depth + np.float32(0.5), 0).astype(np.float32)  # z - min still whole
    edge = depth.copy()
    edge[:, 0] = np.where(valid[:, 0], edge[:, 0] + np.float32(0.25), 0)  # no sample's own depth
    zero = depth.copy()
    zero[5, 5:9] = 0.0
    far = np.where(valid, depth + np.float32(200_000.0), 0).astype(np.float32)  # tolerances too wide to count
    wide = depth.copy()
    wide[3, 10:13] = 2.0**21
    zero_valid = valid.copy()
    zero_valid[5, 5:9] = True  # readings of 0 taken as valid
    for d, v in ((tenths, valid), (halves, valid), (edge, valid), (zero, zero_valid), (far, valid), (wide, valid)):
        assert not _counted(d, v, 1)
        _same(d, v, 1)


def test_counted_ranges_on_tiny_and_empty_frames() -> None:
    # below 200 samples no range (3 x 68: 198 samples), from 200 on two (3 x 69: 201)
    for h, w in ((1, 3), (2, 3), (5, 4), (3, 68), (3, 69)):
        depth = np.full((h, w), 900.0, np.float32)
        for valid in (np.ones((h, w), bool), np.zeros((h, w), bool)):
            got = _range_estimates_counted(depth, valid, 1)
            assert got.shape == ((2, 4) if valid.all() and h * (w - 2) >= 200 else (0, 4))
            _same(depth, valid, 1)


def _same_fit(frames: list) -> int:
    # the ranges and the fit built on them, at the estimate's own row step; returns how many
    # frames took the counting route
    counted = 0
    for f in frames:
        h, w = f.depth.shape
        rows = max(1, h * (w - 2) // 20_000)
        counted += _counted(f.depth, f.valid, rows)
        _same(f.depth, f.valid, rows)
        fit, _ = _range_fit(f.depth, f.valid, rows)
        want = sensor_ranges(f.depth, f.valid, rows)
        np.testing.assert_array_equal(fit, want[want[:, 3] > 0])
    return counted


def test_counted_ranges_on_the_simulator() -> None:
    from depthgram.sensor import simulate

    frames = [
        next(iter(simulate(scene, 1, size=size, seed=seed))).frame
        for scene in ("table", "corridor", "crossing")
        for size in ((176, 132), (640, 480))
        for seed in (0, 1)
    ]
    assert _same_fit(frames) == len(frames)  # whole millimetres: all counted


def test_counted_ranges_on_the_recordings(shared_data: Path) -> None:
    from depthgram import read

    frames = []
    for name, opts in (
        ("7scenes_redkitchen_seq", {}),
        ("nvlabs_ucn_demo_tabletop", {}),
        ("azure_kinect_tof_mug_single", {}),
        ("osd_samples_uoais/disparity", {}),
        ("open3d_tum_nyu_sun_singles/TUM_depth.png", {"scale_mm": 0.2}),
        ("ycbv_0000_labelled", {"scale_mm": 0.1}),
    ):
        path = shared_data / name
        if path.exists():
            frames.append(next(iter(read(path, **opts))))
    if not frames:
        pytest.skip("no recording found")
    _same_fit(frames)


def test_a_frame_without_readings_gets_the_default_profile() -> None:
    # no sample, so no fit: the ToF profile, as for a frame too narrow for a second difference
    from depthgram.segmentation.noise_model import PROFILES, estimate_sensor

    for shape in ((0, 5), (5, 2), (5, 3), (4, 4), (132, 176)):
        assert estimate_sensor(np.zeros(shape, np.float32), np.zeros(shape, bool)) is PROFILES["tof"]
