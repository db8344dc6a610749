"""depthgram describe: one JSON line (or one sentence) per frame."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from depthgram.commands._common import (
    STDOUT,
    Output,
    add_output_argument,
    add_pipeline_arguments,
    deprecated,
    output_target,
    pipeline_results,
)

NAME = "describe"
HELP = "describe every frame: objects, tree, sentence, motion (JSON lines or text)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.epilog = (
        "Outputs name their file, '-' being standard output; with none of --json, --text and --mcap "
        "the JSON lines go to standard output. Several may be given: the input is read once."
    )
    add_pipeline_arguments(p, stills=True)
    add_output_argument(p, "--json", "one JSON line per frame")
    add_output_argument(p, "--text", "one sentence per frame")
    p.add_argument(
        "--mcap",
        default=None,
        metavar="FILE",
        help="write the scene stream as MCAP with Foxglove's schemas (depth image, object outlines, "
        "3-D boxes, the sentence as a log line): opens in Foxglove with no plugin",
    )
    p.add_argument(
        "--format",
        choices=["json", "text"],
        default=None,
        help="deprecated: --format text is --text -, --format json is --json -",
    )
    p.add_argument(
        "--labels-dir", default=None, metavar="DIR", help="write a 16-bit PNG label map per frame (pixel = object id)"
    )


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from contextlib import ExitStack

    from depthgram.label_maps import label_file_name, write_label_map

    json_to, text_to = output_target(args, "json"), output_target(args, "text")
    if args.format is not None:
        new = "--text -" if args.format == "text" else "--json -"
        deprecated(NAME, f"--format {args.format}", new)
        if args.format == "text":
            # the old --json FILE --format text wrote the sentences into FILE
            text_to, json_to = json_to or STDOUT, None
        else:
            json_to = json_to or STDOUT
    if json_to is None and text_to is None and args.mcap is None:
        json_to = STDOUT
    if json_to == STDOUT and text_to == STDOUT:
        from depthgram.errors import InputError

        raise InputError("--json - and --text - both want standard output: give one of them a file")
    labels_dir = Path(args.labels_dir) if args.labels_dir else None
    if labels_dir is not None:
        labels_dir.mkdir(parents=True, exist_ok=True)
    with ExitStack() as stack:
        js = stack.enter_context(Output(json_to, "--json")) if json_to else None
        tx = stack.enter_context(Output(text_to, "--text")) if text_to else None
        src, results = pipeline_results(args, NAME)
        mcap = None
        if args.mcap is not None:
            from depthgram.export.mcap_file import McapWriter

            mcap = stack.enter_context(McapWriter(args.mcap, source=str(args.input), fps=getattr(src, "fps", None)))
        for result in results:
            if js is not None:
                js.write(json.dumps(result.to_record()) + "\n")
            if tx is not None:
                tx.write(result.sentence + "\n")
            if mcap is not None:
                mcap.add(result)
            if labels_dir is not None:
                path = labels_dir / label_file_name(result.frame.name, result.frame.index)
                write_label_map(path, result.segmentation.labels, result.frame.name or f"frame {result.frame.index}")
    return 0
