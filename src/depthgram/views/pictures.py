"""Pictures a person would rather look at than read: depth with object outlines, histograms, tracks.

All functions draw on their own :class:`matplotlib.figure.Figure` with an Agg canvas into a file
(PNG or SVG by suffix). pyplot is never used: the user's backend stays as it was, no figure is
registered in pyplot's global list, so they are safe in notebooks, batch runs and threads.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram._optional import needs_extra
from depthgram.frame import Frame
from depthgram.segmentation.objects import Histogram, Segmentation

with needs_extra("report", "drawing pictures"):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

__all__ = ["draw_histogram", "draw_overlay", "draw_tracks", "label_anchor", "overlay_image"]


def _figure(size_in: tuple[float, float], dpi: int = 100) -> Figure:
    """A figure of ``size_in`` (inches) drawn by Agg, outside pyplot."""
    fig = Figure(figsize=size_in, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def overlay_image(frame: Frame, seg: Segmentation, *, scale: int = 0) -> NDArray[np.uint8]:
    """The depth frame in colour (near warm, far cool, invalid black) with object outlines.

    Parameters
    ----------
    frame : Frame
        The depth frame.
    seg : Segmentation
        Its segmentation; outlines are drawn where the label changes.
    scale : int
        Integer up-scaling factor; 0 picks one that makes the picture at least 640 px wide.

    Returns
    -------
    ndarray of uint8, shape (H * scale, W * scale, 3)
        An RGB image.
    """
    d = frame.depth
    valid = frame.valid
    if valid.any():
        lo, hi = np.percentile(d[valid], [1, 99])
    else:
        lo, hi = 0.0, 1.0
    norm = np.clip((d - lo) / max(hi - lo, 1e-6), 0, 1)
    gray = (255 * (1 - norm)).astype(np.uint8)
    rgb = cv2.cvtColor(cv2.applyColorMap(gray, cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB)
    rgb[~valid] = 0
    if scale <= 0:
        scale = max(1, int(np.ceil(640 / d.shape[1])))
    if scale > 1:
        rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
        labels = np.repeat(np.repeat(seg.labels, scale, axis=0), scale, axis=1)
    else:
        labels = seg.labels
    edge = np.zeros(labels.shape, bool)
    edge[:, 1:] |= labels[:, 1:] != labels[:, :-1]
    edge[1:, :] |= labels[1:, :] != labels[:-1, :]
    edge &= labels > 0
    rgb[edge] = 255
    return np.ascontiguousarray(rgb)


def label_anchor(labels: NDArray[np.integer], object_id: int) -> tuple[float, float]:
    """The object's pixel farthest from its outline: inside it even when it wraps another object.

    The image center of a wall with a hand in front of it lies on the hand; text placed there
    would sit on the wrong object and on the hand's own label.
    """
    mask = (labels == object_id).astype(np.uint8)
    if not mask.any():
        return 0.0, 0.0
    dist = cv2.distanceTransform(np.pad(mask, 1), cv2.DIST_L2, 3)[1:-1, 1:-1]
    y, x = np.unravel_index(int(np.argmax(dist)), dist.shape)
    return float(x), float(y)


def draw_overlay(
    frame: Frame,
    seg: Segmentation,
    path: str | Path,
    *,
    motions: Mapping[int, Any] | None = None,
    title: str | None = None,
) -> None:
    """Depth in colour with object outlines, ids and attributes (depth, area, v_radial)."""
    img = overlay_image(frame, seg)
    s = img.shape[1] / frame.depth.shape[1]
    fig = _figure((img.shape[1] / 100, img.shape[0] / 100 + 0.4))
    ax = fig.subplots()
    ax.imshow(img)
    for o in seg.objects:
        x, y = label_anchor(seg.labels, o.id)
        text = f"#{o.id} {o.kind}\n{o.depth:.0f} mm, A={o.area}"
        m = motions.get(o.id) if motions else None
        if m is not None and getattr(m, "v_radial", None) is not None:
            text += f"\nv={m.v_radial:+.0f} mm/s"
        ax.text(
            (x + 0.5) * s, (y + 0.5) * s, text, color="white", fontsize=7,
            ha="center", va="center", bbox={"facecolor": "black", "alpha": 0.55, "pad": 1.5, "edgecolor": "none"},
        )
    ax.set_axis_off()
    ax.set_title(title or frame.name or f"frame {frame.index}", fontsize=9)
    fig.tight_layout(pad=0.2)
    fig.savefig(path)


def draw_histogram(hist: Histogram, path: str | Path, *, title: str = "global depth histogram") -> None:
    """The depth histogram with its peaks and thresholds marked (the paper's Figs. 3 and 5)."""
    fig = _figure((7, 3.2))
    ax = fig.subplots()
    centers = 0.5 * (hist.edges[:-1] + hist.edges[1:])
    width = float(np.median(np.diff(hist.edges))) if hist.edges.size > 1 else 1.0
    ax.bar(centers, hist.counts, width=width, color="#5577aa", linewidth=0)
    top = float(hist.counts.max(initial=1))
    for i, pk in enumerate(hist.peaks):
        ax.axvline(pk, color="#d62728", lw=1)
        ax.text(pk, top * 1.02, f"o_{i}", color="#d62728", ha="center", fontsize=7)
    for c in hist.cuts:
        ax.axvline(c, color="#2ca02c", lw=1, ls="--")
    ax.set_xlabel("depth (mm)")
    ax.set_ylabel("pixels")
    ax.set_title(f"{title}: peaks (red), thresholds (green, dashed)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


def draw_tracks(
    times: Sequence[float],
    depth: Mapping[int, Sequence[float | None]],
    v_radial: Mapping[int, Sequence[float | None]],
    path: str | Path,
    *,
    time_unit: str = "s",
    v_unit: str = "mm/s",
) -> None:
    """Per-track mean depth and radial velocity over time (one line per track id)."""
    fig = _figure((7, 5))
    a1, a2 = fig.subplots(2, 1, sharex=True)
    t = np.asarray(times, float)
    for tid in sorted(depth):
        d = np.array([np.nan if x is None else x for x in depth[tid]], float)
        v = np.array([np.nan if x is None else x for x in v_radial.get(tid, [None] * len(t))], float)
        a1.plot(t, d, lw=1.2, label=f"#{tid}")
        a2.plot(t, v, lw=1.2, label=f"#{tid}")
    a1.set_ylabel("mean depth (mm)")
    a2.set_ylabel(f"v_radial ({v_unit})")
    a2.axhline(0, color="k", lw=0.5)
    a2.set_xlabel(f"time ({time_unit})")
    if depth:
        a1.legend(fontsize=7, ncol=min(6, len(depth)), loc="upper right")
    a1.set_title("tracks: depth and radial velocity (positive = receding)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
