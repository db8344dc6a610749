"""Raw sample arrays to :class:`~depthgram.frame.Frame`: the encodings of real datasets."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError
from depthgram.frame import Frame, Intrinsics, depth_from_8bit, make_frame
from depthgram.sources.config import SourceConfig
from depthgram.sources.encodings import decode_kinect_disparity, decode_sun
from depthgram.sources.units import check_first_frame

__all__ = ["check_depth_array", "decode_kinect_disparity", "decode_sun", "to_frame"]


def check_depth_array(raw: NDArray[np.generic], where: str) -> NDArray[np.generic]:
    """Check that ``raw`` can be a depth image; return it as 2-D.

    Raises
    ------
    InputError
        For a colour image, a stack or a non-numeric dtype, naming ``where``.
    """
    arr = np.asarray(raw)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim == 3 and arr.shape[2] in (3, 4):
        raise InputError(
            f"{where}: this is a colour image ({arr.shape[1]}x{arr.shape[0]}, {arr.shape[2]} channels); "
            "expected a single-channel depth image"
        )
    if arr.ndim != 2:
        raise InputError(f"{where}: expected a 2-D depth image, got an array of shape {arr.shape}")
    if arr.dtype == np.bool_ or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise InputError(f"{where}: expected integer or float depth samples, got dtype {arr.dtype}")
    if arr.size == 0:
        raise InputError(f"{where}: the depth image is empty (shape {arr.shape})")
    return arr


def to_frame(
    raw: NDArray[np.generic],
    cfg: SourceConfig,
    *,
    where: str,
    index: int = 0,
    time_s: float | None = None,
    intrinsics: Intrinsics | None = None,
    name: str = "",
) -> Frame:
    """Decode one raw image with ``cfg`` and build the frame through :func:`make_frame`.

    Parameters
    ----------
    raw : ndarray, shape (H, W)
        Samples as stored (integer or float).
    cfg : SourceConfig
        Units, invalid markers and encoding.
    where : str
        File (and frame) named in error messages.
    index, time_s, intrinsics, name
        Stored on the frame.

    Raises
    ------
    InputError
        Colour image, wrong dtype, 8-bit image without a depth range, encoding that does not fit.
    """
    arr = check_depth_array(raw, where)
    enc = cfg.encoding
    invalid: tuple[float, ...] = cfg.invalid
    is_int = np.issubdtype(arr.dtype, np.integer)
    if enc == "auto" and arr.dtype == np.uint8 and cfg.scale_mm is None:
        if cfg.depth_range_mm is None:
            raise InputError(
                f"{where}: 8-bit image: the paper's 0-255 depth needs depth_range_mm=(near, far) "
                "(--range NEAR FAR), or give scale_mm if the codes are linear units; an 8-bit PNG is "
                "often a grey preview, not depth"
            )
        enc = "8bit"
    values: NDArray[np.generic]
    if enc == "8bit":
        if arr.dtype != np.uint8:
            raise InputError(f"{where}: encoding '8bit' expects uint8 samples, got {arr.dtype}")
        if cfg.depth_range_mm is None:
            raise InputError(f"{where}: encoding '8bit' needs depth_range_mm=(near, far) in mm")
        codes = arr.copy()
        for v in invalid:
            codes[codes == v] = 0
        values, scale, invalid = depth_from_8bit(codes, *cfg.depth_range_mm), 1.0, ()
    elif enc == "sun":
        if arr.dtype != np.uint16:
            raise InputError(f"{where}: encoding 'sun' expects uint16 samples, got {arr.dtype}")
        values, scale = decode_sun(arr), cfg.scale_mm or 1.0
    elif enc == "kinect-disparity":
        if not is_int:
            raise InputError(f"{where}: encoding 'kinect-disparity' expects integer codes, got {arr.dtype}")
        values, scale, invalid = decode_kinect_disparity(arr, invalid), 1.0, ()
    else:
        values = arr
        default = {"mm": 1.0, "m": 1000.0}.get(enc, 1.0 if is_int else 1000.0)
        scale = cfg.scale_mm if cfg.scale_mm is not None else default
        if arr.dtype == np.uint16:
            invalid = (*invalid, 65535.0)
    near_far = cfg.depth_range_mm if enc != "8bit" else None
    frame = make_frame(
        values,
        scale_mm=scale,
        invalid_values=invalid,
        max_mm=near_far[1] if near_far else None,
        index=index,
        time_s=time_s,
        intrinsics=intrinsics,
        name=name,
        check_units=False,
    )
    if near_far is not None and near_far[0] > 0:
        # The arrays are fresh from make_frame and owned by this frame only.
        too_near = frame.valid & (frame.depth < near_far[0])
        frame.depth[too_near] = 0.0
        frame.valid[too_near] = False
    if index == 0:
        check_first_frame(arr, frame, cfg, where)
    return frame
