"""A live Intel RealSense camera as a source: ``realsense:`` or ``realsense:SERIAL?size=640x480&fps=30``.

Needs the optional extra ``pip install depthgram[realsense]`` (Intel's ``pyrealsense2``). It cannot be
tested without a camera, so it is kept small: one depth stream, the device's own depth scale and
intrinsics, frame times from the device clock. Tests drive it with a fake ``pyrealsense2`` module
that has the same calls.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qsl

from depthgram.errors import InputError
from depthgram.frame import Frame, Intrinsics, make_frame
from depthgram.sources.base import Source

__all__ = ["RealSenseSource", "RealSenseSpec", "parse_realsense_spec"]

PREFIX = "realsense:"


@dataclass(frozen=True)
class RealSenseSpec:
    """A parsed ``realsense:`` spec.

    Attributes
    ----------
    serial : str
        Device serial number; empty for the first camera found.
    size : tuple of int
        Depth stream (width, height) in px; one the camera offers (640x480, 848x480, 1280x720 ...).
    fps : int
        Depth stream rate (frames/s): 6, 15, 30, 60 or 90 on D400 cameras.
    frames : int
        Frames to read; 0 reads until the consumer stops.
    """

    serial: str = ""
    size: tuple[int, int] = (640, 480)
    fps: int = 30
    frames: int = 0


def parse_realsense_spec(spec: str) -> RealSenseSpec:
    """Parse ``realsense:[SERIAL][?size=WxH&fps=F&frames=N]``."""
    body = spec[len(PREFIX) :] if spec.startswith(PREFIX) else spec
    serial, _, query = body.partition("?")
    opts = dict(parse_qsl(query, keep_blank_values=True))
    unknown = set(opts) - {"size", "fps", "frames"}
    if unknown:
        raise InputError(f"{spec}: unknown realsense option(s) {sorted(unknown)}; expected size, fps, frames")
    try:
        w, h = (int(v) for v in opts.get("size", "640x480").lower().split("x"))
        fps = int(opts.get("fps", "30"))
        frames = int(opts.get("frames", "0"))
    except ValueError:
        raise InputError(f"{spec}: size must be WxH and fps, frames whole numbers") from None
    if w <= 0 or h <= 0 or fps <= 0 or frames < 0:
        raise InputError(f"{spec}: size and fps must be positive and frames >= 0")
    return RealSenseSpec(serial, (w, h), fps, frames)


class RealSenseSource(Source):
    """Depth frames from a RealSense camera, one at a time, as the device delivers them."""

    kind = "realsense"
    live = True
    intrinsics_source = "device"  # the camera's own calibration

    def __init__(self, spec: RealSenseSpec, *, name: str = PREFIX, timeout_ms: int = 5000) -> None:
        self.spec = spec
        self.name = name
        self.fps = float(spec.fps)
        self.timeout_ms = timeout_ms
        self.intrinsics: Intrinsics | None = None

    def __len__(self) -> int:
        if self.spec.frames == 0:
            raise TypeError("a live camera has no length")
        return self.spec.frames

    def __iter__(self) -> Iterator[Frame]:
        rs = _backend()
        pipe = rs.pipeline()
        cfg = rs.config()
        if self.spec.serial:
            cfg.enable_device(self.spec.serial)
        w, h = self.spec.size
        cfg.enable_stream(rs.stream.depth, w, h, rs.format.z16, self.spec.fps)
        try:
            profile = pipe.start(cfg)
        except RuntimeError as exc:  # no camera, busy camera, or a mode it does not offer
            raise InputError(
                f"{self.name}: cannot start the RealSense depth stream {w}x{h} at {self.spec.fps} frames/s: {exc}"
            ) from None
        try:
            scale_mm = float(profile.get_device().first_depth_sensor().get_depth_scale()) * 1000.0
            k = profile.get_stream(rs.stream.depth).as_video_stream_profile().get_intrinsics()
            self.intrinsics = Intrinsics(float(k.fx), float(k.fy), float(k.ppx), float(k.ppy))
            index = 0
            t0: float | None = None
            while self.spec.frames == 0 or index < self.spec.frames:
                try:
                    frames = pipe.wait_for_frames(self.timeout_ms)
                except RuntimeError as exc:
                    raise InputError(
                        f"{self.name}: no frame from the camera within {self.timeout_ms} ms (frame {index}): {exc}"
                    ) from None
                depth = frames.get_depth_frame()
                t_ms = float(depth.get_timestamp())
                t0 = t_ms if t0 is None else t0
                yield self.calibrated(
                    make_frame(
                        _as_array(depth.get_data()),
                        scale_mm=scale_mm,
                        index=index,
                        time_s=(t_ms - t0) / 1000.0,
                        intrinsics=self.intrinsics,
                        name=f"{self.name}#{index}",
                    )
                )
                index += 1
        finally:
            pipe.stop()


def _as_array(data: Any) -> Any:
    import numpy as np

    return np.asanyarray(data)


def _backend() -> Any:
    try:
        return importlib.import_module("pyrealsense2")
    except ImportError:
        raise InputError("realsense: needs Intel's pyrealsense2: pip install 'depthgram[realsense]'") from None
