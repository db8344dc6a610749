"""`depthgram info`: text and JSON summaries, options passed through, bad input as exit status 2."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from depthgram.cli import main


def write_seq(folder: Path, n: int) -> None:
    folder.mkdir()
    for i in range(n):
        a = np.full((4, 6), 1000 * (i + 1), np.uint16)
        a[0, 0] = 0
        assert cv2.imwrite(str(folder / f"f{i}.png"), a)


def test_info_text(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_seq(tmp_path / "seq", 3)
    (tmp_path / "seq" / "camera.json").write_text(json.dumps({"fx": 5.0, "fy": 6.0, "cx": 2.5, "cy": 1.5}))
    assert main(["info", str(tmp_path / "seq"), "--fps", "10"]) == 0
    out = capsys.readouterr().out
    assert "frames      3" in out
    assert "size        6 x 4 px" in out
    assert "min 1000  median 2000  max 3000 mm" in out
    assert "invalid     4.2 %" in out  # 3 of 72 pixels
    assert "frame rate  10 frames/s" in out
    assert "fx 5.00  fy 6.00  cx 2.50  cy 1.50 px" in out


def test_info_json_with_scale_and_invalid(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_seq(tmp_path / "seq", 2)
    assert main(["info", str(tmp_path / "seq"), "--scale", "0.2", "--invalid", "2000", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["frames"] == 2 and d["size"] == [6, 4] and d["unit"] == "mm" and d["kind"] == "folder"
    # frame 1 (all 2000) is invalid: only frame 0's 1000 units x 0.2 mm remain
    assert d["depth_min_mm"] == d["depth_median_mm"] == d["depth_max_mm"] == 200.0
    assert d["invalid_fraction"] == pytest.approx(25 / 48)
    assert d["fps"] is None and d["intrinsics"] is None


def test_info_encoding_and_range(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    codes = np.array([[1, 128, 255]], np.uint8)
    assert cv2.imwrite(str(tmp_path / "p.png"), codes)
    assert main(["info", str(tmp_path / "p.png"), "--range", "500", "3040", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["depth_min_mm"], d["depth_median_mm"], d["depth_max_mm"]) == (500.0, 1770.0, 3040.0)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda p: None, "no such file or folder"),
        (lambda p: p.mkdir(), "no depth frames in this folder"),
        (lambda p: p.write_bytes(b"\x89PNG\r\n"), "cannot decode the image"),
    ],
)
def test_info_bad_input_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], make: Callable[[Path], object], match: str
) -> None:
    target = tmp_path / "x.png"
    make(target)
    assert main(["info", str(target)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("depthgram info: error: ") and str(target) in err and match in err


def test_info_progress_bar_only_for_long_sources_on_a_terminal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys

    write_seq(tmp_path / "short", 2)
    write_seq(tmp_path / "long", 25)
    assert main(["info", str(tmp_path / "long")]) == 0
    assert "reading" not in capsys.readouterr().err  # not a terminal: no bar in logs
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["info", str(tmp_path / "short")]) == 0
    assert "reading" not in capsys.readouterr().err
    assert main(["info", str(tmp_path / "long")]) == 0
    captured = capsys.readouterr()
    assert "reading" in captured.err and "/25" in captured.err  # a bar over the 25 frames
    assert "frames      25" in captured.out
