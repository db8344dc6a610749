"""YCB-Video through the command line, as a user runs it: with and without the camera's intrinsics.

Issue 28's measure. Each labelled YCB-Video folder under ``../shared/data`` (``ycbv_0000_labelled``,
``ycbv_0001_0002_labelled/0001`` and ``/0002``; Asus Xtion, 0.1 mm units, exact object masks) is
described by ``depthgram describe FOLDER/*-depth.png --scale 0.1 --labels-dir DIR`` in a
subprocess, once per way a user may give the camera:

- ``none``: nothing (the tool reads the focal length from the scene, or guesses, and says so);
- ``given``: ``--intrinsics`` with PROVENANCE.md's values (fx 1066.778, fy 1067.487, cx 312.987,
  cy 241.311);
- ``--camera xtion``: the named profile (the Xtion's own depth camera, not the colour camera
  YCB-Video registers depth to: a different focal length);
- ``f x0.6`` and ``f x1.6``: the same with a focal length 0.6 and 1.6 times the true one, a user's
  wrong guess either way.

Each written label map is scored against the truth PNG beside the depth frame: per labelled object
the best-IoU segment (:func:`depthgram.segmentation.evaluate`, over the pixels with a reading),
found when its IoU >= 0.5. Pictures of the first frame of each run (depth, truth, labels) go to
``--out`` (default ``benchmarks/out/user_camera/``).

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/user_camera.py`` (``--only NAME``: folders whose
name holds NAME; ``--config TOML``: settings given to every run, e.g. ``[segment]
crease_span_fraction = 0.015625``; ``--run NAME``: only that way of giving the camera, repeatable).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.segmentation import evaluate

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("DEPTHGRAM_DATA") or ROOT.parent / "shared" / "data")  # bench --data
OUT = ROOT / "benchmarks" / "out" / "user_camera"
FOLDERS = ("ycbv_0000_labelled", "ycbv_0001_0002_labelled/0001", "ycbv_0001_0002_labelled/0002")
#: YCB-Video's Xtion, from the folders' PROVENANCE.md (fx, fy, cx, cy; px at 640 x 480)
XTION = (1066.778, 1067.487, 312.987, 241.311)
RUNS: dict[str, list[str]] = {
    "none": [],
    "given": ["--intrinsics", *map(str, XTION)],
    "--camera xtion": ["--camera", "xtion"],
    "f x0.6": ["--intrinsics", str(XTION[0] * 0.6), str(XTION[1] * 0.6), str(XTION[2]), str(XTION[3])],
    "f x1.6": ["--intrinsics", str(XTION[0] * 1.6), str(XTION[1] * 1.6), str(XTION[2]), str(XTION[3])],
}
IOU_FOUND = 0.5


@dataclass(frozen=True)
class Score:
    """One (folder, run): objects found with IoU >= 0.5, objects, their mean IoU, seconds."""

    folder: str
    run: str
    found: int
    objects: int
    mean_iou: float
    seconds: float
    warned: bool


def _depthgram() -> list[str]:
    exe = Path(sys.executable).with_name("depthgram")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "depthgram"]


def describe(folder: Path, options: list[str], out: Path) -> tuple[float, str]:
    """Run ``depthgram describe "FOLDER/*-depth.png"``; the label maps go to ``out``. (seconds, stderr)."""
    cmd = [*_depthgram(), "describe", str(folder / "*-depth.png"), "--scale", "0.1", "--quiet", "--stills", "yes"]
    cmd += [*options, "--labels-dir", str(out), "--json", str(out / "scene.jsonl")]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr[-2000:]}")
    return time.perf_counter() - t0, done.stderr


def _label_maps(out: Path, n: int) -> list[NDArray[np.int32]]:
    maps = sorted(p for p in out.iterdir() if p.suffix == ".png")
    if len(maps) != n:
        raise RuntimeError(f"{out}: expected {n} label maps, found {len(maps)}")
    return [cv2.imread(str(p), cv2.IMREAD_UNCHANGED).astype(np.int32) for p in maps]


def _picture(
    depth_mm: NDArray[np.float32], truth: NDArray[np.integer], labels: NDArray[np.integer], path: Path
) -> None:
    def colour(lab: NDArray[np.integer]) -> NDArray[np.uint8]:
        rng = np.random.default_rng(7)
        lut = rng.integers(40, 255, (int(lab.max()) + 1, 3), dtype=np.uint8)
        lut[0] = 0
        return lut[lab]

    ok = depth_mm > 0
    lo, hi = np.percentile(depth_mm[ok], (2, 98)) if ok.any() else (0.0, 1.0)
    d8 = np.clip((depth_mm - lo) / max(hi - lo, 1e-6) * 255, 0, 255).astype(np.uint8)
    d = cv2.applyColorMap(d8, cv2.COLORMAP_TURBO)
    d[~ok] = 0
    cv2.imwrite(str(path), np.hstack([d, colour(truth), colour(labels)]))


def score_folder(
    folder: Path, name: str, out: Path | None, extra: list[str] | None = None, runs: tuple[str, ...] = ()
) -> list[Score]:
    """The runs of one labelled folder (``extra``: options added to every run, e.g. ``--config``;
    ``runs``: the names of :data:`RUNS` to do, all when empty)."""
    depths = sorted(folder.glob("*-depth.png"))
    truths = [cv2.imread(str(p).replace("-depth.png", "-label.png"), cv2.IMREAD_UNCHANGED) for p in depths]
    raw = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED).astype(np.float32) / 10.0 for p in depths]
    scores = []
    for run, options in RUNS.items():
        if runs and run not in runs:
            continue
        with tempfile.TemporaryDirectory() as tmp:
            seconds, stderr = describe(folder, [*options, *(extra or [])], Path(tmp))
            maps = _label_maps(Path(tmp), len(depths))
        ious = []
        for depth, truth, labels in zip(raw, truths, maps, strict=True):
            ev = evaluate(labels, truth.astype(np.int32), valid=depth > 0)
            ious += [o.iou for o in ev.objects]
        if out is not None:
            out.mkdir(parents=True, exist_ok=True)
            tag = f"{name.replace('/', '_')}-{run.replace(' ', '').replace('.', '')}.png"
            _picture(raw[0], truths[0], maps[0], out / tag)
        scores.append(
            Score(
                name,
                run,
                sum(v >= IOU_FOUND for v in ious),
                len(ious),
                float(np.mean(ious)) if ious else 0.0,
                seconds,
                "intrinsics" in stderr and "warning" in stderr,
            )
        )
    return scores


def table(scores: list[Score]) -> str:
    """A Markdown table of the scores."""
    lines = [
        "| folder | camera given | found (IoU >= 0.5) | mean IoU | warned of a guess | s (whole run) |",
        "|---|---|---|---|---|---|",
    ]
    for s in scores:
        lines.append(
            f"| {s.folder} | {s.run} | {s.found} of {s.objects} | {s.mean_iou:.3f} | "
            f"{'yes' if s.warned else 'no'} | {s.seconds:.1f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Score every folder present and print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default="", help="folders whose name holds this text")
    p.add_argument("--out", type=Path, default=OUT, help="folder for the pictures")
    p.add_argument("--config", type=Path, help="pipeline settings (TOML) given to every run")
    p.add_argument("--run", action="append", default=[], choices=list(RUNS), help="only this way (repeatable)")
    args = p.parse_args(argv)
    extra = ["--config", str(args.config)] if args.config else []
    scores: list[Score] = []
    for name in FOLDERS:
        folder = SHARED / name
        if args.only not in name:
            continue
        if not folder.is_dir():
            print(f"skipped {name}: not found at {folder}")
            continue
        scores += score_folder(folder, name, args.out, extra, tuple(args.run))
    if not scores:
        print(f"no labelled YCB-Video folder found under {SHARED}")
        return 0
    print(table(scores))
    print(f"pictures: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
