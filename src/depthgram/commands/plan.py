"""depthgram plan: the action plan (grasp, avoid, clearance channel) per frame."""

from __future__ import annotations

import argparse
import json

from depthgram.commands._common import add_pipeline_arguments, pipeline_results

NAME = "plan"
HELP = "print the action plan per frame: grasp / avoid per object, the clearance channel, ttc warnings"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_pipeline_arguments(p)
    p.add_argument("--json", action="store_true", help="one JSON line per frame instead of text")


def run(args: argparse.Namespace) -> int:
    from depthgram.act import plan_to_dict, plan_to_text

    _, results = pipeline_results(args, NAME)
    for result in results:
        f = result.frame
        if args.json:
            print(json.dumps({"frame": f.index, "time_s": f.time_s, "source": f.name, **plan_to_dict(result.plan)}))
        else:
            print(f"# frame {f.index} ({f.name})")
            print(plan_to_text(result.plan))
    return 0
