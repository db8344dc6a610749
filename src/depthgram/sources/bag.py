"""ROS bags (ROS 1 ``.bag``, ROS 2 bag folders, ``.mcap``, ``.db3``) read through rosbags.

Depth comes from ``sensor_msgs/Image`` messages: ``16UC1``/``mono16`` in millimetres,
``32FC1`` in metres (as REP 118 says), ``8UC1``/``mono8`` as the paper's 8-bit depth. Frame
times come from the message header (the log time when the header stamp is zero). Gravity comes
from a ``sensor_msgs/Imu`` topic when there is one, turned into the depth image's axes by the
bag's ``/tf_static`` (:mod:`depthgram.sources.imu`).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from depthgram._optional import needs_extra
from depthgram.errors import DepthgramError, InputError
from depthgram.frame import Frame, Gravity, Intrinsics
from depthgram.sources.base import Source
from depthgram.sources.camera import Camera
from depthgram.sources.config import SourceConfig
from depthgram.sources.decode import to_frame
from depthgram.sources.images import check_size
from depthgram.sources.imu import GravityFilter, StaticFrames

__all__ = ["BAG_SUFFIXES", "BagSource", "image_array"]

BAG_SUFFIXES = frozenset({".bag", ".mcap", ".db3"})
_IMAGE = "sensor_msgs/msg/Image"
_INFO = "sensor_msgs/msg/CameraInfo"
_IMU = "sensor_msgs/msg/Imu"
_TF = "tf2_msgs/msg/TFMessage"
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
    intrinsics_source = "bag"  # its CameraInfo

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
        self._info: Camera | None = None  # the CameraInfo with the image size it is for
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
                self.imu_topic = self._choose_imu(sorted({c.topic for c in conns if c.msgtype == _IMU}))
                self.static = self._static_frames(reader, conns) if self.imu_topic else StaticFrames()
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
            intr = Intrinsics(float(k[0]), float(k[4]), float(k[2]), float(k[5]))
            w, h = int(getattr(msg, "width", 0)), int(getattr(msg, "height", 0))
            if w > 0 and h > 0:
                # images of another size than the calibration's (binned, resized) get it scaled
                self._info = Camera(intr, "bag", f"{self.path} {conn.topic}", (w, h))
            return intr
        return None

    def _choose_imu(self, imus: list[str]) -> str | None:
        """Return the IMU topic nearest the depth topic (the longest shared namespace), or None."""
        if not imus:
            return None

        def shared(topic: str) -> int:
            a, b = topic.split("/"), self.topic.split("/")
            n = 0
            while n < min(len(a), len(b)) and a[n] == b[n]:
                n += 1
            return n

        return max(imus, key=lambda t: (shared(t), "accel" in t or "imu" in t, t))

    def _static_frames(self, reader: Any, conns: list[Any]) -> StaticFrames:
        frames = StaticFrames()
        tfs = [c for c in conns if c.msgtype == _TF and c.topic.rstrip("/").endswith("tf_static")]
        if not tfs:
            return frames
        for conn, _, raw in reader.messages(connections=tfs):
            for t in reader.deserialize(raw, conn.msgtype).transforms:
                q = t.transform.rotation
                frames.add(str(t.header.frame_id), str(t.child_frame_id), (q.x, q.y, q.z, q.w))
        return frames

    def _gravity(self, down: Any, imu_frame: str, camera_frame: str) -> Gravity | None:
        """Return gravity in the depth image's axes from the IMU's ``down``, or None (with a warning) when unlinked."""
        if down is None:
            return None
        rot = self.static.rotation(camera_frame, imu_frame)
        if rot is None:
            if not getattr(self, "_warned_tf", False):
                self._warned_tf = True
                warnings.warn(
                    f"{self.path}: the IMU ({self.imu_topic}, frame {imu_frame!r}) has no static transform to the "
                    f"depth image's frame {camera_frame!r} in /tf_static: gravity is not read from it; give it "
                    "with --gravity X Y Z or --tilt DEG",
                    UserWarning,
                    stacklevel=3,
                )
            return None
        v = rot @ down
        return Gravity((float(v[0]), float(v[1]), float(v[2])), "imu")

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
            imu = self.imu_topic if self.gravity is None else None  # the user's gravity wins: skip the IMU
            conns = [c for c in reader.connections if c.topic in (self.topic, imu)]
            first: tuple[int, int] | None = None
            accel, imu_frame = GravityFilter(), ""
            i = 0
            for conn, log_ns, raw in _messages(reader, conns, self.path, self.topic):
                where = f"{self.path} topic {conn.topic} (frame {i})"
                try:
                    msg = reader.deserialize(raw, conn.msgtype)
                except Exception as exc:
                    raise InputError(
                        f"{where}: cannot decode the message at log time {log_ns} ns, the bag is damaged "
                        f"({type(exc).__name__}: {exc})"
                    ) from None
                if conn.topic != self.topic:
                    a = msg.linear_acceleration
                    accel.add((float(a.x), float(a.y), float(a.z)), log_ns * 1e-9)
                    imu_frame = str(msg.header.frame_id)
                    continue
                stamp = msg.header.stamp
                t = stamp.sec + stamp.nanosec * 1e-9
                samples = image_array(msg, where)
                intrinsics = self.intrinsics
                if self._info is not None and intrinsics is not None:
                    intrinsics = self.intrinsics = self._info.for_size((samples.shape[1], samples.shape[0]))
                frame = to_frame(
                    samples,
                    self.cfg,
                    where=where,
                    index=i,
                    time_s=t if t > 0 else log_ns * 1e-9,
                    intrinsics=intrinsics,
                    name=f"bag:{self.topic}#{i}",
                )
                if imu is not None:
                    gravity = self._gravity(accel.down(), imu_frame, str(msg.header.frame_id))
                    if gravity is not None:
                        frame = dataclasses.replace(frame, gravity=gravity)
                if first is None:
                    first = frame.size
                elif frame.size != first:
                    raise InputError(
                        f"{where}: image is {frame.size[0]}x{frame.size[1]} px but frame 0 is "
                        f"{first[0]}x{first[1]} px; all frames of a sequence must have one size"
                    )
                yield self.calibrated(frame)
                i += 1
        finally:
            reader.close()
