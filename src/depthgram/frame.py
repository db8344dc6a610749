"""The depth frame: depth in millimetres, its validity mask and what is needed to read it.

Every source yields :class:`Frame` objects, every later stage takes them. Conversion from a
sensor's raw units happens here, explicitly, once: millimetres (16-bit PNG of most RGB-D
datasets), metres (float images), a units-per-metre scale (TUM's 5000), and the paper's
8-bit 0-255 depth over a stated range.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from depthgram.errors import InputError

__all__ = [
    "DepthError",
    "Frame",
    "Intrinsics",
    "depth_from_8bit",
    "depth_to_8bit",
    "make_frame",
]


class DepthError(InputError):
    """Bad depth input. The message names the file, the frame and what was expected."""


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole camera intrinsics in pixels.

    Parameters
    ----------
    fx, fy : float
        Focal lengths (px).
    cx, cy : float
        Principal point (px), with (0, 0) the centre of the top-left pixel.
    """

    fx: float
    fy: float
    cx: float
    cy: float

    def scaled(self, sx: float, sy: float) -> Intrinsics:
        """Intrinsics of the same camera after resizing the image by ``sx`` x ``sy``."""
        return Intrinsics(self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5)


@dataclass(frozen=True, eq=False)
class Frame:
    """One depth image and what is needed to read it right.

    Attributes
    ----------
    depth : ndarray of float32, shape (H, W)
        Depth along the optical axis in millimetres. Invalid pixels hold 0.
    valid : ndarray of bool, shape (H, W)
        True where the pixel holds a reading. Zero, NaN, saturated or low-confidence pixels
        are invalid: they are never treated as near or far objects.
    index : int
        Position of the frame in its source, from 0.
    time_s : float or None
        Timestamp in seconds, when known.
    intrinsics : Intrinsics or None
        Camera intrinsics, when known.
    name : str
        Where the frame came from (file name, ``bag:topic#n``, ``sim:table#3``); used in
        error messages and to name per-frame outputs.
    """

    depth: NDArray[np.float32]
    valid: NDArray[np.bool_]
    index: int = 0
    time_s: float | None = None
    intrinsics: Intrinsics | None = None
    name: str = ""
    meta: dict[str, object] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) in pixels."""
        h, w = self.depth.shape
        return int(h), int(w)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels, as printed and written in JSON."""
        h, w = self.depth.shape
        return int(w), int(h)

    @property
    def invalid_fraction(self) -> float:
        """Share of pixels without a reading."""
        return 1.0 - float(np.count_nonzero(self.valid)) / self.valid.size


def make_frame(
    raw: ArrayLike,
    *,
    scale_mm: float = 1.0,
    invalid_values: Iterable[float] = (),
    max_mm: float | None = None,
    index: int = 0,
    time_s: float | None = None,
    intrinsics: Intrinsics | None = None,
    name: str = "",
    allow_all_invalid: bool = True,
) -> Frame:
    """Build a :class:`Frame` from raw depth values.

    Parameters
    ----------
    raw : array_like, shape (H, W)
        Raw depth: integers or floats. 0 and NaN always mean no reading.
    scale_mm : float
        Millimetres per raw unit: 1 for millimetre PNGs, 1000 for metres, 0.2 for TUM's
        5000 units per metre.
    invalid_values : iterable of float
        Further raw values that mean no reading (65535 in 7-Scenes, 2047 for raw Kinect).
    max_mm : float, optional
        Readings beyond this depth (mm) are marked invalid (saturated or out of range).
    index, time_s, intrinsics, name
        Stored on the frame.
    allow_all_invalid : bool
        When False, a frame without a single valid pixel raises :class:`DepthError`.

    Returns
    -------
    Frame

    Raises
    ------
    DepthError
        When ``raw`` is not a 2-D numeric image (a colour image given as depth, say).
    """
    where = name or f"frame {index}"
    arr = np.asarray(raw)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim != 2:
        hint = " (a colour image given as depth?)" if arr.ndim == 3 and arr.shape[2] in (3, 4) else ""
        raise DepthError(f"{where}: expected a 2-D depth image, got shape {arr.shape}{hint}")
    numeric = np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
    if arr.dtype == np.bool_ or not numeric:
        raise DepthError(f"{where}: expected integer or float depth values, got dtype {arr.dtype}")
    if arr.size == 0:
        raise DepthError(f"{where}: the depth image is empty (shape {arr.shape})")
    if not np.isfinite(scale_mm) or scale_mm <= 0:
        raise DepthError(f"{where}: scale must be a positive number of mm per unit, got {scale_mm}")
    valid = np.isfinite(arr) if np.issubdtype(arr.dtype, np.floating) else np.ones(arr.shape, bool)
    valid &= arr != 0
    for v in invalid_values:
        valid &= arr != v
    valid &= arr > 0  # negative depth is no reading
    depth = np.where(valid, arr, 0).astype(np.float32)
    if scale_mm != 1.0:
        depth *= np.float32(scale_mm)
    if max_mm is not None:
        too_far = depth > max_mm
        valid &= ~too_far
        depth[too_far] = 0.0
    if not allow_all_invalid and not valid.any():
        raise DepthError(f"{where}: no valid depth pixel (all zero, NaN or marked invalid)")
    return Frame(depth=depth, valid=valid, index=index, time_s=time_s, intrinsics=intrinsics, name=name)


def depth_from_8bit(raw: ArrayLike, near_mm: float, far_mm: float) -> NDArray[np.float32]:
    """Paper's 8-bit depth (0-255 over ``near_mm``..``far_mm``) to millimetres.

    Code 0 means no reading and maps to 0; code ``k`` in 1..255 maps linearly so that 1 is
    ``near_mm`` and 255 is ``far_mm``. One code step is (far - near) / 254 mm, about 12 mm
    over the paper's 3 m range ("on the order of one centimeter").
    """
    codes = np.asarray(raw)
    if far_mm <= near_mm:
        raise DepthError(f"8-bit depth range must have far > near, got {near_mm}..{far_mm} mm")
    step = (far_mm - near_mm) / 254.0
    out = near_mm + (codes.astype(np.float32) - 1.0) * np.float32(step)
    return np.where(codes > 0, out, 0.0).astype(np.float32)


def depth_to_8bit(depth_mm: ArrayLike, near_mm: float, far_mm: float) -> NDArray[np.uint8]:
    """Millimetres to the paper's 8-bit depth; 0 stays 0 (no reading), values clip to 1..255."""
    d = np.asarray(depth_mm, dtype=np.float64)
    if far_mm <= near_mm:
        raise DepthError(f"8-bit depth range must have far > near, got {near_mm}..{far_mm} mm")
    step = (far_mm - near_mm) / 254.0
    codes = np.clip(np.rint((d - near_mm) / step) + 1, 1, 255)
    ok = np.isfinite(d) & (d > 0)
    return np.where(ok, codes, 0).astype(np.uint8)
