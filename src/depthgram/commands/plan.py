"""depthgram plan: the action plan (grasp, avoid, clearance channel) per frame."""

from __future__ import annotations

import argparse
import json

from depthgram.commands._common import (
    STDOUT,
    Output,
    add_output_argument,
    add_pipeline_arguments,
    output_target,
    pipeline_results,
)

NAME = "plan"
HELP = "print the action plan per frame: grasp / avoid per object, the clearance channel, ttc warnings"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.epilog = (
        "The plan is printed as text on standard output unless --json or --text names a file ('-' is standard output)."
    )
    add_pipeline_arguments(p, input_optional=True)
    add_output_argument(p, "--json", "one JSON line per frame", bare_deprecated=True)
    add_output_argument(p, "--text", "the plan as text")


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from contextlib import ExitStack

    from depthgram.act import plan_to_dict, plan_to_text

    json_to = output_target(args, "json")
    text_to = output_target(args, "text")
    if json_to is None and text_to is None:
        text_to = STDOUT
    with ExitStack() as stack:
        js = stack.enter_context(Output(json_to, "--json")) if json_to else None
        tx = stack.enter_context(Output(text_to, "--text")) if text_to else None
        _, results = pipeline_results(args, NAME)
        for result in results:
            f = result.frame
            if js is not None:
                js.write(
                    json.dumps({"frame": f.index, "time_s": f.time_s, "source": f.name, **plan_to_dict(result.plan)})
                    + "\n"
                )
            if tx is not None:
                tx.write(f"# frame {f.index} ({f.name})\n{plan_to_text(result.plan)}\n")
    return 0
