"""One output convention, one set of reading options, --version and the missing extras (issue 16, items 2-4)."""

from __future__ import annotations

import argparse
import json
import socket
import sys
import tomllib
from pathlib import Path

import pytest

import depthgram
from depthgram.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _reading_options(p: argparse.ArgumentParser) -> set[str]:
    group = next(g for g in p._action_groups if g.title == "reading the input")
    return {o for a in group._group_actions for o in a.option_strings}


def test_every_command_that_reads_recordings_takes_the_same_reading_options() -> None:
    subs = _subparsers()
    readers = ["info", "describe", "plan", "report", "run", "sonify", "view", "batch"]
    options = {name: _reading_options(subs[name]) for name in readers}
    assert options["info"] >= {
        "--scale",
        "--invalid",
        "--fps",
        "--timestamps",
        "--encoding",
        "--range",
        "--topic",
        "--key",
    }
    assert all(o == options["info"] for o in options.values()), options


def test_the_offered_encodings_and_methods_are_the_libraries() -> None:
    from depthgram.commands import _common
    from depthgram.segmentation import METHODS
    from depthgram.sources import ENCODINGS

    assert tuple(_common.ENCODINGS) == tuple(ENCODINGS)
    assert set(_common.METHODS) == set(METHODS)


def test_batch_reads_with_the_reading_options(tmp_path: Path, shared_data: Path) -> None:
    # SUN RGB-D's frame is only right with --encoding sun, which batch did not take
    sun = str(shared_data / "open3d_tum_nyu_sun_singles" / "SUN_depth.png")
    assert main(["batch", sun, "--out", str(tmp_path), "--workers", "1", "--encoding", "sun", "--quiet"]) == 0
    lines = [json.loads(x) for f in tmp_path.rglob("*.jsonl") for x in f.read_text().splitlines()]
    # decoded, the frame reads 1.06-9.87 m; read as plain mm its median was 21 m
    assert lines and lines[0]["objects"] and all(o["depth"] < 9900 for o in lines[0]["objects"])


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    # pyproject.toml reads the version from depthgram.__version__ (one place)
    assert "version" in tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dynamic"]
    assert capsys.readouterr().out.strip() == f"depthgram {depthgram.__version__}"


def test_plan_json_takes_a_file_and_dash_is_stdout(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plan.jsonl"
    assert main(["plan", "sim:table?frames=2", "--json", str(out), "--quiet"]) == 0
    assert capsys.readouterr().out == ""  # the output named a file: nothing else on stdout
    recs = [json.loads(x) for x in out.read_text().splitlines()]
    assert [r["frame"] for r in recs] == [0, 1] and all("actions" in r for r in recs)
    assert main(["plan", "sim:table?frames=2", "--json", "-", "--quiet"]) == 0
    cap = capsys.readouterr()
    assert [json.loads(x) for x in cap.out.splitlines()] == recs and cap.err == ""


@pytest.mark.parametrize(
    "argv",
    [
        ["plan", "sim:table?frames=2", "--json", "--quiet"],
        ["plan", "--json", "sim:table?frames=2", "--quiet"],  # the switch before INPUT: INPUT was taken as its file
    ],
)
def test_plan_bare_json_still_works_with_a_deprecation(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 0
    cap = capsys.readouterr()
    assert [json.loads(x)["frame"] for x in cap.out.splitlines()] == [0, 1]
    assert "--json without a file is deprecated" in cap.err and "--json -" in cap.err


def test_plan_text_by_default(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "sim:table?frames=1", "--quiet"]) == 0
    assert capsys.readouterr().out.startswith("# frame 0 (sim:table#0)")


def test_info_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "sim:table?frames=2", "--json", str(tmp_path / "i.json")]) == 0
    d = json.loads((tmp_path / "i.json").read_text())
    assert d["frames"] == 2 and d["size"] == [176, 132]
    assert main(["info", "sim:table?frames=2", "--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out) == d and "deprecated" in cap.err


def test_describe_outputs_and_the_old_format_switch(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = "sim:approach?frames=3"
    j, t = tmp_path / "s.jsonl", tmp_path / "s.txt"
    assert main(["describe", src, "--json", str(j), "--text", str(t), "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    recs = [json.loads(x) for x in j.read_text().splitlines()]
    sentences = t.read_text().splitlines()
    assert len(recs) == 3 and [r["sentence"] for r in recs] == sentences
    assert main(["describe", src, "--quiet"]) == 0  # no output option: JSON lines on stdout
    assert [json.loads(x)["sentence"] for x in capsys.readouterr().out.splitlines()] == sentences
    assert main(["describe", src, "--format", "text", "--quiet"]) == 0
    cap = capsys.readouterr()
    assert cap.out.splitlines() == sentences and "--format text is deprecated" in cap.err and "--text -" in cap.err
    assert main(["describe", src, "--text", "-", "--quiet"]) == 0
    cap = capsys.readouterr()
    assert cap.out.splitlines() == sentences and cap.err == ""
    assert main(["describe", src, "--json", "-", "--text", "-"]) == 2
    assert "standard output" in capsys.readouterr().err


def test_parse_json_file(tmp_path: Path) -> None:
    sentences = tmp_path / "s.txt"
    assert (
        main(
            [
                "describe",
                "sim:approach?frames=2",
                "--text",
                str(sentences),
                "--json",
                str(tmp_path / "d.jsonl"),
                "--quiet",
            ]
        )
        == 0
    )
    out = tmp_path / "trees.jsonl"
    assert main(["parse", str(sentences), "--json", str(out)]) == 0
    trees = [json.loads(x) for x in out.read_text().splitlines()]
    described = [json.loads(x)["objects"] for x in (tmp_path / "d.jsonl").read_text().splitlines()]
    assert len(trees) == 2
    for tree, objects in zip(trees, described, strict=True):  # the sentence carries every object back
        nodes = {n["id"]: n for n in tree["nodes"] if n["kind"] != "Bkg"}
        assert sorted(nodes) == sorted(o["id"] for o in objects)
        assert all(abs(nodes[o["id"]]["depth"] - o["depth"]) <= 0.05 for o in objects)


def test_an_unwritable_output_is_a_message(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "missing" / "x.jsonl"
    assert main(["plan", "sim:table", "--json", str(bad), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"--json {bad}: cannot write" in err


def test_view_without_the_extra_names_it(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "uvicorn", None)  # import fails as after a plain `pip install .`
    assert main(["view", "sim:table", "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert "pip install 'depthgram[view]'" in err and "Traceback" not in err


def test_view_on_a_port_in_use(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("uvicorn")
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        assert main(["view", "sim:table", "--no-browser", "--port", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"port {port} on 127.0.0.1 is already in use" in err and "--port 0" in err


def test_info_on_a_camera_without_the_extra(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)
    assert main(["info", "realsense:"]) == 2  # it died with "a live camera has no length"
    err = capsys.readouterr().err
    assert "pip install 'depthgram[realsense]'" in err
