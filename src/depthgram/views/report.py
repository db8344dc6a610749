"""The HTML report: pictures of chosen frames, their trees and sentences, and the tracks over time."""

from __future__ import annotations

import html
import json
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from depthgram.segmentation.objects import Histogram

if TYPE_CHECKING:
    from depthgram.pipeline import SceneResult

__all__ = ["ReportWriter", "picture_stem", "spread"]


@dataclass
class _Series:
    times: list[float] = field(default_factory=list)
    depth: dict[int, list[float | None]] = field(default_factory=dict)
    v: dict[int, list[float | None]] = field(default_factory=dict)
    per_frame: bool = False


def _slice_histograms(result: SceneResult) -> list[tuple[str, str, Histogram]]:
    """Histograms of a vertical slice through the middle and a horizontal one near the bottom.

    The paper's Fig. 5: a slice about 10 % of the frame wide, thresholded by the same rule as the
    whole frame; walls peak in vertical slices, the floor in horizontal ones.
    """
    from depthgram.segmentation import segment

    f = result.frame
    h, w = f.shape
    out = []
    c0, r0 = int(0.45 * w), int(0.8 * h)
    cuts = {
        "vslice": ("vertical slice, middle 10 % of columns", np.s_[:, c0 : max(int(0.55 * w), c0 + 1)]),
        "hslice": ("horizontal slice, rows 80-90 %", np.s_[r0 : max(int(0.9 * h), r0 + 1), :]),
    }
    for name, (title, sl) in cuts.items():
        if not f.valid[sl].any():
            continue
        seg = segment(f.depth[sl], valid=f.valid[sl], method="threshold")
        if seg.histogram is not None and seg.histogram.counts.size:
            out.append((name, title, seg.histogram))
    return out


def spread(frames: int, count: int) -> frozenset[int]:
    """``count`` frame positions spread evenly over ``frames``, the first and the last included."""
    if frames <= 0 or count <= 0:
        return frozenset()
    return frozenset(int(i) for i in np.unique(np.rint(np.linspace(0, frames - 1, min(count, frames)))))


def picture_stem(frame_name: str, index: int, taken: Iterable[str] = ()) -> str:
    """File stem of a frame's pictures, after its input frame (``000123-depth`` for ``000123-depth.png``).

    Frames without a file of their own (``sim:table#3``, ``bag:topic#12``) are ``frame000003``;
    a stem already ``taken`` (two files of one name in different folders) gets the index added.
    """
    base = Path(frame_name).stem if frame_name and ":" not in frame_name and "#" not in frame_name else ""
    base = re.sub(r"[^\w.-]+", "_", base).strip("._")
    stem = base or f"frame{index:06d}"
    return f"{stem}_{index:06d}" if stem in set(taken) else stem


