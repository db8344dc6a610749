"""The :class:`Source` interface and :class:`SourceInfo`, a streamed summary of a source."""

from __future__ import annotations

import dataclasses
import sys
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Frame, Gravity, Intrinsics

if TYPE_CHECKING:
    from depthgram.sources.camera import Camera

__all__ = ["DepthSummary", "Source", "SourceInfo", "decimated"]

#: Depth histogram bins are 1 mm wide; readings beyond this (mm) share the last bin.
_HIST_MAX_MM = 200_000


@dataclass(frozen=True)
class SourceInfo:
    """What a source holds, computed by streaming every frame once.

    Attributes
    ----------
    path : str
        The spec the source was opened from.
    kind : str
        ``"file"``, ``"folder"``, ``"glob"``, ``"npy-stack"``, ``"npz-stack"``, ``"bag"``, ``"sim"``.
    frames : int
        Number of frames.
    size : (int, int)
        (width, height) in pixels.
    unit : str
        Always ``"mm"``: the unit of the depth figures below and of every frame.
    depth_min_mm, depth_median_mm, depth_max_mm : float or None
        Over all valid pixels of all frames (mm); None when no pixel is valid. The median is
        exact to 1 mm (streamed through a 1 mm histogram).
    invalid_fraction : float
        Share of pixels without a reading, over all frames.
    fps : float or None
        Frame rate (frames/s): given, from a sidecar, or from the timestamps' median step.
    intrinsics : Intrinsics or None
        Camera intrinsics (px), when known.
    duration_s : float or None
        Time from first to last frame (s), when frames carry times.
    sensor : str or None
        The camera's depth step and noise as estimated from the first frame with readings
        (:func:`depthgram.segmentation.sensor.estimate_sensor`), for people; None without one.
    intrinsics_source : str
        Where the intrinsics came from (``given``, ``file``, ``bag``, ``device``, ``simulator``,
        ``profile``); "" without intrinsics (the segmentation then guesses them).
    intrinsics_from : str
        The calibration file (or sidecar) or camera profile they came from, when one did.
    gravity : dict or None
        The first frame's gravity (:meth:`depthgram.frame.Gravity.to_dict`), when known.
    """

    path: str
    kind: str
    frames: int
    size: tuple[int, int]
    unit: str
    depth_min_mm: float | None
    depth_median_mm: float | None
    depth_max_mm: float | None
    invalid_fraction: float
    fps: float | None
    intrinsics: Intrinsics | None = None
    duration_s: float | None = None
    sensor: str | None = None
    intrinsics_source: str = ""
    intrinsics_from: str = ""
    gravity: dict[str, object] | None = None

    def to_dict(self) -> dict[str, object]:
        """Plain JSON-ready dictionary."""
        d = asdict(self)
        d["size"] = list(self.size)
        return d


