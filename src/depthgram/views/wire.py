"""The viewer's frame message: one binary WebSocket message holding a JSON header and the raw arrays.

Layout (all little-endian)::

    uint32 n | header: n bytes of UTF-8 JSON | space padding to a multiple of 4 bytes | body

The body is the depth image as uint16 millimetres (0 = invalid, values beyond 65535 mm are
clipped) followed by the label image (the ids of ``Segmentation.labels``) as the smallest of
``uint8``, ``uint16`` and ``uint32`` that holds the largest id (the header's ``labels_dtype``),
both row-major H x W; when the header's ``compressed`` is true the body is one zlib stream
(``DecompressionStream("deflate")`` in the page). The page colours the depth and draws the
outlines itself, which is what lets it show the depth and the object under the mouse and the
frame as a point cloud; why pictures are no longer encoded on the server is in
``docs/design-notes.md``.
"""

from __future__ import annotations

import json
import struct
import zlib
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["colour_table", "depth_range_mm", "pack_body", "pack_frame", "unpack_frame"]


_NAMES = {"u1": "uint8", "<u2": "uint16", "<u4": "uint32"}
_DTYPES = {v: k for k, v in _NAMES.items()}


def colour_table() -> list[list[int]]:
    """Return the depth colours as 256 RGB triples: entry ``i`` is for ``i / 255`` of the way from far to near.

    OpenCV's TURBO map, as :func:`depthgram.views.pictures.overlay_image` uses it (near warm, far cool).
    """
    bgr = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_TURBO)[:, 0, :]
    return [[int(c[2]), int(c[1]), int(c[0])] for c in bgr]


def depth_range_mm(depth: NDArray[np.floating], valid: NDArray[np.bool_]) -> tuple[float, float]:
    """Robust colour range (mm): the 1st and 99th percentiles of the valid depths.

    Taken on every second row and column (a quarter of the pixels, the same percentiles within
    the sampling error) so that it costs well under a millisecond at 640 x 480.
    """
    sub = depth[::2, ::2][valid[::2, ::2]]
    if sub.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(sub, [1, 99])
    return float(lo), float(max(hi, lo + 1.0))


def pack_body(
    depth: NDArray[np.floating], valid: NDArray[np.bool_], labels: NDArray[np.integer], compress: bool
) -> tuple[bytes, str]:
    """Return the body of a frame message and the label image's dtype name (``uint8``, ``uint16`` or ``uint32``)."""
    d16 = np.rint(np.clip(depth, 0, 65535)).astype("<u2")
    d16[~valid] = 0
    top = int(labels.max()) if labels.size else 0
    lab_dtype = "u1" if top <= 0xFF else "<u2" if top <= 0xFFFF else "<u4"
    body = d16.tobytes() + np.ascontiguousarray(labels, dtype=lab_dtype).tobytes()
    if compress:
        body = zlib.compress(body, 1)
    return body, _NAMES[lab_dtype]


def pack_frame(header: dict[str, Any] | str, body: bytes) -> bytes:
    """One binary message: length-prefixed JSON header, padding to 4 bytes, body.

    ``header`` is a dict, or already serialised as JSON text.
    """
    text = header if isinstance(header, str) else json.dumps(header, separators=(",", ":"))
    head = text.encode("utf-8")
    pad = (-(4 + len(head))) % 4
    return b"".join((struct.pack("<I", len(head)), head, b" " * pad, body))


def unpack_frame(data: bytes) -> tuple[dict[str, Any], NDArray[np.uint16], NDArray[np.unsignedinteger]]:
    """Return the header, depth image (uint16 mm) and label image of a message made by :func:`pack_frame`."""
    (n,) = struct.unpack_from("<I", data, 0)
    header = json.loads(data[4 : 4 + n].decode("utf-8"))
    start = 4 + n + (-(4 + n)) % 4
    body = data[start:]
    if header.get("compressed"):
        body = zlib.decompress(body)
    w, h = header["size"]
    depth = np.frombuffer(body, "<u2", count=w * h).reshape(h, w)
    labels = np.frombuffer(body, _DTYPES[header["labels_dtype"]], count=w * h, offset=2 * w * h).reshape(h, w)
    return header, depth, labels
