"""One frame's results as Foxglove messages: built once for the MCAP file and the live Foxglove server.

Topics, all in the camera's optical frame ``camera`` (x right, y down, z forward, metres):

=========================== ============================== ================================================
topic                       schema                         what
=========================== ============================== ================================================
``/depthgram/depth``        ``foxglove.RawImage``          the depth image, ``16UC1`` in mm (0 = no reading)
``/depthgram/calibration``  ``foxglove.CameraCalibration`` the pinhole intrinsics (the 3-D panel needs them)
``/depthgram/objects``      ``foxglove.ImageAnnotations``  each object's outline (a closed line in its
                                                           colour) and a label "#id kind depth [ttc]"
``/depthgram/boxes``        ``foxglove.SceneUpdate``       each object as a 3-D box over its pixels
``/depthgram/sentence``     ``foxglove.Log``               the frame's sentence of the grammar (INFO;
                                                           WARNING when a time to collision is short)
``/depthgram/scene``        JSON (``depthgram.Scene``)     the ``depthgram describe`` JSON line: objects,
                                                           v_radial, ttc, relations (plot them in Foxglove)
=========================== ============================== ================================================

The Foxglove schemas are the protobuf ones of ``foxglove-schemas-protobuf``; the caller imports
this module inside :func:`depthgram._optional.needs_extra` with its own extra (``mcap`` for the
file, ``foxglove`` for the live server).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TextAnnotation_pb2 import TextAnnotation
from foxglove_schemas_protobuf.TextPrimitive_pb2 import TextPrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.descriptor import FileDescriptor
from google.protobuf.descriptor_pb2 import FileDescriptorSet
from google.protobuf.duration_pb2 import Duration
from google.protobuf.message import Message
from google.protobuf.timestamp_pb2 import Timestamp
from numpy.typing import NDArray

from depthgram.frame import Frame, Intrinsics

if TYPE_CHECKING:
    from depthgram.pipeline import SceneResult

__all__ = [
    "FRAME_ID",
    "SCENE_SCHEMA",
    "TOPICS",
    "TopicMessage",
    "assumed_intrinsics",
    "colour",
    "frame_messages",
    "object_box_m",
    "object_outlines",
    "protobuf_schema",
]


#: The camera's optical frame: every topic's frame_id.
FRAME_ID = "camera"

#: Topic -> schema name, in the order they are written for each frame.
TOPICS = {
    "/depthgram/depth": "foxglove.RawImage",
    "/depthgram/calibration": "foxglove.CameraCalibration",
    "/depthgram/objects": "foxglove.ImageAnnotations",
    "/depthgram/boxes": "foxglove.SceneUpdate",
    "/depthgram/sentence": "foxglove.Log",
    "/depthgram/scene": "depthgram.Scene",
}

#: Horizontal field of view assumed without intrinsics (degrees): the boxes are then drawn to
#: scale only roughly, and the calibration says so in its distortion model name.
_ASSUMED_FOV_DEG = 64.0

#: Pixels of an object sampled for its 3-D box.
_BOX_SAMPLE = 4000

#: Object colours by id (Okabe-Ito, distinguishable with colour-blindness), RGB 0..1.
_PALETTE = (
    (0.90, 0.62, 0.0),
    (0.34, 0.71, 0.91),
    (0.0, 0.62, 0.45),
    (0.94, 0.89, 0.26),
    (0.0, 0.45, 0.70),
    (0.84, 0.37, 0.0),
    (0.80, 0.47, 0.65),
    (0.6, 0.6, 0.6),
)

#: The JSON schema of ``/depthgram/scene`` (the ``depthgram describe`` line; loose on purpose:
#: Foxglove only needs to know it is an object to show and plot its fields).
SCENE_SCHEMA = {
    "title": "depthgram.Scene",
    "description": "One frame as depthgram describe writes it: objects (mm, px, mm/s, s), relations, sentence",
    "type": "object",
    "properties": {
        "frame": {"type": "integer"},
        "time_s": {"type": ["number", "null"]},
        "sentence": {"type": "string"},
        "objects": {"type": "array", "items": {"type": "object"}},
        "relations": {"type": "array"},
    },
}


def colour(object_id: int, alpha: float = 1.0) -> Color:
    """Return the colour of an object (by id, so a track keeps its colour)."""
    r, g, b = _PALETTE[(object_id - 1) % len(_PALETTE)]
    return Color(r=r, g=g, b=b, a=alpha)


def assumed_intrinsics(width: int, height: int) -> Intrinsics:
    """Return a pinhole camera of :data:`_ASSUMED_FOV_DEG` horizontal field of view, centred (px)."""
    f = (width / 2.0) / math.tan(math.radians(_ASSUMED_FOV_DEG / 2.0))
    return Intrinsics(f, f, (width - 1) / 2.0, (height - 1) / 2.0)


def object_outlines(
    labels: NDArray[np.integer], object_id: int, box: tuple[int, int, int, int]
) -> list[NDArray[np.int32]]:
    """Outer outlines of an object's pixels as closed polygons of (x, y) pixel corners.

    Only the object's box is searched; polygons are simplified to within 1 px
    (``cv2.approxPolyDP``) so that a frame's annotations stay a few kB.
    """
    x0, y0, x1, y1 = box
    mask = np.ascontiguousarray(labels[y0:y1, x0:x1] == object_id, dtype=np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = []
    for c in contours:
        if cv2.contourArea(c) < 4.0:
            continue
        poly = cv2.approxPolyDP(c, 1.0, True).reshape(-1, 2).astype(np.int32)
        out.append(poly + np.array([x0, y0], np.int32))
    return out


def object_box_m(
    frame: Frame, labels: NDArray[np.integer], object_id: int, box: tuple[int, int, int, int], k: Intrinsics
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Centre and size (m) of the 3-D box over an object's pixels, in the camera's optical frame.

    The 2nd to 98th percentile of the back-projected pixels on each axis: a few stray pixels
    (mixed depths at the object's rim) do not stretch the box. None when no pixel is valid.
    """
    x0, y0, x1, y1 = box
    sel = (labels[y0:y1, x0:x1] == object_id) & frame.valid[y0:y1, x0:x1]
    rows, cols = np.nonzero(sel)
    if rows.size == 0:
        return None
    if rows.size > _BOX_SAMPLE:
        # every k-th pixel: the same percentiles to a few mm, at a fraction of the cost of
        # sorting a wall's 100,000 depths (it was most of the time per frame written)
        step = rows.size // _BOX_SAMPLE
        rows, cols = rows[::step], cols[::step]
    z = frame.depth[y0:y1, x0:x1][rows, cols].astype(np.float64) / 1000.0
    x = (cols + x0 - k.cx) * z / k.fx
    y = (rows + y0 - k.cy) * z / k.fy
    pts = np.stack([x, y, z])
    lo, hi = np.percentile(pts, [2.0, 98.0], axis=1)
    # a surface facing the camera is flat: give it the thickness of one depth step rather than 0
    return (lo + hi) / 2.0, np.maximum(hi - lo, 0.005)


