"""depthgram run: play a recording through the pipeline as a live sensor would deliver it."""

from __future__ import annotations

import argparse
import gc
import itertools
import sys
import time

from depthgram.commands._common import add_pipeline_arguments, make_pipeline, open_input, progress, source_len

NAME = "run"
HELP = "play a recording at its frame rate (or --fast) and report per-frame latency and dropped frames"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    add_pipeline_arguments(p, workers=False)  # latency is one frame's: workers would not cut it
    p.add_argument("--fast", action="store_true", help="as fast as possible instead of the recording's rate")
    p.add_argument(
        "--read-ahead",
        type=int,
        default=2,
        metavar="N",
        help="frames decoded ahead in a thread beside the pipeline, as a sensor delivers them "
        "(default 2; 0 reads on the pipeline's thread)",
    )
    p.add_argument("--print", dest="print_sentences", action="store_true", help="print each frame's sentence")


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    import numpy as np

    from depthgram.pacing import Pacer
    from depthgram.sources.prefetch import prefetch

    if args.read_ahead < 0:
        print(f"depthgram run: --read-ahead must be >= 0, got {args.read_ahead}", file=sys.stderr)
        return 2
    src = open_input(args)
    pipe = make_pipeline(args)
    fps = getattr(src, "fps", None) or args.fps
    period = None if args.fast or not fps else 1.0 / fps
    latencies: list[float] = []
    dropped = 0
    # frames are decoded in a thread beside the pipeline (as Pipeline.run does), as a sensor
    # delivers them; the loop is written out here because a live sensor drops late frames
    frames = prefetch(src, ahead=args.read_ahead)
    first = next(frames, None)
    if first is None:
        print("depthgram run: the recording has no frame", file=sys.stderr)
        return 1
    # compiled kernels load before the clock starts, as a live system starts before its sensor
    warm_s = pipe.warm_up(first)
    # Everything loaded so far (modules, compiled kernels) lives as long as the process: out of
    # the collector's sight, a full collection no longer stalls a frame (docs/design-notes.md).
    gc.freeze()
    try:
        frames = itertools.chain([first], frames)
        # The viewer's player drops frames by the same rule (views/player.py), so the two compare.
        pacer = Pacer(period or 1.0, clock=time.perf_counter)
        start = pacer.due
        for i, frame in enumerate(progress(frames, total=source_len(src), desc=NAME, quiet=args.quiet)):
            if period is not None:
                # A live sensor does not wait: a frame whose slot has passed while we were busy is lost.
                if not pacer.admit(frame.time_s if frame.time_s is not None else i * period):
                    dropped += 1
                    continue
            result = pipe.process(frame)
            latencies.append(result.latency_s)
            if args.print_sentences:
                print(result.sentence)
    finally:
        gc.unfreeze()  # main() is also called in-process (tests, scripts)
    wall = time.perf_counter() - start
    n = len(latencies)
    if n == 0:
        print("no frame processed", file=sys.stderr)
        return 1
    lat = np.asarray(latencies) * 1e3
    mode = "as fast as possible" if period is None else f"at {1.0 / period:.1f} frames/s"
    print(
        f"{n + dropped} frames played {mode} in {wall:.2f} s: {n} processed, {dropped} dropped "
        f"(start-up before the first frame: {warm_s * 1e3:.0f} ms)"
    )
    print(
        f"latency per frame: median {np.median(lat):.2f} ms, p95 {np.percentile(lat, 95):.2f} ms, "
        f"max {lat.max():.2f} ms; throughput {n / wall:.1f} frames/s"
    )
    return 0
