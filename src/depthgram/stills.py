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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
    """

    related: bool
    agree: float
    reason: str = ""


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
    a = prev.depth[::_STEP, ::_STEP]
    b = frame.depth[::_STEP, ::_STEP]
    both = prev.valid[::_STEP, ::_STEP] & frame.valid[::_STEP, ::_STEP]
    n = int(both.sum())
    if n == 0:
        return Kinship(False, 0.0, "no pixel has a depth in both frames")
    da, db = a[both].astype(np.float64), b[both].astype(np.float64)
    tol = np.maximum(_TOL_MM, _TOL_REL * np.minimum(da, db))
    agree = float(np.count_nonzero(np.abs(da - db) <= tol)) / n
    timed = prev.time_s is not None and frame.time_s is not None
    need = MIN_AGREE if timed else MIN_AGREE_UNTIMED
    if agree < need:
        what = "" if timed else " (frames without timestamps)"
        return Kinship(False, agree, f"only {agree:.0%} of their depths agree, below {need:.0%}{what}")
    return Kinship(True, agree)
