"""The second hour's papercuts (issue 32.6): each as a user met it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

import depthgram
from depthgram.cli import main


def _env(**extra: str) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(Path(depthgram.__file__).resolve().parents[1]), **extra}


def _folder(path: Path, n: int = 2) -> Path:
    path.mkdir()
    z = np.full((30, 40), 1500, np.uint16)
    z[10:20, 10:20] = 1000
    for i in range(n):
        assert cv2.imwrite(str(path / f"{i:03d}.png"), z)
    return path


def test_an_unquoted_glob_is_told_to_quote_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rec = _folder(tmp_path / "rec", 3)
    files = sorted(str(p) for p in rec.iterdir())  # what the shell made of rec/*.png
    with pytest.raises(SystemExit) as exit_:
        main(["info", *files])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "quote" in err and "'" in err and "*" in err
    assert err.count(files[2]) <= 1  # not every file name over again


def test_config_check_says_ok_briefly(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text('[segment]\nmethod = "threshold"\n', encoding="utf-8")
    assert main(["config", "--check", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert len(out.splitlines()) <= 2 and "OK" in out and str(cfg) in out


def test_preset_lists_its_choices(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["sonify", "sim:table", "--wav", str(tmp_path / "a.wav"), "--preset", "loud"])
    err = capsys.readouterr().err
    assert all(name in err for name in ("calm", "default", "detailed"))
    with pytest.raises(SystemExit):
        main(["lesson", "--help"])
    assert "calm" in capsys.readouterr().out


def test_demo_prints_where_the_report_is(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    pytest.importorskip("soundfile")
    assert main(["demo", "--out", str(tmp_path / "demo"), "--frames", "2"]) == 0
    out = capsys.readouterr().out
    pages = [word.strip(",()") for line in out.splitlines() for word in line.split() if "index.html" in word]
    assert pages, out
    for page in pages:
        assert Path(page).is_file() or (tmp_path / "demo" / page).is_file(), out


def test_report_on_a_folder_names_the_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    rec = _folder(tmp_path / "rec")
    assert main(["report", str(rec), "--out", str(tmp_path / "rep"), "--fps", "10"]) == 0
    page = (tmp_path / "rep" / "index.html").read_text(encoding="utf-8")
    assert f"source: <code>{rec}</code>" in page


def test_a_missing_extra_names_the_pip_package_not_a_submodule(monkeypatch: pytest.MonkeyPatch) -> None:
    from depthgram._optional import needs_extra
    from depthgram.errors import MissingExtraError

    monkeypatch.setitem(sys.modules, "matplotlib.backends", None)  # import fails as when missing
    with pytest.raises(MissingExtraError) as info, needs_extra("report", "pictures"):
        import matplotlib.backends  # noqa: F401
    text = str(info.value)
    assert "matplotlib.backends" not in text and "'matplotlib'" in text and "pip install 'depthgram[report]'" in text
    monkeypatch.setitem(sys.modules, "mcap.well_known", None)
    with pytest.raises(MissingExtraError) as info, needs_extra("mcap", "writing MCAP"):
        import mcap.well_known  # noqa: F401
    assert "mcap.well_known" not in str(info.value) and "pip install 'depthgram[mcap]'" in str(info.value)


def test_a_missing_extra_named_by_main_names_the_package(monkeypatch: pytest.MonkeyPatch) -> None:
    from depthgram._optional import extra_for

    exc = ModuleNotFoundError("No module named 'foxglove_schemas_protobuf.RawImage_pb2'")
    exc.name = "foxglove_schemas_protobuf.RawImage_pb2"
    text = str(extra_for(exc))
    assert "foxglove-schemas-protobuf" in text and "RawImage_pb2" not in text


def test_read_documents_its_options_and_intrinsics_is_top_level() -> None:
    doc = depthgram.read.__doc__ or ""
    for option in ("scale_mm", "invalid", "fps", "encoding", "topic", "depth_range_mm", "key", "timestamps"):
        assert option in doc, option
    from depthgram.frame import Intrinsics

    assert depthgram.Intrinsics is Intrinsics and "Intrinsics" in depthgram.__all__


def test_the_first_frame_of_a_folder_leaves_no_resource_warning(tmp_path: Path) -> None:
    rec = _folder(tmp_path / "rec")
    code = f"import depthgram; f = next(iter(depthgram.read({str(rec)!r}))); print(f.size)"
    proc = subprocess.run(
        [sys.executable, "-X", "dev", "-W", "error::ResourceWarning", "-c", code],
        env=_env(),
        text=True,
        capture_output=True,
        timeout=300,
    )
    assert proc.returncode == 0 and "(40, 30)" in proc.stdout
    assert "ResourceWarning" not in proc.stderr, proc.stderr


def test_sim_table_is_one_still_everywhere(capsys: pytest.CaptureFixture[str]) -> None:
    from depthgram.sources import open_source

    assert len(open_source("sim:table")) == 1  # type: ignore[arg-type]
    assert len(open_source("sim:corridor")) == 1  # type: ignore[arg-type]
    assert len(open_source("sim:approach")) == 30  # type: ignore[arg-type]
    assert len(open_source("sim:table?frames=5")) == 5  # type: ignore[arg-type]
    assert main(["info", "sim:table"]) == 0
    assert "frames      1" in capsys.readouterr().out


def test_still_scenes_are_the_simulators_scenes_without_motion() -> None:
    from depthgram.sensor import SCENES
    from depthgram.sensor.scenes import build_scene
    from depthgram.sources.sim import STILL_SCENES

    assert STILL_SCENES == {s for s in SCENES if not any(b.moving for b in build_scene(s, (64, 48)).bodies)}


def test_the_preset_choices_are_the_sound_presets() -> None:
    from depthgram.commands.sonify import PRESETS as CHOICES
    from depthgram.sound import PRESETS

    assert CHOICES == tuple(sorted(PRESETS))


def test_bench_data_names_where_the_recordings_are(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scripts = tmp_path / "benchmarks"
    scripts.mkdir()
    (scripts / "real.py").write_text(
        "import os\n\ndef main(argv):\n    print('data at', os.environ['DEPTHGRAM_DATA'])\n    return 0\n",
        encoding="utf-8",
    )
    data = tmp_path / "recordings"
    data.mkdir()
    old = os.environ.get("DEPTHGRAM_DATA")
    try:
        assert main(["bench", "real", "--dir", str(scripts), "--data", str(data)]) == 0
    finally:  # bench sets it for the scripts it loads: leave the suite's environment as it was
        if old is None:
            os.environ.pop("DEPTHGRAM_DATA", None)
        else:
            os.environ["DEPTHGRAM_DATA"] = old
    assert f"data at {data}" in capsys.readouterr().out
    assert main(["bench", "real", "--dir", str(scripts), "--data", str(tmp_path / "none")]) == 2
    assert "--data" in capsys.readouterr().err


@pytest.mark.parametrize("script", ["real", "table1", "golden", "bench_segmentation"])
def test_the_benchmarks_read_the_recordings_where_depthgram_data_says(tmp_path: Path, script: str) -> None:
    root = Path(depthgram.__file__).resolve().parents[2]
    if not (root / "benchmarks" / f"{script}.py").is_file():
        pytest.skip("not a source checkout")
    code = f"from benchmarks import {script}; print({script}.SHARED)"
    proc = subprocess.run(
        [sys.executable, "-c", code],
        env=_env(DEPTHGRAM_DATA=str(tmp_path), PYTHONPATH=f"{root}{os.pathsep}{root / 'src'}"),
        cwd=root,
        text=True,
        capture_output=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(tmp_path)
