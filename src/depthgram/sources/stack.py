"""A 3-D array (N, H, W) in an ``.npy`` or ``.npz`` file as a sequence, read frame by frame.

``.npy`` stacks are memory-mapped. ``.npz`` members cannot be memory-mapped (they may be
deflated), so the member is streamed: the ``.npy`` header is parsed and then one frame's bytes
are read at a time. Either way memory stays at about one frame.
"""

from __future__ import annotations

import zipfile
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path
from typing import IO

import numpy as np
from numpy.lib import format as npformat

from depthgram.errors import InputError
from depthgram.frame import Frame, Intrinsics
from depthgram.sources.base import Source
from depthgram.sources.config import SourceConfig
from depthgram.sources.decode import to_frame
from depthgram.sources.images import npz_pick
from depthgram.sources.sidecars import read_timestamps

__all__ = ["NpyStackSource", "NpzStackSource", "npz_member_header"]


def _read_header(fh: IO[bytes], where: str) -> tuple[tuple[int, ...], bool, np.dtype]:
    try:
        version = npformat.read_magic(fh)
        if version == (1, 0):
            shape, fortran, dtype = npformat.read_array_header_1_0(fh)
        else:
            shape, fortran, dtype = npformat.read_array_header_2_0(fh)
    except Exception as exc:  # numpy's header parser and zipfile raise many types for damage (issue 32.2)
        raise InputError(f"{where}: not a valid array ({exc})") from None
    return tuple(shape), bool(fortran), dtype


def npz_member_header(path: Path, key: str | None) -> tuple[str, tuple[int, ...], bool, np.dtype]:
    """Chosen member name, shape, Fortran order and dtype of an ``.npz`` array, without loading it."""
    try:
        with zipfile.ZipFile(path) as zf:
            headers = {}
            for n in zf.namelist():
                if n.endswith(".npy"):
                    with zf.open(n) as fh:
                        headers[n[:-4]] = _read_header(fh, f"{path}[{n[:-4]}]")
    except InputError:
        raise
    except Exception as exc:  # numpy's header parser and zipfile raise many types for damage (issue 32.2)
        raise InputError(f"{path}: cannot read the .npz ({exc})") from None
    name = npz_pick(list(headers), {k: v[0] for k, v in headers.items()}, key, str(path))
    return (name, *headers[name])


class _StackSource(Source):
    intrinsics_source = "file"  # a sidecar beside the stack

    def __init__(
        self, path: Path, cfg: SourceConfig, n: int, *, name: str, intrinsics: Intrinsics | None, fps: float | None
    ) -> None:
        self.path = path
        self.cfg = cfg
        self.n = n
        self.name = name
        self.intrinsics = intrinsics
        self.fps = fps
        self.times = read_timestamps(Path(cfg.timestamps), n) if cfg.timestamps else None

    def __len__(self) -> int:
        return self.n

    def _frame(self, raw: np.ndarray, i: int) -> Frame:
        t = self.times[i] if self.times is not None else (i / self.fps if self.fps else None)
        return to_frame(
            raw,
            self.cfg,
            where=f"{self.path} (frame {i})",
            index=i,
            time_s=t,
            intrinsics=self.intrinsics,
            name=f"{self.path.name}#{i}",
        )


class NpyStackSource(_StackSource):
    """Frames of an (N, H, W) ``.npy`` stack, memory-mapped.

    Parameters
    ----------
    path : Path
        The ``.npy`` file.
    cfg : SourceConfig
        Units, encoding, timestamps.
    name : str
        The spec.
    intrinsics, fps
        Put on the frames.
    """

    kind = "npy-stack"

    def __init__(
        self,
        path: Path,
        cfg: SourceConfig,
        *,
        name: str,
        intrinsics: Intrinsics | None = None,
        fps: float | None = None,
    ) -> None:
        try:
            self.stack = np.load(path, mmap_mode="r", allow_pickle=False)
        except Exception as exc:  # numpy's header parser and zipfile raise many types for damage (issue 32.2)
            raise InputError(f"{path}: cannot read the .npy ({exc})") from None
        if self.stack.ndim != 3:
            raise InputError(f"{path}: expected an (N, H, W) stack, got shape {self.stack.shape}")
        super().__init__(path, cfg, int(self.stack.shape[0]), name=name, intrinsics=intrinsics, fps=fps)

    def __iter__(self) -> Iterator[Frame]:
        for i in range(self.n):
            # Copy one frame out of the map so that pages of earlier frames can be dropped.
            yield self.calibrated(self._frame(np.array(self.stack[i]), i))


class NpzStackSource(_StackSource):
    """Frames of an (N, H, W) array inside an ``.npz``, streamed from the zip member.

    Parameters
    ----------
    path : Path
        The ``.npz`` file.
    cfg : SourceConfig
        Units, encoding, timestamps, ``key`` (array name; default the first 2-D or 3-D array).
    name : str
        The spec.
    intrinsics, fps
        Put on the frames.
    """

    kind = "npz-stack"

    def __init__(
        self,
        path: Path,
        cfg: SourceConfig,
        *,
        name: str,
        intrinsics: Intrinsics | None = None,
        fps: float | None = None,
    ) -> None:
        self.member, shape, self.fortran, self.dtype = npz_member_header(path, cfg.key)
        if len(shape) != 3:
            raise InputError(f"{path}[{self.member}]: expected an (N, H, W) stack, got shape {shape}")
        if self.dtype.hasobject:
            raise InputError(f"{path}[{self.member}]: expected numeric depth samples, got dtype {self.dtype}")
        self.shape = shape
        super().__init__(path, cfg, shape[0], name=name, intrinsics=intrinsics, fps=fps)

    def __iter__(self) -> Iterator[Frame]:
        _, h, w = self.shape
        nbytes = h * w * self.dtype.itemsize
        with ExitStack() as opened:
            try:
                zf = opened.enter_context(zipfile.ZipFile(self.path))
                fh = opened.enter_context(zf.open(self.member + ".npy"))
                _read_header(fh, str(self.path))
                # Fortran order interleaves frames; rare enough to accept a full load.
                full = npformat.read_array(fh, allow_pickle=False) if self.fortran else None
            except InputError:
                raise
            except Exception as exc:  # zipfile and numpy raise many types for damage (issue 32.2)
                raise InputError(f"{self.path}[{self.member}]: cannot read the .npz ({exc})") from None
            if full is not None:
                for i in range(self.n):
                    yield self.calibrated(self._frame(np.ascontiguousarray(full[i]), i))
                return
            for i in range(self.n):
                try:
                    buf = fh.read(nbytes)
                except Exception as exc:  # zipfile: a CRC error, a damaged deflate stream (issue 32.2)
                    raise InputError(f"{self.path}[{self.member}] (frame {i}): cannot read the .npz ({exc})") from None
                if len(buf) != nbytes:
                    raise InputError(f"{self.path}[{self.member}] (frame {i}): truncated stack")
                yield self.calibrated(self._frame(np.frombuffer(buf, self.dtype).reshape(h, w), i))
