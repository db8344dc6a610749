"""Where the CPU of `depthgram listen`'s loop goes, stage by stage, per 7-Scenes frame read as 320 x 240.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/listen_stages.py [--frames N]``. Thread CPU
(``time.thread_time``) a frame of: reading as ``listen`` reads (PNG decode, conversion to mm,
every 2nd pixel of every 2nd row), the pipeline's stages (run on one thread here, so that each
stage's CPU is its own; the live pipeline runs the tracker's image motion and half of its core
readings on a second thread), choosing the voices, and the synthesis of the chosen voices for
one frame's 6.25 audio blocks of 256 samples at 48 kHz. ``Pipeline.process`` as the live loop
calls it (two threads) is given too, as the process's CPU (``getrusage``). Without the
recording (``../shared/data``) it reads ``sim:corridor`` at 640 x 480.
"""

from __future__ import annotations

import argparse
import functools
import gc
import itertools
import resource
import time
import warnings
from collections import defaultdict
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SEVEN_SCENES = ROOT.parent / "shared" / "data" / "7scenes_redkitchen_seq"


def _process_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _timed(owner: Any, name: str, label: str, spent: dict[str, float]) -> None:
    """Replace ``owner.name`` by a wrapper adding its thread CPU to ``spent[label]``."""
    fn: Callable[..., Any] = getattr(owner, name)

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t = time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            spent[label] += time.thread_time() - t

    setattr(owner, name, wrapper)


class _Here:
    """An executor that runs each task at once on the caller's thread."""

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Future[Any]:
        done: Future[Any] = Future()
        done.set_result(fn(*args, **kwargs))
        return done


def main(argv: Sequence[str] | None = None) -> int:
    """Print the CPU a frame of each stage (ms)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--frames", type=int, default=300, help="frames read (default 300)")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore")  # the tracker's note on a recording without a frame rate

    import depthgram.dynamics.camera_motion as camera_motion
    import depthgram.dynamics.tracker as tracker
    import depthgram.pipeline as pipeline
    from depthgram import read
    from depthgram.commands.listen import decimation
    from depthgram.pipeline import Pipeline
    from depthgram.scene.kinds import GravityKinds
    from depthgram.sound import SoundMapping
    from depthgram.sound.choose import Chooser
    from depthgram.sound.live import LiveSonifier
    from depthgram.sources.base import decimated

    spec = str(SEVEN_SCENES) if SEVEN_SCENES.is_dir() else "sim:corridor?size=640x480&frames=300"
    t = time.thread_time()
    raw = iter(read(spec))
    whole = next(raw)
    step = decimation("auto", whole.size[0])
    frames = [whole.decimated(step), *itertools.islice(decimated(raw, step), args.frames - 1)]
    n = len(frames)
    rows: list[tuple[str, float]] = [("reading (decode, mm, decimation)", (time.thread_time() - t) / n)]

    live = Pipeline()
    live.warm_up(frames[0])
    gc.freeze()
    c0 = _process_cpu()
    results = [live.process(f) for f in frames]
    rows.append(("Pipeline.process as listen runs it (process CPU, 2 threads)", (_process_cpu() - c0) / n))

    spent: dict[str, float] = defaultdict(float)
    stages = (
        (pipeline, "_segment", "segmentation"),
        (camera_motion.EgoMotion, "update", "tracker: camera motion (ICP)"),
        (tracker.Tracker, "_shift", "tracker: frame's shift"),
        (tracker, "core_depth_change", "tracker: core readings"),
        (tracker.Tracker, "update", "tracker: update (with core readings)"),
        (GravityKinds, "__call__", "kinds by gravity"),
        (pipeline, "build_tree", "tree"),
        (pipeline, "plan_scene", "plan"),
        (Pipeline, "_still_reason", "still or related"),
        (pipeline, "_relabel", "track ids on the labels"),
    )
    for owner, name, label in stages:
        _timed(owner, name, label, spent)
    one = Pipeline()
    one.warm_up(frames[0])
    one._beside = lambda: _Here()  # type: ignore[method-assign,assignment,return-value]
    spent.clear()
    t = time.thread_time()
    for f in frames:
        one.process(f)
    total = time.thread_time() - t
    rows.append(("Pipeline.process on one thread", total / n))
    rows += [(f"  {label}", spent[label] / n) for *_, label in stages]

    chooser = Chooser(SoundMapping())
    t = time.thread_time()
    targets = [
        chooser.voices(r.tree, f.size, r.segmentation.objects, f.intrinsics, f.gravity)
        for r, f in zip(results, frames, strict=True)
    ]
    rows.append(("choosing the voices", (time.thread_time() - t) / n))
    son = LiveSonifier(SoundMapping(), 48000, (2, 2))
    son.warm_up()
    blocks = 0
    t = 0.0
    for rep in range(2):  # the first pass warms up
        t = time.thread_time()
        for v in targets:
            son.set_targets(v, frame=0, arrival_s=0.0)
            for _ in range(6):
                son.render_block(256)
                blocks += rep
        t = time.thread_time() - t
    rows.append(("synthesis (6.25 blocks of 256 samples)", t / blocks * 6.25))

    print(f"{spec}: {n} frames read as {frames[0].size[0]}x{frames[0].size[1]}; thread CPU a frame")
    for label, s in rows:
        print(f"  {label:62s} {1e3 * s:6.2f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
