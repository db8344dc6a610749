"""depthgram config: print or check the pipeline settings."""

from __future__ import annotations

import argparse

NAME = "config"
HELP = "print the default pipeline settings as TOML (--dump) or check a settings file (--check)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--dump", action="store_true", help="print the defaults as TOML")
    g.add_argument("--check", metavar="TOML", help="load a settings file and print it with defaults filled in")


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from depthgram.pipeline import Config

    cfg = Config.load(args.check) if args.check else Config()
    print(cfg.dumps(), end="")
    return 0
