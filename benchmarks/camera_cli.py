"""YCB-Video through the command line, as a user runs it, with and without the camera told (issue 28).

Runs ``depthgram describe "FOLDER/*-depth.png" --scale 0.1 --labels-dir DIR`` with each way of
telling the camera (nothing, ``--intrinsics`` with the true values, ``--camera xtion``, and the
true focal length times 0.6 and 1.6), then scores the label maps against the truth masks: objects
found (IoU >= 0.5) and their mean IoU. Every object of the truth counts (class id = instance id).

    .venv/bin/python benchmarks/camera_cli.py [FOLDER ...]
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from depthgram.segmentation import evaluate

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
FOLDERS = (
    SHARED / "ycbv_0000_labelled",
    SHARED / "ycbv_0001_0002_labelled" / "0001",
    SHARED / "ycbv_0001_0002_labelled" / "0002",
)
#: YCB-Video's colour camera (depth is registered to it), from the folders' PROVENANCE.md.
FX, FY, CX, CY = 1066.778, 1067.487, 312.987, 241.311


def runs() -> list[tuple[str, list[str]]]:
    """Return each way of telling the camera, as a name and the command-line options."""

    def focal(k: float) -> list[str]:
        return ["--intrinsics", f"{FX * k:.3f}", f"{FY * k:.3f}", f"{CX}", f"{CY}"]

    return [
        ("no intrinsics", []),
        ("--intrinsics", focal(1.0)),
        ("--camera xtion", ["--camera", "xtion"]),
        ("focal x0.6", focal(0.6)),
        ("focal x1.6", focal(1.6)),
    ]


def score(folder: Path, options: list[str]) -> tuple[int, int, float]:
    """Return (objects found, objects, mean IoU) of ``depthgram describe`` on ``folder`` with ``options``."""
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "depthgram.cli", "describe", str(folder / "*-depth.png"), "--scale", "0.1"]
        cmd += ["--quiet", "--labels-dir", out, "--json", str(Path(out) / "describe.jsonl"), *options]
        subprocess.run(cmd, check=True, capture_output=True, text=True)
        ious: list[float] = []
        for truth_path in sorted(folder.glob("*-label.png")):
            stem = truth_path.name[:6]
            truth = cv2.imread(str(truth_path), cv2.IMREAD_UNCHANGED).astype(np.int32)
            raw = cv2.imread(str(folder / f"{stem}-depth.png"), cv2.IMREAD_UNCHANGED)
            labels = cv2.imread(str(Path(out) / f"{stem}-depth.png"), cv2.IMREAD_UNCHANGED).astype(np.int32)
            ids = [int(i) for i in np.unique(truth) if i > 0]
            ev = evaluate(labels, truth, valid=raw > 0, truth_ids=ids, iou_found=0.5)
            ious += [o.iou for o in ev.objects]
    iou = np.asarray(ious)
    return int(np.count_nonzero(iou >= 0.5)), int(iou.size), float(iou.mean()) if iou.size else 0.0


def main(argv: list[str] | None = None) -> int:
    """Print one row per folder and way of telling the camera."""
    folders = [Path(a) for a in (argv if argv is not None else sys.argv[1:])] or list(FOLDERS)
    missing = [f for f in folders if not f.is_dir()]
    if missing:
        print(f"camera_cli: skipped, no recordings at {', '.join(map(str, missing))}")
        return 0
    print(f"{'recording':28s} {'camera told by':16s} found   mean IoU")
    for folder in folders:
        for name, options in runs():
            found, total, iou = score(folder, options)
            print(f"{folder.name:28s} {name:16s} {found:>2d}/{total:<3d}  {iou:.3f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
