"""Reading one stored image file as its raw samples (PNG, PGM, TIFF, ``.npy``, ``.npz``)."""

from __future__ import annotations

import atexit
import os
import re
import struct
import sys
import tempfile
import threading
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
    except InputError:
        raise
    except Exception as exc:  # numpy's header parser and zipfile raise many types for damage (issue 32.2)
        raise InputError(f"{where}: cannot read the .npz ({exc})") from None


_CAPTURE_LOCK = threading.Lock()
_CAPTURE_FILE: list[IO[bytes]] = []  # one file, made on first use and reused (a new one per frame costs)


@contextmanager
def _stderr_captured() -> Iterator[list[str]]:
    """Capture what C libraries (libpng) write to file descriptor 2 inside the block.

    It arrives as one stripped string in the yielded list once the block ends.
    """
    said: list[str] = []
    with _CAPTURE_LOCK:
        if not _CAPTURE_FILE:
            _CAPTURE_FILE.append(tempfile.TemporaryFile())
            # closed at exit: left to the garbage collector it is a ResourceWarning (issue 32.6)
            atexit.register(_CAPTURE_FILE[0].close)
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


#: Largest frame read (pixels) unless the environment variable ``DEPTHGRAM_MAX_PIXELS`` says
#: otherwise: 25 million (5000 x 5000) is 20x a 1280 x 720 depth camera, and processing one
#: frame takes about 40 bytes per pixel, 1 GB here (docs/design-notes.md: frames, issue 18.6).
MAX_PIXELS = 25_000_000


def max_pixels() -> int:
    """Return the frame size limit (pixels): ``DEPTHGRAM_MAX_PIXELS`` when set, else :data:`MAX_PIXELS`."""
    text = os.environ.get("DEPTHGRAM_MAX_PIXELS", "").strip()
    if not text:
        return MAX_PIXELS
    try:
        value = int(float(text))
    except ValueError:
        raise InputError(f"DEPTHGRAM_MAX_PIXELS={text!r}: expected a number of pixels") from None
    if value < 1:
        raise InputError(f"DEPTHGRAM_MAX_PIXELS={text!r}: expected a number of pixels >= 1")
    return value


def check_size(height: int, width: int, where: str) -> None:
    """Refuse a frame above :func:`max_pixels` before it is decoded or allocated."""
    limit = max_pixels()
    if height * width > limit:
        raise InputError(
            f"{where}: the frame is {width} x {height} px ({height * width:,} pixels), above the limit of "
            f"{limit:,}; set DEPTHGRAM_MAX_PIXELS to read it anyway"
        )


def _header_size(buf: NDArray[np.uint8]) -> tuple[int, int] | None:
    """(height, width) from a PNG or PGM header, read before decoding; None for other files."""
    head = buf[:1024].tobytes()
    if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        w, h = struct.unpack(">II", head[16:24])
        return int(h), int(w)
    m = re.match(rb"P[1-6]((?:\s+|#[^\n]*\n)+)(\d+)((?:\s+|#[^\n]*\n)+)(\d+)", head)
    if m:
        return int(m.group(4)), int(m.group(2))
    return None


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
        except Exception as exc:  # numpy's header parser and zipfile raise many types for damage (issue 32.2)
            raise InputError(f"{where}: cannot read the .npy ({exc})") from None
        if arr.ndim >= 2:
            check_size(int(arr.shape[0]), int(arr.shape[1]), where)
        return arr
    if suffix == ".npz":
        return _read_npz(path, key, where)
    if suffix in (".tif", ".tiff"):
        import tifffile

        try:
            with tifffile.TiffFile(path) as tif:
                shape = tif.pages[0].shape
                if len(shape) >= 2:
                    check_size(int(shape[0]), int(shape[1]), where)
                return np.asarray(tif.asarray())
        except InputError:
            raise
        except Exception as exc:  # tifffile raises many unrelated types for bad files
            raise InputError(f"{where}: cannot read the TIFF (truncated or not a TIFF?): {exc}") from None
    import cv2

    # imdecode over a bytes buffer, not imread: it handles non-ASCII paths and lets a
    # truncated file be told apart from a missing one.
    try:
        buf = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise InputError(f"{where}: cannot read the file ({exc.strerror or exc})") from None
    size = _header_size(buf)
    if size is not None:
        check_size(*size, where)
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
