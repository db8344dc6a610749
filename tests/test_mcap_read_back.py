"""depthgram reads the MCAP it writes: its depth topic and calibration give the same frames (issue 32.4)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("mcap_protobuf")

from depthgram.cli import main
from depthgram.errors import InputError
from depthgram.frame import Intrinsics
from depthgram.sources import open_source, read


def test_describe_reads_its_own_mcap_and_gives_the_same_frames(tmp_path: Path) -> None:
    # issue 32.4: `describe out.mcap` on its own --mcap output said "Profile is not ros2"
    spec = "sim:approach?frames=4"
    out = tmp_path / "out.mcap"
    assert main(["describe", spec, "--quiet", "--mcap", str(out), "--json", str(tmp_path / "a.jsonl")]) == 0
    first = list(read(spec))
    again = list(read(out))
    assert len(again) == len(first) == len(open_source(out))  # type: ignore[arg-type]
    for a, b in zip(first, again, strict=True):
        np.testing.assert_allclose(b.depth, np.rint(a.depth), atol=0)  # written as 16-bit mm
        np.testing.assert_array_equal(b.valid, a.valid)
        assert b.index == a.index and b.time_s == pytest.approx(a.time_s, abs=1e-9)
        assert b.intrinsics == a.intrinsics
    assert main(["describe", str(out), "--quiet", "--json", str(tmp_path / "b.jsonl")]) == 0
    before = [json.loads(x) for x in (tmp_path / "a.jsonl").read_text().splitlines()]
    after = [json.loads(x) for x in (tmp_path / "b.jsonl").read_text().splitlines()]
    assert [r["sentence"] for r in after] == [r["sentence"] for r in before]


def test_intrinsics_assumed_when_writing_are_not_read_back_as_the_cameras(tmp_path: Path) -> None:
    folder = tmp_path / "rec"
    folder.mkdir()
    z = np.full((30, 40), 1500, np.uint16)
    z[10:20, 10:20] = 1000
    for i in range(2):
        assert cv2.imwrite(str(folder / f"{i:03d}.png"), z)
    out = tmp_path / "out.mcap"
    assert main(["describe", str(folder), "--quiet", "--fps", "10", "--mcap", str(out), "--json", "/dev/null"]) == 0
    frames = list(read(out))
    assert [f.intrinsics for f in frames] == [None, None]  # the writer's 64-degree guess is not the camera
    assert [f.time_s for f in frames] == pytest.approx([0.0, 0.1])
    np.testing.assert_array_equal(frames[1].depth, z.astype(np.float32))


def test_the_cameras_intrinsics_are_read_back(tmp_path: Path) -> None:
    from depthgram.export.mcap_file import McapWriter
    from depthgram.frame import make_frame
    from depthgram.pipeline import Pipeline

    given = Intrinsics(fx=50.0, fy=52.0, cx=19.5, cy=14.5)
    z = np.full((30, 40), 1500, np.uint16)
    frame = make_frame(z, intrinsics=given, time_s=2.5, name="a.png")
    out = tmp_path / "out.mcap"
    with McapWriter(out) as w:
        for result in Pipeline().run([frame]):
            w.add(result)
    back = list(read(out))
    assert len(back) == 1 and back[0].intrinsics == given and back[0].time_s == pytest.approx(2.5)


def test_a_damaged_own_mcap_is_a_clear_error(tmp_path: Path) -> None:
    out = tmp_path / "out.mcap"
    assert main(["describe", "sim:approach?frames=3", "--quiet", "--mcap", str(out), "--json", "/dev/null"]) == 0
    data = out.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"cut\.mcap"):
        list(read(cut))
