"""Files beside the frames: intrinsics, frame rate, timestamps; and natural file order."""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from depthgram.errors import InputError
from depthgram.frame import Intrinsics

__all__ = ["Sidecar", "find_sidecar", "natural_key", "read_timestamps"]

_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> tuple[object, ...]:
    """Sort key putting ``frame2`` before ``frame10`` (digit runs compare as numbers)."""
    return tuple(int(p) if p.isdigit() else p.lower() for p in _DIGITS.split(name))


@dataclass(frozen=True)
class Sidecar:
    """What the files beside a recording say.

    Attributes
    ----------
    intrinsics : Intrinsics or None
        Pinhole intrinsics (px).
    fps : float or None
        Frame rate (frames/s), from ``camera.json``.
    depth_range_mm : (float, float) or None
        (near, far) in mm for 8-bit frames, from ``camera.json``.
    source : str
        The file it came from ("" when none).
    """

    intrinsics: Intrinsics | None = None
    fps: float | None = None
    depth_range_mm: tuple[float, float] | None = None
    source: str = ""


def _number(d: dict[str, object], key: str, where: Path) -> float:
    v = d.get(key)
    if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
        raise InputError(f"{where}: expected a number for {key!r}, got {v!r}")
    return float(v)


def _json(path: Path) -> dict[str, object]:
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read the JSON ({exc})") from None
    if not isinstance(d, dict):
        raise InputError(f"{path}: expected a JSON object with fx, fy, cx, cy")
    return d


def _camera_json(path: Path) -> Sidecar:
    # Written by `depthgram simulate`: fx, fy, cx, cy (px), optional fps and depth_range_mm.
    d = _json(path)
    intr = Intrinsics(*(_number(d, k, path) for k in ("fx", "fy", "cx", "cy")))
    fps = _number(d, "fps", path) if d.get("fps") is not None else None
    rng = d.get("depth_range_mm")
    near_far = None
    if isinstance(rng, list) and len(rng) == 2:
        near_far = (float(rng[0]), float(rng[1]))
    return Sidecar(intr, fps, near_far, str(path))


def _camera_params_json(path: Path) -> Sidecar:
    # NVlabs UnseenObjectClustering: fx, fy, x_offset, y_offset (px).
    d = _json(path)
    intr = Intrinsics(*(_number(d, k, path) for k in ("fx", "fy", "x_offset", "y_offset")))
    return Sidecar(intr, None, None, str(path))


def _intrinsics_txt(path: Path) -> Sidecar:
    # 7-Scenes / tsdf-fusion: a 3x3 camera matrix in plain text.
    try:
        k = np.loadtxt(path, dtype=float)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read the 3x3 camera matrix ({exc})") from None
    if k.shape != (3, 3):
        raise InputError(f"{path}: expected a 3x3 camera matrix, got shape {k.shape}")
    return Sidecar(Intrinsics(float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])), None, None, str(path))


_READERS = (
    ("camera.json", _camera_json),
    ("camera_params.json", _camera_params_json),
    ("camera-intrinsics.txt", _intrinsics_txt),
)


def find_sidecar(*folders: Path) -> Sidecar:
    """First intrinsics sidecar in ``folders`` (searched in order), or an empty :class:`Sidecar`."""
    for folder in folders:
        for fname, reader in _READERS:
            p = folder / fname
            if p.is_file():
                return reader(p)
    return Sidecar()


def read_timestamps(path: Path, n_frames: int) -> list[float]:
    """Frame times in seconds from a text file.

    One time per line, or ``index time`` pairs (indices 0..n-1 in any order). Blank lines and
    lines starting with ``#`` are skipped.

    Raises
    ------
    InputError
        Unreadable file, wrong number of times for ``n_frames`` frames, or times that do not
        strictly increase.
    """
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the timestamps file ({exc})") from None
    pairs: list[tuple[int, float]] = []
    for lineno, line in enumerate(lines, 1):
        text = line.split("#", 1)[0].strip().replace(",", " ")
        if not text:
            continue
        parts = text.split()
        try:
            if len(parts) == 1:
                pairs.append((len(pairs), float(parts[0])))
            elif len(parts) == 2:
                pairs.append((int(parts[0]), float(parts[1])))
            else:
                raise ValueError
        except ValueError:
            raise InputError(
                f"{path} line {lineno}: expected 'time' or 'index time' in seconds, got {line.strip()!r}"
            ) from None
    if len(pairs) != n_frames:
        raise InputError(f"{path}: {len(pairs)} timestamps for {n_frames} frames; expected one per frame")
    pairs.sort()
    if [i for i, _ in pairs] != list(range(n_frames)):
        raise InputError(f"{path}: frame indices must be 0..{n_frames - 1}, each once")
    times = [t for _, t in pairs]
    for i in range(1, len(times)):
        if not (math.isfinite(times[i]) and times[i] > times[i - 1]):
            raise InputError(
                f"{path}: times must strictly increase; frame {i} at {times[i]} s follows {times[i - 1]} s"
            )
    return times
