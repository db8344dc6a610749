"""Image files as a source: one file, a folder or a glob of frames in natural order."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path

from depthgram.errors import InputError
from depthgram.frame import Frame, Intrinsics
from depthgram.sources.base import Source
from depthgram.sources.config import SourceConfig
from depthgram.sources.decode import check_depth_array, to_frame
from depthgram.sources.images import IMAGE_SUFFIXES, read_image
from depthgram.sources.sidecars import natural_key, read_timestamps

__all__ = ["FileFrames", "FilesSource", "list_frames"]


def list_frames(folder: Path) -> list[Path]:
    """Depth frame files of ``folder`` in natural order.

    When some file names contain ``depth`` only those are kept, so that a folder mixing
    ``000001-color.png`` and ``000001-depth.png`` (NVlabs, Azure Kinect exports) reads the depth.

    Raises
    ------
    InputError
        When the folder holds no frame file.
    """
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
    depth_named = [p for p in files if "depth" in p.name.lower()]
    files = depth_named or files
    if not files:
        raise InputError(
            f"{folder}: no depth frames in this folder (expected {', '.join(sorted(IMAGE_SUFFIXES))} files)"
            + _subfolder_hint(folder)
        )
    return sorted(files, key=lambda p: natural_key(p.name))


def _subfolder_hint(folder: Path) -> str:
    """Return a hint naming the subfolders that do hold frame files (datasets nest them), or ''."""
    found = [
        d
        for d in sorted(folder.iterdir(), key=lambda p: natural_key(p.name))
        if d.is_dir() and any(f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES for f in d.iterdir())
    ]
    if not found:
        return ""
    # A subfolder named for depth is the likely one; name it first.
    found.sort(key=lambda d: not any(k in d.name.lower() for k in ("depth", "disparity")))
    return "; these subfolders hold image files: " + ", ".join(str(d) for d in found[:4])


class FilesSource(Source):
    """Frames stored one per file.

    Parameters
    ----------
    paths : sequence of Path
        The frame files, in order.
    cfg : SourceConfig
        Units, encoding, frame rate and timestamps file.
    name : str
        The spec, for :class:`~depthgram.sources.SourceInfo` and errors.
    kind : str
        ``"file"``, ``"folder"`` or ``"glob"``.
    intrinsics : Intrinsics, optional
        Camera intrinsics (px) put on every frame.
    times : sequence of float, optional
        Frame times (s); otherwise ``index / fps`` when the frame rate is known.
    fps : float, optional
        Frame rate (frames/s).
    """

    intrinsics_source = "file"  # a sidecar beside the frames

    def __init__(
        self,
        paths: Sequence[Path],
        cfg: SourceConfig,
        *,
        name: str,
        kind: str,
        intrinsics: Intrinsics | None = None,
        times: Sequence[float] | None = None,
        fps: float | None = None,
    ) -> None:
        self.paths = tuple(paths)
        self.cfg = cfg
        self.name = name
        self.kind = kind
        self.intrinsics = intrinsics
        self.fps = fps
        if times is None and cfg.timestamps is not None:
            times = read_timestamps(Path(cfg.timestamps), len(self.paths))
        if times is not None and len(times) != len(self.paths):
            raise InputError(f"{name}: {len(times)} timestamps for {len(self.paths)} frames")
        self.times = None if times is None else tuple(times)

    def __len__(self) -> int:
        return len(self.paths)

    def _time(self, i: int) -> float | None:
        if self.times is not None:
            return self.times[i]
        return i / self.fps if self.fps else None

    def __iter__(self) -> FileFrames:
        return FileFrames(self)


class FileFrames(Iterator[Frame]):
    """The frames of a :class:`FilesSource`, read one file at a time.

    :meth:`decimate` makes the frames read after it every ``step``-th pixel of every
    ``step``-th row, as :meth:`Frame.decimated` would (:func:`depthgram.sources.base.decimated`
    asks for it): the samples left out are never converted to millimetres.
    """

    def __init__(self, source: FilesSource) -> None:
        self._source = source
        self._i = 0
        self._step = 1
        self._first: tuple[Path, tuple[int, int]] | None = None

    def decimate(self, step: int) -> None:
        """Read every ``step``-th pixel of every ``step``-th row of the frames from the next one on."""
        if step < 1:
            raise InputError(f"{self._source.name}: decimation step must be >= 1, got {step}")
        self._step = step

    def close(self) -> None:
        """Read no further frame."""
        self._i = len(self._source.paths)

    def __next__(self) -> Frame:
        src = self._source
        i = self._i
        if i >= len(src.paths):
            raise StopIteration
        self._i += 1
        path = src.paths[i]
        where = f"{path} (frame {i})" if len(src.paths) > 1 else str(path)
        raw = read_image(path, key=src.cfg.key, where=where)
        step = self._step
        whole = check_depth_array(raw, where) if step > 1 else raw
        # every sample becomes mm on its own: the frame of the kept samples is the kept pixels
        # of the whole frame
        frame = to_frame(
            whole[::step, ::step] if step > 1 else raw,
            src.cfg,
            where=where,
            index=i,
            time_s=src._time(i),
            intrinsics=src.intrinsics,
            name=path.name,
        )
        size = (int(whole.shape[1]), int(whole.shape[0])) if step > 1 else frame.size
        if self._first is None:
            self._first = (path, size)
        elif size != self._first[1]:
            first, known = self._first
            raise InputError(
                f"{path} (frame {i}) is {size[0]}x{size[1]} px but {first} (frame 0) is "
                f"{known[0]}x{known[1]} px; all frames of a sequence must have one size"
            )
        if step == 1:
            return src.calibrated(frame)
        return src.calibrated(frame, size=size).decimated(step, read=True)
