"""The default segmentation on the simulator's scenes for new mountings (issue 28, item 6), scored against exact truth.

For each scene and sensor model: objects found (IoU >= 0.5) and their mean IoU (the table itself
left out: it is the support), and what kinds the segments covering the table, the floor, the
walls and the ceiling were given (a table seen from above must never be a ``ceiling``; the kinds follow gravity,
:mod:`depthgram.scene.kinds`). With and without the exact gravity handed to the pipeline
(without it, gravity is estimated from the supports seen from above).

    .venv/bin/python benchmarks/mountings.py [--size 640x480] [--frames 3] [--raised 4] [--peers]
        [--scenes arm_down,arm_45,chest_walk,table,corridor,crossing]

``--raised K`` cuts flat objects out of every support at K sigmas (``[segment] raised_sigmas = K,
raised_supports = "all"``, as the command line's ``--raised``; by default only a support facing
the camera is cut, at 4). ``--peers`` adds, on the arm cameras' tabletops, what a user would
otherwise pick, each tuned on the same frames (``benchmarks/real.py``'s grids; ``--quick-peers``
one setting each): Open3D plane removal + DBSCAN and scikit-image ``felzenszwalb``, beside
depthgram by default and on every support, found / mean IoU / milliseconds a frame.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from depthgram import Pipeline
from depthgram.pipeline import Config
from depthgram.segmentation import SegmentConfig, evaluate
from depthgram.sensor import simulate

SCENES = ("arm_down", "arm_45", "chest_walk", "table")


def score(
    scene: str, sensor: str, size: tuple[int, int], frames: int, with_gravity: bool, raised: float | None = None
) -> str:
    """Return one table row: found / total, mean IoU, the table's kinds, the room's (floor, walls, ceiling)."""
    sims = list(simulate(scene, frames, size=size, sensor=sensor, seed=1))
    gravity = sims[0].gravity if with_gravity else None
    seg = SegmentConfig() if raised is None else SegmentConfig(raised_sigmas=raised, raised_supports="all")
    config = Config(segment=seg)
    pipe = Pipeline(config, track=False, gravity=gravity)
    ious: list[float] = []
    table_kinds: set[str] = set()
    room_kinds: dict[str, set[str]] = {}
    for sim in sims:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the simulator's frames carry their intrinsics; nothing to say
            result = pipe.process(sim.frame)
        labels = result.segmentation.labels
        names = {o.id: o.name for o in sim.truth}
        objects = [o.id for o in sim.truth if o.kind == "object" and o.name != "table"]
        ev = evaluate(labels, sim.instances, valid=sim.frame.valid, truth_ids=objects, iou_found=0.5)
        ious += [o.iou for o in ev.objects]
        for o in result.segmentation.objects:
            ids, counts = np.unique(sim.instances[labels == o.id], return_counts=True)
            name = names.get(int(ids[counts.argmax()]), "")
            if name == "table":
                table_kinds.add(o.kind)
            elif (name in ("floor", "ceiling") or name.endswith("wall")) and o.area >= 0.02 * labels.size:
                room_kinds.setdefault(name.split("_")[-1], set()).add(o.kind)
    iou = np.asarray(ious)
    found = int(np.count_nonzero(iou >= 0.5))
    room = " ".join(f"{k}:{'/'.join(sorted(v))}" for k, v in sorted(room_kinds.items())) or "-"
    mean = f"{iou.mean():.2f}" if iou.size else " -  "
    return f"{found:>2d}/{iou.size:<3d} {mean}   {', '.join(sorted(table_kinds)) or '-':16s} {room}"


def peers(size: tuple[int, int], frames: int, quick: bool) -> None:
    """Print found / mean IoU / ms a frame of depthgram and the peers on ``arm_down`` and ``arm_45``."""
    import time

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks import real

    print(f"{'scene':11s} {'sensor':6s} {'method':30s} found  IoU    ms/frame  setting")
    for scene in ("arm_down", "arm_45"):
        for sensor in ("tof", "sl"):
            lfs, wanted = [], []
            for sim in simulate(scene, frames, size=size, sensor=sensor, seed=1):
                ids = [o.id for o in sim.truth if o.kind == "object" and o.name != "table"]
                truth = np.where(np.isin(sim.instances, ids), sim.instances, 0).astype(np.int32)
                f = sim.frame
                assert f.intrinsics is not None
                lfs.append(real.LabelledFrame(f.name, f.depth, f.valid, truth, f.intrinsics))
                wanted.append(ids)
            methods = real.methods(quick=quick)
            methods.insert(1, real.Method("depthgram --raised 4 (all)", _raised_labels))
            for m in methods:
                setting = real.tune(m, lfs, progress=False)
                m.run(lfs[0], setting)  # compiled kernels and imports before the clock
                ious: list[float] = []
                t0 = time.perf_counter()
                for lf, ids in zip(lfs, wanted, strict=True):
                    ev = evaluate(m.run(lf, setting), lf.truth, valid=lf.valid, truth_ids=ids, iou_found=0.5)
                    ious += [o.iou for o in ev.objects]
                ms = 1e3 * (time.perf_counter() - t0) / len(lfs)
                iou = np.asarray(ious)
                found = int(np.count_nonzero(iou >= 0.5))
                row = f"{scene:11s} {sensor:6s} {m.name:30s} {found:>2d}/{iou.size:<3d} {iou.mean():.2f}   {ms:8.0f}"
                print(f"{row}  {setting or ''}", flush=True)


def _raised_labels(f: Any, params: dict[str, Any]) -> Any:
    """depthgram with flat things cut out of every support (``--raised 4``)."""
    from benchmarks import real

    return real.depthgram_labels(f, {"raised_sigmas": 4.0, "raised_supports": "all", **params})


def main(argv: list[str] | None = None) -> int:
    """Print one row per scene, sensor model and gravity."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="640x480", help="frame size WxH (px)")
    p.add_argument("--frames", type=int, default=3, help="frames per scene")
    p.add_argument(
        "--raised", type=float, default=None, help="cut every support at this many sigmas (default: as segment does)"
    )
    p.add_argument(
        "--scenes",
        default=",".join(SCENES),
        help=f"comma-separated simulator scenes (default {','.join(SCENES)}; corridor and crossing have rooms too)",
    )
    p.add_argument("--peers", action="store_true", help="also the peers on the arm cameras' tabletops")
    p.add_argument("--quick-peers", action="store_true", help="the peers with one setting each (no tuning)")
    args = p.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    if args.peers or args.quick_peers:
        peers((w, h), args.frames, args.quick_peers)
        print()
    print(f"{'scene':11s} {'sensor':6s} {'gravity':8s} found  IoU    table's kinds    the room's kinds")
    for scene in args.scenes.split(","):
        for sensor in ("tof", "sl"):
            for with_gravity in (False, True):
                row = score(scene, sensor, (w, h), args.frames, with_gravity, args.raised)
                print(f"{scene:11s} {sensor:6s} {'given' if with_gravity else '-':8s} {row}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