class DepthSummary:
    """Running min / median / max of valid depth and invalid share, one frame at a time.

    Memory stays at one 1 mm histogram (<= 1.6 MB) however many frames are added.
    """

    def __init__(self) -> None:
        self.hist: NDArray[np.int64] = np.zeros(0, np.int64)
        self.pixels = 0
        self.valid = 0
        self.lo = np.inf
        self.hi = -np.inf
        self.sensor: str | None = None

    def add(self, frame: Frame) -> None:
        """Count one frame's pixels."""
        d = frame.depth[frame.valid]
        if self.sensor is None and d.size:
            from depthgram.segmentation.sensor import estimate_sensor

            self.sensor = estimate_sensor(frame.depth, frame.valid).describe()
        self.pixels += frame.valid.size
        self.valid += d.size
        if d.size == 0:
            return
        lo, hi = float(d.min()), float(d.max())
        self.lo, self.hi = min(self.lo, lo), max(self.hi, hi)
        # Depth is positive, so adding 0.5 and truncating rounds to the nearest mm; cheaper than
        # np.rint + np.minimum, which only far outliers need.
        bins = (np.minimum(d, _HIST_MAX_MM) if hi > _HIST_MAX_MM else d) + np.float32(0.5)
        counts = np.bincount(bins.astype(np.intp))
        if counts.size > self.hist.size:
            self.hist = np.pad(self.hist, (0, counts.size - self.hist.size))
        self.hist[: counts.size] += counts

    def median(self) -> float | None:
        """Lower median of the valid depths, to the nearest mm."""
        if self.valid == 0:
            return None
        cum = np.cumsum(self.hist)
        return float(np.searchsorted(cum, (self.valid + 1) // 2))


class Source(ABC):
    """Frames from one place, read one at a time.

    Attributes
    ----------
    name : str
        The spec it was opened from.
    kind : str
        See :class:`SourceInfo`.
    fps : float or None
        Frame rate (frames/s), when known.
    intrinsics : Intrinsics or None
        Camera intrinsics (px), when known.
    live : bool
        A camera delivering frames as they happen: never read ahead, since a frame queued
        while the pipeline works would be stale by the time it is processed.
    intrinsics_source : str
        Where the source's own intrinsics came from (``file``, ``bag``, ``device``,
        ``simulator``), "" without them.
    camera : Camera or None
        The camera the user named (``intrinsics=`` / ``camera=``): it wins over the source's own
        intrinsics, scaled to each frame's size (:meth:`calibrated`).
    gravity : Gravity or None
        Gravity the user gave (``gravity=`` / ``tilt_deg=``); wins over a recording's IMU.
    """

    name: str = ""
    kind: str = ""
    fps: float | None = None
    intrinsics: Intrinsics | None = None
    live: bool = False
    intrinsics_source: str = ""
    intrinsics_from: str = ""
    camera: Camera | None = None
    gravity: Gravity | None = None

    def calibrated(self, frame: Frame, *, size: tuple[int, int] | None = None) -> Frame:
        """Return ``frame`` with the user's camera and gravity, and where its intrinsics came from.

        Every source passes its frames through this before yielding them. ``size`` (width,
        height) px: of the frame as stored, when ``frame`` holds only some of its pixels (the
        camera's intrinsics are for that size).
        """
        cam, grav = self.camera, self.gravity
        changes: dict[str, object] = {}
        if cam is not None:
            k = cam.for_size(size or frame.size)
            self.intrinsics, self.intrinsics_source = k, cam.source
            changes.update(intrinsics=k, intrinsics_source=cam.source)
            if cam.origin:
                frame.meta["intrinsics_from"] = cam.origin
            if cam.sensor:
                frame.meta["sensor_profile"] = cam.sensor
        elif frame.intrinsics is not None and not frame.intrinsics_source and self.intrinsics_source:
            changes["intrinsics_source"] = self.intrinsics_source
            if self.intrinsics_from:
                frame.meta["intrinsics_from"] = self.intrinsics_from
        if grav is not None:
            changes["gravity"] = grav
        return dataclasses.replace(frame, **changes) if changes else frame  # type: ignore[arg-type]

    @abstractmethod
    def __iter__(self) -> Iterator[Frame]:
        """Yield the frames in order, reading each only when asked for."""

    @abstractmethod
    def __len__(self) -> int:
        """Return the number of frames."""

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.kind} {self.name!r}>"

    def _sensor_said(self, estimated: str | None) -> str | None:
        """Return the sensor line of :meth:`info`: the named camera's model, else the estimate."""
        name = self.camera.sensor if self.camera is not None else None
        if not name:
            return estimated
        from depthgram.segmentation.sensor import sensor_model

        return f"{sensor_model(name).describe()} (camera profile {self.camera.origin if self.camera else ''})"

    def info(self, *, progress: bool = False) -> SourceInfo:
        """Stream every frame once and summarise the source.

        Parameters
        ----------
        progress : bool
            Show a tqdm progress bar on stderr (for long sources).
        """
        summary = DepthSummary()
        size: tuple[int, int] = (0, 0)
        gravity: Gravity | None = None
        times: list[float] = []
        count = 0
        frames: Iterator[Frame] = iter(self)
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(self), file=sys.stderr, unit="frame", desc="reading", leave=False)
        try:
            for frame in frames:
                if count == 0:
                    size, gravity = frame.size, frame.gravity
                summary.add(frame)
                if frame.time_s is not None:
                    times.append(frame.time_s)
                count += 1
                if bar is not None:
                    bar.update()
        finally:
            if bar is not None:
                bar.close()
        fps = self.fps
        duration = times[-1] - times[0] if len(times) == count and count > 1 else None
        if fps is None and duration is not None:
            step = float(np.median(np.diff(times)))
            fps = 1.0 / step if step > 0 else None
        return SourceInfo(
            path=self.name,
            kind=self.kind,
            frames=count,
            size=size,
            unit="mm",
            depth_min_mm=summary.lo if summary.valid else None,
            depth_median_mm=summary.median(),
            depth_max_mm=summary.hi if summary.valid else None,
            invalid_fraction=1.0 - summary.valid / summary.pixels if summary.pixels else 1.0,
            sensor=self._sensor_said(summary.sensor),
            fps=fps,
            intrinsics=self.intrinsics,
            duration_s=duration,
            intrinsics_source=self.intrinsics_source if self.intrinsics is not None else "",
            intrinsics_from=self.camera.origin if self.camera is not None else self.intrinsics_from,
            gravity=gravity.to_dict() if gravity is not None else None,
        )


def decimated(frames: Iterator[Frame], step: int) -> Iterator[Frame]:
    """Yield the rest of ``frames`` as :meth:`Frame.decimated` gives them (``step``: every how many pixels and rows).

    The frames of an iterator that can read only those pixels (a ``decimate(step)`` method: the
    image files of :class:`~depthgram.sources.files.FilesSource`) are read so: the same frames,
    without converting the samples left out. ``frames`` is iterated here only.
    """
    tell = getattr(frames, "decimate", None)
    if tell is not None:
        tell(step)
        yield from frames
        return
    for frame in frames:
        yield frame.decimated(step)
