"""Outputs that appear whole or not at all: written under a temporary name, renamed on success.

A reader (or a resumed batch) that finds ``scenes.jsonl``, a label map or a WAV can trust it is
complete: a failure or a kill mid-write leaves at most a hidden ``.NAME.part`` file, removed
when the failure is an exception (issue 18.7).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

__all__ = ["atomic_open", "atomic_path"]


def _part(path: Path) -> Path:
    # the suffix is kept so that writers choosing the format by extension (OpenCV, soundfile) still can
    return path.with_name(f".{path.stem}.part{path.suffix}")


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Return a temporary path beside ``path`` to write to; renamed to ``path`` when the block succeeds.

    On an exception the temporary file is removed and ``path`` is left as it was.
    """
    final = Path(path)
    tmp = _part(final)
    try:
        yield tmp
        os.replace(tmp, final)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:  # type: ignore[type-arg]
    """``open(path, mode)`` into a temporary file, renamed to ``path`` when the block succeeds."""
    with atomic_path(path) as tmp:
        with open(tmp, mode, encoding=None if "b" in mode else encoding) as fh:
            yield fh
