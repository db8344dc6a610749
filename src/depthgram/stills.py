"""Telling a recording from a folder of unrelated still images, from the depth itself.

Range flow (v_radial, time to collision) and the sound's approach cue only mean something
between frames of one recording. A folder of stills of different scenes (NVlabs' or OSD's
tabletop pictures) read in file order looks like a video to the tracker, which then reads
velocities between different scenes. Two frames of one recording share most of what they see
(their depths agree on most pixels both see), unrelated stills very little, and different
pictures from one tripod over one table somewhere between (the agreement measured on real
recordings and stills is in docs/design-notes.md). Hence two thresholds: :data:`MIN_AGREE`
for any pair, and the stricter :data:`MIN_AGREE_UNTIMED` for frames that carry no time (a
folder of images without a rate), where a user is likeliest to hand over stills.

A hand-held camera that turns fast moves the whole image by several pixels between two frames,
which alone makes their depths disagree along every edge (7-Scenes: 6 of 299 pairs below
:data:`MIN_AGREE_UNTIMED`, the lowest at 62 %). A pair that falls short is compared again
after one image shift (:func:`depthgram.dynamics.camera_motion.image_shift`, phase correlation): then
the lowest 7-Scenes pair agrees on 87 %, while unrelated stills stay at 2-9 %.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.dynamics.camera_motion import image_shift
from depthgram.frame import Frame

__all__ = ["MIN_AGREE", "MIN_AGREE_UNTIMED", "Kinship", "kinship"]

#: Below this share of agreeing depths two frames have nothing in common.
MIN_AGREE = 0.3
#: Below this share, two frames without timestamps are taken for stills of different scenes.
MIN_AGREE_UNTIMED = 0.8
_TOL_REL = 0.02
_TOL_MM = 15.0
_STEP = 4  # every 4th row and column: the share is a statistic of thousands of pixels


@dataclass(frozen=True)
class Kinship:
    """How much two successive frames have in common.

    Attributes
    ----------
    related : bool
        True when they look like two frames of one recording.
    agree : float
        Share (0..1) of the pixels valid in both whose depths agree within 2 % or 15 mm;
        0 for frames of different sizes.
    reason : str
        Why they were judged unrelated (empty when related).
    shift : tuple of float
        The image shift (dx, dy) px under which ``agree`` was measured: (0, 0) unless the
        frames agreed too little as they are (see the module's docstring).
    """

    related: bool
    agree: float
    reason: str = ""
    shift: tuple[float, float] = (0.0, 0.0)


def _agreement(da: NDArray[np.floating], db: NDArray[np.floating], both: NDArray[np.bool_]) -> tuple[float, int]:
    """Share of the pixels valid in both whose depths agree within 2 % or 15 mm, and their count."""
    n = int(both.sum())
    if n == 0:
        return 0.0, 0
    a, b = da[both].astype(np.float64), db[both].astype(np.float64)
    tol = np.maximum(_TOL_MM, _TOL_REL * np.minimum(a, b))
    return float(np.count_nonzero(np.abs(a - b) <= tol)) / n, n


def _shifted(prev: Frame, frame: Frame, shift: tuple[float, float]) -> NDArray[np.float32]:
    """Return the previous frame's depth (mm, 0 where invalid) moved by ``shift`` onto this frame's pixels."""
    h, w = frame.depth.shape
    z = np.where(prev.valid, prev.depth, 0).astype(np.float32)
    # nearest neighbour: a depth edge must not be blended into a depth neither frame has
    m = np.array([[1, 0, shift[0]], [0, 1, shift[1]]], dtype=np.float32)
    return np.asarray(cv2.warpAffine(z, m, (w, h), flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP), np.float32)


def kinship(prev: Frame, frame: Frame) -> Kinship:
    """Judge whether ``frame`` continues the recording of ``prev``.

    Parameters
    ----------
    prev, frame : Frame
        Two successive frames.

    Returns
    -------
    Kinship
    """
    if prev.depth.shape != frame.depth.shape:
        return Kinship(False, 0.0, f"frame sizes differ ({prev.size} then {frame.size})")
    b = frame.depth[::_STEP, ::_STEP]
    vb = frame.valid[::_STEP, ::_STEP]
    agree, n = _agreement(prev.depth[::_STEP, ::_STEP], b, prev.valid[::_STEP, ::_STEP] & vb)
    if n == 0:
        return Kinship(False, 0.0, "no pixel has a depth in both frames")
    timed = prev.time_s is not None and frame.time_s is not None
    need = MIN_AGREE if timed else MIN_AGREE_UNTIMED
    shift = (0.0, 0.0)
    if agree < need:
        moved_shift = image_shift(prev.depth, frame.depth)
        if moved_shift != (0.0, 0.0):
            a = _shifted(prev, frame, moved_shift)[::_STEP, ::_STEP]
            moved, _ = _agreement(a, b, (a > 0) & vb)
            if moved > agree:
                agree, shift = moved, moved_shift
    if agree < need:
        what = "" if timed else " (frames without timestamps)"
        return Kinship(False, agree, f"only {agree:.0%} of their depths agree, below {need:.0%}{what}", shift)
    return Kinship(True, agree, shift=shift)
