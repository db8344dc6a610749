"""Units checked against what a depth camera can see (issue 28, item 4): the right advice per case."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from depthgram.frame import UnitsWarning
from depthgram.sources import read
from depthgram.sources.units import sample_grid


def desk_mm(seed: int = 0) -> np.ndarray:
    """A desk scene in mm, as a Kinect-like camera gives it: desk 520-900 mm, objects, a far wall and room.

    Readings are whole millimetres with sensor noise, so they lie on no grid coarser than 1 mm.
    Median about 630 mm, a far tail to 1.6 m (as YCB-Video's frames: 406-1588 mm).
    """
    rng = np.random.default_rng(seed)
    h, w = 120, 160
    rows = np.arange(h, dtype=np.float64)[:, None]
    d = np.broadcast_to(900.0 - 3.2 * rows, (h, w)).copy()  # the desk, nearer toward the bottom
    d[:25, :] = 1500.0 + rng.uniform(0, 100, (25, w))  # the room beyond the desk
    d[50:80, 40:70] = 560.0  # a box
    d[60:90, 100:120] = 600.0  # a can
    d += rng.normal(0, 1.5, d.shape)
    return np.rint(d)


def room_mm(seed: int = 1) -> np.ndarray:
    """A room in mm: floor 0.8-2.5 m, walls at 2-3 m, median about 1.9 m (as 7-Scenes)."""
    rng = np.random.default_rng(seed)
    h, w = 120, 160
    cols = np.arange(w, dtype=np.float64)[None, :]
    rows = np.arange(h, dtype=np.float64)[:, None]
    d = 2000.0 + 6.0 * cols + 0.0 * rows
    d[70:, :] = np.broadcast_to(2500.0 - 34.0 * (rows[70:] - 70), (50, w))
    d += rng.normal(0, 4.0, d.shape)
    return np.rint(d)


def write(folder: Path, depth: np.ndarray, n: int = 2) -> Path:
    folder.mkdir()
    for i in range(n):
        assert cv2.imwrite(str(folder / f"{i:06d}-depth.png"), depth.astype(np.uint16))
    return folder


def units_warnings(spec: Path | str, **options: object) -> list[str]:
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        list(read(spec, **options))  # type: ignore[arg-type]
    return [str(w.message) for w in rec if issubclass(w.category, UnitsWarning)]


def test_the_synthetic_scenes_are_what_they_claim() -> None:
    d = desk_mm()
    assert 600 < np.median(d) < 720 and np.percentile(d, 95) > 1450
    assert sample_grid(d.astype(np.uint16)) is None
    assert sample_grid((d * 10).astype(np.uint16)) == (10, 0.1)
    assert sample_grid((d * 5).astype(np.uint16)) == (5, 0.2)
    assert sample_grid(np.full(100, 1000, np.uint16)) is None  # a flat frame is on every grid: says nothing
    r = room_mm()
    assert 1700 < np.median(r) < 2300 and np.percentile(r, 5) > 800


def test_tenth_mm_frames_read_as_mm_warn_scale_0_1(tmp_path: Path) -> None:
    # a median of 6.3 m: under the old 8 m threshold, but a far tail no camera reads
    folder = write(tmp_path / "ycb", desk_mm() * 10)
    msgs = units_warnings(folder)
    assert len(msgs) == 1
    assert "beyond 1" in msgs[0] and "try --scale 0.1 (every sample is a multiple of 10" in msgs[0]
    assert "0.2" not in msgs[0]
    assert units_warnings(folder, scale_mm=0.1) == []


def test_mm_frames_read_with_scale_0_1_warn_drop_it(tmp_path: Path) -> None:
    folder = write(tmp_path / "room", room_mm())
    assert units_warnings(folder) == []
    msgs = units_warnings(folder, scale_mm=0.1)
    assert len(msgs) == 1 and "nearer than depth cameras read" in msgs[0]
    assert "try dropping --scale 0.1" in msgs[0]


def test_mm_frames_read_with_scale_1000_warn_drop_it_not_0_2(tmp_path: Path) -> None:
    folder = write(tmp_path / "room", room_mm())
    msgs = units_warnings(folder, scale_mm=1000.0)
    assert len(msgs) == 1 and "beyond 8 m" in msgs[0]
    assert "try dropping --scale 1000" in msgs[0] and "--scale 0.2" not in msgs[0]


def test_plausible_scenes_do_not_warn(tmp_path: Path) -> None:
    assert units_warnings(write(tmp_path / "desk", desk_mm())) == []
    # the same desk in TUM's units, read with its scale; and in metres as floats
    assert units_warnings(write(tmp_path / "tum", desk_mm() * 5), scale_mm=0.2) == []
    metres = tmp_path / "m.npy"
    np.save(metres, (room_mm() / 1000.0).astype(np.float32))
    assert units_warnings(metres) == []


def test_a_close_range_scene_without_another_reading_does_not_warn(tmp_path: Path) -> None:
    # a mug 15 cm from a close-range camera, in mm: nothing else reads it better, so nothing is said
    d = np.full((60, 80), 160.0)
    d[20:40, 30:50] = 120.0
    d += np.random.default_rng(2).normal(0, 0.5, d.shape)
    assert units_warnings(write(tmp_path / "close", np.rint(d))) == []


@pytest.mark.parametrize(
    ("folder", "options", "advice"),
    [
        ("ycbv_0000_labelled/*-depth.png", {}, "try --scale 0.1"),
        ("ycbv_0001_0002_labelled/0001", {}, "try --scale 0.1"),
        ("7scenes_redkitchen_seq", {"scale_mm": 0.1}, "try dropping --scale 0.1"),
        ("7scenes_redkitchen_seq", {"scale_mm": 1000.0}, "try dropping --scale 1000"),
        ("nvlabs_ucn_demo_tabletop", {"scale_mm": 0.1}, "try dropping --scale 0.1"),
    ],
)
def test_real_recordings_in_wrong_units_get_the_right_advice(
    shared_data: Path, folder: str, options: dict[str, object], advice: str
) -> None:
    msgs = units_warnings(str(shared_data / folder), **options)
    assert len(msgs) == 1 and advice in msgs[0] and msgs[0].count("--scale") == 1


@pytest.mark.parametrize(
    ("folder", "options"),
    [
        ("ycbv_0000_labelled/*-depth.png", {"scale_mm": 0.1}),
        ("ycbv_0001_0002_labelled/0002", {"scale_mm": 0.1}),
        ("7scenes_redkitchen_seq", {}),
        ("nvlabs_ucn_demo_tabletop", {}),
        ("azure_kinect_tof_mug_single/depth.png", {}),
        ("open3d_tum_nyu_sun_singles/TUM_depth.png", {"scale_mm": 0.2}),
    ],
)
def test_real_recordings_in_their_units_do_not_warn(shared_data: Path, folder: str, options: dict[str, object]) -> None:
    assert units_warnings(str(shared_data / folder), **options) == []
