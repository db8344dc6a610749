"""Label map files: one 16-bit PNG per frame, named after the frame's input file.

Written by ``depthgram describe --labels`` and by the batch runner (:mod:`depthgram.batch`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["label_file_name", "write_label_map"]


def label_file_name(frame_name: str, index: int) -> str:
    """Label map file name, after the input frame's file when it has one."""
    stem = Path(frame_name).stem if frame_name and ":" not in frame_name else ""
    if stem and "#" in Path(frame_name).name:  # a frame of a stack ("st.npy#2"): every frame its own map
        stem = f"{Path(frame_name.partition('#')[0]).stem}-{index:06d}"
    return f"{stem or f'{index:06d}'}.png"


def write_label_map(path: Path, labels: NDArray[np.integer], frame_name: str) -> None:
    """Write ``labels`` (object or track id per pixel) as a 16-bit PNG.

    Raises
    ------
    InputError
        When an id does not fit in 16 bits (track ids grow over a long recording and would
        wrap silently), or the file cannot be written.
    """
    import cv2

    from depthgram.errors import InputError

    top = int(labels.max(initial=0))
    if top > 65535:
        raise InputError(f"{frame_name}: object id {top} is above 65535; cannot write a 16-bit PNG label map ({path})")
    from depthgram.atomic import atomic_path

    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), labels.astype("uint16")):
            raise InputError(f"{path}: could not write the label map")
