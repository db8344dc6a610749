"""Golden regression of the segmentation: the same label maps and objects after every speed step.

Segments a fixed set of frames with every method and compares, per (frame, method), a digest of
the label map, the orientation classes, the band limits and the objects (their repr, so every
field of every object and part) with the stored digests in ``benchmarks/golden.json``. The
frames: the simulator's ``table``, ``corridor`` and ``crossing`` scenes at 176 x 132 and
640 x 480 with seeds 0 and 1 (``table`` also at 1280 x 720, where the subsampling steps differ),
and the real recordings under ``../shared/data`` (skipped when absent), YCB-Video read with
``--scale 0.1``. The ``surfaces`` method runs twice: with the sensor model estimated from the
frame (what ``segment`` does) and with a fixed profile (what the pipeline passes).

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/golden.py`` (exit 1 on any difference;
``--update`` rewrites the digests; ``--ycb`` also scores YCB-Video against its label PNGs;
``--only SUBSTRING`` limits the cases). Objects are compared twice: exactly, and with every
float rounded to 9 significant digits, so a change in the last bits of a sum (reassociated
additions) is told apart from a changed result.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from depthgram.frame import Frame
from depthgram.segmentation import segment

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("DEPTHGRAM_DATA") or ROOT.parent / "shared" / "data")  # bench --data
DIGESTS = Path(__file__).with_name("golden.json")
METHODS = ("threshold", "slices", "surfaces", "region", "paper")
#: (recording, read options, frames taken)
REAL: tuple[tuple[str, dict[str, Any], int], ...] = (
    ("7scenes_redkitchen_seq", {}, 3),
    ("nvlabs_ucn_demo_tabletop", {}, 2),
    ("azure_kinect_tof_mug_single", {}, 1),
    ("osd_samples_uoais/disparity", {}, 2),
    ("open3d_tum_nyu_sun_singles/TUM_depth.png", {"scale_mm": 0.2}, 1),
    ("ycbv_0000_labelled", {"scale_mm": 0.1}, 10),
)
_FLOAT = re.compile(r"-?\d+\.\d+(?:e[-+]?\d+)?")


def frames() -> Iterator[tuple[str, Frame]]:
    """(case name, frame) of every golden case."""
    from depthgram import read
    from depthgram.sensor import simulate

    sims = [(s, size, seed) for s in ("table", "corridor", "crossing") for size in ((176, 132), (640, 480))
            for seed in (0, 1)]  # fmt: skip
    sims.append(("table", (1280, 720), 0))
    for scene, size, seed in sims:
        f = next(iter(simulate(scene, 1, size=size, seed=seed))).frame
        yield f"sim:{scene}@{size[0]}x{size[1]}#s{seed}", f
    for name, opts, n in REAL:
        path = SHARED / name
        if not path.exists():
            continue
        for i, f in enumerate(read(path, **opts)):
            if i >= n:
                break
            yield f"{name}#{i}", f


def _sha(*arrays: Any) -> str:
    h = hashlib.sha256()
    for a in arrays:
        if a is None:
            h.update(b"none")
            continue
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def _rounded(text: str) -> str:
    return _FLOAT.sub(lambda m: f"{float(m.group()):.9g}", text)


def digest(f: Frame, method: str, sensor: str | None = None) -> dict[str, Any]:
    """Digests of one segmentation."""
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics, method=method, sensor=sensor)
    text = repr(seg.objects)
    return {
        "labels": _sha(seg.labels),
        "classes": _sha(seg.classes),
        "bands": _sha(seg.bands_mm),
        "objects": hashlib.sha256(text.encode()).hexdigest()[:16],
        "objects_9g": hashlib.sha256(_rounded(text).encode()).hexdigest()[:16],
        "n": len(seg.objects),
    }


def compute(only: str = "") -> dict[str, dict[str, Any]]:
    """Digests of every case (``only``: cases whose key holds this text)."""
    out: dict[str, dict[str, Any]] = {}
    for name, f in frames():
        runs: list[tuple[str, str | None]] = [(m, None) for m in METHODS] + [("surfaces", "kinect-v1")]
        for method, sensor in runs:
            key = f"{name} {method}" + (f" sensor={sensor}" if sensor else "")
            if only and only not in key:
                continue
            out[key] = digest(f, method, sensor)
    return out


def ycb_scores() -> tuple[int, int, float]:
    """(objects found with IoU >= 0.5, objects, mean IoU) of the default method on YCB-Video."""
    import cv2
    import scipy.io

    from depthgram.frame import Intrinsics
    from depthgram.segmentation import evaluate

    d = SHARED / "ycbv_0000_labelled"
    ious = []
    for i in range(1, 11):
        depth = cv2.imread(str(d / f"{i:06d}-depth.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 10
        truth = cv2.imread(str(d / f"{i:06d}-label.png"), cv2.IMREAD_UNCHANGED).astype(np.int32)
        k = scipy.io.loadmat(str(d / f"{i:06d}-meta.mat"))["intrinsic_matrix"]
        cam = Intrinsics(float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]))
        ev = evaluate(segment(depth, intrinsics=cam).labels, truth)
        ious += [o.iou for o in ev.objects]
    return sum(v >= 0.5 for v in ious), len(ious), float(np.mean(ious))


def main(argv: list[str] | None = None) -> int:
    """Compare with (or with ``--update`` rewrite) the stored digests; 1 on any difference."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--update", action="store_true", help="store the digests of this run")
    p.add_argument("--ycb", action="store_true", help="also score YCB-Video (found, mean IoU)")
    p.add_argument("--only", default="", help="cases whose name holds this text")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    now = compute(args.only)
    status = 0
    if args.update:
        old = json.loads(DIGESTS.read_text()) if DIGESTS.exists() and args.only else {}
        old.update(now)
        DIGESTS.write_text(json.dumps(old, indent=1, sort_keys=True) + "\n")
        print(f"stored {len(now)} digests in {DIGESTS.name}")
    else:
        stored = json.loads(DIGESTS.read_text())
        same = 0
        for key, d in now.items():
            ref = stored.get(key)
            if ref is None:
                print(f"NEW      {key}")
                status = 1
                continue
            diff = [k for k in ("labels", "classes", "bands", "objects") if d[k] != ref[k]]
            if not diff:
                same += 1
                continue
            status = 1
            tag = "LAST-BITS" if diff == ["objects"] and d["objects_9g"] == ref["objects_9g"] else "CHANGED"
            print(f"{tag:8} {key}: {', '.join(diff)} (objects {ref['n']} -> {d['n']})")
        print(f"{same} of {len(now)} cases identical")
    if args.ycb:
        found, total, iou = ycb_scores()
        print(f"YCB-Video (default method): {found} of {total} objects found, mean IoU {iou:.3f}")
    print(f"({time.perf_counter() - t0:.0f} s)")
    return status


if __name__ == "__main__":
    sys.exit(main())
