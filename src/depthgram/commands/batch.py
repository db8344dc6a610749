"""depthgram batch: many recordings, each into JSON lines, label maps and a summary."""

from __future__ import annotations

import argparse
import sys

NAME = "batch"
HELP = "process many recordings (local cores, or a Dask cluster with --scheduler); resumable"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="recordings (files, folders, bags, sim:SCENE)")
    p.add_argument("--out", required=True, metavar="DIR", help="output root; one folder per recording")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask distributed scheduler address, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--config", default=None, metavar="TOML", help="pipeline settings")
    p.add_argument("--scale", type=float, default=None, metavar="MM_PER_UNIT", help="millimetres per raw unit")
    p.add_argument("--invalid", type=float, nargs="+", default=[], metavar="VALUE", help="raw no-reading values")
    p.add_argument("--fps", type=float, default=None, help="frame rate of folders without timestamps")
    p.add_argument("--stills", "--no-track", dest="no_track", action="store_true",
                   help="the frames are unrelated still images: no motion read between them")
    p.add_argument("--quiet", action="store_true", help="no per-recording lines")


def run(args: argparse.Namespace) -> int:
    from depthgram.batch import BatchResult, run_batch
    from depthgram.errors import InputError
    from depthgram.pipeline import Config

    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be at least 1, got {args.workers}")
    cfg = Config.load(args.config) if args.config else Config()
    opts = {"scale_mm": args.scale, "invalid": tuple(args.invalid), "fps": args.fps}

    def show(r: BatchResult) -> None:
        if args.quiet:
            return
        detail = f"{r.frames} frames, {r.objects} objects" if r.status != "failed" else r.error
        print(f"{r.status:8s} {r.input}: {detail}", file=sys.stderr)

    results = run_batch(args.inputs, args.out, config=cfg.to_dict(), source_options=opts, workers=args.workers,
                        scheduler=args.scheduler, track=not args.no_track, on_done=show)
    failed = [r for r in results if r.status == "failed"]
    print(f"{len(results)} recordings: {sum(r.status == 'done' for r in results)} done, "
          f"{sum(r.status == 'skipped' for r in results)} skipped (finished before), {len(failed)} failed")
    return 1 if failed else 0
