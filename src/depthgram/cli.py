"""The ``depthgram`` command: a thin shell over the pipeline and the stage modules."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence

from depthgram import commands
from depthgram.errors import DepthgramError

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every sub-command found in :mod:`depthgram.commands`."""
    parser = argparse.ArgumentParser(
        prog="depthgram",
        description="Depth frames to a compact scene description: objects, motion, grammar, actions, sound.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"depthgram.commands.{info.name}")
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status (0 success, 2 bad input, 1 other failure)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except DepthgramError as exc:
        print(f"depthgram {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        from depthgram._optional import extra_for

        missing = extra_for(exc)
        if missing is None:
            raise
        print(f"depthgram {args.command}: error: {missing}", file=sys.stderr)
        return 2
    except OSError as exc:  # an output that cannot be written: the message says which and why
        print(f"depthgram {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"depthgram {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
