"""Outputs that appear whole or not at all: written under a temporary name, renamed on success.

A reader (or a resumed batch) that finds ``scenes.jsonl``, a label map or a WAV can trust it is
complete: a failure or a kill mid-write leaves at most a hidden ``.NAME.XXXXXXXX.part`` file,
removed when the failure is an exception (issue 18.7).

Only a new or a regular file is written that way. A FIFO, a character device (``/dev/null``) or a
socket is written in place: renaming over it would replace the device or pipe with a plain file,
and its reader would get nothing (issue 32.1). A symbolic link is followed, so the file it names is
replaced and the link stays. Each write has its own temporary name, so two writers of one file
both finish and the file is whole: the last to finish wins.
"""

from __future__ import annotations

import os
import secrets
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

__all__ = ["atomic_open", "atomic_path", "writes_in_place"]


def writes_in_place(path: str | os.PathLike[str]) -> bool:
    """Tell whether ``path`` exists and is not a regular file (a FIFO, a device, a socket).

    Such a path is written directly: it cannot be replaced by renaming a file over it.
    """
    try:
        mode = os.stat(path).st_mode  # follows symbolic links: what matters is what they name
    except OSError:
        return False
    return not stat.S_ISREG(mode) and not stat.S_ISDIR(mode)


def _is_socket(path: str | os.PathLike[str]) -> bool:
    try:
        return stat.S_ISSOCK(os.stat(path).st_mode)
    except OSError:
        return False


def _temporary(final: Path) -> Path:
    """Create an empty, uniquely named file beside ``final`` and return its path.

    Created with ``os.open(..., 0o666)`` rather than ``tempfile.mkstemp`` (0600) so that the
    umask decides the permissions, as for any new file; the suffix is kept so that writers
    choosing the format by extension (OpenCV, soundfile) still can.
    """
    for _ in range(100):
        tmp = final.with_name(f".{final.stem}.{secrets.token_hex(4)}.part{final.suffix}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        return tmp
    raise FileExistsError(f"{final}: no free temporary name beside it")


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Return a path to write ``path``'s content to; a temporary one renamed to ``path`` on success.

    A FIFO, a device or a socket is returned itself, to be written in place. On an exception the
    temporary file is removed and ``path`` is left as it was.
    """
    final = Path(path)
    if writes_in_place(final):
        yield final
        return
    final = Path(os.path.realpath(final))  # a link stays a link; the file it names is replaced
    tmp = _temporary(final)
    try:
        try:
            os.chmod(tmp, stat.S_IMODE(os.stat(final).st_mode))  # replacing: keep the file's permissions
        except FileNotFoundError:
            pass
        yield tmp
        os.replace(tmp, final)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:  # type: ignore[type-arg]
    """``open(path, mode)`` into a temporary file, renamed to ``path`` when the block succeeds.

    A FIFO or a device is opened and written directly (see :func:`atomic_path`); a Unix socket is
    connected to and written as a stream.
    """
    if _is_socket(path):
        import socket

        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.connect(os.fspath(path))
            if "b" in mode:
                with sock.makefile("wb") as bfh:
                    yield bfh
            else:
                with sock.makefile("w", encoding=encoding) as tfh:
                    yield tfh
        return
    with atomic_path(path) as tmp:
        with open(tmp, mode, encoding=None if "b" in mode else encoding) as fh:
            yield fh
