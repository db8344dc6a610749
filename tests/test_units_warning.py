"""Wrong units warn once and name the likely option (issue 16, item 2); Frames go to segment/describe (item 1)."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

import depthgram
from depthgram.frame import Frame, Intrinsics, UnitsWarning, make_frame
from depthgram.sources import read

K = Intrinsics(200.0, 200.0, 79.5, 59.5)


def _scene_mm() -> np.ndarray:
    """A wall at 2 m with a box at 0.9 m: 160 x 120 px."""
    d = np.full((120, 160), 2000.0, np.float32)
    d[40:80, 60:100] = 900.0
    return d


def _units_warnings(record: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in record if issubclass(w.category, UnitsWarning)]


def test_segment_takes_a_frame_with_its_validity_and_intrinsics() -> None:
    depth = _scene_mm()
    depth[10:30, 10:40] = 600.0  # a nearer block the mask says is no reading (depth left nonzero)
    valid = np.ones(depth.shape, bool)
    valid[10:30, 10:40] = False
    frame = Frame(depth=depth, valid=valid, intrinsics=K, name="hand-made")
    seg = depthgram.segment(frame, method="threshold")
    assert not any(abs(o.depth - 600.0) < 1 for o in seg.objects)  # the invalid block is ignored
    box = [o for o in seg.objects if abs(o.depth - 900.0) < 1]
    assert len(box) == 1 and box[0].area == 40 * 40
    # metric attributes exist only with intrinsics: they came from the frame
    assert box[0].centroid_mm is not None
    same = depthgram.segment(depth, valid=valid, intrinsics=K, method="threshold")
    assert np.array_equal(seg.labels, same.labels)
    # explicit arguments win over the frame's
    assert depthgram.segment(frame, intrinsics=None, method="threshold").objects[0].centroid_mm is not None


def test_describe_takes_a_frame() -> None:
    frame = next(iter(read("sim:table")))
    assert frame.intrinsics is not None
    a = depthgram.describe(frame)
    b = depthgram.describe(frame.depth, intrinsics=frame.intrinsics)
    assert a.sentence == b.sentence and a.frame is frame
    assert a.sentence.startswith("Bkg")


def test_float_metres_to_segment_warn_and_name_the_fix() -> None:
    metres = _scene_mm() / 1000.0
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        depthgram.segment(metres, method="threshold")
    msgs = _units_warnings(rec)
    assert len(msgs) == 1 and "metres" in msgs[0] and "1000" in msgs[0]


def test_millimetres_do_not_warn() -> None:
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        depthgram.segment(_scene_mm(), method="threshold")
        make_frame(_scene_mm())
        depthgram.describe(_scene_mm())
    assert _units_warnings(rec) == []


def test_make_frame_warns_on_a_median_beyond_8_m_and_under_50_mm() -> None:
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        make_frame(_scene_mm() * 5, name="far.png")  # TUM's 5000 units per metre read as mm
        make_frame(_scene_mm() / 100, scale_mm=1.0, name="near.png", check_units=True)
    msgs = _units_warnings(rec)
    assert len(msgs) == 2
    assert msgs[0].startswith("far.png") and "beyond 8 m" in msgs[0]
    assert msgs[1].startswith("near.png") and "under 50 mm" in msgs[1]


def test_a_folder_in_wrong_units_warns_once_naming_the_scale(tmp_path: Path) -> None:
    # TUM-style: 5000 units per metre, three frames of a slanted wall (2000-2159 mm: raw values
    # are not all multiples of 8, which would also fit SUN's bit shift)
    d = _scene_mm() + np.arange(160, dtype=np.float32)[None, :] * (_scene_mm() == 2000.0)
    for i in range(3):
        assert cv2.imwrite(str(tmp_path / f"{i:03d}.png"), (d * 5).astype(np.uint16))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        frames = list(read(tmp_path))
    msgs = _units_warnings(rec)
    assert len(frames) == 3 and len(msgs) == 1
    assert "--scale 0.2" in msgs[0] and "000.png" in msgs[0]
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        frames = list(read(tmp_path, scale_mm=0.2))
    assert _units_warnings(rec) == [] and 2000 <= float(np.median(frames[0].depth)) < 2160


@pytest.mark.parametrize(
    ("name", "hint", "fix"),
    [
        ("TUM_depth.png", "--scale 0.2", {"scale_mm": 0.2}),
        ("SUN_depth.png", "--encoding sun", {"encoding": "sun"}),
        ("NYU_depth.pgm", "--encoding kinect-disparity", {"encoding": "kinect-disparity"}),
    ],
)
def test_real_frames_in_the_wrong_units_name_their_flag(
    shared_data: Path, name: str, hint: str, fix: dict[str, object]
) -> None:
    path = shared_data / "open3d_tum_nyu_sun_singles" / name
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        next(iter(read(path)))
    msgs = _units_warnings(rec)
    assert len(msgs) == 1 and hint in msgs[0] and "beyond 8 m" in msgs[0]
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        frame = next(iter(read(path, **fix)))  # type: ignore[arg-type]
    assert _units_warnings(rec) == []
    assert 500 < float(np.median(frame.depth[frame.valid])) < 5000


def test_the_command_line_prints_the_warning_as_one_line(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from depthgram.cli import main

    tum = str(shared_data / "open3d_tum_nyu_sun_singles" / "TUM_depth.png")
    assert main(["info", tum]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("depthgram info: warning: ") and "--scale 0.2" in err[0]
    assert main(["info", tum, "--scale", "0.2"]) == 0
    assert capsys.readouterr().err == ""


def test_the_units_tests_read_what_their_definitions_say() -> None:
    # metres: the finite positive readings all under 20 (an +inf reading is no reading, NaN
    # and negatives neither); beyond or under the limits: the median of the readings, which a
    # count of the readings past a limit settles only when fewer than half lie past it
    from depthgram.frame import _float_metres, implausible_depth

    metres = np.full((30, 40), 2.0, np.float32)
    assert _float_metres(metres) and _float_metres(metres.astype(np.float16))
    for odd in (np.inf, np.nan, -50.0, 0.0):
        m = metres.copy()
        m[3, 4] = odd
        assert _float_metres(m)
    m = metres.copy()
    m[3, 4] = 20.0
    assert not _float_metres(m)
    m = np.full((30, 40), np.inf, np.float32)
    m[0, 0] = 3.0
    assert _float_metres(m) and not _float_metres(np.full((3, 3), np.nan))
    assert not _float_metres(np.zeros((3, 3))) and not _float_metres(np.full((3, 3), 2, np.uint16))
    # an even count: the median is the mean of the two middle readings
    d = np.array([[7000.0, 7000.0, 9000.0, 9200.0]], np.float32)
    assert implausible_depth(d) is None  # median 8000: at the limit, not beyond
    d[0, 1] = 7100.0
    d[0, 0] = 8001.0
    found = implausible_depth(d)
    assert found is not None and found[1] and "8500 mm" in found[0]
    near = np.array([[40.0, 40.0, 60.0, np.nan, np.inf, 0.0]], np.float32)
    found = implausible_depth(near)
    assert found is not None and not found[1] and "40.0 mm" in found[0]
    assert implausible_depth(near, np.array([[False, True, True, False, False, False]])) is None
