"""From a spec (path, glob, bag, ``sim:`` scene) to the matching :class:`Source`."""

from __future__ import annotations

import dataclasses
import glob
import os
import re
from collections.abc import Sequence
from pathlib import Path
from urllib.parse import parse_qs

import numpy as np

from depthgram.errors import InputError
from depthgram.frame import Gravity, Intrinsics, as_gravity
from depthgram.sources.bag import BAG_SUFFIXES, BagSource
from depthgram.sources.base import Source
from depthgram.sources.camera import Camera, resolve_camera
from depthgram.sources.config import SourceConfig
from depthgram.sources.files import FilesSource, list_frames
from depthgram.sources.images import IMAGE_SUFFIXES
from depthgram.sources.own_mcap import OwnMcapSource, is_own_mcap
from depthgram.sources.realsense import PREFIX as REALSENSE_PREFIX
from depthgram.sources.realsense import RealSenseSource, parse_realsense_spec
from depthgram.sources.sidecars import find_sidecar, natural_key
from depthgram.sources.sim import SimSource, parse_sim_spec, scene_names
from depthgram.sources.stack import NpyStackSource, NpzStackSource, npz_member_header

__all__ = ["open_source", "read"]

_GLOB_CHARS = re.compile(r"[*?\[]")
_SCENE_NAME = re.compile(r"^[A-Za-z][\w-]*(\?.*)?$")


def _split_query(text: str) -> tuple[str, dict[str, str]]:
    # "frames.npz?key=depth": only when the text itself is not an existing path.
    base, _, query = text.partition("?")
    if not query or not Path(base).exists():
        return text, {}
    return base, {k: v[-1] for k, v in parse_qs(query).items()}


def open_source(
    spec: str | os.PathLike[str],
    *,
    scale_mm: float | None = None,
    invalid: Sequence[float] = (),
    fps: float | None = None,
    timestamps: str | os.PathLike[str] | None = None,
    depth_range_mm: tuple[float, float] | None = None,
    encoding: str = "auto",
    topic: str | None = None,
    intrinsics: Intrinsics | Sequence[float] | None = None,
    key: str | None = None,
    camera: str | os.PathLike[str] | Camera | None = None,
    gravity: Gravity | Sequence[float] | None = None,
    tilt_deg: float | None = None,
) -> Source:
    """Open any depth source; nothing is read beyond headers and sidecars until iteration.

    Parameters
    ----------
    spec : str or path
        - an image file: 16-bit PNG (mm), 8-bit PNG (paper's 0-255 over ``depth_range_mm``),
          TIFF, PGM, ``.npy``, ``.npz`` (``file.npz?key=NAME`` or ``key=`` picks the array);
          a 3-D (N, H, W) ``.npy``/``.npz`` array is a sequence;
        - a folder of frames (natural order; a ``depth/`` subfolder is read instead when
          present; files named ``*depth*`` are preferred over the others) or a glob;
        - a ROS 1 ``.bag``, a ROS 2 bag folder (``metadata.yaml``), ``.mcap`` or ``.db3``, and
          depthgram's own ``describe --mcap`` file (its depth topic and calibration);
        - ``realsense:[SERIAL][?size=640x480&fps=30&frames=N]``: a live Intel RealSense camera
          (extra ``depthgram[realsense]``);
        - ``sim:SCENE?frames=30&size=176x132&seed=0&fps=30`` (without ``frames``: 30, one still
          of a scene where nothing moves: ``table``, ``corridor``, ``ball_wall``, ``touching``),
          or a bare scene name when no file of that name exists.
    scale_mm : float, optional
        Millimetres per raw unit (default 1 for integer images, 1000 for float: metres).
    invalid : sequence of float
        Raw values meaning no reading (65535 in uint16 images is always invalid).
    fps : float, optional
        Frame rate (frames/s); overrides ``camera.json``. Ignored for times when timestamps exist.
    timestamps : path, optional
        Timestamps file (s); default ``timestamps.txt`` beside the frames, when present.
    depth_range_mm : (float, float), optional
        (near, far) in mm: range of 8-bit codes, else the valid range.
    encoding : str
        ``auto``, ``raw``, ``8bit``, ``sun`` (SUN RGB-D) or ``kinect-disparity`` (NYU raw).
    topic : str, optional
        Bag topic; required when a bag has several depth-like Image topics.
    intrinsics : Intrinsics or (fx, fy, cx, cy), optional
        Pinhole intrinsics (px) of the frames as read (``--intrinsics``). They, and ``camera``,
        override any sidecar (``camera.json``, ``camera_params.json``, ``camera-intrinsics.txt``
        in the folder or its parent), a bag's CameraInfo and a camera's own calibration.
    key : str, optional
        Array name in an ``.npz``.
    camera : str or path, optional
        A calibration file or a camera profile (``--camera``, see
        :func:`depthgram.sources.camera.resolve_camera`): intrinsics scaled to the frames' size,
        and for a profile the sensor model of the segmentation.
    gravity : Gravity or (x, y, z), optional
        Which way is down in camera coordinates (x right, y down, z forward; any length):
        ``--gravity``. Overrides a recording's IMU.
    tilt_deg : float, optional
        The camera looks down by this many degrees, without roll (``--tilt``); instead of ``gravity``.

    Returns
    -------
    Source

    Raises
    ------
    InputError
        Missing path, empty folder, glob matching nothing, bad options.
    """
    cam = resolve_camera(intrinsics, camera)
    grav = as_gravity(gravity, tilt_deg)
    src = _open(os.fspath(spec), scale_mm, invalid, fps, timestamps, depth_range_mm, encoding, topic, key)
    src.camera, src.gravity = cam, grav
    if cam is not None:
        size = src.spec.size if isinstance(src, SimSource) else None
        if cam.size is None or size is not None:
            src.intrinsics = cam.for_size(size) if size is not None else cam.intrinsics
            src.intrinsics_source = cam.source
    return src


