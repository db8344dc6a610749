"""Histogram thresholding: depth bands split into connected objects (paper, section 3).

Cost model: one binning pass, one bincount for the histogram, one lookup of every pixel's band
through a bin -> band table, one labelling pass for all bands together; never one mask per peak.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.segment.config import SegmentConfig
from depthgram.segment.histogram import Bands, bin_index, depth_bands
from depthgram.segment.label import ACTIVE, BLOCK, HOLE, label_keyed

__all__ = ["band_image", "threshold_labels"]


def band_image(
    depth_mm: NDArray[np.floating], valid: NDArray[np.bool_], config: SegmentConfig
) -> tuple[NDArray[np.int32], Bands]:
    """Band index of every pixel (-1 for invalid pixels and pixels between bands) and the bands."""
    bins, edges = bin_index(depth_mm, valid, config)
    bands = depth_bands(bins, edges, int(np.count_nonzero(valid)), config)
    band = bands.lut[bins]
    band[bins < 0] = -1
    return band, bands


def threshold_labels(
    band: NDArray[np.int32],
    valid: NDArray[np.bool_],
    config: SegmentConfig,
    *,
    include: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.int32], int]:
    """Connected same-band components, holes of up to ``fill_holes_px`` bridged.

    Parameters
    ----------
    band : ndarray of int32, shape (H, W)
        From :func:`band_image`.
    valid : ndarray of bool
        Pixels with a reading; the others are holes that may be bridged.
    include : ndarray of bool, optional
        Only these pixels are labelled (the others, when valid, block a bridge).
    """
    state = np.where(valid, np.int8(BLOCK), np.int8(HOLE))
    active = band >= 0
    if include is not None:
        active &= include
    state[active] = ACTIVE
    return label_keyed(band, state, tol=0.0, bridge=config.fill_holes_px)
