"""batch: a scheduler that never answers (issue 32.3), resume by content and --method (issue 32.5)."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from depthgram.cli import main


@pytest.fixture
def silent_server() -> Iterator[str]:
    """A TCP server that accepts connections and never says a word: not a Dask scheduler."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    held: list[socket.socket] = []

    def accept() -> None:
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            held.append(conn)

    threading.Thread(target=accept, daemon=True).start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    server.close()
    for c in held:
        c.close()


def test_a_scheduler_that_never_answers_is_a_clear_error(tmp_path: Path, silent_server: str) -> None:
    pytest.importorskip("distributed")
    import depthgram

    env = {**os.environ, "PYTHONPATH": str(Path(depthgram.__file__).resolve().parents[1])}
    args = ["batch", "sim:table?frames=1", "--out", str(tmp_path / "out"), "--scheduler", silent_server]
    # the subprocess's own timeout only keeps a regression (the hang) from stalling the suite
    proc = subprocess.run(
        [sys.executable, "-m", "depthgram.cli", *args, "--connect-timeout", "2"],
        env=env,
        text=True,
        capture_output=True,
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    assert f"--scheduler {silent_server}" in proc.stderr and "no answer" in proc.stderr and "2 s" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_the_connect_timeout_must_be_positive(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["batch", "sim:table?frames=1", "--out", str(tmp_path / "o"), "--connect-timeout", "0"]
    assert main(args) == 2
    assert "--connect-timeout" in capsys.readouterr().err


def _folder(path: Path, depth_mm: int) -> Path:
    import cv2

    path.mkdir(exist_ok=True)
    z = np.full((48, 64), depth_mm, np.uint16)
    z[10:30, 20:40] = depth_mm - 300  # a box in front of a wall
    for i in range(2):
        assert cv2.imwrite(str(path / f"{i:03d}.png"), z)
    return path


def _summary(out: Path, name: str) -> dict[str, object]:
    return json.loads((out / name / "summary.json").read_text(encoding="utf-8"))  # type: ignore[no-any-return]


def test_a_recording_changed_in_place_is_redone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # issue 32.5: a folder re-recorded in place was skipped and kept the old results
    rec = _folder(tmp_path / "rec", 2000)
    out = tmp_path / "out"
    assert main(["batch", str(rec), "--out", str(out), "--quiet"]) == 0
    first = (out / "rec" / "scenes.jsonl").read_text(encoding="utf-8")
    assert main(["batch", str(rec), "--out", str(out), "--quiet"]) == 0
    assert "1 skipped" in capsys.readouterr().out  # unchanged: not redone
    _folder(rec, 1500)  # the same names, new content
    os.utime(rec / "000.png", ns=(1, 1))  # an old time, as a copy keeping its times (cp -p) has
    assert main(["batch", str(rec), "--out", str(out), "--quiet"]) == 0
    assert "1 done" in capsys.readouterr().out
    again = (out / "rec" / "scenes.jsonl").read_text(encoding="utf-8")
    assert again != first
    depths = [o["depth"] for o in json.loads(again.splitlines()[0])["objects"]]
    assert min(depths) == pytest.approx(1200, abs=30)


def test_a_recording_with_a_file_added_is_redone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import shutil

    rec = _folder(tmp_path / "rec", 2000)
    out = tmp_path / "out"
    assert main(["batch", str(rec), "--out", str(out), "--quiet"]) == 0
    shutil.copy(rec / "001.png", rec / "002.png")
    assert main(["batch", str(rec), "--out", str(out), "--quiet"]) == 0
    assert "1 done" in capsys.readouterr().out
    assert _summary(out, "rec")["frames"] == 3


def test_batch_method_is_the_segmentation_method(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["batch", "sim:table", "--out", str(out), "--quiet", "--method", "threshold"]) == 0
    capsys.readouterr()
    assert main(["batch", "sim:table", "--out", str(out), "--quiet", "--method", "threshold"]) == 0
    assert "1 skipped" in capsys.readouterr().out
    assert main(["batch", "sim:table", "--out", str(out), "--quiet", "--method", "surfaces"]) == 0
    assert "1 done" in capsys.readouterr().out  # another method: other results, redone
    with pytest.raises(SystemExit) as exit_:
        main(["batch", "sim:table", "--out", str(out), "--method", "nonsense"])
    assert exit_.value.code == 2
