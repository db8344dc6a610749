"""depthgram config: print or check the pipeline settings."""

from __future__ import annotations

import argparse

NAME = "config"
HELP = "print the default pipeline settings as TOML (--dump) or check a settings file (--check)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.add_argument("--dump", action="store_true", help="print the defaults (with --check: the file's settings) as TOML")
    p.add_argument(
        "--check", metavar="TOML", help="check a settings file: OK and the settings it changes, or what is wrong"
    )


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from depthgram.pipeline import Config

    cfg = Config.load(args.check) if args.check else Config()
    if args.check and not args.dump:
        changed = _changed(cfg.to_dict(), Config().to_dict())
        said = ", ".join(changed[:6]) + (f" and {len(changed) - 6} more" if len(changed) > 6 else "")
        print(f"{args.check}: OK; " + (f"changes {said}" if changed else "every setting is the default"))
        return 0
    print(cfg.dumps(), end="")
    return 0


def _changed(mine: dict[str, object], defaults: dict[str, object], prefix: str = "") -> list[str]:
    # "section.key = value" for every setting that differs from the default, in file order
    out: list[str] = []
    for key, value in mine.items():
        base = defaults.get(key)
        if isinstance(value, dict) and isinstance(base, dict):
            out += _changed(value, base, f"{prefix}{key}.")
        elif value != base:
            out.append(f"{prefix}{key} = {value!r}")
    return out
