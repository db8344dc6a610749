"""The raised pass (``[segment] raised_sigmas``, off by default): its cost, and what it cuts on real frames.

Two measures behind issue 28, item 5 (objects lying flat on a support):

- **Cost**: thread CPU of a ``segment`` call with the pass off (``raised_sigmas = 0``), as by
  default (4, ``raised_supports = "facing"``) and on every support (``"all"``), the minimum over
  ``--repeats`` rounds that alternate the three, on the simulator's ``table`` (176 x 132 and 640 x
  480) and ``arm_down`` (640 x 480, flat objects to cut) and on the first frames of 7-Scenes and
  NVlabs (``../shared/data``, skipped when absent).
- **Pictures** (``--pictures``): a recording through the pipeline (as ``depthgram describe``
  runs it: the sensor model estimated once and kept), with the pass off and on the supports
  ``--supports`` names (default ``all``, as ``--raised 4``); per frame the
  objects the pass made (no object of the run without it overlaps them by IoU >= 0.5), and for
  the first ``--shown`` frames a picture (depth, labels without, labels with, the new objects
  outlined in white) in ``--out``.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/raised.py [--repeats 15]`` or ``... --pictures
../shared/data/nvlabs_ucn_demo_tabletop --frames 10``.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import os
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from depthgram import Pipeline, read, segment
from depthgram.frame import Frame
from depthgram.pipeline import Config
from depthgram.sensor import simulate

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("DEPTHGRAM_DATA") or ROOT.parent / "shared" / "data")


def _cases() -> dict[str, list[Frame]]:
    cases = {
        "sim:table 176x132": [s.frame for s in simulate("table", 4, size=(176, 132), seed=1)],
        "sim:table 640x480": [s.frame for s in simulate("table", 4, size=(640, 480), seed=1)],
        "arm_down 640x480": [s.frame for s in simulate("arm_down", 2, size=(640, 480), seed=1)],
    }
    for name, frames in (("7scenes_redkitchen_seq", 6), ("nvlabs_ucn_demo_tabletop", 4)):
        if (SHARED / name).is_dir():
            cases[name] = list(itertools.islice(read(str(SHARED / name)), frames))
    return cases


def cost(repeats: int) -> list[str]:
    """Return one line per case: thread CPU ms a frame with the pass off, as by default, and on every support."""
    runs = {"off": {"raised_sigmas": 0.0}, "default": {}, "all": {"raised_supports": "all"}}
    lines = []
    for name, frames in _cases().items():
        best = dict.fromkeys(runs, float("inf"))
        for kw in runs.values():  # compiled before timing
            segment(frames[0], **kw)
        for _ in range(repeats):
            for key, kw in runs.items():
                t0 = time.thread_time()
                for f in frames:
                    segment(f, **kw)
                best[key] = min(best[key], (time.thread_time() - t0) / len(frames))
        off = 1e3 * best["off"]
        parts = [f"{name:26s} off {off:6.3f} ms"]
        for key in ("default", "all"):
            ms = 1e3 * best[key]
            parts.append(f"{key} {ms:6.3f} ms ({100 * (ms / off - 1):+.0f} %)")
        lines.append("  ".join(parts))
    return lines


def _colour(labels: np.ndarray) -> np.ndarray:
    rng = np.random.default_rng(3)
    lut = rng.integers(40, 255, (int(labels.max()) + 1, 3), dtype=np.uint8)
    lut[0] = 0
    return lut[labels]


def pictures(spec: str, frames: int, shown: int, out: Path, supports: str = "all") -> list[str]:
    """Return one line per frame (objects without and with the pass, the new ones); write pictures."""
    import cv2

    kw = {"scale_mm": 0.1} if "ycbv" in spec else {}
    taken = list(itertools.islice(read(spec, **kw), frames))

    def run(k: float) -> list:
        cfg = Config()
        cfg = dataclasses.replace(
            cfg, segment=dataclasses.replace(cfg.segment, raised_sigmas=k, raised_supports=supports)
        )
        pipe = Pipeline(cfg, track=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the intrinsics and units notes: the same for both runs
            return [pipe.process(f).segmentation for f in taken]

    without, with_ = run(0.0), run(4.0)
    out.mkdir(parents=True, exist_ok=True)
    lines, total = [], 0
    for i, (a, b, f) in enumerate(zip(without, with_, taken, strict=True)):
        new = []
        for o in b.objects:
            mine = b.labels == o.id
            ids = [j for j in np.unique(a.labels[mine]) if j]
            iou = max(
                (np.count_nonzero((a.labels == j) & mine) / np.count_nonzero((a.labels == j) | mine) for j in ids),
                default=0.0,
            )
            if iou < 0.5:
                new.append(o)
        total += len(new)
        lines.append(
            f"frame {i}: objects {len(a.objects)} -> {len(b.objects)}, new "
            + ", ".join(f"{o.area} px at {o.depth:.0f} mm" for o in new)
        )
        if i < shown:
            d, ok = f.depth, f.valid
            lo, hi = np.percentile(d[ok], (2, 98)) if ok.any() else (0.0, 1.0)
            depth = cv2.applyColorMap(
                np.clip((d - lo) / max(hi - lo, 1e-6) * 255, 0, 255).astype(np.uint8), cv2.COLORMAP_TURBO
            )
            depth[~ok] = 0
            marked = _colour(b.labels).copy()
            for o in new:
                edges, _ = cv2.findContours(
                    (b.labels == o.id).astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE
                )
                cv2.drawContours(marked, edges, -1, (255, 255, 255), 2)
            cv2.imwrite(str(out / f"{Path(spec).name}_{i}.png"), np.hstack([depth, _colour(a.labels), marked]))
    lines.append(f"new objects in {len(taken)} frames: {total}; pictures in {out}")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Print the figures; return 0."""
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument("--repeats", type=int, default=15, help="rounds of the cost (default 15)")
    p.add_argument("--pictures", metavar="RECORDING", default=None, help="a recording through the pipeline instead")
    p.add_argument("--frames", type=int, default=10, help="frames of the recording (default 10)")
    p.add_argument("--shown", type=int, default=3, help="frames drawn (default 3)")
    p.add_argument("--supports", choices=("facing", "all"), default="all", help="the supports cut (default all)")
    p.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out" / "raised")
    args = p.parse_args(argv)
    if args.pictures:
        lines = pictures(args.pictures, args.frames, args.shown, args.out, args.supports)
    else:
        lines = cost(args.repeats)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
