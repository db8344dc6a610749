"""The command line end to end: simulate, describe, parse, plan, sonify, run, report, config, errors."""

from __future__ import annotations

import gc
import json
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest
import soundfile as sf

from depthgram.cli import main


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sim") / "crossing"
    assert (
        main(
            [
                "simulate",
                "crossing",
                "--frames",
                "6",
                "--size",
                "176x132",
                "--out",
                str(out),
                "--seed",
                "2",
                "--fps",
                "15",
            ]
        )
        == 0
    )
    return out


def test_describe_writes_json_lines_and_label_maps_named_after_frames(sim_dir: Path, tmp_path: Path) -> None:
    jsonl = tmp_path / "out.jsonl"
    labels = tmp_path / "labels"
    assert main(["describe", str(sim_dir), "--json", str(jsonl), "--labels-dir", str(labels), "--quiet"]) == 0
    lines = [json.loads(x) for x in jsonl.read_text().splitlines()]
    frames = sorted((sim_dir / "depth").glob("*.png"))
    assert len(lines) == len(frames) == 6
    assert [r["frame"] for r in lines] == list(range(6))
    assert lines[1]["time_s"] == pytest.approx(1 / 15)
    for rec, fpath in zip(lines, frames, strict=True):
        lab = cv2.imread(str(labels / fpath.name), cv2.IMREAD_UNCHANGED)
        assert lab is not None and lab.dtype == np.uint16 and lab.shape == (132, 176)
        assert set(np.unique(lab)) - {0} == {o["id"] for o in rec["objects"]}
        for o in rec["objects"]:
            assert o["status"] in {"visible", "entering", "leaving", "occluded"}
            assert o["v_unit"] == "mm/s"


def test_text_sentences_parse_back(sim_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["describe", str(sim_dir), "--format", "text", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert len(text.splitlines()) == 6 and all(line.startswith("Bkg") for line in text.splitlines())
    sentences = tmp_path / "s.txt"
    sentences.write_text(text)
    assert main(["parse", str(sentences)]) == 0
    parsed = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert len(parsed) == 6


def test_plan_json_and_sonify_duration(sim_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", str(sim_dir), "--json", "--quiet"]) == 0
    plans = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert len(plans) == 6 and all("actions" in p for p in plans)
    wav = tmp_path / "s.wav"
    assert main(["sonify", str(sim_dir), "--wav", str(wav), "--quiet"]) == 0
    audio, sr = sf.read(wav)
    assert audio.shape[1] == 2
    assert len(audio) / sr == pytest.approx(6 / 15, abs=2 / sr)


def test_run_fast_reports_latency(sim_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", str(sim_dir), "--fast", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "6 processed, 0 dropped" in out and "latency per frame" in out
    assert "start-up before the first frame" in out  # kept out of the first frame's latency
    assert gc.get_freeze_count() == 0  # the collector is given back as it was
    assert main(["run", str(sim_dir), "--fast", "--quiet", "--read-ahead", "0"]) == 0
    assert "6 processed, 0 dropped" in capsys.readouterr().out
    assert main(["run", str(sim_dir), "--read-ahead", "-1"]) == 2
    assert "--read-ahead must be >= 0, got -1" in capsys.readouterr().err


def test_report_writes_pictures_and_index(sim_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    assert main(["report", str(sim_dir), "--out", str(out), "--pictures", "2", "--quiet"]) == 0
    page = (out / "index.html").read_text()
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert "tracks.png" in pngs and any(p.endswith("_objects.png") for p in pngs)
    for p in pngs:
        assert p in page
        assert cv2.imread(str(out / p)) is not None


def test_config_dump_is_loadable_toml(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["config", "--dump"]) == 0
    text = capsys.readouterr().out
    data = tomllib.loads(text)
    assert {"segment", "tree", "tracker", "act", "sound"} <= set(data)
    path = tmp_path / "c.toml"
    path.write_text(text)
    assert main(["config", "--check", str(path), "--dump"]) == 0  # the file with defaults filled in
    assert capsys.readouterr().out == text


@pytest.mark.parametrize(
    ("make", "expect"),
    [
        (lambda d: d / "missing.png", "missing.png"),
        (lambda d: (d / "empty").mkdir() or d / "empty", "empty"),
        (lambda d: (d / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage") and d / "bad.png", "bad.png"),
    ],
)
def test_bad_input_is_a_clear_message_and_exit_2(
    make, expect: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = make(tmp_path)
    assert main(["describe", str(path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "error" in err and expect in err and "Traceback" not in err


def test_bad_config_value_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text("[segment]\nmin_area = -5\n")
    assert main(["describe", "sim:table", "--config", str(cfg), "--quiet"]) == 2
    assert "min_area" in capsys.readouterr().err


def test_unwritable_outputs_are_messages_not_tracebacks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sonify", "sim:table", "--wav", str(tmp_path / "no" / "x.wav"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and "Traceback" not in err
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["describe", "sim:table", "--labels-dir", str(blocker / "sub"), "--quiet"]) == 1
    assert "error" in capsys.readouterr().err


def test_all_invalid_frame_is_an_empty_scene_not_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "zeros.npy"
    np.save(path, np.zeros((48, 64), np.uint16))
    assert main(["describe", str(path), "--quiet"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["objects"] == [] and rec["sentence"].startswith("Bkg")
