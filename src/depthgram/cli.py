"""The ``depthgram`` command: a thin shell over the pipeline and the stage modules."""

from __future__ import annotations

import argparse
import errno
import importlib
import io
import os
import pkgutil
import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

from depthgram import __version__, commands
from depthgram.errors import DepthgramError

__all__ = ["build_parser", "main"]

#: Warnings raised from inside the package are printed for people, as one line.
_PACKAGE = Path(__file__).resolve().parent


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser with every sub-command found in :mod:`depthgram.commands`."""
    parser = argparse.ArgumentParser(
        prog="depthgram",
        description="Depth frames to a compact scene description: objects, motion, grammar, actions, sound.",
    )
    parser.add_argument("--version", action="version", version=f"depthgram {__version__}")
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
    # OpenCV's own warnings ("PNG input buffer is incomplete") would print above our message
    os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
    _closed_streams()
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:
        parser.error(_unrecognized(args, extra))
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        with _plain_warnings(args.command):
            status = int(args._run(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here for output still buffered
        return status
    except BrokenPipeError:
        # the reader stopped (``| head``): stop quietly as other Unix tools do
        _silence_stdout()
        return 141  # 128 + SIGPIPE, the status a shell shows for them
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


def _unrecognized(args: argparse.Namespace, extra: list[str]) -> str:
    """Return argparse's message for arguments left over, with a hint when the shell expanded a glob.

    ``depthgram info rec/*.png`` unquoted reaches us as every file name: argparse's
    "unrecognized arguments" then lists them all and says nothing of the cause (issue 32.6).
    """
    given = getattr(args, "input", None)
    files = [given, *extra] if isinstance(given, str) else []
    if len(files) < 2 or not all(Path(f).exists() and not f.startswith("-") for f in files):
        return f"unrecognized arguments: {' '.join(extra)}"
    parent = os.path.dirname(files[0])
    suffixes = {Path(f).suffix for f in files}
    pattern = os.path.join(parent, "*" + (suffixes.pop() if len(suffixes) == 1 else ""))
    return (
        f"one INPUT, but {len(files)} files were given ({files[0]} ... {files[-1]}): the shell expands an "
        f"unquoted pattern into every file it matches; quote it: depthgram {args.command} '{pattern}' "
        "(or give the folder)"
    )


class _ClosedStream(io.TextIOBase):
    """Stand in for a standard stream the caller closed (``>&-``, ``<&-``).

    Python leaves None there, which turned writes into tracebacks and ``print`` into silently
    lost output (issue 18.10).
    """

    def __init__(self, name: str) -> None:
        self._name = name

    def _closed(self) -> OSError:
        return OSError(errno.EBADF, f"standard {self._name} is closed")

    def write(self, text: str) -> int:
        raise self._closed()

    def read(self, size: int | None = -1) -> str:
        raise self._closed()


def _closed_streams() -> None:
    if sys.stdin is None:
        sys.stdin = _ClosedStream("input")
    if sys.stdout is None:
        sys.stdout = _ClosedStream("output")


def _silence_stdout() -> None:
    """Point standard output at /dev/null.

    The interpreter's last flush of what is still buffered then finds nowhere to fail
    ("Exception ignored ... Broken pipe").
    """
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # no real file descriptor behind it (tests, closed)
        pass


@contextmanager
def _plain_warnings(command: str) -> Iterator[None]:
    """Show depthgram's own warnings (wrong units ...) as one line for people, without the source line."""
    shown = warnings.showwarning

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        if category.__module__.startswith("depthgram") or Path(filename).resolve().is_relative_to(_PACKAGE):
            print(f"depthgram {command}: warning: {message}", file=sys.stderr)
        else:
            shown(message, category, filename, lineno, file, line)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = shown


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
