"""The sample encodings of real datasets that are not a linear unit: SUN RGB-D's bit shift, raw Kinect disparity.

Their own module, so that :mod:`depthgram.sources.decode` (which applies them) and
:mod:`depthgram.sources.units` (which tries them on a frame read in the wrong units) both import
them without importing each other.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["decode_kinect_disparity", "decode_sun"]

#: NYU Depth v2 toolbox constants: depth_m = 351.3 / (1092.5 - d) for raw Kinect disparity d.
_KINECT_NUM_M = 351.3
_KINECT_DEN = 1092.5
_KINECT_MAX_CODE = 2047


def decode_sun(raw: NDArray[np.generic]) -> NDArray[np.uint16]:
    """SUN RGB-D depth PNG to millimetres: undo the 3-bit circular shift ``(p >> 3) | (p << 13)``."""
    p = np.asarray(raw).astype(np.uint16)
    return (p >> np.uint16(3)) | (p << np.uint16(13))


def decode_kinect_disparity(raw: NDArray[np.generic], invalid: tuple[float, ...] = ()) -> NDArray[np.float32]:
    """NYU raw Kinect disparity to millimetres (0 where invalid).

    ``depth_m = 351.3 / (1092.5 - d)``; invalid when ``d >= 1092.5`` (2047 included) or d = 0.
    NYU's raw PGMs store the samples little-endian although PGM is big-endian; a code above 2047
    cannot be an 11-bit disparity, so such an image is byte-swapped back (unambiguous).
    """
    d = np.asarray(raw)
    if d.dtype == np.uint16 and d.size and int(d.max()) > _KINECT_MAX_CODE:
        d = d.byteswap()
    df = d.astype(np.float64)
    ok = (df > 0) & (df < _KINECT_DEN)
    for v in invalid:
        ok &= df != v
    with np.errstate(divide="ignore", invalid="ignore"):
        mm = np.where(ok, 1000.0 * _KINECT_NUM_M / (_KINECT_DEN - df), 0.0)
    return mm.astype(np.float32)
