"""The default segmentation on the simulator's scenes for new mountings (issue 28, item 6), scored against exact truth.

For each scene and sensor model: objects found (IoU >= 0.5) and their mean IoU (the table itself
left out: it is the support), and what kinds the segments covering the table, the floor and the
walls were given (a table seen from above must never be a ``ceiling``; the kinds follow gravity,
:mod:`depthgram.scene.kinds`). With and without the exact gravity handed to the pipeline
(without it, gravity is estimated from the supports seen from above).

    .venv/bin/python benchmarks/mountings.py [--size 640x480] [--frames 3] [--raised 4]

``--raised K`` sets ``[segment] raised_sigmas`` (flat objects cut out of the supports, off by
default).
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np

from depthgram import Pipeline
from depthgram.pipeline import Config
from depthgram.segmentation import SegmentConfig, evaluate
from depthgram.sensor import simulate

SCENES = ("arm_down", "arm_45", "chest_walk", "table")


def score(scene: str, sensor: str, size: tuple[int, int], frames: int, with_gravity: bool, raised: float = 0.0) -> str:
    """Return one table row: found / total, mean IoU, the table's kinds, the floor's and walls'."""
    sims = list(simulate(scene, frames, size=size, sensor=sensor, seed=1))
    gravity = sims[0].gravity if with_gravity else None
    config = Config(segment=SegmentConfig(raised_sigmas=raised))
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
            elif (name == "floor" or name.endswith("wall")) and o.area >= 0.02 * labels.size:
                room_kinds.setdefault(name.split("_")[-1], set()).add(o.kind)
    iou = np.asarray(ious)
    found = int(np.count_nonzero(iou >= 0.5))
    room = " ".join(f"{k}:{'/'.join(sorted(v))}" for k, v in sorted(room_kinds.items())) or "-"
    return f"{found:>2d}/{iou.size:<3d} {iou.mean():.2f}   {', '.join(sorted(table_kinds)) or '-':16s} {room}"


def main(argv: list[str] | None = None) -> int:
    """Print one row per scene, sensor model and gravity."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="640x480", help="frame size WxH (px)")
    p.add_argument("--frames", type=int, default=3, help="frames per scene")
    p.add_argument("--raised", type=float, default=0.0, help="[segment] raised_sigmas (0: off, the default)")
    args = p.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    print(f"{'scene':11s} {'sensor':6s} {'gravity':8s} found  IoU    table's kinds    floor's and walls' kinds")
    for scene in SCENES:
        for sensor in ("tof", "sl"):
            for with_gravity in (False, True):
                row = score(scene, sensor, (w, h), args.frames, with_gravity, args.raised)
                print(f"{scene:11s} {sensor:6s} {'given' if with_gravity else '-':8s} {row}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
