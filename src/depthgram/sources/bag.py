"""ROS bags (ROS 1 ``.bag``, ROS 2 bag folders, ``.mcap``, ``.db3``) read through rosbags.

Depth comes from ``sensor_msgs/Image`` messages: ``16UC1``/``mono16`` in millimetres,
``32FC1`` in metres (as REP 118 says), ``8UC1``/``mono8`` as the paper's 8-bit depth. Frame
times come from the message header (the log time when the header stamp is zero).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from depthgram._optional import needs_extra
from depthgram.errors import DepthgramError, InputError
from depthgram.frame import Frame, Intrinsics
from depthgram.sources.base import Source
from depthgram.sources.config import SourceConfig
from depthgram.sources.decode import to_frame
from depthgram.sources.images import check_size

__all__ = ["BAG_SUFFIXES", "BagSource", "image_array"]

BAG_SUFFIXES = frozenset({".bag", ".mcap", ".db3"})
_IMAGE = "sensor_msgs/msg/Image"
_INFO = "sensor_msgs/msg/CameraInfo"
_DTYPES = {"16uc1": "u2", "mono16": "u2", "32fc1": "f4", "8uc1": "u1", "mono8": "u1", "16sc1": "i2"}


def image_array(msg: Any, where: str) -> np.ndarray:
    """Return the (H, W) samples of a ``sensor_msgs/Image`` depth message, honouring step and endianness."""
    enc = str(msg.encoding).lower()
    if enc not in _DTYPES:
        raise InputError(f"{where}: image encoding {msg.encoding!r} is not depth; expected 16UC1 (mm) or 32FC1 (m)")
    dtype = np.dtype(_DTYPES[enc]).newbyteorder(">" if msg.is_bigendian else "<")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    check_size(h, w, where)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * dtype.itemsize or data.size < h * step:
        raise InputError(f"{where}: image data of {data.size} bytes is too short for {w}x{h} {msg.encoding}")
    rows = data[: h * step].reshape(h, step)[:, : w * dtype.itemsize]
    return np.ascontiguousarray(rows).view(dtype).reshape(h, w).astype(dtype.newbyteorder("="))


def _reader(path: Path) -> Any:
    with needs_extra("bags", f"{path}: reading ROS bags"):
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

    # Bags without embedded message definitions (ROS 2 before Iron) need a default typestore.
    return AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))


def _messages(reader: Any, conns: list[Any], path: Path, topic: str) -> Iterator[tuple[Any, int, bytes]]:
    """Yield ``reader.messages``, a damaged file's error turned into an InputError.

    The errors turned are rosbags' ReaderError, AssertionError, sqlite's CorruptError and a
    decompressor's; the InputError names the message.
    """
    it = iter(reader.messages(connections=conns))
    i = 0
    last: int | None = None
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except Exception as exc:
            after = f", after log time {last} ns" if last is not None else ""
            raise InputError(
                f"{path}: the bag is damaged at message {i} of topic {topic}{after} ({type(exc).__name__}: {exc})"
            ) from None
        last = item[1]
        i += 1
        yield item


class BagSource(Source):
    """Depth frames of one ``sensor_msgs/Image`` topic of a ROS bag.

    Parameters
    ----------
    path : Path
        ``.bag`` file, ROS 2 bag folder (with ``metadata.yaml``), ``.mcap`` or ``.db3`` file.
    cfg : SourceConfig
        Units and ``topic``: needed when the bag has several depth-like Image topics.
    name : str
        The spec.
    intrinsics : Intrinsics, optional
        Overrides the first ``CameraInfo`` of the topic's namespace.
    fps : float, optional
        Frame rate (frames/s) to report; frame times always come from the headers.
    """

    kind = "bag"

    def __init__(
        self,
        path: Path,
        cfg: SourceConfig,
        *,
        name: str,
        intrinsics: Intrinsics | None = None,
        fps: float | None = None,
    ) -> None:
        self.path = path
        self.cfg = cfg
        self.name = name
        self.fps = fps
        if cfg.timestamps is not None:
            raise InputError(f"{path}: a bag's frame times come from its message headers; drop timestamps=")
        try:
            with _reader(path) as reader:
                conns = list(reader.connections)
                topics = sorted({c.topic for c in conns})
                images = sorted({c.topic for c in conns if c.msgtype == _IMAGE})
                self.topic = self._choose(topics, images)
                mine = [c for c in conns if c.topic == self.topic]
                self.n = sum(int(c.msgcount) for c in mine)
                self.intrinsics = intrinsics or self._camera_info(reader, conns)
        except DepthgramError:  # ours already (a missing extra, a bad topic): as it is
            raise
        except Exception as exc:
            raise InputError(
                f"{path}: cannot read the bag, damaged or not a bag ({type(exc).__name__}: {exc})"
            ) from None

    def _choose(self, topics: list[str], images: list[str]) -> str:
        listing = ", ".join(topics) or "no topics"
        if self.cfg.topic is not None:
            if self.cfg.topic not in images:
                raise InputError(
                    f"{self.path}: no sensor_msgs/Image topic {self.cfg.topic!r}; "
                    f"Image topics: {', '.join(images) or 'none'} (all topics: {listing})"
                )
            return self.cfg.topic
        if not images:
            raise InputError(f"{self.path}: no sensor_msgs/Image depth topic in the bag (topics: {listing})")
        depthish = [t for t in images if "depth" in t.lower()]
        if len(images) == 1:
            return images[0]
        if len(depthish) == 1:
            return depthish[0]
        raise InputError(f"{self.path}: several Image topics ({', '.join(images)}); choose one with topic= (--topic)")

    def _camera_info(self, reader: Any, conns: list[Any]) -> Intrinsics | None:
        # camera_info lives beside the image topic: /cam/depth/image_raw -> /cam/depth/camera_info.
        ns = self.topic.rsplit("/", 1)[0]
        infos = [c for c in conns if c.msgtype == _INFO and c.topic.rsplit("/", 1)[0] == ns]
        if not infos:  # an empty connection list would mean "all messages" to rosbags
            return None
        for conn, _, raw in reader.messages(connections=infos[:1]):
            msg = reader.deserialize(raw, conn.msgtype)
            k = getattr(msg, "k", None)
            if k is None:  # ROS 1 spells it K
                k = msg.K
            return Intrinsics(float(k[0]), float(k[4]), float(k[2]), float(k[5]))
        return None

    def __len__(self) -> int:
        return self.n

    def __iter__(self) -> Iterator[Frame]:
        try:
            reader = _reader(self.path)
            reader.open()
        except DepthgramError:  # ours already (a missing extra, a bad topic): as it is
            raise
        except Exception as exc:
            raise InputError(f"{self.path}: cannot read the bag, damaged or not a bag ({exc})") from None
        try:
            conns = [c for c in reader.connections if c.topic == self.topic]
            first: tuple[int, int] | None = None
            for i, (conn, log_ns, raw) in enumerate(_messages(reader, conns, self.path, self.topic)):
                where = f"{self.path} topic {self.topic} (frame {i})"
                try:
                    msg = reader.deserialize(raw, conn.msgtype)
                except Exception as exc:
                    raise InputError(
                        f"{where}: cannot decode the message at log time {log_ns} ns, the bag is damaged "
                        f"({type(exc).__name__}: {exc})"
                    ) from None
                try:
                    stamp = msg.header.stamp
                    t = stamp.sec + stamp.nanosec * 1e-9
                    samples = image_array(msg, where)
                except DepthgramError:  # ours already (an encoding that is not depth): as it is
                    raise
                except (AttributeError, TypeError, ValueError) as exc:
                    # a damaged message definition embedded in the bag decodes to other fields (issue 32.2)
                    raise InputError(
                        f"{where}: the message at log time {log_ns} ns is not a readable sensor_msgs/Image, "
                        f"the bag is damaged ({type(exc).__name__}: {exc})"
                    ) from None
                frame = to_frame(
                    samples,
                    self.cfg,
                    where=where,
                    index=i,
                    time_s=t if t > 0 else log_ns * 1e-9,
                    intrinsics=self.intrinsics,
                    name=f"bag:{self.topic}#{i}",
                )
                if first is None:
                    first = frame.size
                elif frame.size != first:
                    raise InputError(
                        f"{where}: image is {frame.size[0]}x{frame.size[1]} px but frame 0 is "
                        f"{first[0]}x{first[1]} px; all frames of a sequence must have one size"
                    )
                yield frame
        finally:
            reader.close()
