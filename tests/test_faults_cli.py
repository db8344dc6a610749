"""The command line under faults (issue 18.7, 18.10, 16.4): no look-alike outputs, closed pipes, clean errors."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from depthgram.cli import main


def _env() -> dict[str, str]:
    import depthgram

    return {**os.environ, "PYTHONPATH": str(Path(depthgram.__file__).resolve().parents[1])}


def test_a_failed_describe_leaves_no_output_file(tmp_path: Path) -> None:
    out = tmp_path / "scenes.jsonl"
    assert main(["describe", str(tmp_path / "missing.png"), "--json", str(out)]) == 2
    assert not out.exists()  # was a 0-byte file
    bad = tmp_path / "rec"
    bad.mkdir()
    (bad / "a.png").write_bytes(b"")  # the first frame fails
    assert main(["describe", str(bad), "--json", str(out)]) == 2
    assert list(tmp_path.glob("*scenes*")) == []


def test_write_wav_replaces_nothing_on_failure(tmp_path: Path) -> None:
    pytest.importorskip("soundfile")
    import numpy as np

    from depthgram.atomic import atomic_path
    from depthgram.sound.wav import write_wav

    wav = tmp_path / "a.wav"
    write_wav(wav, np.zeros((100, 2)), 8000)
    before = wav.read_bytes()
    with pytest.raises(RuntimeError), atomic_path(wav) as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("killed mid-write")
    assert wav.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["a.wav"]


def _depthgram(args: list[str], **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "depthgram.cli", *args], env=_env(), text=True, capture_output=True, timeout=300, **kw
    )  # type: ignore[call-overload,no-any-return]


def test_a_closed_pipe_ends_quietly(tmp_path: Path) -> None:
    # issue 16.4: `depthgram describe ... | head` printed "Broken pipe" (and a traceback)
    proc = subprocess.Popen(
        # the camera's tilt given: nothing estimated, so nothing at all is said on stderr
        [sys.executable, "-m", "depthgram.cli", "describe", "sim:crossing?frames=300", "--tilt", "8"],
        env=_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None and proc.stderr is not None
    first = proc.stdout.readline()
    proc.stdout.close()  # what `head -1` does
    err = proc.stderr.read()
    assert proc.wait(timeout=300) == 141
    assert first.strip() and err == ""


@pytest.mark.parametrize(
    ("args", "stream"),
    [(["info", "sim:table"], "output"), (["describe", "sim:table"], "output"), (["parse", "-"], "input")],
)
def test_a_closed_standard_stream_is_an_error_not_a_traceback_or_lost_output(args: list[str], stream: str) -> None:
    # issue 18.10: `info >&-` lost its output with exit 0, `parse - <&-` and `describe >&-` were tracebacks
    fd = 1 if stream == "output" else 0
    proc = subprocess.run(
        [sys.executable, "-m", "depthgram.cli", *args],
        env=_env(),
        stderr=subprocess.PIPE,
        text=True,
        timeout=300,
        pass_fds=(),
        preexec_fn=lambda: os.close(fd),
    )
    assert proc.returncode == 1
    assert f"standard {stream} is closed" in proc.stderr and "Traceback" not in proc.stderr


def test_library_messages_go_into_the_error_line(tmp_path: Path) -> None:
    # issue 18.10: libpng and OpenCV printed their own lines above depthgram's message
    import cv2
    import numpy as np

    good = tmp_path / "good.png"
    cv2.imwrite(str(good), (np.arange(64 * 48, dtype=np.uint16).reshape(48, 64) * 7) % 4000 + 500)
    data = good.read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    damaged = bytearray(data)
    damaged[len(data) // 2 : len(data) // 2 + 40] = b"x" * 40
    (tmp_path / "bad.png").write_bytes(bytes(damaged))
    for name in ("cut.png", "bad.png"):
        proc = _depthgram(["info", str(tmp_path / name)])
        assert proc.returncode == 2
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"depthgram info: error: {tmp_path / name}"), proc.stderr


def test_a_huge_frame_is_refused_before_it_is_decoded(tmp_path: Path) -> None:
    # issue 18.6: a 20000 x 20000 frame was a MemoryError after 5 GB; a 0.9 MB PNG took 8.8 GB
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    # a valid 16-bit grey PNG header of 20000 x 20000 px with a tiny (truncated) body
    ihdr = struct.pack(">IIBBBBB", 20000, 20000, 16, 0, 0, 0, 0)
    png = tmp_path / "huge.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 1000)))
    pgm = tmp_path / "huge.pgm"
    pgm.write_bytes(b"P5\n# big\n20000 20000\n65535\n" + b"\0" * 100)
    for path in (png, pgm):
        proc = _depthgram(["info", str(path)])
        assert proc.returncode == 2, proc.stderr
        assert "20000 x 20000 px" in proc.stderr and "DEPTHGRAM_MAX_PIXELS" in proc.stderr
        assert "Traceback" not in proc.stderr
    env = {**_env(), "DEPTHGRAM_MAX_PIXELS": "100"}
    proc = subprocess.run(
        [sys.executable, "-m", "depthgram.cli", "info", "sim:table"],
        env=env,
        text=True,
        capture_output=True,
        timeout=300,
    )
    assert proc.returncode == 0  # simulated frames are made, not read: no limit there
    small = tmp_path / "small.png"
    import cv2
    import numpy as np

    cv2.imwrite(str(small), np.full((20, 10), 1000, np.uint16))
    proc = subprocess.run(
        [sys.executable, "-m", "depthgram.cli", "info", str(small)],
        env=env,
        text=True,
        capture_output=True,
        timeout=300,
    )
    assert proc.returncode == 2 and "10 x 20 px" in proc.stderr
