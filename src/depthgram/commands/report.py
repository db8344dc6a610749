"""depthgram report: pictures and an index.html a person can look at."""

from __future__ import annotations

import argparse

from depthgram.commands._common import (
    add_config_arguments,
    add_source_arguments,
    load_config,
    open_input,
    progress,
    source_len,
)

NAME = "report"
HELP = "write pictures (objects, histogram, tree, tracks) and an index.html for a recording"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_source_arguments(p)
    add_config_arguments(p)
    p.add_argument("--out", required=True, metavar="DIR", help="folder to write the report into")
    p.add_argument("--pictures", type=int, default=6, help="how many frames to picture (spread over the input)")
    p.add_argument("--no-track", action="store_true", help="treat frames as unrelated stills")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from depthgram.errors import InputError
    from depthgram.pipeline import Pipeline
    from depthgram.views.report import ReportWriter

    if args.pictures < 1:
        raise InputError(f"--pictures must be at least 1, got {args.pictures}")
    src = open_input(args)
    n = source_len(src)
    every = max(1, (n or args.pictures) // args.pictures)
    writer = ReportWriter(args.out, every=every, max_pictures=args.pictures)
    pipe = Pipeline(load_config(args), track=not args.no_track)
    writer.add_all(progress(pipe.run(src), total=n, desc=NAME, quiet=args.quiet))
    index = writer.finish()
    print(f"report written: {index}")
    return 0
