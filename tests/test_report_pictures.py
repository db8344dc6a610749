"""Report pictures readable at a glance (issue 16, item 6): robust colour scale, labels that never
overlap and stay inside, pictures named after their input frames, chosen frames spread over the recording."""

from __future__ import annotations

import itertools
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("matplotlib")

from depthgram.cli import main
from depthgram.frame import make_frame
from depthgram.views.pictures import depth_limits, place_labels
from depthgram.views.report import picture_stem, spread


def test_the_colour_scale_ignores_far_outliers() -> None:
    # a room at 2-3 m with 1 % of far junk at 46 m (as TUM's frame): min..max would put the
    # whole room in the bottom 2 % of the scale
    rng = np.random.default_rng(0)
    d = rng.uniform(2000, 3000, (120, 160)).astype(np.float32)
    d.flat[rng.choice(d.size, d.size // 100, replace=False)] = 46_000.0
    lo, hi = depth_limits(make_frame(d))
    assert 2000 <= lo < 2100 and 2900 < hi <= 3000


def test_labels_never_overlap_and_stay_inside() -> None:
    # twelve labels all wanting the same spot near the corner of a 640 x 480 picture
    anchors = [(10.0, 10.0)] * 6 + [(630.0, 470.0)] * 6
    sizes = [(120.0, 30.0)] * 12
    placed = place_labels(anchors, sizes, (640, 480))
    boxes = [(x - 60, y - 15, x + 60, y + 15) for p in placed if p is not None for x, y in [p]]
    assert len(boxes) == 12
    assert all(b[0] >= 0 and b[1] >= 0 and b[2] <= 640 and b[3] <= 480 for b in boxes)
    for a, b in itertools.combinations(boxes, 2):
        assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
    # a lone label sits at its anchor
    assert place_labels([(300.0, 200.0)], [(50.0, 20.0)], (640, 480)) == [(300.0, 200.0)]


def test_labels_with_no_room_are_left_out() -> None:
    placed = place_labels([(50.0, 20.0)] * 3, [(100.0, 40.0)] * 3, (100, 40))
    assert placed[0] == (50.0, 20.0) and placed[1:] == [None, None]


def test_spread_and_names() -> None:
    assert spread(300, 6) == {0, 60, 120, 179, 239, 299}
    assert spread(3, 6) == {0, 1, 2} and spread(1, 6) == {0}
    assert picture_stem("000123-depth.png", 123) == "000123-depth"
    assert picture_stem("sim:table#3", 3) == "frame000003"
    assert picture_stem("depth.png", 7, {"depth"}) == "depth_000007"


def test_report_pictures_are_named_after_their_frames_and_spread(tmp_path: Path) -> None:
    frames = tmp_path / "rec"
    frames.mkdir()
    d = np.full((60, 80), 2000, np.uint16)
    d[20:40, 30:50] = 900
    for i in range(10):
        assert cv2.imwrite(str(frames / f"scan_{i:02d}.png"), d)
    out = tmp_path / "report"
    assert main(["report", str(frames), "--out", str(out), "--pictures", "3", "--fps", "10", "--quiet"]) == 0
    objects = sorted(p.name for p in out.glob("*_objects.png"))
    assert objects == ["scan_00_objects.png", "scan_04_objects.png", "scan_09_objects.png"]
    page = (out / "index.html").read_text()
    assert page.count("<section><h2>frame") == 3 and "scan_09_objects.png" in page
