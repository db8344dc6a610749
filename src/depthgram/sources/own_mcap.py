"""depthgram's own MCAP (``describe --mcap``) read back: its depth topic and calibration as frames.

The file holds Foxglove's protobuf schemas, not ROS 2 messages, so rosbags refuses it ("Profile
is not ros2", issue 32.4). ``/depthgram/depth`` is a ``foxglove.RawImage`` in ``16UC1`` mm and
``/depthgram/calibration`` a ``foxglove.CameraCalibration`` of the same frame; the frame's time
is the message's. Intrinsics the writer assumed for a frame without any (its distortion model
says so) are not read back as the camera's.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from depthgram._optional import needs_extra
from depthgram.errors import DepthgramError, InputError
from depthgram.frame import Frame, Intrinsics
from depthgram.sources.base import Source
from depthgram.sources.config import SourceConfig
from depthgram.sources.decode import to_frame

__all__ = ["OwnMcapSource", "is_own_mcap"]

DEPTH_TOPIC = "/depthgram/depth"
CALIBRATION_TOPIC = "/depthgram/calibration"
#: The writer's ``library`` field (``McapWriter``): depthgram's file rather than a ROS 2 bag.
LIBRARY = "depthgram"
_ASSUMED = "assumed"


def is_own_mcap(path: Path) -> bool:
    """Tell whether ``path`` is an MCAP file that depthgram wrote (its header names depthgram).

    False for anything else, a ROS 2 MCAP bag or a file too damaged to have a header, which the
    bag reader then reads or refuses.
    """
    try:
        from mcap.reader import make_reader
    except ImportError:  # without the extra the bag reader's message names what to install
        return False
    try:
        with open(path, "rb") as fh:
            header = make_reader(fh).get_header()
    except Exception:  # not an MCAP file, or damaged at its start: not ours to say
        return False
    return header.profile != "ros2" and str(header.library).startswith(LIBRARY)


class OwnMcapSource(Source):
    """Depth frames of depthgram's own MCAP file, with the intrinsics of its calibration topic.

    Parameters
    ----------
    path : Path
        The ``.mcap`` file ``depthgram describe --mcap`` wrote.
    cfg : SourceConfig
        Units and invalid markers (the file holds millimetres: the defaults read it as written).
    name : str
        The spec.
    intrinsics : Intrinsics, optional
        Overrides the file's calibration.
    fps : float, optional
        Frame rate (frames/s) to report; frame times come from the messages.
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
        self._given = intrinsics
        self.intrinsics = intrinsics
        if cfg.timestamps is not None:
            raise InputError(f"{path}: an MCAP file's frame times come from its messages; drop timestamps=")
        self.n = 0
        for _ in self._messages(DEPTH_TOPIC):
            self.n += 1
        if self.n == 0:
            raise InputError(f"{path}: no {DEPTH_TOPIC} messages in depthgram's MCAP file")
        if self.intrinsics is None:
            for _, calibration in self._messages(CALIBRATION_TOPIC):
                self.intrinsics = _intrinsics(calibration)
                break

    def _messages(self, topic: str) -> Iterator[tuple[int, Any]]:
        """Yield (log time ns, decoded protobuf message) of ``topic``, damage as an InputError."""
        with needs_extra("mcap", f"{self.path}: reading depthgram's MCAP"):
            from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
            from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
            from mcap.reader import make_reader
        decode: Any = {DEPTH_TOPIC: RawImage, CALIBRATION_TOPIC: CameraCalibration}[topic]
        i = 0
        try:
            with open(self.path, "rb") as fh:
                # (mcap reads a file without its summary, cut short by a killed writer, in
                # file order: its frames up to the cut are kept)
                for _, _channel, message in make_reader(fh).iter_messages(topics=[topic]):
                    yield message.log_time, decode.FromString(message.data)
                    i += 1
        except DepthgramError:
            raise
        except Exception as exc:  # mcap's and protobuf's many error types for a damaged file
            raise InputError(
                f"{self.path}: depthgram's MCAP file is damaged at message {i} of topic {topic} "
                f"({type(exc).__name__}: {exc})"
            ) from None

    def __len__(self) -> int:
        return self.n

    def __iter__(self) -> Iterator[Frame]:
        from depthgram.sources.bag import image_array

        first: tuple[int, int] | None = None
        for i, (log_ns, msg) in enumerate(self._messages(DEPTH_TOPIC)):
            where = f"{self.path} topic {DEPTH_TOPIC} (frame {i})"
            image = _RosLike(msg)
            frame = to_frame(
                image_array(image, where),
                self.cfg,
                where=where,
                index=i,
                time_s=log_ns * 1e-9,
                intrinsics=self.intrinsics,
                name=f"mcap:{DEPTH_TOPIC}#{i}",
            )
            if first is None:
                first = frame.size
            elif frame.size != first:
                raise InputError(
                    f"{where}: image is {frame.size[0]}x{frame.size[1]} px but frame 0 is "
                    f"{first[0]}x{first[1]} px; all frames of a sequence must have one size"
                )
            yield frame


class _RosLike:
    """A ``foxglove.RawImage`` seen as the ``sensor_msgs/Image`` that :func:`image_array` reads."""

    def __init__(self, msg: Any) -> None:
        self.height, self.width, self.step = msg.height, msg.width, msg.step
        self.encoding = msg.encoding
        self.is_bigendian = 0  # Foxglove's RawImage is little-endian by definition
        self.data = memoryview(msg.data)


def _intrinsics(calibration: Any) -> Intrinsics | None:
    if str(calibration.distortion_model).startswith(_ASSUMED) or len(calibration.K) != 9:
        return None
    k = calibration.K
    return Intrinsics(fx=float(k[0]), fy=float(k[4]), cx=float(k[2]), cy=float(k[5]))
