"""depthgram batch: many recordings, each into JSON lines, label maps and a summary."""

from __future__ import annotations

import argparse
import sys

from depthgram.commands._common import add_config_arguments, add_reading_arguments, load_config, reading_options

NAME = "batch"
HELP = "process many recordings (local cores, or a Dask cluster with --scheduler); resumable"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="recordings (files, folders, bags, sim:SCENE)")
    p.add_argument("--out", required=True, metavar="DIR", help="output root; one folder per recording")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="Dask distributed scheduler address, e.g. tcp://10.0.0.5:8786",
    )
    p.add_argument(
        "--connect-timeout",
        type=float,
        default=None,
        metavar="S",
        help="seconds the scheduler has to answer as a Dask scheduler (default: 30)",
    )
    add_config_arguments(p)  # --config and --method, as describe takes them
    add_reading_arguments(p)  # the same reading options as every command, applied to each recording
    p.add_argument("--quiet", action="store_true", help="no per-recording lines")


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from depthgram.batch import BatchResult, run_batch
    from depthgram.errors import InputError

    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be at least 1, got {args.workers}")
    cfg = load_config(args)  # with --stills
    opts = reading_options(args)
    if args.trust_intrinsics:
        opts["trust_intrinsics"] = True  # the pipeline's, carried with the reading options to each worker

    def show(r: BatchResult) -> None:
        if args.quiet:
            return
        detail = f"{r.frames} frames, {r.objects} objects" if r.status != "failed" else r.error
        print(f"{r.status:8s} {r.input}: {detail}", file=sys.stderr)

    results = run_batch(
        args.inputs,
        args.out,
        config=cfg.to_dict(),
        source_options=opts,
        workers=args.workers,
        scheduler=args.scheduler,
        track=True,
        on_done=show,
        **({} if args.connect_timeout is None else {"connect_timeout_s": args.connect_timeout}),
    )
    failed = [r for r in results if r.status == "failed"]
    print(
        f"{len(results)} recordings: {sum(r.status == 'done' for r in results)} done, "
        f"{sum(r.status == 'skipped' for r in results)} skipped (finished before), {len(failed)} failed"
    )
    return 1 if failed else 0
