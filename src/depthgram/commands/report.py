"""depthgram report: pictures and an index.html a person can look at."""

from __future__ import annotations

import argparse

from depthgram.commands._common import add_pipeline_arguments, pipeline_results, source_len

NAME = "report"
HELP = "write pictures (objects, histogram, tree, tracks) and an index.html for a recording"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    add_pipeline_arguments(p, stills=True)
    p.add_argument("--out", required=True, metavar="DIR", help="folder to write the report into")
    p.add_argument(
        "--pictures",
        type=int,
        default=6,
        help="how many frames to picture, spread evenly from the first to the last (default 6)",
    )


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from depthgram._optional import needs_extra
    from depthgram.errors import InputError
    from depthgram.views.report import ReportWriter

    with needs_extra("report", "depthgram report (pictures)"):
        import depthgram.views.pictures  # noqa: F401  (fails here, before any frame is processed)

    if args.pictures < 1:
        raise InputError(f"--pictures must be at least 1, got {args.pictures}")
    src, results = pipeline_results(args, NAME)
    n = source_len(src)
    every = max(1, (n or args.pictures) // args.pictures)
    # with a known length the pictured frames are spread from the first to the last
    writer = ReportWriter(args.out, every=every, max_pictures=args.pictures, frames=n, source=str(args.input))
    writer.add_all(results)
    index = writer.finish()
    print(f"report written: {index}")
    return 0
