"""Input checks shared by the segmentation entry points."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError

__all__ = ["check_depth"]


def check_depth(
    depth_mm: object, valid: object | None, where: str = "segment"
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """Depth as contiguous float32 with 0 where invalid, and the validity mask.

    Raises
    ------
    InputError
        For a non-2-D or non-numeric depth array, or a mask of another shape.
    """
    arr = np.asarray(depth_mm)
    if arr.ndim != 2:
        raise InputError(f"{where}: expected a 2-D depth image in mm, got shape {arr.shape}")
    if arr.dtype == np.bool_ or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise InputError(f"{where}: expected integer or float depth in mm, got dtype {arr.dtype}")
    if arr.size == 0:
        raise InputError(f"{where}: the depth image is empty (shape {arr.shape})")
    depth = np.ascontiguousarray(arr, dtype=np.float32)
    ok = np.isfinite(depth) & (depth > 0)
    if valid is not None:
        v = np.asarray(valid)
        if v.shape != arr.shape:
            raise InputError(f"{where}: valid mask has shape {v.shape}, depth has shape {arr.shape}")
        if v.dtype != np.bool_:
            raise InputError(f"{where}: valid mask must be boolean, got dtype {v.dtype}")
        ok &= v
    if not ok.all():
        depth = np.where(ok, depth, np.float32(0))
    return depth, ok
