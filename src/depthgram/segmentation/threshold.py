"""Histogram thresholding: depth bands split into connected objects (paper, section 3).

Cost model: one binning pass, one bincount for the histogram, one lookup of every pixel's band
through a bin -> band table, one labelling pass for all bands together; never one mask per peak.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from depthgram.segmentation.binning import band_state
from depthgram.segmentation.config import SegmentConfig
from depthgram.segmentation.histogram import Bands, bin_index, depth_bands
from depthgram.segmentation.label import label_keyed

__all__ = ["band_image", "threshold_labels"]


def band_image(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    config: SegmentConfig,
    *,
    include: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.float32], NDArray[np.int8], Bands]:
    """Band of every pixel, the labeller state, and the bands.

    The histogram is taken over the valid pixels in ``include`` (all valid pixels by default);
    pixels outside a band or outside ``include`` are not labelled but block hole bridging.
    """
    hist_mask = valid if include is None else valid & include
    bins, edges, counts = bin_index(depth_mm, hist_mask, config)
    bands = depth_bands(counts, edges, config)
    band, state = band_state(bins, bands.lut, valid, include)
    return band, state, bands


def threshold_labels(
    band: NDArray[np.float32], state: NDArray[np.int8], config: SegmentConfig
) -> tuple[NDArray[np.int32], int]:
    """Return connected same-band components (one pass for all bands), holes of up to ``fill_holes_px`` bridged."""
    return label_keyed(band, state, tol=0.0, bridge=config.fill_holes_px)