def _open(
    text: str,
    scale_mm: float | None,
    invalid: Sequence[float],
    fps: float | None,
    timestamps: str | os.PathLike[str] | None,
    depth_range_mm: tuple[float, float] | None,
    encoding: str,
    topic: str | None,
    key: str | None,
) -> Source:
    intrinsics = None  # the user's camera is put on each frame by Source.calibrated
    if text.startswith(REALSENSE_PREFIX):
        return RealSenseSource(parse_realsense_spec(text), name=text)
    if text.startswith("sim:"):
        return SimSource(parse_sim_spec(text, fps), name=text, intrinsics=intrinsics)
    text_path, query = _split_query(text)
    key = key if key is not None else query.get("key")
    cfg = SourceConfig(
        scale_mm=scale_mm,
        invalid=tuple(invalid),
        fps=fps,
        timestamps=os.fspath(timestamps) if timestamps is not None else None,
        depth_range_mm=depth_range_mm,
        encoding=encoding,
        topic=topic,
        key=key,
    )
    path = Path(text_path)
    if path.is_dir():
        if (path / "metadata.yaml").is_file():
            return BagSource(path, cfg, name=text, intrinsics=intrinsics, fps=fps)
        folder = path / "depth" if (path / "depth").is_dir() else path
        return _files(list_frames(folder), cfg, text, "folder", folder, intrinsics)
    if path.is_file():
        suffix = path.suffix.lower()
        if suffix == ".mcap" and is_own_mcap(path):  # describe --mcap's file, not a ROS 2 bag (issue 32.4)
            return OwnMcapSource(path, cfg, name=text, intrinsics=intrinsics, fps=fps)
        if suffix in BAG_SUFFIXES:
            return BagSource(path, cfg, name=text, intrinsics=intrinsics, fps=fps)
        side = find_sidecar(path.parent)
        intr = intrinsics or side.intrinsics
        rate = fps or side.fps
        if suffix == ".npy" and _is_stack(_npy_shape(path)):
            return NpyStackSource(path, cfg, name=text, intrinsics=intr, fps=rate)
        if suffix == ".npz" and _is_stack(npz_member_header(path, key)[1]):
            return NpzStackSource(path, cfg, name=text, intrinsics=intr, fps=rate)
        return _files([path], cfg, text, "file", path.parent, intrinsics)
    matches = [Path(p) for p in glob.glob(text)] if _GLOB_CHARS.search(text) else []
    matches = [p for p in matches if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES]
    if matches:
        matches.sort(key=lambda p: natural_key(str(p)))
        return _files(matches, cfg, text, "glob", matches[0].parent, intrinsics)
    if _SCENE_NAME.match(text) and _is_scene(text.partition("?")[0]):
        return SimSource(parse_sim_spec(text, fps), name=f"sim:{text}", intrinsics=intrinsics)
    if _GLOB_CHARS.search(text):
        raise InputError(f"{text}: the pattern matches no depth frame files")
    raise InputError(f"{text}: no such file or folder")


def _is_scene(name: str) -> bool:
    return name in scene_names()


def _is_stack(shape: tuple[int, ...]) -> bool:
    # (H, W, 1|3|4) is one image (grey or colour, refused later with a clear message), not a
    # stack of frames 1, 3 or 4 pixels wide.
    return len(shape) == 3 and shape[2] not in (1, 3, 4)


def _npy_shape(path: Path) -> tuple[int, ...]:
    try:
        return tuple(np.load(path, mmap_mode="r", allow_pickle=False).shape)
    except Exception as exc:  # numpy's header parser and zipfile raise many types for damage (issue 32.2)
        raise InputError(f"{path}: cannot read the .npy ({exc})") from None


