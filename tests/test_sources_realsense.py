"""The RealSense source, driven by a fake pyrealsense2 with the same calls (no camera here)."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.sources import open_source
from depthgram.sources.realsense import parse_realsense_spec


class _FakeDepthFrame:
    def __init__(self, data: np.ndarray, t_ms: float) -> None:
        self._data, self._t = data, t_ms

    def get_data(self) -> np.ndarray:
        return self._data

    def get_timestamp(self) -> float:
        return self._t


def _fake_rs(frames: list[np.ndarray], scale_m: float = 0.001, fail_start: bool = False) -> types.ModuleType:
    """A module with the pyrealsense2 calls the source makes; it records what was asked."""
    rs = types.ModuleType("pyrealsense2")
    rs.stream = types.SimpleNamespace(depth="depth")
    rs.format = types.SimpleNamespace(z16="z16")
    rs.log: list[tuple] = []

    class Config:
        def enable_stream(self, *args: object) -> None:
            rs.log.append(("enable_stream", *args))

        def enable_device(self, serial: str) -> None:
            rs.log.append(("enable_device", serial))

    intr = types.SimpleNamespace(fx=385.0, fy=386.0, ppx=321.5, ppy=239.5)
    profile = types.SimpleNamespace(
        get_device=lambda: types.SimpleNamespace(
            first_depth_sensor=lambda: types.SimpleNamespace(get_depth_scale=lambda: scale_m)
        ),
        get_stream=lambda s: types.SimpleNamespace(
            as_video_stream_profile=lambda: types.SimpleNamespace(get_intrinsics=lambda: intr)
        ),
    )

    class Pipeline:
        def __init__(self) -> None:
            self.k = 0

        def start(self, cfg: Config) -> object:
            if fail_start:
                raise RuntimeError("No device connected")
            rs.log.append(("start",))
            return profile

        def wait_for_frames(self, timeout_ms: int) -> object:
            if self.k >= len(frames):
                raise RuntimeError("Frame didn't arrive within 5000")
            f = _FakeDepthFrame(frames[self.k], 1000.0 + 33.4 * self.k)
            self.k += 1
            return types.SimpleNamespace(get_depth_frame=lambda: f)

        def stop(self) -> None:
            rs.log.append(("stop",))

    rs.config = Config
    rs.pipeline = Pipeline
    return rs


def test_frames_come_in_millimetres_with_device_intrinsics_and_times(monkeypatch: pytest.MonkeyPatch) -> None:
    raw = [np.full((4, 6), 1000 + 10 * k, np.uint16) for k in range(3)]
    raw[1][0, 0] = 0
    rs = _fake_rs(raw, scale_m=0.0005)  # D400 cameras can be set to 0.5 mm units
    monkeypatch.setitem(sys.modules, "pyrealsense2", rs)
    src = open_source("realsense:123?size=6x4&fps=30&frames=3")
    assert len(src) == 3 and src.fps == 30
    out = list(src)
    assert [f.index for f in out] == [0, 1, 2]
    assert out[0].depth[0, 0] == pytest.approx(500.0)  # 1000 units * 0.5 mm
    assert not out[1].valid[0, 0]
    assert [f.time_s for f in out] == pytest.approx([0.0, 0.0334, 0.0668])
    assert out[0].intrinsics is not None and out[0].intrinsics.fx == 385.0
    assert ("enable_device", "123") in rs.log and ("enable_stream", "depth", 6, 4, "z16", 30) in rs.log
    assert rs.log[-1] == ("stop",)  # the camera is released


def test_live_source_has_no_length_and_stops_when_the_consumer_stops(monkeypatch: pytest.MonkeyPatch) -> None:
    rs = _fake_rs([np.ones((2, 2), np.uint16)] * 10)
    monkeypatch.setitem(sys.modules, "pyrealsense2", rs)
    src = open_source("realsense:")
    with pytest.raises(TypeError):
        len(src)
    it = iter(src)
    next(it)
    it.close()
    assert rs.log[-1] == ("stop",)


def test_errors_say_what_is_wrong(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pyrealsense2", _fake_rs([], fail_start=True))
    with pytest.raises(InputError, match="cannot start the RealSense depth stream 640x480"):
        list(open_source("realsense:"))
    monkeypatch.setitem(sys.modules, "pyrealsense2", _fake_rs([]))
    with pytest.raises(InputError, match="no frame from the camera"):
        list(open_source("realsense:?frames=2"))
    with pytest.raises(InputError, match="unknown realsense option"):
        parse_realsense_spec("realsense:?zoom=2")
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)  # not installed
    with pytest.raises(InputError, match="pip install"):
        list(open_source("realsense:"))


def test_read_gives_the_source_so_a_pipeline_never_reads_a_camera_ahead(monkeypatch: pytest.MonkeyPatch) -> None:
    # read() used to be a bare generator: Pipeline.run could not see that the camera is live
    # and read it from the prefetch thread, frames ahead of the one being processed.
    import threading

    from depthgram import Pipeline, read
    from depthgram.sources import Source

    rs = _fake_rs([np.full((24, 32), 1500 + 100 * k, np.uint16) for k in range(3)])
    readers: list[str] = []
    wait = rs.pipeline.wait_for_frames

    def wait_for_frames(self: object, timeout_ms: int) -> object:
        readers.append(threading.current_thread().name)
        return wait(self, timeout_ms)

    monkeypatch.setattr(rs.pipeline, "wait_for_frames", wait_for_frames)
    monkeypatch.setitem(sys.modules, "pyrealsense2", rs)
    src = read("realsense:?size=32x24&frames=3")
    assert isinstance(src, Source) and src.live
    results = list(Pipeline().run(src, read_ahead=2))
    assert len(results) == 3
    assert readers == [threading.current_thread().name] * 3