#: The protobuf message class of each Foxglove topic (the scene topic is JSON).
MESSAGE_TYPES: dict[str, type[Message]] = {
    "/depthgram/depth": RawImage,
    "/depthgram/calibration": CameraCalibration,
    "/depthgram/objects": ImageAnnotations,
    "/depthgram/boxes": SceneUpdate,
    "/depthgram/sentence": Log,
}


def protobuf_schema(message_class: type[Message]) -> bytes:
    """Return the schema of a protobuf message class as Foxglove and MCAP want it.

    A serialised ``FileDescriptorSet`` of its file and every file it depends on.
    """
    fds = FileDescriptorSet()
    seen: set[str] = set()

    def add(fd: FileDescriptor) -> None:
        for dep in fd.dependencies:
            if dep.name not in seen:
                seen.add(dep.name)
                add(dep)
        fd.CopyToProto(fds.file.add())

    add(message_class.DESCRIPTOR.file)
    return bytes(fds.SerializeToString())


@dataclass(frozen=True)
class TopicMessage:
    """One message of a frame: its topic and its payload (a protobuf message, or a dict for JSON)."""

    topic: str
    message: Message | dict[str, Any]

    def encode(self) -> bytes:
        """Return the message's bytes on the wire (protobuf, or UTF-8 JSON)."""
        if isinstance(self.message, dict):
            return json.dumps(self.message).encode()
        return bytes(self.message.SerializeToString())


