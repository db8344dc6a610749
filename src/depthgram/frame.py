"""The depth frame: depth in millimetres, its validity mask and what is needed to read it.

Every source yields :class:`Frame` objects, every later stage takes them. Conversion from a
sensor's raw units happens here, explicitly, once: millimetres (16-bit PNG of most RGB-D
datasets), metres (float images), a units-per-metre scale (TUM's 5000), and the paper's
8-bit 0-255 depth over a stated range.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from depthgram.errors import InputError

__all__ = [
    "DepthError",
    "Frame",
    "Gravity",
    "GravityWarning",
    "Intrinsics",
    "UnitsWarning",
    "as_gravity",
    "depth_from_8bit",
    "depth_to_8bit",
    "implausible_depth",
    "make_frame",
    "warn_units",
]

#: Median valid depth (mm) a depth camera can plausibly see: below 50 mm no camera reads, and
#: beyond 8 m structured light and ToF give noise, not scenes (TUM read without its scale gives
#: 12 m, SUN and NYU without their encodings 21 m and 54 m).
PLAUSIBLE_MEDIAN_MM = (50.0, 8000.0)

#: A float image whose readings all sit under this is metres or a normalised image, not mm.
FLOAT_METRES_BELOW = 20.0

#: Pixels sampled for the check: a strided subset, whose median is within a few mm of the
#: whole frame's at a small part of the cost.
_SAMPLE_PX = 10_000


class UnitsWarning(UserWarning):
    """Depth values implausible for a depth camera: the units or the encoding are probably wrong."""


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


class GravityWarning(UserWarning):
    """Gravity was estimated from the scene: give it (``--gravity`` / ``--tilt``, or an IMU) to be sure."""


@dataclass(frozen=True)
class Gravity:
    """Which way is down, in the camera's frame, and how that is known.

    Parameters
    ----------
    vector : (float, float, float)
        Unit vector along gravity (pointing down) in camera coordinates: x right, y down, z
        forward along the optical axis. A level camera has (0, 1, 0); one looking straight down
        (0, 0, 1). Any length is accepted and normalised.
    source : str
        ``given`` (a vector from the user), ``tilt`` (a pitch from the user), ``imu`` (the
        recording's accelerometer), ``file`` (a file beside the frames), ``simulator`` (exact),
        ``estimated`` (from the scene's supports, :mod:`depthgram.scene.kinds`; reported, never
        put on a frame).
    """

    vector: tuple[float, float, float]
    source: str = "given"

    def __post_init__(self) -> None:
        try:
            v = np.asarray(self.vector, dtype=np.float64).reshape(3)
        except (TypeError, ValueError):
            raise InputError(f"gravity (--gravity X Y Z): expected three numbers, got {self.vector!r}") from None
        norm = float(np.linalg.norm(v))
        if not (np.all(np.isfinite(v)) and norm > 1e-9):
            raise InputError(f"gravity (--gravity X Y Z): expected a finite, non-zero vector, got {tuple(v.tolist())}")
        object.__setattr__(self, "vector", tuple(float(x) + 0.0 for x in v / norm))  # no -0.0

    @classmethod
    def from_tilt(cls, tilt_deg: float, roll_deg: float = 0.0) -> Gravity:
        """Gravity of a camera pitched down by ``tilt_deg`` degrees (negative: up), rolled by ``roll_deg``.

        Pitch turns about the camera's x axis, so looking down by t moves gravity from (0, 1, 0)
        toward the optical axis: (0, cos t, sin t). Roll (clockwise as the camera sees) then turns it
        about z.
        """
        if not (math.isfinite(tilt_deg) and -90.0 <= tilt_deg <= 90.0):
            raise InputError(f"tilt (--tilt DEG): expected -90 (up) to 90 (straight down) degrees, got {tilt_deg}")
        if not math.isfinite(roll_deg):
            raise InputError(f"roll: expected degrees, got {roll_deg}")
        t, r = math.radians(tilt_deg), math.radians(roll_deg)
        y, z = math.cos(t), math.sin(t)
        return cls((-math.sin(r) * y, math.cos(r) * y, z), "tilt")

    @property
    def tilt_deg(self) -> float:
        """How far the optical axis points below the horizon (degrees; negative: above)."""
        return math.degrees(math.asin(max(-1.0, min(1.0, self.vector[2]))))

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: the unit vector, its source and the tilt it means (degrees)."""
        vector = [round(c, 6) for c in self.vector]
        return {"vector": vector, "source": self.source, "tilt_deg": round(self.tilt_deg, 2)}


def as_gravity(gravity: Gravity | Sequence[float] | None = None, tilt_deg: float | None = None) -> Gravity | None:
    """Return the user's gravity (a :class:`Gravity` or X, Y, Z) or tilt (degrees down) as a :class:`Gravity`.

    Raises
    ------
    InputError
        Both given, or not three finite numbers, or a zero vector.
    """
    if gravity is not None and tilt_deg is not None:
        raise InputError("give the gravity (--gravity X Y Z) or the tilt (--tilt DEG), not both")
    if tilt_deg is not None:
        return Gravity.from_tilt(float(tilt_deg))
    if gravity is None or isinstance(gravity, Gravity):
        return gravity
    try:
        xyz = tuple(float(v) for v in gravity)
    except (TypeError, ValueError):
        raise InputError(f"gravity (--gravity X Y Z): expected three numbers, got {gravity!r}") from None
    if len(xyz) != 3:
        raise InputError(f"gravity (--gravity X Y Z): expected three numbers, got {len(xyz)}")
    return Gravity((xyz[0], xyz[1], xyz[2]))


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
    meta : dict
        Source-specific notes (the simulator's scene and seed; ``sensor_profile``, the sensor
        model a named camera implies; ``intrinsics_from``, the file or profile of the intrinsics).
    intrinsics_source : str
        Where ``intrinsics`` came from (:data:`depthgram.sources.camera.INTRINSICS_SOURCES`:
        ``given``, ``file``, ``bag``, ``device``, ``simulator``, ``profile``); "" without them.
    gravity : Gravity or None
        Which way is down in the camera's frame, when known.
    """

    depth: NDArray[np.float32]
    valid: NDArray[np.bool_]
    index: int = 0
    time_s: float | None = None
    intrinsics: Intrinsics | None = None
    name: str = ""
    meta: dict[str, object] = field(default_factory=dict)
    intrinsics_source: str = ""
    gravity: Gravity | None = None

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

    def decimated(self, step: int, *, read: bool = False) -> Frame:
        """Every ``step``-th pixel of each ``step``-th row, with the intrinsics to match.

        The readings are kept as they are, not averaged: a mean of pixels across an outline
        would be a depth no surface has (a flying pixel), and the sensor model's noise still
        describes each kept pixel. Pixel ``(i, j)`` of the result is pixel ``(step i, step j)``.
        ``read``: this frame's arrays hold those pixels already (a source read only them) while
        the rest (intrinsics) is the whole frame's: only the rest changes.
        """
        if step < 1:
            raise InputError(f"{self.name or 'frame'}: decimation step must be >= 1, got {step}")
        if step == 1:
            return self
        k = self.intrinsics
        return replace(
            self,
            depth=self.depth if read else np.ascontiguousarray(self.depth[::step, ::step]),
            valid=self.valid if read else np.ascontiguousarray(self.valid[::step, ::step]),
            intrinsics=None if k is None else Intrinsics(k.fx / step, k.fy / step, k.cx / step, k.cy / step),
            meta={**self.meta, "decimated": step},
        )


def implausible_depth(
    depth_mm: NDArray[np.floating], valid: NDArray[np.bool_] | None = None
) -> tuple[str, bool] | None:
    """Why the depths cannot come from a depth camera in these units, or None when they can.

    Parameters
    ----------
    depth_mm : ndarray, shape (H, W)
        Depth as read (mm).
    valid : ndarray of bool, shape (H, W), optional
        Pixels with a reading; by default the finite and positive ones.

    Returns
    -------
    (str, bool) or None
        The reason (``"the median depth 12075 mm is beyond 8 m ..."``, from a strided sample of
        the valid pixels) and whether the depths are too far (else too near); None when the
        median lies in :data:`PLAUSIBLE_MEDIAN_MM` or nothing is valid.
    """
    step = max(1, int(np.sqrt(depth_mm.size / _SAMPLE_PX)))
    sample = depth_mm[::step, ::step]
    if valid is None:
        # the sample's readings alone: the rest of the frame is never read
        d = sample[np.isfinite(sample) & (sample > 0)]
    else:
        d = sample[valid[::step, ::step]]
    if d.size == 0:
        return None
    lo, hi = PLAUSIBLE_MEDIAN_MM
    # the median lies beyond a limit only when at least half the readings do: counting them
    # settles a plausible frame without the selection a median takes
    if 2 * np.count_nonzero(d > hi) < d.size and 2 * np.count_nonzero(d < lo) < d.size:
        return None
    med = float(np.median(d))
    if med > hi:
        return f"the median depth {med:.0f} mm is beyond {hi / 1000:.0f} m, farther than depth cameras read", True
    if med < lo:
        return f"the median depth {med:.1f} mm is under {lo:.0f} mm, nearer than depth cameras read", False
    return None


def warn_units(where: str, reason: str, hints: Sequence[str]) -> None:
    """Warn (:class:`UnitsWarning`) that the units of ``where`` look wrong, naming the likely fixes.

    Python shows a given warning once per place, so a sequence read in the wrong units warns
    once, not once per frame, when the message names the source rather than the frame.
    """
    fix = ("try " + "; or ".join(hints)) if hints else "check the units in the recording's documentation (--scale)"
    warnings.warn(f"{where}: {reason}: the units are likely wrong; {fix}", UnitsWarning, stacklevel=3)


def _float_metres(arr: NDArray[np.generic]) -> bool:
    """Return a float image whose readings all sit under :data:`FLOAT_METRES_BELOW` (metres, not mm)."""
    if not np.issubdtype(arr.dtype, np.floating) or arr.size == 0:
        return False
    # compared in float64, as before; float16 to float64 values are the same numbers
    a = np.asarray(arr, dtype=np.float64) if arr.dtype.itemsize > 8 else np.asarray(arr)
    # the largest reading leaving NaN out: when it is finite it is the largest finite one, and
    # only an image holding +inf needs its finite readings picked out (a frame-sized copy)
    top = float(np.fmax.reduce(a, axis=None))
    if top == math.inf:
        with np.errstate(invalid="ignore"):
            d = a[np.isfinite(a) & (a > 0)]
        return bool(d.size) and float(d.max()) < FLOAT_METRES_BELOW
    return 0.0 < top < FLOAT_METRES_BELOW


def check_array_units(arr: ArrayLike, where: str, valid: NDArray[np.bool_] | None = None) -> None:
    """Warn when a depth array handed over as millimetres looks like metres or other units.

    For the entry points that take bare arrays (:func:`make_frame`, :func:`depthgram.segment`,
    :func:`depthgram.describe`): float values all under 20 are metres; a median beyond 8 m or
    under 50 mm is some other unit.
    """
    a = np.asarray(arr)
    if a.ndim != 2 or a.size == 0 or a.dtype.kind not in "iuf":
        return  # the entry point's own checks give the error
    if _float_metres(a):
        warn_units(
            where,
            f"float depths all under {FLOAT_METRES_BELOW:.0f} look like metres, read here as mm",
            ["scale_mm=1000 (--scale 1000), or multiply by 1000 before passing"],
        )
        return
    found = implausible_depth(a, valid)
    if found:
        warn_units(where, found[0], _scale_hints(found[1]))


def _scale_hints(too_far: bool) -> list[str]:
    if too_far:
        return ["scale_mm=MM_PER_UNIT (--scale 0.2 for TUM's 5000 units per metre, --scale 0.1 for 0.1 mm units)"]
    return ["scale_mm=1000 (--scale 1000) if the depths are metres"]


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
    check_units: bool = True,
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
    check_units : bool
        Warn (:class:`UnitsWarning`) when the first frame (``index`` 0) holds depths no depth
        camera reads: float values all under 20 (metres read as mm), a median beyond 8 m or
        under 50 mm. Sources that know the raw encoding check themselves and pass False.

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
    unsigned = arr.dtype.kind == "u"
    valid = arr != 0
    if np.issubdtype(arr.dtype, np.floating):
        valid &= np.isfinite(arr)
    for v in invalid_values:
        valid &= arr != v
    if not unsigned:
        valid &= arr > 0  # negative depth is no reading
    with np.errstate(over="ignore"):  # an overflow is found and handled just below
        if unsigned:
            # a reading times 1 or 0 is itself or +0 exactly: one pass instead of a where
            # (slow on 16-bit samples) and a cast
            depth = np.multiply(arr, valid, dtype=np.float32)
        else:
            depth = np.where(valid, arr, 0).astype(np.float32)
        if scale_mm != 1.0:
            depth *= np.float32(scale_mm)
    if _may_overflow(arr.dtype, scale_mm):
        # a reading beyond float32 once in mm (float64 1e300, float32's largest in metres) is
        # no reading: left in, it is an infinite depth that every later stage would trip on
        # (issue 32.2)
        endless = np.isinf(depth)
        if endless.any():
            valid &= ~endless
            depth[endless] = 0.0
    if max_mm is not None:
        too_far = depth > max_mm
        valid &= ~too_far
        depth[too_far] = 0.0
    if not allow_all_invalid and not valid.any():
        raise DepthError(f"{where}: no valid depth pixel (all zero, NaN or marked invalid)")
    if check_units and index == 0:
        if scale_mm == 1.0 and _float_metres(arr):
            warn_units(
                where,
                f"float depths all under {FLOAT_METRES_BELOW:.0f} look like metres, read here as mm",
                ["scale_mm=1000 (--scale 1000)"],
            )
        else:
            found = implausible_depth(depth, valid)
            if found:
                warn_units(where, found[0], _scale_hints(found[1]))
    return Frame(depth=depth, valid=valid, index=index, time_s=time_s, intrinsics=intrinsics, name=name)


def _may_overflow(dtype: np.dtype[Any], scale_mm: float) -> bool:
    # whether a finite raw value can leave float32's range once cast and scaled: checked so that
    # the usual frames (16-bit mm, float32 read as they are) pay no pass for it
    f32_max = float(np.finfo(np.float32).max)
    if np.issubdtype(dtype, np.integer):
        return float(np.iinfo(dtype).max) * scale_mm >= f32_max
    return dtype != np.float32 or scale_mm > 1.0


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
