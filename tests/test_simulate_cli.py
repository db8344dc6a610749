"""``depthgram simulate``: files written, read back to the simulator's arrays, clear errors."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from depthgram.cli import main
from depthgram.sensor import ToFConfig, simulate


def test_writes_depth_instances_truth_and_camera_that_read_back(tmp_path: Path) -> None:
    out = tmp_path / "sim"
    assert (
        main(
            [
                "simulate",
                "crossing",
                "--frames",
                "3",
                "--size",
                "88x66",
                "--out",
                str(out),
                "--seed",
                "4",
                "--fps",
                "15",
            ]
        )
        == 0
    )
    sims = list(simulate("crossing", 3, size=(88, 66), fps=15.0, seed=4))
    cam = json.loads((out / "depth" / "camera.json").read_text())
    k = sims[0].frame.intrinsics
    assert k is not None
    assert cam["unit"] == "mm" and cam["scene"] == "crossing" and cam["seed"] == 4 and cam["fps"] == 15.0
    assert (cam["fx"], cam["fy"], cam["cx"], cam["cy"]) == pytest.approx((k.fx, k.fy, k.cx, k.cy))
    for sim in sims:
        stem = f"{sim.frame.index:06d}"
        depth = cv2.imread(str(out / "depth" / f"{stem}.png"), cv2.IMREAD_UNCHANGED)
        inst = cv2.imread(str(out / "instances" / f"{stem}.png"), cv2.IMREAD_UNCHANGED)
        assert depth.dtype == np.uint16 and depth.shape == (66, 88)
        np.testing.assert_array_equal(depth, sim.frame.depth.astype(np.uint16))
        np.testing.assert_array_equal((depth > 0), sim.frame.valid)
        np.testing.assert_array_equal(inst, sim.instances)
        truth = json.loads((out / "truth" / f"{stem}.json").read_text())
        assert truth["index"] == sim.frame.index
        assert truth["time_s"] == pytest.approx(sim.frame.index / 15.0)
        assert [o["id"] for o in truth["objects"]] == [o.id for o in sim.truth]
        for got, want in zip(truth["objects"], sim.truth, strict=True):
            assert got["name"] == want.name and got["area"] == want.area == int((inst == want.id).sum())
            assert tuple(got["center_xy"]) == pytest.approx(want.center_xy)
            assert got["v_radial"] == pytest.approx(want.v_radial)
            assert got["parent"] == want.parent


def test_eight_bit_and_no_noise_options(tmp_path: Path) -> None:
    assert main(["simulate", "table", "--size", "44x33", "--out", str(tmp_path), "--bits", "8", "--no-noise"]) == 0
    (sim,) = simulate("table", 1, size=(44, 33), noise=False, tof=ToFConfig(bits=8))
    depth = cv2.imread(str(tmp_path / "depth" / "000000.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(depth, np.rint(sim.frame.depth).astype(np.uint16))
    assert json.loads((tmp_path / "depth" / "camera.json").read_text())["bits"] == 8


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["kitchen"], "known scenes: table, corridor, approach, crossing"),
        (["table", "--size", "176by132"], "WxH"),
        (["table", "--size", "0x132"], "8..4096"),
        (["table", "--size", "100000x100000"], "8..4096"),
        (["table", "--frames", "0"], "--frames must be >= 1"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert main(["simulate", *args, "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_unwritable_output_folder_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    assert main(["simulate", "table", "--out", str(blocker / "sim")]) == 2
    err = capsys.readouterr().err
    assert "cannot create the output folders" in err and str(blocker) in err


def test_the_help_names_every_scene_of_the_simulator() -> None:
    import argparse

    from depthgram.commands import simulate as simulate_command
    from depthgram.commands._common import add_source_arguments
    from depthgram.sensor import SCENES

    for add in (simulate_command.add_arguments, add_source_arguments):
        parser = argparse.ArgumentParser()
        add(parser)
        text = parser.format_help().replace("\n", " ")
        missing = [s for s in SCENES if s not in text]
        assert not missing, f"{add.__module__}: help does not name {missing}"