class ReportWriter:
    """Collects results frame by frame and writes ``index.html`` with its pictures.

    Only the pictured frames' images and the per-track series (a few numbers per frame) are
    kept, so a long recording does not fill memory.

    Parameters
    ----------
    out_dir : Path
        Folder to write into (created).
    every : int
        Picture every ``every``-th frame (frame 0 always), when ``frames`` is not known.
    max_pictures : int
        At most this many pictured frames.
    frames : int, optional
        How many frames the recording has: the pictured ones are then ``max_pictures`` spread
        evenly from the first to the last (:func:`spread`).
    source : str
        What was read (a folder, a bag, ``sim:approach``), named on the page; without it, the
        first frame's name.
    """

    def __init__(
        self,
        out_dir: str | Path,
        *,
        every: int = 1,
        max_pictures: int = 8,
        frames: int | None = None,
        source: str = "",
    ) -> None:
        self.out = Path(out_dir)
        self.out.mkdir(parents=True, exist_ok=True)
        self.every = max(1, every)
        self.max_pictures = max_pictures
        self._chosen = spread(frames, max_pictures) if frames else None
        self._stems: set[str] = set()
        self._sections: list[str] = []
        self._series = _Series()
        self._n = 0
        self._source = source

    def add(self, result: SceneResult) -> None:
        """Take one frame's result: picture it if chosen, extend the track series."""
        from depthgram.views.pictures import draw_histogram, draw_overlay
        from depthgram.views.tree_plot import draw_tree

        f = result.frame
        self._source = self._source or f.name.split("#")[0]
        k = self._n
        self._n += 1
        self._extend_series(result)
        chosen = (k in self._chosen) if self._chosen is not None else k % self.every == 0
        if not chosen or len(self._sections) >= self.max_pictures:
            return
        stem = picture_stem(f.name, f.index, self._stems)
        self._stems.add(stem)
        draw_overlay(f, result.segmentation, self.out / f"{stem}_objects.png", motions=result.motions)
        pics = [f"{stem}_objects.png"]
        if result.segmentation.histogram is not None:
            draw_histogram(result.segmentation.histogram, self.out / f"{stem}_histogram.png")
            pics.append(f"{stem}_histogram.png")
        for name, title, hist in _slice_histograms(result):
            draw_histogram(hist, self.out / f"{stem}_{name}.png", title=title)
            pics.append(f"{stem}_{name}.png")
        draw_tree(result.tree, self.out / f"{stem}_tree.png")
        pics.append(f"{stem}_tree.png")
        rows = "".join(
            f"<tr><td>{o['id']}</td><td>{o['kind']}</td><td>o_{o['depth_label']}</td><td>{o['depth']}</td>"
            f"<td>{o['area']}</td><td>({o['center_xy'][0]}, {o['center_xy'][1]})</td><td>{o['parent']}</td>"
            f"<td>{o.get('v_radial')}</td><td>{o.get('ttc')}</td><td>{o.get('status', '')}</td></tr>"
            for o in result.to_record()["objects"]
        )
        imgs = "".join(f'<img src="{p}" alt="{p}">' for p in pics)
        self._sections.append(
            f"<section><h2>frame {f.index} <small>{html.escape(f.name)}"
            f"{'' if f.time_s is None else f', t = {f.time_s:.3f} s'}</small></h2>"
            f"<p class=sentence><code>{html.escape(result.sentence)}</code></p><div class=pics>{imgs}</div>"
            "<table><tr><th>id</th><th>kind</th><th>label</th><th>depth mm</th><th>area px</th>"
            "<th>center</th><th>parent</th><th>v_radial</th><th>ttc s</th><th>status</th></tr>"
            f"{rows}</table></section>"
        )

    def _extend_series(self, result: SceneResult) -> None:
        if not result.motions:
            return  # unrelated stills: ids are not tracks, a plot over them would mean nothing
        s = self._series
        f = result.frame
        i = len(s.times)
        s.times.append(f.time_s if f.time_s is not None else float(f.index))
        for o in result.segmentation.objects:
            m = result.motions.get(o.id)
            d = s.depth.setdefault(o.id, [None] * i)
            v = s.v.setdefault(o.id, [None] * i)
            d.append(o.depth)
            v.append(None if m is None else m.v_radial)
            if f.time_s is None:
                s.per_frame = True  # no timestamps: the time axis counts frames
        for lst in (*s.depth.values(), *s.v.values()):
            if len(lst) < i + 1:
                lst.append(None)

    def add_all(self, results: Iterable[SceneResult]) -> None:
        """Take every result of an iterable."""
        for r in results:
            self.add(r)

    def finish(self) -> Path:
        """Write the track plot (sequences) and ``index.html``; return the page's path."""
        from depthgram.views.pictures import draw_tracks

        extra = ""
        s = self._series
        if len(s.times) > 1 and s.depth:
            # Only tracks seen in at least three frames: one-frame flickers would bury the plot.
            keep = {k: v for k, v in s.depth.items() if sum(x is not None for x in v) >= 3}
            draw_tracks(
                s.times,
                keep,
                {k: s.v[k] for k in keep},
                self.out / "tracks.png",
                time_unit="frame" if s.per_frame else "s",
                v_unit="mm/s",
            )
            extra = '<section><h2>tracks</h2><img src="tracks.png" alt="tracks"></section>'
        (self.out / "series.json").write_text(
            json.dumps({"times": s.times, "depth": s.depth, "v_radial": s.v}), encoding="utf-8"
        )
        page = (
            "<!doctype html><html><head><meta charset=utf-8><title>depthgram report</title><style>"
            "body{font-family:sans-serif;margin:1.5em;max-width:1400px}img{max-width:100%;margin:4px;"
            "border:1px solid #ccc}.pics{display:flex;flex-wrap:wrap;align-items:flex-start}"
            ".pics img{max-width:48%}table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;"
            "padding:2px 6px}.sentence code{white-space:pre-wrap;background:#f4f4f4;display:block;padding:6px}"
            "</style></head><body>"
            f"<h1>depthgram report</h1><p>source: <code>{html.escape(self._source)}</code>, "
            f"{self._n} frames processed, {len(self._sections)} pictured.</p>"
            f"{extra}{''.join(self._sections)}</body></html>"
        )
        index = self.out / "index.html"
        index.write_text(page, encoding="utf-8")
        return index
