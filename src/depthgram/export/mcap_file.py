"""The scene stream as MCAP with Foxglove's schemas: opens in Foxglove with no plugin.

One file per recording, frame after frame (memory stays at one frame). The topics and their
schemas (depth image, calibration, outlines, 3-D boxes, the sentence as a log line and the JSON
scene) are those of :mod:`depthgram.export.messages`, shared with the live Foxglove server of
``depthgram view --foxglove``.

Message times are the frames' (``time_s``; else index / rate), so Foxglove's timeline plays the
recording at its own pace. Written through the ``mcap`` library and the schemas of
``foxglove-schemas-protobuf`` (extra ``depthgram[mcap]``).
"""

from __future__ import annotations

import json
import os
from types import TracebackType
from typing import IO, TYPE_CHECKING

from depthgram._optional import needs_extra

with needs_extra("mcap", "writing MCAP"):
    from mcap.well_known import MessageEncoding, SchemaEncoding
    from mcap.writer import CompressionType, Writer

    from depthgram.export.messages import (
        FRAME_ID,
        MESSAGE_TYPES,
        SCENE_SCHEMA,
        TOPICS,
        assumed_intrinsics,
        colour,
        frame_messages,
        object_box_m,
        object_outlines,
        protobuf_schema,
    )

from depthgram.errors import InputError
from depthgram.frame import Frame

if TYPE_CHECKING:
    from depthgram.pipeline import SceneResult

# The message helpers are re-exported: they lived here before the live Foxglove server shared them.
__all__ = [
    "FRAME_ID",
    "TOPICS",
    "McapWriter",
    "assumed_intrinsics",
    "colour",
    "object_box_m",
    "object_outlines",
]

#: Frame rate assumed for frames with neither timestamps nor a known rate (frames/s).
_DEFAULT_FPS = 30.0


class _Counted:
    """A stream that cannot seek (a FIFO) with the ``tell`` the mcap writer asks for its offsets.

    The writer only ever appends, so the position is the count of bytes written (issue 32.1:
    ``--mcap FIFO`` failed with "Illegal seek").
    """

    def __init__(self, raw: IO[bytes]) -> None:
        self._raw = raw
        self._written = 0

    def write(self, data: bytes) -> int:
        n = self._raw.write(data)
        self._written += len(data) if n is None else n
        return len(data) if n is None else n

    def tell(self) -> int:
        return self._written

    def flush(self) -> None:
        self._raw.flush()


class McapWriter:
    """Write :class:`~depthgram.pipeline.SceneResult` frames to an MCAP file for Foxglove.

    Parameters
    ----------
    path : str or path
        The ``.mcap`` file to write (replaced when it exists).
    source : str
        What was read (stored in the file's ``depthgram`` metadata).
    fps : float, optional
        Frame rate (frames/s) for frames without timestamps; 30 when unknown.
    ttc_warn_s : float
        A frame with an object whose time to collision is under this (s) logs its sentence as
        a WARNING, so Foxglove's log panel shows it in colour.

    Examples
    --------
    >>> with McapWriter("out.mcap", source="sim:approach") as w:    # doctest: +SKIP
    ...     for result in Pipeline().run(read("sim:approach")):
    ...         w.add(result)
    """

    def __init__(
        self, path: str | os.PathLike[str], *, source: str = "", fps: float | None = None, ttc_warn_s: float = 3.0
    ) -> None:
        self.path = os.fspath(path)
        self.fps = fps or _DEFAULT_FPS
        self.ttc_warn_s = ttc_warn_s
        self.frames = 0
        self.counts: dict[str, int] = dict.fromkeys(TOPICS, 0)
        try:
            self._file = open(self.path, "wb")  # closed in close()
        except OSError as exc:
            raise InputError(f"--mcap {self.path}: cannot write ({exc.strerror or exc})") from None
        stream: IO[bytes] = self._file if self._file.seekable() else _Counted(self._file)  # type: ignore[assignment]
        self._writer = Writer(stream, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="depthgram")
        from depthgram import __version__

        self._writer.add_metadata("depthgram", {"source": source, "version": __version__})
        self._channels: dict[str, int] = {}
        scene_schema = self._writer.register_schema(
            name="depthgram.Scene", encoding=SchemaEncoding.JSONSchema, data=json.dumps(SCENE_SCHEMA).encode()
        )
        self._channels["/depthgram/scene"] = self._writer.register_channel(
            topic="/depthgram/scene", message_encoding=MessageEncoding.JSON, schema_id=scene_schema
        )
        self._closed = False

    def _time_ns(self, frame: Frame) -> int:
        t = frame.time_s if frame.time_s is not None else frame.index / self.fps
        return max(0, round(t * 1e9))

    def add(self, result: SceneResult) -> None:
        """Write one frame: its depth image, calibration, outlines, boxes, sentence and JSON record."""
        t_ns = self._time_ns(result.frame)
        for m in frame_messages(result, t_ns, self.ttc_warn_s):
            if m.topic not in self._channels:
                schema = self._writer.register_schema(
                    name=TOPICS[m.topic], encoding=SchemaEncoding.Protobuf, data=protobuf_schema(MESSAGE_TYPES[m.topic])
                )
                self._channels[m.topic] = self._writer.register_channel(
                    topic=m.topic, message_encoding=MessageEncoding.Protobuf, schema_id=schema
                )
            self._writer.add_message(
                channel_id=self._channels[m.topic],
                log_time=t_ns,
                publish_time=t_ns,
                sequence=self.frames,
                data=m.encode(),
            )
            self.counts[m.topic] += 1
        self.frames += 1

    def close(self) -> None:
        """Write the index and footer and close the file (also on error: what was written stays readable)."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()  # type: ignore[no-untyped-call]
        finally:
            self._file.close()

    def __enter__(self) -> McapWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
