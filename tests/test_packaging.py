"""Packaging: one version, and a clear message naming the extra when an optional package is missing."""

from __future__ import annotations

import importlib.metadata
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

import depthgram
from depthgram.cli import main
from depthgram.errors import DepthgramError, MissingExtraError

ROOT = Path(__file__).resolve().parents[1]


def test_one_version_source() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "version" not in project and "version" in project["dynamic"]
    assert importlib.metadata.version("depthgram") == depthgram.__version__


def test_core_dependencies_leave_the_heavy_ones_to_extras() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = {d.split(">")[0].split("=")[0].strip() for d in project["dependencies"]}
    assert {"numpy", "scipy", "opencv-python-headless", "numba", "lark"} <= core
    assert not core & {"rosbags", "matplotlib", "soundfile", "fastapi", "uvicorn", "dask", "distributed", "mcap"}
    extras = project["optional-dependencies"]
    for extra in ("bags", "report", "sound", "view", "dask", "mcap"):
        assert extra in extras and "depthgram[bags,report,sound,view,dask,mcap]" in extras["dev"]


@pytest.mark.parametrize(
    ("module", "argv", "extra"),
    [
        ("soundfile", ["sonify", "sim:table?frames=2", "--wav", "{tmp}/a.wav"], "sound"),
        ("matplotlib", ["report", "sim:table?frames=2", "--out", "{tmp}/rep"], "report"),
        ("soundfile", ["demo", "--out", "{tmp}/demo"], "sound,report"),
        ("uvicorn", ["view", "sim:table", "--no-browser"], "view"),
        ("mcap.writer", ["describe", "sim:table?frames=2", "--mcap", "{tmp}/a.mcap"], "mcap"),
        ("sounddevice", ["listen", "sim:table?frames=2"], "listen"),
    ],
)
def test_a_missing_extra_is_named_on_the_command_line(
    module: str,
    argv: list[str],
    extra: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setitem(sys.modules, module, None)  # import raises ModuleNotFoundError
    for name in [m for m in sys.modules if m.startswith(("depthgram.views.", "depthgram.export."))]:
        monkeypatch.delitem(sys.modules, name)  # imported afresh, as in a new process
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    err = capsys.readouterr().err
    assert f"pip install 'depthgram[{extra}]'" in err and "Traceback" not in err


def test_library_calls_raise_a_depthgram_error_naming_the_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from depthgram.sound import write_wav
    from depthgram.sources.bag import _reader

    monkeypatch.setitem(sys.modules, "soundfile", None)
    with pytest.raises(MissingExtraError, match=r"depthgram\[sound\]") as info:
        write_wav(tmp_path / "a.wav", np.zeros((10, 2)), 22050)
    assert isinstance(info.value, DepthgramError) and isinstance(info.value, ImportError)
    monkeypatch.setitem(sys.modules, "rosbags", None)
    monkeypatch.delitem(sys.modules, "rosbags.highlevel", raising=False)
    with pytest.raises(MissingExtraError, match=r"x.bag: reading ROS bags needs .*depthgram\[bags\]"):
        _reader(tmp_path / "x.bag")


def test_bench_outside_a_checkout_says_it_needs_one(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from depthgram.commands import bench

    here = bench.benchmarks_dir()  # the tests run from a checkout, so it is found
    assert here is not None and (here / "table1.py").is_file()
    monkeypatch.setattr(bench, "benchmarks_dir", lambda: None)  # as from an installed wheel
    assert main(["bench", "--quick"]) == 2
    assert "source checkout" in capsys.readouterr().err
    assert main(["bench", "--dir", str(tmp_path / "nowhere")]) == 2
    assert "no such folder" in capsys.readouterr().err
