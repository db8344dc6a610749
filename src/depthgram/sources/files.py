"""Image files as a source: one file, a folder or a glob of frames in natural order."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path

from depthgram.errors import InputError
from depthgram.frame import Frame, Intrinsics
from depthgram.sources.base import Source
from depthgram.sources.config import SourceConfig
from depthgram.sources.decode import to_frame
from depthgram.sources.images import IMAGE_SUFFIXES, read_image
from depthgram.sources.sidecars import natural_key, read_timestamps

__all__ = ["FilesSource", "list_frames"]


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

    def __iter__(self) -> Iterator[Frame]:
        first: tuple[Path, tuple[int, int]] | None = None
        seq = len(self.paths) > 1
        for i, path in enumerate(self.paths):
            where = f"{path} (frame {i})" if seq else str(path)
            raw = read_image(path, key=self.cfg.key, where=where)
            frame = to_frame(
                raw,
                self.cfg,
                where=where,
                index=i,
                time_s=self._time(i),
                intrinsics=self.intrinsics,
                name=path.name,
            )
            if first is None:
                first = (path, frame.size)
            elif frame.size != first[1]:
                raise InputError(
                    f"{path} (frame {i}) is {frame.size[0]}x{frame.size[1]} px but {first[0]} (frame 0) is "
                    f"{first[1][0]}x{first[1][1]} px; all frames of a sequence must have one size"
                )
            yield self.calibrated(frame)