def _files(
    paths: list[Path], cfg: SourceConfig, name: str, kind: str, folder: Path, intrinsics: Intrinsics | None
) -> FilesSource:
    side = find_sidecar(folder, folder.parent)
    if cfg.depth_range_mm is None and side.depth_range_mm is not None:
        cfg = dataclasses.replace(cfg, depth_range_mm=side.depth_range_mm)
    if cfg.timestamps is None and kind != "file":
        for cand in (folder / "timestamps.txt", folder.parent / "timestamps.txt"):
            if cand.is_file():
                cfg = dataclasses.replace(cfg, timestamps=str(cand))
                break
    src = FilesSource(
        paths,
        cfg,
        name=name,
        kind=kind,
        intrinsics=intrinsics or side.intrinsics,
        fps=cfg.fps or side.fps,
    )
    if intrinsics is None and side.intrinsics is not None:
        src.intrinsics_from = side.source
    return src


def read(
    spec: str | os.PathLike[str],
    *,
    scale_mm: float | None = None,
    invalid: Sequence[float] = (),
    fps: float | None = None,
    timestamps: str | os.PathLike[str] | None = None,
    depth_range_mm: tuple[float, float] | None = None,
    encoding: str = "auto",
    topic: str | None = None,
    intrinsics: Intrinsics | Sequence[float] | None = None,
    key: str | None = None,
    camera: str | os.PathLike[str] | Camera | None = None,
    gravity: Gravity | Sequence[float] | None = None,
    tilt_deg: float | None = None,
) -> Source:
    """Return the frames of any source, one at a time.

    Returns the :class:`Source` itself, not a bare generator: iterating it reads frame after
    frame (memory stays at about one frame however long the recording), and consumers see
    what it is. :meth:`depthgram.Pipeline.run` reads a source whose ``live`` is true (a
    camera) on the caller's thread instead of ahead, since a queued frame would be stale.
    Bad specs raise :class:`~depthgram.errors.InputError` here rather than at the first frame.
    The options are the command line's reading options (``--scale``, ``--invalid``, ...).

    Parameters
    ----------
    spec : str or path
        An image file (16-bit PNG in mm, TIFF, PGM, ``.npy``, ``.npz``; a 3-D array is a
        sequence), a folder of frames or a glob, a ROS 1 ``.bag``, a ROS 2 bag folder,
        ``.mcap`` or ``.db3`` (depthgram's own ``describe --mcap`` file too),
        ``realsense:[SERIAL]`` or ``sim:SCENE?frames=N&size=WxH&seed=S&fps=F`` (30 frames; one
        still of a scene where nothing moves, ``table`` say); details in :func:`open_source`.
    scale_mm : float, optional
        Millimetres per raw unit: 0.2 for TUM's 5000 units per metre, 1000 for metres (default
        1 for integer images, 1000 for float ones).
    invalid : sequence of float
        Further raw values meaning no reading (0 always is one, 65535 in 16-bit images too).
    fps : float, optional
        Frame rate (frames/s) when the source has no timestamps.
    timestamps : path, optional
        Timestamps file (s, one per frame); default ``timestamps.txt`` beside the frames.
    depth_range_mm : (float, float), optional
        (near, far) in mm of the paper's 8-bit depth codes.
    encoding : str
        ``auto``, ``raw``, ``8bit``, ``sun`` (SUN RGB-D) or ``kinect-disparity`` (raw NYU).
    topic : str, optional
        Bag topic, when a bag has several depth-like image topics.
    intrinsics : Intrinsics or (fx, fy, cx, cy), optional
        Camera intrinsics (px, for the frames as read), overriding any sidecar or calibration in
        the source (``--intrinsics``).
    key : str, optional
        Array name in an ``.npz``.
    camera : str or path, optional
        A calibration file (ROS ``camera_info`` or OpenCV/Kalibr YAML, Open3D JSON, a 3x3 matrix
        in text) or a camera profile (``kinect-v1``, ``xtion``, ``realsense-d435``, ...), scaled
        to the frames' size (``--camera``); instead of ``intrinsics``.
    gravity : Gravity or (x, y, z), optional
        Which way is down in camera coordinates (x right, y down, z forward; ``--gravity``).
        Overrides a recording's IMU.
    tilt_deg : float, optional
        The camera looks down by this many degrees, without roll (``--tilt``); instead of
        ``gravity``.

    Returns
    -------
    Source
        Iterate it for :class:`~depthgram.frame.Frame` objects.

    Examples
    --------
    >>> frame = next(iter(read("sim:table")))
    >>> frames = read("recording/", scale_mm=0.2, fps=30)  # doctest: +SKIP
    """
    return open_source(
        spec,
        scale_mm=scale_mm,
        invalid=invalid,
        fps=fps,
        timestamps=timestamps,
        depth_range_mm=depth_range_mm,
        encoding=encoding,
        topic=topic,
        intrinsics=intrinsics,
        key=key,
        camera=camera,
        gravity=gravity,
        tilt_deg=tilt_deg,
    )
