"""The camera a recording was made with: its intrinsics, where they came from, and its sensor model.

A user tells the camera in one of two ways, on the command line and in Python alike:

- ``intrinsics=(fx, fy, cx, cy)`` (``--intrinsics FX FY CX CY``): pixels, for the frames as read;
- ``camera=FILE_OR_PROFILE`` (``--camera``): a calibration file (a ROS ``camera_info`` YAML, an
  OpenCV or Kalibr calibration YAML, an Open3D ``PinholeCameraIntrinsic`` JSON, a 3x3 matrix in
  text, or the sidecars this project already reads) or a named profile (:data:`PROFILES`:
  ``kinect-v1``, ``xtion``, ``realsense-d435``, ``azure-kinect-nfov`` ...), which also names the
  sensor model of the segmentation.

A file or profile that states the image size it was calibrated at is scaled to the frames' size.
Every frame then says where its intrinsics came from (:data:`INTRINSICS_SOURCES`).
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from depthgram.errors import InputError
from depthgram.frame import Intrinsics

__all__ = [
    "INTRINSICS_SOURCES",
    "PROFILES",
    "Camera",
    "CameraProfile",
    "IntrinsicsWarning",
    "as_intrinsics",
    "load_camera_file",
    "resolve_camera",
]

#: Where a frame's intrinsics came from: the user's numbers, a calibration file (or a sidecar
#: beside the frames), a bag's CameraInfo, a live camera's own calibration, the simulator's exact
#: ones, a named profile, estimated from the scene, or the 64-degree guess of a frame without any.
INTRINSICS_SOURCES = ("given", "file", "bag", "device", "simulator", "profile", "estimated", "guessed")

#: Aspect ratios closer than this (relative) are one image shape resized, not a crop.
_ASPECT_TOL = 0.01


class IntrinsicsWarning(UserWarning):
    """The intrinsics were guessed or adapted: give them (``--intrinsics`` / ``--camera``) to be sure."""


@dataclass(frozen=True)
class CameraProfile:
    """A camera model's published intrinsics and the sensor model its depth follows.

    Attributes
    ----------
    name : str
        Profile name (``--camera NAME``).
    sensor : str
        The matching profile of :data:`depthgram.segmentation.sensor.PROFILES` (the
        segmentation's depth step and noise), used when the configuration says ``auto``.
    modes : tuple of ((int, int), Intrinsics)
        Native depth modes: (width, height) in px and the intrinsics (px) at that size.
    note : str
        Where the figures come from.
    """

    name: str
    sensor: str
    modes: tuple[tuple[tuple[int, int], Intrinsics], ...]
    note: str = ""

    def intrinsics_for(self, size: tuple[int, int]) -> Intrinsics:
        """Return the intrinsics (px) for frames of ``size`` = (width, height) px.

        The mode of that size when there is one; else the mode of the nearest aspect ratio,
        scaled (:meth:`~depthgram.frame.Intrinsics.scaled`); when the aspect ratios differ (a
        crop, whose principal point no profile knows) scaled by the width and centred, with an
        :class:`IntrinsicsWarning`.
        """
        return _fit(self.modes, size, f"camera profile {self.name!r}")


def _fit(modes: Sequence[tuple[tuple[int, int], Intrinsics]], size: tuple[int, int], what: str) -> Intrinsics:
    w, h = size
    for (mw, mh), k in modes:
        if (mw, mh) == (w, h):
            return k
    aspect = w / h
    (mw, mh), k = min(modes, key=lambda m: (abs(math.log(m[0][0] / m[0][1] / aspect)), -m[0][0]))
    if abs(mw / mh / aspect - 1.0) <= _ASPECT_TOL:
        return k.scaled(w / mw, h / mh)
    # Another aspect ratio is a crop (or another sensor): pixels stay square, so the width sets the
    # scale, and the crop is taken as centred vertically.
    warnings.warn(
        f"{what} is for {mw}x{mh} px frames, these are {w}x{h} px (another aspect ratio: a crop?); its "
        "intrinsics were scaled by the width and centred, give the true ones with --intrinsics FX FY CX CY",
        IntrinsicsWarning,
        stacklevel=3,
    )
    s = w / mw
    scaled = k.scaled(s, s)
    return Intrinsics(scaled.fx, scaled.fy, scaled.cx, scaled.cy + (h - mh * s) / 2.0)


def _k(fx: float, fy: float, cx: float, cy: float) -> Intrinsics:
    return Intrinsics(fx, fy, cx, cy)


_XTION = CameraProfile(
    "xtion",
    "xtion",
    (((640, 480), _k(570.3422, 570.3422, 319.5, 239.5)),),
    "OpenNI's default depth calibration of the PrimeSense family (Asus Xtion, Carmine)",
)
_AZURE = "one unit's factory calibration (lens f 504.6 px on the 1024 px grid), cropped as the Azure Kinect SDK crops"

#: Azure Kinect depth modes: (width, height) px, the grid the normalised calibration is scaled to
#: (px) and the crop offset (px) on it, as the Azure Kinect SDK's mode-specific calibration does.
AZURE_MODES = (
    ((640, 576), 1024, (192, 180)),  # NFOV unbinned
    ((320, 288), 512, (96, 90)),  # NFOV 2x2 binned
    ((1024, 1024), 1024, (0, 0)),  # WFOV unbinned
    ((512, 512), 512, (0, 0)),  # WFOV 2x2 binned
)


def azure_modes(cx: float, cy: float, fx: float, fy: float) -> tuple[tuple[tuple[int, int], Intrinsics], ...]:
    """Return the intrinsics (px) of every Azure Kinect depth mode from its normalised calibration.

    ``cx, cy, fx, fy`` as the device stores them (fractions of the sensor's width and height,
    origin at the top-left corner); the SDK scales them to each mode's grid, subtracts the crop and
    half a pixel (to the centre of the top-left pixel, this project's convention too).
    """
    out = []
    for size, grid, (ox, oy) in AZURE_MODES:
        out.append((size, Intrinsics(fx * grid, fy * grid, cx * grid - ox - 0.5, cy * grid - oy - 0.5)))
    return tuple(out)


#: The shared Azure Kinect recording's depth calibration (normalised cx, cy, fx, fy).
_AZURE_UNIT = azure_modes(0.5129697918891907, 0.5169235467910767, 0.4927808940410614, 0.49290284514427185)

#: Named cameras. Published or typical factory values; a unit's own calibration differs by a few
#: per cent, which the segmentation tolerates (focal x0.8 to x1.25 keeps YCB-Video's 30 objects).
PROFILES: dict[str, CameraProfile] = {
    "kinect-v1": CameraProfile(
        "kinect-v1",
        "kinect-v1",
        (((640, 480), _k(525.0, 525.0, 319.5, 239.5)),),
        "ROS openni_launch and TUM RGB-D's default Kinect v1 depth calibration",
    ),
    "xtion": _XTION,
    "primesense": CameraProfile("primesense", "primesense", _XTION.modes, _XTION.note),
    "realsense-d435": CameraProfile(
        "realsense-d435",
        "realsense-d400",
        (
            ((1280, 720), _k(645.0, 645.0, 639.5, 359.5)),
            ((848, 480), _k(427.0, 427.0, 423.5, 239.5)),
            ((640, 480), _k(385.0, 385.0, 319.5, 239.5)),
        ),
        "typical factory calibration of the D435 depth stream (87 x 58 degrees); 640x480 is its own crop",
    ),
    "azure-kinect-nfov": CameraProfile(
        "azure-kinect-nfov",
        "azure-kinect",
        _AZURE_UNIT[:2],
        _AZURE + " (NFOV: offset 192, 180)",
    ),
    "azure-kinect-wfov": CameraProfile(
        "azure-kinect-wfov",
        "azure-kinect",
        _AZURE_UNIT[2:],
        _AZURE,
    ),
    # a ToF camera with a 1 mm output unit, as the Azure Kinect: its sensor model is the nearest
    "kinect-v2": CameraProfile(
        "kinect-v2",
        "azure-kinect",
        (((512, 424), _k(365.5, 365.5, 255.5, 205.5)),),
        "iai_kinect2's default depth calibration of the Kinect v2",
    ),
}


@dataclass(frozen=True)
class Camera:
    """Intrinsics as the user (or a file, or a profile) gave them, for frames of any size.

    Attributes
    ----------
    intrinsics : Intrinsics
        Pinhole intrinsics (px) at ``size``, or for the frames as read when ``size`` is None.
    source : str
        One of :data:`INTRINSICS_SOURCES`.
    origin : str
        The file or profile they came from ("" for numbers given).
    size : (int, int) or None
        (width, height) in px the intrinsics were calibrated at; frames of another size get
        them scaled. None: they are for the frames as read, whatever their size.
    sensor : str or None
        Sensor model profile of the segmentation (a camera profile names one), else None.
    profile : CameraProfile or None
        The named camera, when one was given.
    modes : tuple of ((int, int), Intrinsics)
        Intrinsics per frame size, when the source knows several (a profile, an Azure Kinect
        calibration): frames take the mode of their size, else the nearest one scaled.
    """

    intrinsics: Intrinsics
    source: str
    origin: str = ""
    size: tuple[int, int] | None = None
    sensor: str | None = None
    profile: CameraProfile | None = None
    modes: tuple[tuple[tuple[int, int], Intrinsics], ...] = ()
    _cache: dict[tuple[int, int], Intrinsics] = field(default_factory=dict, compare=False, repr=False)

    def for_size(self, size: tuple[int, int]) -> Intrinsics:
        """Return the intrinsics (px) for frames of ``size`` = (width, height) px."""
        found = self._cache.get(size)
        if found is None:
            if self.modes and self.source != "given":
                found = _fit(self.modes, size, f"the camera {self.origin}")
            elif self.size is None or self.size == size:
                found = self.intrinsics
            else:
                found = _fit(((self.size, self.intrinsics),), size, f"the calibration {self.origin}")
            self._cache[size] = found
        return found

    def with_intrinsics(self, intrinsics: Intrinsics) -> Camera:
        """Return the same camera (sensor model) with intrinsics given for the frames as read."""
        return Camera(intrinsics, "given", "", None, self.sensor, self.profile)  # no modes: for the frames as read


def as_intrinsics(value: object, where: str = "intrinsics") -> Intrinsics:
    """Return ``value`` (an :class:`Intrinsics` or four numbers fx, fy, cx, cy in px) as :class:`Intrinsics`.

    Raises
    ------
    InputError
        Not four finite numbers, or a focal length that is not positive.
    """
    if isinstance(value, Intrinsics):
        k = value
    else:
        try:
            nums = [float(v) for v in value]  # type: ignore[attr-defined]
        except (TypeError, ValueError):
            raise InputError(f"{where}: expected four numbers FX FY CX CY (px), got {value!r}") from None
        if len(nums) != 4:
            raise InputError(f"{where}: expected four numbers FX FY CX CY (px), got {len(nums)}")
        k = Intrinsics(*nums)
    vals = (k.fx, k.fy, k.cx, k.cy)
    if not all(math.isfinite(v) for v in vals) or k.fx <= 0 or k.fy <= 0:
        raise InputError(f"{where}: expected positive focal lengths and finite numbers (px), got {vals}")
    return k


def _matrix(values: object, where: Path, what: str) -> Intrinsics:
    try:
        m = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {what} is not a list of numbers") from None
    if m.size != 9:
        raise InputError(f"{where}: {what} has {m.size} numbers; expected the 9 of a 3x3 camera matrix")
    m = m.reshape(3, 3)
    if not (abs(m[2, 2] - 1.0) < 1e-6 and abs(m[1, 0]) < 1e-9 and abs(m[2, 0]) < 1e-9 and abs(m[2, 1]) < 1e-9):
        raise InputError(f"{where}: {what} is not a camera matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]]: {m.tolist()}")
    return as_intrinsics((m[0, 0], m[1, 1], m[0, 2], m[1, 2]), str(where))


def _size(w: object, h: object) -> tuple[int, int] | None:
    if isinstance(w, (int, float)) and isinstance(h, (int, float)) and w > 0 and h > 0:
        return int(w), int(h)
    return None


def _azure_json(d: dict[str, Any], path: Path) -> Camera:
    # the Azure Kinect's factory calibration (k4a's calibration.json): the depth camera D0
    cams = d["CalibrationInformation"].get("Cameras", [])
    depth = [c for c in cams if isinstance(c, dict) and c.get("Location") == "CALIBRATION_CameraLocationD0"]
    if not depth:
        raise InputError(f"{path}: no depth camera (CALIBRATION_CameraLocationD0) in this Azure Kinect calibration")
    try:
        cx, cy, fx, fy = (float(v) for v in depth[0]["Intrinsics"]["ModelParameters"][:4])
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{path}: the depth camera's Intrinsics.ModelParameters are not cx, cy, fx, fy") from None
    modes = azure_modes(cx, cy, fx, fy)
    return Camera(modes[0][1], "file", str(path), modes[0][0], "azure-kinect", None, modes)


def _from_json(path: Path) -> tuple[Intrinsics, tuple[int, int] | None] | Camera:
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read the JSON ({exc})") from None
    if isinstance(d, dict) and isinstance(d.get("CalibrationInformation"), dict):
        return _azure_json(d, path)
    if isinstance(d, dict) and "intrinsic_matrix" in d:
        # Open3D's PinholeCameraIntrinsic: the matrix column by column (Eigen's order)
        m = np.asarray(d["intrinsic_matrix"], dtype=float).reshape(-1)
        if m.size != 9:
            raise InputError(f"{path}: intrinsic_matrix has {m.size} numbers; expected 9")
        return _matrix(m.reshape(3, 3).T, path, "intrinsic_matrix"), _size(d.get("width"), d.get("height"))
    if isinstance(d, dict):
        for keys in (("fx", "fy", "cx", "cy"), ("fx", "fy", "x_offset", "y_offset")):
            if all(k in d for k in keys):
                return as_intrinsics([d[k] for k in keys], str(path)), _size(d.get("width"), d.get("height"))
    raise InputError(
        f"{path}: not a camera file this reads: expected an Open3D PinholeCameraIntrinsic JSON "
        "(width, height, intrinsic_matrix), an Azure Kinect calibration.json or fx, fy, cx, cy"
    )


def _opencv_yaml(path: Path) -> tuple[Intrinsics, tuple[int, int] | None]:
    import cv2

    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        if not fs.isOpened():
            raise InputError(f"{path}: OpenCV cannot read this calibration file")
        for name in ("camera_matrix", "cameraMatrix", "K", "intrinsic_matrix", "M1"):
            node = fs.getNode(name)
            if not node.empty():
                m = node.mat()
                if m is None:
                    raise InputError(f"{path}: {name} is not an OpenCV matrix")
                size = _size(fs.getNode("image_width").real(), fs.getNode("image_height").real())
                return _matrix(m, path, name), size
    finally:
        fs.release()
    raise InputError(f"{path}: no camera_matrix (or cameraMatrix, K) in this OpenCV calibration file")


def _plain_yaml(path: Path) -> tuple[Intrinsics, tuple[int, int] | None]:
    import yaml

    try:
        d = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f"{path}: cannot read the YAML ({exc})") from None
    if not isinstance(d, dict):
        raise InputError(f"{path}: expected a YAML mapping (camera_info, OpenCV or Kalibr calibration)")
    if isinstance(d.get("camera_matrix"), dict):
        # camera_calibration_parsers' camera_info YAML (ROS 1 and 2)
        return _matrix(d["camera_matrix"].get("data"), path, "camera_matrix"), _size(
            d.get("image_width"), d.get("image_height")
        )
    for key in ("k", "K"):
        if key in d:  # a CameraInfo message as `rostopic echo` / `ros2 topic echo` print it
            return _matrix(d[key], path, key), _size(d.get("width"), d.get("height"))
    cams = sorted(k for k, v in d.items() if isinstance(k, str) and k.startswith("cam") and isinstance(v, dict))
    if cams:
        # Kalibr's camchain: the first camera (cam0); intrinsics [fu, fv, pu, pv] for a pinhole model
        cam = d[cams[0]]
        model = cam.get("camera_model", "pinhole")
        if model != "pinhole":
            raise InputError(f"{path}: {cams[0]} has camera_model {model!r}; expected a pinhole camera")
        res = cam.get("resolution") or [None, None]
        return as_intrinsics(cam.get("intrinsics"), f"{path} {cams[0]}.intrinsics"), _size(res[0], res[1])
    raise InputError(
        f"{path}: no camera matrix found: expected a ROS camera_info YAML (camera_matrix, or K), "
        "an OpenCV calibration (%YAML:1.0, camera_matrix) or a Kalibr camchain (cam0: intrinsics)"
    )


def _text_matrix(path: Path) -> tuple[Intrinsics, tuple[int, int] | None]:
    try:
        m = np.loadtxt(path, dtype=float, ndmin=2)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: cannot read a 3x3 camera matrix ({exc})") from None
    if m.shape != (3, 3):
        raise InputError(f"{path}: expected a 3x3 camera matrix in text, got shape {m.shape}")
    return _matrix(m, path, "the matrix"), None


def load_camera_file(path: str | Path) -> Camera:
    """Read a calibration file: intrinsics (px) and, when it says, the image size they are for.

    Parameters
    ----------
    path : str or Path
        A ROS ``camera_info`` YAML (``camera_matrix`` of camera_calibration_parsers, or a dumped
        CameraInfo with ``K``/``k``); an OpenCV FileStorage YAML or XML (``camera_matrix``,
        ``image_width``); a Kalibr camchain YAML (``cam0``); an Open3D ``PinholeCameraIntrinsic``
        JSON; an Azure Kinect ``calibration.json`` (every depth mode, and its sensor model); a
        JSON with ``fx, fy, cx, cy``; or a 3x3 matrix in text (``.txt``).

    Returns
    -------
    Camera
        ``source="file"``; ``size`` when the file states it.

    Raises
    ------
    InputError
        A missing file, or one from which no pinhole camera matrix can be read.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such calibration file")
    suffix = p.suffix.lower()
    if suffix == ".json":
        found = _from_json(p)
        if isinstance(found, Camera):
            return found
        k, size = found
    elif suffix == ".xml":
        k, size = _opencv_yaml(p)
    elif suffix in (".yaml", ".yml"):
        try:
            head = p.read_text(errors="replace")[:4096]
        except OSError as exc:
            raise InputError(f"{p}: cannot read ({exc.strerror or exc})") from None
        # OpenCV's YAML 1.0 dialect (its %YAML:1.0 line and !!opencv-matrix tags) is not YAML
        # that PyYAML reads: OpenCV's own reader takes it
        k, size = _opencv_yaml(p) if head.startswith("%YAML:1.0") or "!!opencv-matrix" in head else _plain_yaml(p)
    else:
        k, size = _text_matrix(p)
    return Camera(k, "file", str(p), size)


def _profile_names() -> str:
    return ", ".join(sorted(PROFILES))


def resolve_camera(intrinsics: object = None, camera: object = None) -> Camera | None:
    """Turn the user's ``intrinsics`` and ``camera`` options into one :class:`Camera` (None: neither given).

    Parameters
    ----------
    intrinsics : Intrinsics or sequence of 4 float, optional
        fx, fy, cx, cy (px) for the frames as read; wins over the camera's intrinsics.
    camera : str, Path, Camera or CameraProfile, optional
        A profile name of :data:`PROFILES` or a calibration file (:func:`load_camera_file`).

    Raises
    ------
    InputError
        Unknown profile and no such file; an unreadable file; bad numbers.
    """
    cam: Camera | None = None
    if isinstance(camera, Camera):
        cam = camera
    elif isinstance(camera, CameraProfile):
        cam = Camera(
            camera.modes[0][1], "profile", camera.name, camera.modes[0][0], camera.sensor, camera, camera.modes
        )
    elif camera is not None:
        text = str(camera)
        prof = PROFILES.get(text.lower())
        if prof is not None:
            cam = resolve_camera(camera=prof)
        elif Path(text).is_file():
            cam = load_camera_file(text)
        else:
            raise InputError(
                f"--camera {text}: neither a calibration file nor a camera profile; profiles: {_profile_names()}"
            )
    if intrinsics is not None:
        k = as_intrinsics(intrinsics, "--intrinsics")
        cam = Camera(k, "given") if cam is None else cam.with_intrinsics(k)
    return cam


def camera_record(camera: Camera | None, size: tuple[int, int]) -> dict[str, Any]:
    """Return what JSON outputs say of a camera: intrinsics (px) for ``size``, source, origin, sensor."""
    if camera is None:
        return {"intrinsics": None, "source": None}
    k = camera.for_size(size)
    out: dict[str, Any] = {
        "intrinsics": {"fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy},
        "source": camera.source,
    }
    if camera.origin:
        out["from"] = camera.origin
    if camera.sensor:
        out["sensor"] = camera.sensor
    return out
