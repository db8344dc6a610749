"""Frames read decimated (``listen --decimate``): the same frames as decimating the whole ones."""

from __future__ import annotations

import itertools
from pathlib import Path

import cv2
import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.frame import Frame
from depthgram.sources import open_source
from depthgram.sources.base import decimated


def _same(a: Frame, b: Frame) -> bool:
    return (
        np.array_equal(a.depth, b.depth)
        and np.array_equal(a.valid, b.valid)
        and a.depth.dtype == b.depth.dtype
        and a.depth.flags.c_contiguous
        and b.depth.flags.c_contiguous
        and (a.index, a.time_s, a.name, a.intrinsics, a.intrinsics_source, a.meta, a.gravity)
        == (b.index, b.time_s, b.name, b.intrinsics, b.intrinsics_source, b.meta, b.gravity)
    )


@pytest.fixture
def pngs(tmp_path: Path) -> Path:
    rng = np.random.default_rng(3)
    for i in range(5):
        raw = rng.integers(300, 4000, (47, 62)).astype(np.uint16)
        raw[rng.random(raw.shape) < 0.1] = 0
        raw[0, : 3 + i] = 65535  # the 7-Scenes marker of no reading
        cv2.imwrite(str(tmp_path / f"frame-{i:02d}.depth.png"), raw)
    return tmp_path


@pytest.mark.parametrize(
    "options",
    [{}, {"intrinsics": (60.0, 61.0, 30.5, 23.0), "fps": 30.0}, {"depth_range_mm": (500.0, 3500.0), "tilt_deg": 15.0}],
)
@pytest.mark.parametrize("step", [1, 2, 3])
def test_image_files_read_decimated_are_the_whole_frames_decimated(
    pngs: Path, options: dict[str, object], step: int
) -> None:
    src = open_source(str(pngs), **options)  # type: ignore[arg-type]
    expected = [f.decimated(step) for f in src]
    frames = iter(src)
    first = next(frames).decimated(step)  # as listen reads: the first whole, to choose the step
    got = [first, *decimated(frames, step)]
    assert len(got) == len(expected) == 5
    assert all(_same(a, b) for a, b in zip(got, expected, strict=True))


def test_a_source_that_cannot_leave_pixels_out_is_decimated_frame_by_frame() -> None:
    src = open_source("sim:corridor?size=64x48&frames=4")
    expected = [f.decimated(2) for f in src]
    got = list(decimated(iter(list(src)), 2))
    assert [f.size for f in got] == [(32, 24)] * 4
    assert all(_same(a, b) for a, b in zip(got, expected, strict=True))


def test_a_frame_of_another_size_is_named_with_the_sizes_as_stored(pngs: Path) -> None:
    cv2.imwrite(str(pngs / "frame-09.depth.png"), np.full((30, 40), 1000, np.uint16))
    with pytest.raises(InputError, match=r"is 40x30 px but .* is 62x47 px"):
        list(itertools.islice(decimated(iter(open_source(str(pngs))), 2), 10))


def test_the_step_must_be_positive(pngs: Path) -> None:
    with pytest.raises(InputError, match="step must be >= 1"):
        list(decimated(iter(open_source(str(pngs))), 0))
