"""How raw samples become millimetres: the sources stage configuration.

Rules (``encoding="auto"`` only decides the unambiguous cases):

- integer images are millimetres (``scale_mm`` overrides, 0.2 for TUM's 5000 per metre);
  in a ``uint16`` image 65535 is always invalid (7-Scenes' marker: no indoor sensor reads 65.5 m);
- float images are metres (``scale_mm`` overrides; give 1.0 for float millimetres);
- ``uint8`` images are the paper's 0-255 depth over ``depth_range_mm`` and are refused without it
  (an 8-bit PNG is far more often a grey preview than metric depth; guessing a range would give
  silently wrong distances). With ``scale_mm`` instead they are read as linear units;
- ``"mm"`` / ``"m"`` say the samples are millimetres / metres whatever their dtype (float
  millimetre arrays, integer metre grids); ``"raw"`` is ``auto`` without the 8-bit refusal;
- ``"sun"`` (SUN RGB-D's 3-bit circular shift) and ``"kinect-disparity"`` (NYU's raw disparity)
  are never guessed: they are given explicitly.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from depthgram.errors import InputError

__all__ = ["ENCODINGS", "SourceConfig"]

#: Accepted values of :attr:`SourceConfig.encoding`.
ENCODINGS = ("auto", "raw", "mm", "m", "8bit", "sun", "kinect-disparity")


@dataclass(frozen=True)
class SourceConfig:
    """How to read depth samples from any source.

    Parameters
    ----------
    scale_mm : float or None
        Millimetres per raw unit. None: 1 for integer images, 1000 for float images (metres).
    invalid : tuple of float
        Raw values that mean no reading, besides 0 and NaN (and 65535 in uint16 images).
    fps : float or None
        Frame rate (frames/s) for sequences without timestamps; ``time_s = index / fps``.
    timestamps : str or None
        Path of a timestamps file (one time in s per line, or ``index time`` pairs).
    depth_range_mm : (float, float) or None
        (near, far) in mm. For 8-bit images the range of codes 1..255; for other images
        readings outside it are marked invalid.
    encoding : str
        One of :data:`ENCODINGS`.
    topic : str or None
        Bag topic to read; needed when a bag holds several depth Image topics.
    key : str or None
        Array name inside an ``.npz`` file.
    """

    scale_mm: float | None = None
    invalid: tuple[float, ...] = ()
    fps: float | None = None
    timestamps: str | None = None
    depth_range_mm: tuple[float, float] | None = None
    encoding: str = "auto"
    topic: str | None = None
    key: str | None = None

    def __post_init__(self) -> None:
        if self.scale_mm is not None and not (math.isfinite(self.scale_mm) and self.scale_mm > 0):
            raise InputError(f"scale_mm must be a positive number of mm per raw unit, got {self.scale_mm}")
        if self.fps is not None and not (math.isfinite(self.fps) and 0 < self.fps <= 100_000):
            raise InputError(f"fps must be a positive frame rate in frames/s, got {self.fps}")
        if self.encoding not in ENCODINGS:
            raise InputError(f"unknown depth encoding {self.encoding!r}; expected one of {', '.join(ENCODINGS)}")
        if self.depth_range_mm is not None:
            if len(self.depth_range_mm) != 2:
                raise InputError(f"depth_range_mm must be (near, far) in mm, got {self.depth_range_mm}")
            near, far = (float(v) for v in self.depth_range_mm)
            if not (math.isfinite(near) and math.isfinite(far) and 0 <= near < far):
                raise InputError(f"depth_range_mm must satisfy 0 <= near < far (mm), got {near}..{far}")
            object.__setattr__(self, "depth_range_mm", (near, far))
        try:
            inv = tuple(float(v) for v in self.invalid)
        except (TypeError, ValueError):
            raise InputError(f"invalid must be a list of numbers, got {self.invalid!r}") from None
        object.__setattr__(self, "invalid", inv)
        if self.timestamps is not None:
            object.__setattr__(self, "timestamps", os.fspath(self.timestamps))
