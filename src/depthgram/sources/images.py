"""Reading one stored image file as its raw samples (PNG, PGM, TIFF, ``.npy``, ``.npz``)."""

from __future__ import annotations

import os
import sys
import tempfile
import threading
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError

__all__ = ["IMAGE_SUFFIXES", "npz_pick", "read_image"]

#: File suffixes read as depth frames. JPEG is left out on purpose: lossy compression destroys depth.
IMAGE_SUFFIXES = frozenset({".png", ".pgm", ".tif", ".tiff", ".npy", ".npz"})


def npz_pick(names: list[str], shapes: dict[str, tuple[int, ...]], key: str | None, where: str) -> str:
    """Name of the array to read from an ``.npz``: ``key``, else the first 2-D or 3-D array."""
    if key is not None:
        if key not in names:
            raise InputError(f"{where}: no array named {key!r} in the .npz (it holds {', '.join(names) or 'none'})")
        return key
    for n in names:
        if len(shapes[n]) in (2, 3):
            return n
    listing = ", ".join(f"{n} {shapes[n]}" for n in names) or "no arrays"
    raise InputError(f"{where}: no 2-D image or 3-D stack in the .npz ({listing})")


def _read_npz(path: Path, key: str | None, where: str) -> NDArray[np.generic]:
    try:
        with np.load(path, allow_pickle=False) as z:
            names = list(z.files)
            shapes = {n: tuple(z[n].shape) for n in names}
            return np.asarray(z[npz_pick(names, shapes, key, where)])
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"{where}: cannot read the .npz ({exc})") from None


_CAPTURE_LOCK = threading.Lock()
_CAPTURE_FILE: list[IO[bytes]] = []  # one file, made on first use and reused (a new one per frame costs)


@contextmanager
def _stderr_captured() -> Iterator[list[str]]:
    """What C libraries (libpng) write to file descriptor 2 inside the block, as one stripped
    string in the yielded list once the block ends."""
    said: list[str] = []
    with _CAPTURE_LOCK:
        if not _CAPTURE_FILE:
            _CAPTURE_FILE.append(tempfile.TemporaryFile())
        tmp = _CAPTURE_FILE[0]
        tmp.seek(0)
        tmp.truncate()
        try:
            sys.stderr.flush()
            saved = os.dup(2)
        except (OSError, ValueError):  # no descriptor 2 to borrow: leave it alone
            yield said
            return
        os.dup2(tmp.fileno(), 2)
        try:
            yield said
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            said.append(tmp.read(4096).decode(errors="replace").strip())


def read_image(path: Path, *, key: str | None = None, where: str | None = None) -> NDArray[np.generic]:
    """Raw samples of one image file, exactly as stored (no unit conversion).

    Parameters
    ----------
    path : Path
        A PNG/PGM (OpenCV), TIFF (tifffile), ``.npy`` or ``.npz`` file.
    key : str, optional
        Array name in an ``.npz``; default the first 2-D or 3-D array.
    where : str, optional
        How to name the file in errors (default: the path).

    Raises
    ------
    InputError
        Missing, unreadable, truncated or object-dtype file.
    """
    where = where or str(path)
    if not path.is_file():
        raise InputError(f"{where}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            arr: NDArray[np.generic] = np.load(path, mmap_mode="r", allow_pickle=False)
            return arr
        except (ValueError, OSError, EOFError) as exc:
            raise InputError(f"{where}: cannot read the .npy ({exc})") from None
    if suffix == ".npz":
        return _read_npz(path, key, where)
    if suffix in (".tif", ".tiff"):
        import tifffile

        try:
            return np.asarray(tifffile.imread(path))
        except Exception as exc:  # tifffile raises many unrelated types for bad files
            raise InputError(f"{where}: cannot read the TIFF (truncated or not a TIFF?): {exc}") from None
    import cv2

    # imdecode over a bytes buffer, not imread: it handles non-ASCII paths and lets a
    # truncated file be told apart from a missing one.
    try:
        buf = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise InputError(f"{where}: cannot read the file ({exc.strerror or exc})") from None
    with _stderr_captured() as said:
        try:
            img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED) if buf.size else None
        except cv2.error:
            img = None
    if img is None:
        # libpng's own complaint ("IDAT: CRC error") goes into the message instead of above it
        detail = f": {said[0]}" if said and said[0] else ""
        raise InputError(f"{where}: cannot decode the image (truncated, empty or not an image file){detail}")
    if said and said[0]:
        print(said[0], file=sys.stderr)  # not ours to drop: another thread's output, or a warning
    # A colour image comes back (H, W, 3) and is refused later with a message saying so.
    return img