def _stamp(t_ns: int) -> Timestamp:
    return Timestamp(seconds=t_ns // 1_000_000_000, nanos=t_ns % 1_000_000_000)


def frame_messages(result: SceneResult, t_ns: int, ttc_warn_s: float = 3.0) -> list[TopicMessage]:
    """One frame's messages, one per topic of :data:`TOPICS` and in its order.

    Parameters
    ----------
    result : SceneResult
        The pipeline's result for the frame.
    t_ns : int
        The messages' time stamp (ns): the frame's time in a file, the wall clock live.
    ttc_warn_s : float
        A frame with an object whose time to collision is under this (s) logs its sentence
        as a WARNING, so Foxglove's log panel shows it in colour.
    """
    frame = result.frame
    labels = result.segmentation.labels
    stamp = _stamp(t_ns)
    out: list[TopicMessage] = []
    w, h = frame.size
    k = frame.intrinsics or assumed_intrinsics(w, h)

    depth = np.minimum(np.rint(frame.depth), 65535).astype("<u2")
    out.append(
        TopicMessage(
            "/depthgram/depth",
            RawImage(
                timestamp=stamp,
                frame_id=FRAME_ID,
                width=w,
                height=h,
                encoding="16UC1",
                step=2 * w,
                data=depth.tobytes(),
            ),
        )
    )
    out.append(
        TopicMessage(
            "/depthgram/calibration",
            CameraCalibration(
                timestamp=stamp,
                frame_id=FRAME_ID,
                width=w,
                height=h,
                distortion_model="" if frame.intrinsics else "assumed (64 degrees)",
                K=[k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
                R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                P=[k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            ),
        )
    )

    record = result.to_record()
    by_id = {o["id"]: o for o in record["objects"]}
    points: list[PointsAnnotation] = []
    texts: list[TextAnnotation] = []
    entities: list[SceneEntity] = []
    warn = False
    for obj in result.segmentation.objects:
        rec = by_id.get(obj.id, {})
        ttc = rec.get("ttc")
        warn |= ttc is not None and 0 < ttc < ttc_warn_s
        label = f"#{obj.id} {obj.kind} {obj.depth / 1000:.2f} m" + (f" ttc {ttc:.1f} s" if ttc is not None else "")
        for poly in object_outlines(labels, obj.id, obj.bbox_xy):
            points.append(
                PointsAnnotation(
                    timestamp=stamp,
                    type=PointsAnnotation.Type.LINE_LOOP,
                    thickness=2.0,
                    outline_color=colour(obj.id),
                    fill_color=colour(obj.id, 0.15),
                    points=[Point2(x=float(x), y=float(y)) for x, y in poly],
                )
            )
        x0, y0 = obj.bbox_xy[:2]
        texts.append(
            TextAnnotation(
                timestamp=stamp,
                position=Point2(x=float(x0), y=float(y0)),
                text=label,
                font_size=12.0,
                text_color=Color(r=1, g=1, b=1, a=1),
                background_color=colour(obj.id, 0.8),
            )
        )
        box = object_box_m(frame, labels, obj.id, obj.bbox_xy, k)
        if box is None:
            continue
        centre, size = box
        pose = Pose(position=Vector3(x=centre[0], y=centre[1], z=centre[2]), orientation=Quaternion(w=1.0))
        top = Pose(
            position=Vector3(x=centre[0], y=centre[1] - size[1] / 2 - 0.03, z=centre[2]),
            orientation=Quaternion(w=1.0),
        )
        entities.append(
            SceneEntity(
                timestamp=stamp,
                frame_id=FRAME_ID,
                id=str(obj.id),
                lifetime=Duration(),
                cubes=[
                    CubePrimitive(pose=pose, size=Vector3(x=size[0], y=size[1], z=size[2]), color=colour(obj.id, 0.35))
                ],
                texts=[
                    TextPrimitive(
                        pose=top,
                        billboard=True,
                        font_size=14.0,
                        scale_invariant=True,
                        color=Color(r=1, g=1, b=1, a=1),
                        text=label,
                    )
                ],
            )
        )
    out.append(TopicMessage("/depthgram/objects", ImageAnnotations(points=points, texts=texts)))
    # objects that left the view must leave the 3-D view too: each update replaces them all
    out.append(
        TopicMessage(
            "/depthgram/boxes",
            SceneUpdate(
                deletions=[SceneEntityDeletion(timestamp=stamp, type=SceneEntityDeletion.Type.ALL)],
                entities=entities,
            ),
        )
    )
    out.append(
        TopicMessage(
            "/depthgram/sentence",
            Log(
                timestamp=stamp,
                level=Log.Level.WARNING if warn else Log.Level.INFO,
                message=result.sentence,
                name="depthgram",
                file=frame.name,
                line=frame.index,
            ),
        )
    )
    out.append(TopicMessage("/depthgram/scene", record))
    return out
