"""Golden regression of the segmentation: the same label maps and objects, within a stated tolerance.

Segments a fixed set of frames with every method and compares, per (frame, method), the label map,
the orientation classes, the band limits and the objects (their repr, so every field of every
object and part) with the stored values in ``benchmarks/golden.npz``. The frames: the simulator's
``table``, ``corridor`` and ``crossing`` scenes at 176 x 132 and 640 x 480 with seeds 0 and 1
(``table`` also at 1280 x 720, where the subsampling steps differ), and the real recordings under
``../shared/data`` (skipped when absent), YCB-Video read with ``--scale 0.1``. The ``surfaces``
method runs twice: with the sensor model estimated from the frame (what ``segment`` does) and with
a fixed profile (what the pipeline passes).

The tolerance. Integer outputs (labels, classes, object count, areas, ids, kinds: the objects'
repr with every float taken out) must be identical, except for a case listed in :data:`ALLOWED`
with the number of label pixels that may change and the reason. Floats (band limits, depths,
centres, spreads, planes) must agree to 9 significant digits (``rtol`` 1e-9): the last bits of a
float move with the CPU's BLAS kernels (``OPENBLAS_CORETYPE``) and with reassociated sums, and
such a move is not a changed result.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/golden.py`` (exit 1 on any difference beyond
the tolerance; ``--update`` rewrites the stored values; ``--ycb`` also scores YCB-Video against
its label PNGs; ``--only SUBSTRING`` limits the cases). ``tests/test_golden.py`` runs the same
comparison in CI.
"""

from __future__ import annotations

import argparse
import io
import os
import re
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from depthgram.frame import Frame
from depthgram.segmentation import segment

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("DEPTHGRAM_DATA") or ROOT.parent / "shared" / "data")  # bench --data
STORE = Path(__file__).with_name("golden.npz")
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
#: relative tolerance of every float: 9 significant digits
RTOL = 1e-9
#: case -> (label pixels that may change, why); empty: every case's labels are identical
ALLOWED: dict[str, tuple[int, str]] = {}
_FLOAT = re.compile(r"-?\d+\.\d+(?:e[-+]?\d+)?|-?\d+e[-+]?\d+|nan|-?inf")


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


def _split(text: str) -> tuple[str, np.ndarray]:
    """The repr with its floats taken out, and the floats."""
    floats = np.array([float(m) for m in _FLOAT.findall(text)], np.float64)
    return _FLOAT.sub("#", text), floats


@dataclass(frozen=True)
class Case:
    """What one segmentation gives: the arrays and the objects' repr split in text and floats."""

    labels: np.ndarray
    classes: np.ndarray | None
    bands: np.ndarray | None
    skeleton: str
    floats: np.ndarray


def record(f: Frame, method: str, sensor: str | None = None) -> Case:
    """Segment one frame and keep what the comparison reads."""
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics, method=method, sensor=sensor)
    skeleton, floats = _split(repr(seg.objects))
    return Case(seg.labels, seg.classes, seg.bands_mm, skeleton, floats)


def cases(only: str = "") -> Iterator[tuple[str, Frame, str, str | None]]:
    """(key, frame, method, sensor) of every golden case (``only``: keys holding this text)."""
    for name, f in frames():
        runs: list[tuple[str, str | None]] = [(m, None) for m in METHODS] + [("surfaces", "kinect-v1")]
        for method, sensor in runs:
            key = f"{name} {method}" + (f" sensor={sensor}" if sensor else "")
            if not only or only in key:
                yield key, f, method, sensor


def compute(only: str = "") -> dict[str, Case]:
    """Every case's record."""
    return {key: record(f, method, sensor) for key, f, method, sensor in cases(only)}


def _close(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=RTOL, atol=0.0, equal_nan=True))


def compare(key: str, got: Case, want: Case) -> list[str]:
    """What differs beyond the tolerance (empty: the same result)."""
    out = []
    if got.labels.shape != want.labels.shape:
        return [f"labels shaped {got.labels.shape}, stored {want.labels.shape}"]
    changed = int(np.count_nonzero(got.labels != want.labels))
    allowed, why = ALLOWED.get(key, (0, ""))
    if changed > allowed:
        out.append(f"labels: {changed} pixels changed (allowed {allowed})")
    elif changed:
        print(f"  {key}: {changed} label pixels changed, within the allowance: {why}")
    for name in ("classes",):
        a, b = getattr(got, name), getattr(want, name)
        if (a is None) != (b is None) or (a is not None and b is not None and not np.array_equal(a, b)):
            out.append(f"{name} differ")
    if not _close(got.bands, want.bands):
        out.append("band limits differ beyond 9 significant digits")
    if changed == 0:
        if got.skeleton != want.skeleton:
            out.append("objects differ (count, areas, ids, kinds or parts)")
        elif not _close(got.floats, want.floats):
            worst = float(np.nanmax(np.abs(got.floats - want.floats) / np.maximum(np.abs(want.floats), 1e-300)))
            out.append(f"object floats differ beyond 9 significant digits (worst relative {worst:.2g})")
    return out


def save(records: dict[str, Case], path: Path = STORE) -> None:
    """Store the records, one compressed member per array."""
    arrays: dict[str, np.ndarray] = {}
    for i, (key, c) in enumerate(sorted(records.items())):
        arrays[f"{i}.key"] = np.array(key)
        arrays[f"{i}.labels"] = c.labels
        if c.classes is not None:
            arrays[f"{i}.classes"] = c.classes
        if c.bands is not None:
            arrays[f"{i}.bands"] = c.bands
        arrays[f"{i}.skeleton"] = np.array(c.skeleton)
        arrays[f"{i}.floats"] = c.floats
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)  # type: ignore[arg-type]
    path.write_bytes(buf.getvalue())


def load(path: Path = STORE) -> dict[str, Case]:
    """The stored records."""
    out: dict[str, Case] = {}
    with np.load(path) as z:
        names = set(z.files)
        i = 0
        while f"{i}.key" in names:
            out[str(z[f"{i}.key"])] = Case(
                z[f"{i}.labels"],
                z[f"{i}.classes"] if f"{i}.classes" in names else None,
                z[f"{i}.bands"] if f"{i}.bands" in names else None,
                str(z[f"{i}.skeleton"]),
                z[f"{i}.floats"],
            )
            i += 1
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
    """Compare with (or with ``--update`` rewrite) the stored values; 1 on any difference."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--update", action="store_true", help="store the values of this run")
    p.add_argument("--ycb", action="store_true", help="also score YCB-Video (found, mean IoU)")
    p.add_argument("--only", default="", help="cases whose name holds this text")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    now = compute(args.only)
    status = 0
    if args.update:
        old = load() if STORE.exists() and args.only else {}
        old.update(now)
        save(old)
        print(f"stored {len(now)} cases in {STORE.name}")
    else:
        stored = load()
        same = 0
        for key, got in now.items():
            want = stored.get(key)
            if want is None:
                print(f"NEW      {key}")
                status = 1
                continue
            diff = compare(key, got, want)
            if not diff:
                same += 1
                continue
            status = 1
            print(f"CHANGED  {key}: {'; '.join(diff)}")
        print(f"{same} of {len(now)} cases the same within the tolerance")
    if args.ycb:
        found, total, iou = ycb_scores()
        print(f"YCB-Video (default method): {found} of {total} objects found, mean IoU {iou:.3f}")
    print(f"({time.perf_counter() - t0:.0f} s)")
    return status


if __name__ == "__main__":
    sys.exit(main())
