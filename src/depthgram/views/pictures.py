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

__all__ = [
    "DEPTH_PERCENTILES",
    "depth_limits",
    "draw_histogram",
    "draw_overlay",
    "draw_tracks",
    "label_anchor",
    "overlay_image",
    "place_labels",
]


def _figure(size_in: tuple[float, float], dpi: int = 100) -> Figure:
    """Return a figure of ``size_in`` (inches) drawn by Agg, outside pyplot."""
    fig = Figure(figsize=size_in, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


#: Percentiles of the valid depths that span the colour scale: a few far outliers (TUM's frame
#: reads up to 46 m behind a 2-3 m room) do not squeeze the scene into one colour.
DEPTH_PERCENTILES = (2.0, 98.0)


def depth_limits(frame: Frame) -> tuple[float, float]:
    """Return the depth range (mm) of the colour scale: the :data:`DEPTH_PERCENTILES` of the valid pixels."""
    if not frame.valid.any():
        return 0.0, 1.0
    step = max(1, int(np.sqrt(frame.depth.size / 40_000)))  # a strided sample: same limits, a tenth of the time
    sample = frame.depth[::step, ::step][frame.valid[::step, ::step]]
    if sample.size == 0:
        sample = frame.depth[frame.valid]
    lo, hi = np.percentile(sample, DEPTH_PERCENTILES)
    return float(lo), float(max(hi, lo + 1.0))


def overlay_image(frame: Frame, seg: Segmentation, *, scale: int = 0, outline_px: int = 0) -> NDArray[np.uint8]:
    """Return the depth frame in colour (near warm, far cool, invalid black) with object outlines.

    Parameters
    ----------
    frame : Frame
        The depth frame.
    seg : Segmentation
        Its segmentation; outlines are drawn where the label changes.
    scale : int
        Integer up-scaling factor; 0 picks one that makes the picture at least 640 px wide.
    outline_px : int
        Outline width in output pixels; 0 is one pixel per ``scale`` step (at least 2).

    Returns
    -------
    ndarray of uint8, shape (H * scale, W * scale, 3)
        An RGB image. The colours span :func:`depth_limits` (``TURBO`` reversed).
    """
    d = frame.depth
    valid = frame.valid
    lo, hi = depth_limits(frame)
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
    width = outline_px or max(2, scale)
    if width > 1:
        edge = cv2.dilate(edge.astype(np.uint8), np.ones((width, width), np.uint8)).astype(bool)
    rgb[edge] = 255
    return np.ascontiguousarray(rgb)


def place_labels(
    anchors: Sequence[tuple[float, float]], sizes: Sequence[tuple[float, float]], bounds: tuple[float, float]
) -> list[tuple[float, float] | None]:
    """Centres for text boxes near their anchors, inside ``bounds``, without overlapping each other.

    Parameters
    ----------
    anchors : sequence of (x, y)
        Where each label wants to be (px); earlier ones are placed first (give the largest
        objects first).
    sizes : sequence of (w, h)
        Each label's box (px).
    bounds : (width, height)
        The picture (px): boxes are moved inside it, never clipped.

    Returns
    -------
    list of (x, y) or None
        Each label's centre, or None when no free place lies within a few box heights of its
        anchor (the label is left out rather than drawn over another).
    """
    width, height = bounds
    placed: list[tuple[float, float, float, float]] = []
    out: list[tuple[float, float] | None] = []
    for (ax_, ay), (w, h) in zip(anchors, sizes, strict=True):
        best = None
        steps = [(0.0, 0.0)]
        for k in (1, 2, 3, 4):
            steps += [
                (0.0, -k * h),
                (0.0, k * h),
                (-k * w * 0.6, 0.0),
                (k * w * 0.6, 0.0),
                (-k * w * 0.6, -k * h),
                (k * w * 0.6, k * h),
                (k * w * 0.6, -k * h),
                (-k * w * 0.6, k * h),
            ]
        for dx, dy in steps:
            cx = min(max(ax_ + dx, w / 2), width - w / 2)
            cy = min(max(ay + dy, h / 2), height - h / 2)
            box = (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)
            if all(box[2] <= b[0] or b[2] <= box[0] or box[3] <= b[1] or b[3] <= box[1] for b in placed):
                best = (cx, cy)
                placed.append(box)
                break
        out.append(best)
    return out


def label_anchor(labels: NDArray[np.integer], object_id: int) -> tuple[float, float]:
    """Return the object's pixel farthest from its outline: inside it even when it wraps another object.

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
    """Depth in colour with a colour bar (mm), object outlines, and labels that never overlap.

    Labels ("#id kind", depth, area, v_radial) sit at each object's innermost pixel, moved
    aside when they would cover an earlier one (largest objects first) and kept inside the
    picture; a label with no free place near its object is left out.
    """
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    img = overlay_image(frame, seg)
    s = img.shape[1] / frame.depth.shape[1]
    lo, hi = depth_limits(frame)
    fig = _figure((img.shape[1] / 100 + 1.1, img.shape[0] / 100 + 0.4))
    ax = fig.subplots()
    ax.imshow(img)
    ax.set_xlim(-0.5, img.shape[1] - 0.5)
    ax.set_ylim(img.shape[0] - 0.5, -0.5)
    fontsize = 8
    texts, anchors, sizes = [], [], []
    for o in sorted(seg.objects, key=lambda o: -o.area):
        x, y = label_anchor(seg.labels, o.id)
        text = f"#{o.id} {o.kind}\n{o.depth:.0f} mm, A={o.area}"
        m = motions.get(o.id) if motions else None
        if m is not None and getattr(m, "v_radial", None) is not None:
            text += f"\nv={m.v_radial:+.0f} mm/s"
        lines = text.split("\n")
        # box size from the font (points at 100 dpi, about 0.6 em per character), plus padding
        pt = fontsize * 100 / 72
        sizes.append((0.6 * pt * max(map(len, lines)) + 6, 1.25 * pt * len(lines) + 6))
        anchors.append(((x + 0.5) * s, (y + 0.5) * s))
        texts.append(text)
    for text, pos in zip(texts, place_labels(anchors, sizes, (img.shape[1], img.shape[0])), strict=True):
        if pos is None:
            continue
        ax.text(
            pos[0],
            pos[1],
            text,
            color="white",
            fontsize=fontsize,
            ha="center",
            va="center",
            bbox={"facecolor": "black", "alpha": 0.6, "pad": 1.5, "edgecolor": "none"},
            clip_on=True,
        )
    ax.set_axis_off()
    cmap = colormaps["turbo_r"]
    bar = fig.colorbar(ScalarMappable(norm=Normalize(lo, hi), cmap=cmap), ax=ax, fraction=0.04, pad=0.01)
    bar.set_label(
        f"depth (mm), {DEPTH_PERCENTILES[0]:g}-{DEPTH_PERCENTILES[1]:g} % of valid pixels; black = none", fontsize=8
    )
    bar.ax.tick_params(labelsize=8)
    ax.set_title(title or frame.name or f"frame {frame.index}", fontsize=9)
    fig.tight_layout(pad=0.2)
    fig.savefig(path)


def draw_histogram(hist: Histogram, path: str | Path, *, title: str = "global depth histogram") -> None:
    """Return the depth histogram with its peaks and thresholds marked (the paper's Figs. 3 and 5)."""
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


#: Most tracks named in the tracks picture's legend; a hand-held recording has some seventy.
_TRACK_LEGEND_MAX = 12


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
    title = "tracks: depth and radial velocity (positive = receding)"
    if 0 < len(depth) <= _TRACK_LEGEND_MAX:
        # beside the plots, not over them: the legend of a hand-held recording covered the depths
        a1.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    elif depth:
        title += f"; {len(depth)} tracks (no legend beyond {_TRACK_LEGEND_MAX})"
    a1.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
