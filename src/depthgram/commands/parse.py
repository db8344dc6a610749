"""``depthgram parse FILE``: read scene sentences and print each tree as one JSON line."""

from __future__ import annotations

import argparse

NAME = "parse"
HELP = "Parse scene sentences (one per line, '-' for stdin) and print each tree as a JSON line."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's arguments."""
    from depthgram.commands._common import add_output_argument

    parser.add_argument("file", help="text file with one sentence per line, or '-' for standard input")
    add_output_argument(parser, "--json", "the trees as JSON lines (default: standard output)")


def run(args: argparse.Namespace) -> int:
    """Parse the sentences; a bad one raises SentenceError (file, line, column: exit status 2)."""
    import json
    import sys
    from pathlib import Path

    from depthgram.errors import InputError
    from depthgram.scene import parse_sentence, tree_to_dict

    if args.file == "-":
        text, source = sys.stdin.read(), "<stdin>"
    else:
        path = Path(args.file)
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise InputError(f"{path}: no such file (expected a text file of scene sentences)") from None
        except UnicodeDecodeError as exc:
            raise InputError(f"{path}: not UTF-8 text at byte {exc.start}") from None
        except OSError as exc:
            raise InputError(f"{path}: cannot read ({exc.strerror})") from None
        source = str(path)
    from depthgram.commands._common import STDOUT, Output

    # Trees of the lines before a bad one are still written: parse line by line.
    with Output(args.json or STDOUT, "--json") as out:
        for i, line in enumerate(text.splitlines()):
            if not line.strip():
                continue
            tree = parse_sentence(line, source=source, first_line=i + 1)
            out.write(json.dumps(tree_to_dict(tree), separators=(",", ":")) + "\n")
    return 0
