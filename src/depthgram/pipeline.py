"""The one path from frame to scene: segmentation, tree, tracks, plan (and sound on request).

The command line, the Python API, the batch runner and the viewer all run this code with the
same :class:`Config`, which loads from and saves to TOML.
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing
import time
import tomllib
import warnings
from collections import deque
from collections.abc import Iterable, Iterator, Mapping
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from depthgram.act import ActConfig, Plan
from depthgram.act import plan as plan_scene
from depthgram.dynamics import FramePixels, Tracker, TrackerConfig
from depthgram.dynamics import warm_up as warm_up_dynamics
from depthgram.errors import InputError
from depthgram.focal_length import CHECKED_SOURCES, FocalCheck, RecordingFocal
from depthgram.frame import Frame, Gravity, GravityWarning, Intrinsics, as_gravity
from depthgram.scene import TreeConfig, build_tree, to_sentence, tree_to_dict
from depthgram.scene.kinds import GravityKinds
from depthgram.scene.tree import Motion, SceneTree
from depthgram.segmentation import SegmentConfig, SensorModel, estimate_sensor, segment, sensor_model
from depthgram.segmentation import warm_up as warm_up_segmentation
from depthgram.segmentation.label import relabel
from depthgram.segmentation.objects import SceneObject, Segmentation
from depthgram.segmentation.orientation import default_intrinsics
from depthgram.sound import SoundMapping
from depthgram.sources.camera import Camera, IntrinsicsWarning, resolve_camera
from depthgram.sources.prefetch import prefetch
from depthgram.stills import kinship

__all__ = ["Config", "Pipeline", "SceneResult", "describe"]

_SECTIONS: dict[str, type] = {
    "segment": SegmentConfig,
    "tree": TreeConfig,
    "tracker": TrackerConfig,
    "act": ActConfig,
    "sound": SoundMapping,
}


@dataclass(frozen=True)
class Config:
    """Every stage's settings in one place; see each section's class for units and meaning.

    Sections: ``segment`` (:class:`depthgram.segmentation.SegmentConfig`), ``tree``
    (:class:`depthgram.scene.TreeConfig`), ``tracker`` (:class:`depthgram.dynamics.TrackerConfig`),
    ``act`` (:class:`depthgram.act.ActConfig`), ``sound`` (:class:`depthgram.sound.SoundMapping`).

    ``stills`` (top-level key) says whether the frames are unrelated still images: ``true``
    (never read motion between frames), ``false`` (one recording: always track) or ``"auto"``
    (the default: track, but not across two frames with nothing in common, see
    :func:`depthgram.stills.kinship`).
    """

    segment: SegmentConfig = field(default_factory=SegmentConfig)
    tree: TreeConfig = field(default_factory=TreeConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    act: ActConfig = field(default_factory=ActConfig)
    sound: SoundMapping = field(default_factory=SoundMapping)
    stills: bool | str = "auto"

    def __post_init__(self) -> None:
        if self.stills not in (True, False, "auto"):
            raise InputError(f'config: stills must be true, false or "auto", got {self.stills!r}')

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict (TOML-ready: no None values)."""
        out: dict[str, Any] = {"stills": self.stills}
        for name in _SECTIONS:
            section = dataclasses.asdict(getattr(self, name))
            out[name] = {k: _toml_value(v) for k, v in section.items() if v is not None}
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, where: str = "config") -> Config:
        """Build from a nested dict; unknown sections or keys are errors, not silently dropped."""
        data = dict(data)
        stills = data.pop("stills", "auto")
        unknown = set(data) - set(_SECTIONS)
        if unknown:
            raise InputError(f"{where}: unknown section(s) {sorted(unknown)}; expected {sorted(_SECTIONS)}")
        kwargs: dict[str, Any] = {}
        for name, klass in _SECTIONS.items():
            values = data.get(name, {})
            if not isinstance(values, Mapping):
                raise InputError(f"{where}: [{name}] must be a table of settings")
            kwargs[name] = _build_section(klass, values, f"{where} [{name}]")
        try:
            return cls(**kwargs, stills=stills)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None

    @classmethod
    def load(cls, path: str | Path) -> Config:
        """Read a TOML file written by :meth:`save` or by hand (missing keys keep their defaults)."""
        p = Path(path)
        try:
            data = tomllib.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(f"{p}: config file not found") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"{p}: not valid TOML: {exc}") from None
        return cls.from_dict(data, where=str(p))

    def dumps(self) -> str:
        """Return the configuration as TOML text."""
        import tomli_w

        return tomli_w.dumps(self.to_dict())

    def save(self, path: str | Path) -> None:
        """Write the configuration as TOML."""
        Path(path).write_text(self.dumps(), encoding="utf-8")

    def replace(self, **sections: Mapping[str, Any]) -> Config:
        """Return a copy with some settings changed, e.g. ``cfg.replace(segment={"min_area": 50})``."""
        data = self.to_dict()
        for name, values in sections.items():
            if name not in _SECTIONS:
                raise InputError(f"unknown config section {name!r}; expected {sorted(_SECTIONS)}")
            data[name] = {**data[name], **dict(values)}
        return Config.from_dict(data)

    def with_stills(self, stills: bool | str) -> Config:
        """Return a copy with the ``stills`` setting changed."""
        return dataclasses.replace(self, stills=stills)


def _toml_value(v: Any) -> Any:
    if isinstance(v, tuple):
        return [_toml_value(x) for x in v]
    if isinstance(v, dict):
        return {k: _toml_value(x) for k, x in v.items() if x is not None}
    return v


def _build_section(klass: type, values: Mapping[str, Any], where: str) -> Any:
    # A section that knows more than its fields (the sound mapping's ``preset``) builds itself.
    own = getattr(klass, "from_dict", None)
    fields = {f.name: f for f in dataclasses.fields(klass)}
    unknown = set(values) - set(fields)
    if unknown and own is None:
        raise InputError(f"{where}: unknown setting(s) {sorted(unknown)}; known: {sorted(fields)}")
    default = klass()
    kwargs: dict[str, Any] = {}
    for k, v in values.items():
        # TOML has arrays, not tuples: give tuple-typed fields their tuple back.
        if isinstance(v, list) and isinstance(getattr(default, k, None), tuple):
            v = tuple(tuple(x) if isinstance(x, list) else x for x in v)
        if k in fields:
            _check_type(k, v, getattr(default, k), where)
        kwargs[k] = v
    try:
        return own(kwargs) if own is not None else klass(**kwargs)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise InputError(f"{where}: {exc}") from None


def _check_type(name: str, value: Any, default: Any, where: str) -> None:
    """Refuse a setting whose kind differs from its default's (issue 18.9).

    Python's truth rules made ``relations = "false"`` true, ``bin_mm = true`` a width of 1 and
    a string in a numeric field a raw TypeError deep in a stage; the stages' own checks see
    only the values. A field whose default is None (optional) is left to its stage.
    """
    if isinstance(default, bool):
        ok, expected = isinstance(value, bool), "true or false"
    elif isinstance(default, int):
        ok, expected = isinstance(value, int) and not isinstance(value, bool), "an integer"
    elif isinstance(default, float):
        ok, expected = isinstance(value, (int, float)) and not isinstance(value, bool), "a number"
    elif isinstance(default, str):
        ok, expected = isinstance(value, str), "a string"
    elif isinstance(default, tuple):
        ok, expected = isinstance(value, tuple), "an array"
    else:
        return
    if not ok:
        raise InputError(f"{where}: {name} = {value!r} ({type(value).__name__}), expected {expected}")


@dataclass(frozen=True, eq=False)
class SceneResult:
    """Everything the pipeline knows about one frame.

    Object ids are track ids when the pipeline tracks (sequences), so the same object keeps
    its id, and its pixel value in ``segmentation.labels``, from frame to frame.
    """

    frame: Frame
    segmentation: Segmentation
    tree: SceneTree
    motions: Mapping[int, Motion]
    occluded: tuple[tuple[SceneObject, Motion], ...]
    plan: Plan
    latency_s: float
    #: Why this frame was taken as a still unrelated to the previous one (no motion read into
    #: it; ids start again): the ``stills`` setting or what the data showed. Empty otherwise.
    still: str = ""
    #: The intrinsics the frame was segmented with and where they came from, and the sensor model
    #: (:meth:`Pipeline.camera_record`): on the first frame of a run, and wherever they change.
    camera: Mapping[str, Any] | None = None
    #: Gravity estimated from the scene (source ``estimated``) where the frame carries none: the
    #: supports' kinds were named by it.
    gravity_estimate: Gravity | None = None

    @property
    def sentence(self) -> str:
        """The scene as one sentence of the grammar."""
        return to_sentence(self.tree)

    def to_record(self) -> dict[str, Any]:
        """Return the JSON line of ``depthgram describe``."""
        f = self.frame
        tree = tree_to_dict(self.tree)
        nodes = {n["id"]: n for n in tree["nodes"]}
        objects = [_object_record(o, nodes.get(o.id, {}), self.motions.get(o.id)) for o in self.segmentation.objects]
        occluded = [_object_record(o, {}, m) for o, m in self.occluded]
        rec: dict[str, Any] = {
            "frame": f.index,
            "time_s": f.time_s,
            "source": f.name,
            "size": list(f.size),
            "unit": "mm",
        }
        if self.camera is not None:
            rec["camera"] = dict(self.camera)
        if f.gravity is not None:
            rec["gravity"] = f.gravity.to_dict()
        elif self.gravity_estimate is not None:
            rec["gravity"] = self.gravity_estimate.to_dict()
        return rec | {
            "objects": objects,
            "occluded": occluded,
            "relations": tree["relations"],
            "sentence": self.sentence,
        }


def _clean(v: float | None, nd: int = 2) -> float | None:
    if v is None or not math.isfinite(v):
        return None
    return round(float(v), nd)


def _object_record(o: SceneObject, node: Mapping[str, Any], m: Motion | None) -> dict[str, Any]:
    rec: dict[str, Any] = {
        "id": o.id,
        "kind": o.kind,
        "depth_label": o.depth_label,
        "depth": _clean(o.depth, 1),
        "depth_std": _clean(o.depth_std, 1),
        "area": o.area,
        "area_fraction": _clean(o.area_fraction, 5),
        "center_xy": [_clean(o.center_xy[0]), _clean(o.center_xy[1])],
        "bbox_xy": list(o.bbox_xy),
        "centroid_mm": None if o.centroid_mm is None else [_clean(c, 1) for c in o.centroid_mm],
        "area_mm2": _clean(o.area_mm2, 0),
        "parent": node.get("parent"),
        "children": node.get("children", []),
        "parts": [
            {
                "depth_label": p.depth_label,
                "depth": _clean(p.depth, 1),
                "area": p.area,
                "center_xy": [_clean(c) for c in p.center_xy],
            }
            for p in o.parts
        ],
    }
    if m is not None:
        rec["v_radial"] = _clean(m.v_radial)
        rec["v_unit"] = "mm/s"
        rec["v_sigma"] = _clean(m.v_sigma)
        rec["ttc"] = _clean(m.ttc, 3)
        if m.fps_assumed is not None:  # no timestamps and no --fps: the rate v and ttc rest on
            rec["fps_assumed"] = m.fps_assumed
        rec["status"] = m.status
    return rec


#: Frames between two estimates of the sensor model in a stream.
_SENSOR_EVERY = 30
#: Unrelated successive pairs that, once they are at least half of the pairs seen, make a source
#: without timestamps a folder of stills (:meth:`Pipeline._still_reason`).
_STILLS_EVIDENCE = 2


class Pipeline:
    """Frame in, scene out.

    Parameters
    ----------
    config : Config, optional
        All stage settings; defaults when omitted.
    track : bool
        Track objects across frames (range flow). False is the same as the config's
        ``stills = true``: unrelated still images, ids restart at 1 and no velocity is read
        between different scenes. With ``stills = "auto"`` (the default) the tracks are
        dropped wherever two successive frames have nothing in common
        (:func:`depthgram.stills.kinship`); a source without timestamps whose unrelated pairs
        come as often as related ones (two at least) is taken for a folder of stills from then on.

    intrinsics : Intrinsics or (fx, fy, cx, cy), optional
        Pinhole intrinsics (px) of the frames, overriding theirs (``--intrinsics``).
    camera : str or path, optional
        A calibration file or a camera profile (``--camera``;
        :func:`depthgram.sources.camera.resolve_camera`), overriding the frames' intrinsics; a
        profile also names the sensor model when the configuration's is ``auto``.
    gravity : Gravity or (x, y, z), optional
        Which way is down in camera coordinates (``--gravity``), put on every frame.
    tilt_deg : float, optional
        The camera looks down by this many degrees (``--tilt``), instead of ``gravity``.
    check_intrinsics : bool
        Hold intrinsics a person chose (given, a calibration file or sidecar, a profile) against
        the focal length the scene shows (:class:`depthgram.focal_length.FocalCheck`): more
        than 1.4 times off, the scene's wins, with a warning. False (``--trust-intrinsics``)
        uses them as they are.

    Frames without intrinsics take the focal length their scene shows, else a guess (a 64-degree
    field of view), with an :class:`~depthgram.sources.camera.IntrinsicsWarning` naming the
    options that tell the camera.

    Examples
    --------
    >>> from depthgram import Pipeline, read
    >>> pipe = Pipeline()
    >>> for result in pipe.run(read("sim:approach?frames=10")):  # doctest: +SKIP
    ...     print(result.sentence)
    """

    def __init__(
        self,
        config: Config | None = None,
        *,
        track: bool = True,
        intrinsics: Intrinsics | tuple[float, float, float, float] | None = None,
        camera: str | Path | Camera | None = None,
        gravity: Gravity | tuple[float, float, float] | None = None,
        tilt_deg: float | None = None,
        check_intrinsics: bool = True,
    ) -> None:
        self.config = config or Config()
        self.check_intrinsics = check_intrinsics
        self.track = track
        self.camera = resolve_camera(intrinsics, camera)
        self.gravity = as_gravity(gravity, tilt_deg)
        self._said_camera: dict[str, Any] | None = None  # the camera record last given in a result
        self._warned_guess = False
        self._warned_gravity = False
        self._warned_estimate = False
        self._focal = RecordingFocal()  # the focal length read from the scene, once found
        self._focal_check = FocalCheck()  # the user's intrinsics against the scene
        self._tracker = Tracker(self.config.tracker)
        self._where = ""
        self._sensor: SensorModel | None = None
        self._sensor_age = 0
        self._prev: Frame | None = None
        self._untimed_stills = ""  # the reason, once an untimed source is taken for stills
        self._untimed_pairs = [0, 0]  # untimed successive pairs seen, and how many were unrelated
        self._motion_thread: ThreadPoolExecutor | None = None  # made on first use
        self._kinds = GravityKinds()  # the supports' kinds by gravity, given or estimated

    def reset(self) -> None:
        """Forget all tracks and the sensor estimate (start of a new recording)."""
        self._tracker = Tracker(self.config.tracker)
        self._sensor = None
        self._prev = None
        self._untimed_stills = ""
        self._untimed_pairs = [0, 0]
        self._said_camera = None
        self._focal = RecordingFocal()
        self._focal_check = FocalCheck()
        self._kinds = GravityKinds()

    def _calibrated(self, frame: Frame) -> Frame:
        """Return ``frame`` with this pipeline's camera and gravity; warn once when its intrinsics are a guess."""
        cam, changes = self.camera, {}
        if cam is not None:
            meta = {**frame.meta, "intrinsics_from": cam.origin} if cam.origin else dict(frame.meta)
            if cam.sensor:
                meta["sensor_profile"] = cam.sensor
            changes = {"intrinsics": cam.for_size(frame.size), "intrinsics_source": cam.source, "meta": meta}
        if self.gravity is not None:
            changes["gravity"] = self.gravity
        if changes:
            frame = dataclasses.replace(frame, **changes)  # type: ignore[arg-type]
        if self.check_intrinsics and frame.intrinsics is not None and frame.intrinsics_source in CHECKED_SOURCES:
            frame = self._checked(frame, frame.intrinsics)
        if frame.intrinsics is None:
            k = self._scene_focal(frame)
            if k is not None:
                return dataclasses.replace(frame, intrinsics=k, intrinsics_source="estimated")
        if frame.intrinsics is None and not self._warned_guess:
            self._warned_guess = True
            k = default_intrinsics(frame.shape)
            warnings.warn(
                f"{frame.name or f'frame {frame.index}'}: no camera intrinsics, and the scene does not show its "
                f"focal length (no support seen at an angle with surfaces square to it): guessed fx = fy = "
                f"{k.fx:.0f} px (a 64-degree field of view); tell the camera with --intrinsics FX FY CX CY or "
                "--camera FILE|PROFILE (in Python: intrinsics= or camera=)",
                IntrinsicsWarning,
                stacklevel=2,
            )
        return frame

    def _checked(self, frame: Frame, given: Intrinsics) -> Frame:
        """Return ``frame`` with the scene's focal length where it overrules the user's; warn when it does."""
        k, overruled = self._focal_check.read(frame.depth, frame.valid, given)
        if overruled is not None:
            origin = frame.meta.get("intrinsics_from") or {"given": "--intrinsics"}.get(frame.intrinsics_source, "")
            warnings.warn(
                f"{frame.name or f'frame {frame.index}'}: the camera's intrinsics ({frame.intrinsics_source}"
                f"{f', {origin}' if origin else ''}: fx = {given.fx:.0f}, fy = {given.fy:.0f} px) disagree with the "
                f"scene: the right angles between a support seen {overruled.tilt_deg:.0f} degrees from face-on and "
                f"what rises from it say fx = fy = {overruled.intrinsics.fx:.0f} px ({k.fx / given.fx:.2f} times "
                "theirs; are they for another camera or resolution?); using the scene's focal length. If yours are "
                "right, pass --trust-intrinsics (in Python: Pipeline(check_intrinsics=False))",
                IntrinsicsWarning,
                stacklevel=3,
            )
        if k is given:
            return frame
        overruling = f"the scene (overruling {frame.intrinsics_source} fx = {given.fx:.0f} px)"
        meta = {**frame.meta, "intrinsics_from": overruling}
        return dataclasses.replace(frame, intrinsics=k, intrinsics_source="estimated", meta=meta)

    def _scene_focal(self, frame: Frame) -> Intrinsics | None:
        """Return the intrinsics read from the scene for a frame without any; tell the user once."""
        k, found = self._focal.read(frame.depth, frame.valid)
        if found is not None and not self._warned_estimate:
            self._warned_estimate = True
            warnings.warn(
                f"{frame.name or f'frame {frame.index}'}: no camera intrinsics: estimated fx = fy = "
                f"{found.intrinsics.fx:.0f} px from the scene (the right angles between a support seen "
                f"{found.tilt_deg:.0f} degrees from face-on and what rises from it; principal point at "
                "the centre); tell the camera with --intrinsics FX FY CX CY or --camera FILE|PROFILE "
                "(in Python: intrinsics= or camera=) to be sure",
                IntrinsicsWarning,
                stacklevel=3,
            )
        return k

    def camera_record(self, frame: Frame) -> dict[str, Any]:
        """Return what the JSON says of the camera of ``frame``: intrinsics (px), where from, sensor model.

        ``source`` is one of :data:`depthgram.sources.camera.INTRINSICS_SOURCES`: ``guessed``
        (with the guess the segmentation used) when the frame has no intrinsics.
        """
        k = frame.intrinsics
        source = frame.intrinsics_source or "given"
        if k is None:
            k, source = default_intrinsics(frame.shape), "guessed"
        rec: dict[str, Any] = {
            "intrinsics": {"fx": round(k.fx, 3), "fy": round(k.fy, 3), "cx": round(k.cx, 3), "cy": round(k.cy, 3)},
            "intrinsics_source": source,
        }
        origin = frame.meta.get("intrinsics_from")
        if origin:
            rec["intrinsics_from"] = str(origin)
        seg = self.config.segment
        hint = frame.meta.get("sensor_profile")
        if seg.sensor != "auto":
            rec["sensor"], rec["sensor_source"] = seg.sensor, "config"
        elif hint and seg.method == "surfaces":
            rec["sensor"], rec["sensor_source"] = str(hint), "profile"
        else:
            rec["sensor"], rec["sensor_source"] = "auto", "estimated"
        return rec

    def _still_reason(self, frame: Frame) -> str:
        """Why ``frame`` must not be tracked from the previous one ("" when it may)."""
        prev, self._prev = self._prev, frame
        stills = self.config.stills
        if not self.track or stills is True:
            return "stills setting"
        if stills is False or prev is None:
            return ""
        if self._untimed_stills and frame.time_s is None:
            return self._untimed_stills
        kin = kinship(prev, frame)
        if frame.time_s is None:
            self._untimed_pairs[0] += 1
            self._untimed_pairs[1] += not kin.related
        if kin.related:
            return ""
        reason = f"{prev.name} and {frame.name} have nothing in common: {kin.reason}"
        seen, unrelated = self._untimed_pairs
        # One unrelated pair in a long recording is a glitch (a fast turn, a dropped frame): its
        # tracks restart there. Unrelated pairs as often as related ones make a folder of stills,
        # and a tracker that waits for related pairs there would read motion between pictures.
        if frame.time_s is None and unrelated >= _STILLS_EVIDENCE and 2 * unrelated >= seen:
            self._untimed_stills = (
                f"a folder of stills ({unrelated} of its first {seen} frame pairs unrelated; {reason})"
            )
        return reason

    def _sensor_model(self, frame: Frame) -> SensorModel | None:
        """Return the camera's sensor model, estimated from the stream every ``_SENSOR_EVERY`` frames.

        A camera's depth step and noise do not change from frame to frame, while estimating
        them costs a fair share of a frame's segmentation (docs/design-notes.md).
        """
        seg = self.config.segment
        if seg.method != "surfaces" or seg.sensor != "auto":
            return None
        named = self._named_sensor(frame)
        if named is not None:
            return named  # a named camera's model: as if the configuration named it
        if self._sensor is None or self._sensor_age >= _SENSOR_EVERY:
            self._sensor = estimate_sensor(frame.depth, frame.valid)
            self._sensor_age = 0
        self._sensor_age += 1
        return self._sensor

    def _named_sensor(self, frame: Frame) -> SensorModel | None:
        """Return the camera's model by name: the config's ``sensor``, else the frame's camera profile, else None."""
        if self.config.segment.sensor != "auto":
            return sensor_model(self.config.segment.sensor)
        hint = frame.meta.get("sensor_profile")
        return sensor_model(hint) if isinstance(hint, str) else None

    def _known_sensor(self, frame: Frame) -> SensorModel | None:
        """Return the sensor model this frame was segmented with, when known (named, or the stream's last estimate)."""
        return self._named_sensor(frame) or self._sensor

    def warm_up(self, frame: Frame) -> float:
        """Run ``frame`` through a throwaway copy of this pipeline; return the time it took (s).

        The first frame of a process loads the compiled kernels from numba's cache and the
        stages' lazy imports, which takes a few hundred milliseconds. Calling this before a
        live stream starts keeps that out of the first frame's latency; this pipeline's
        tracks are not touched. A real-time loop may then call ``gc.freeze()``, as
        ``depthgram run`` does: Python's full collections then skip everything loaded so far,
        which otherwise stalls a frame now and then (docs/design-notes.md).
        """
        t0 = time.perf_counter()
        throwaway = Pipeline(self.config, track=self.track)
        throwaway.camera, throwaway.gravity = self.camera, self.gravity
        throwaway._warned_guess = throwaway._warned_estimate = True
        throwaway.process(frame)
        # A second frame, so that the tracker reads motion (its core's kernel) here too.
        later = None if frame.time_s is None else frame.time_s + 1.0 / 30.0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the throwaway tracker's note on a missing frame rate
            throwaway.process(dataclasses.replace(frame, index=frame.index + 1, time_s=later))
            # Then every track of it ends, so that the kernels of ending tracks load too (on a
            # fresh install they compiled at frame 1 of a 7-Scenes run: 660 ms).
            for k in range(throwaway._tracker.config.max_missed + 2):
                t = None if later is None else later + (k + 1) / 30.0
                throwaway._tracker.update((), t, frame.size)
        # Kernels that only rare branches of the segmentation reach compiled, on a fresh install,
        # at the first frame taking them: 470 ms in the middle of a 7-Scenes stream.
        warm_up_segmentation()
        warm_up_dynamics()
        return time.perf_counter() - t0

    def process(self, frame: Frame) -> SceneResult:
        """Segment one frame, build its tree, update tracks and plan actions."""
        # the thread beside has found this frame's image motion by the time the tracker reads
        # the cores, and would idle: it reads half of them
        return self._describe(*self._segmented(frame), helper=self._beside())

    def _segmented(self, frame: Frame) -> tuple[Frame, Segmentation, float, Future[None] | None]:
        """Segment ``frame`` with its image motion started beside: what :meth:`_describe` takes."""
        t0 = time.perf_counter()
        frame = self._calibrated(frame)
        args = _segment_args(frame, self.config.segment, self._sensor_model(frame))
        motion = self._prepare_motion(frame)
        return frame, _segment(*args), t0, motion

    def _prepare_motion(self, frame: Frame) -> Future[None] | None:
        """Start the tracker's image motion of ``frame`` in a thread beside its segmentation.

        The camera's motion (ICP) and the frame's shift need the depth alone, and both release
        the GIL for most of their time, as do the segmentation's compiled kernels (``nogil``):
        on 2 cores the two overlap (docs/design-notes.md, the real-time loop). None when no
        motion will be read from this frame's pixels.
        """
        cfg = self.config
        if not self.track or cfg.stills is True or cfg.tracker.depth_from != "core":
            return None
        # the tracker is looked up when the task runs: in :meth:`run` the previous frame's
        # description, queued before it on the same thread, may start a new tracker (a still)
        return self._beside().submit(lambda: self._tracker.prepare(frame.depth, frame.intrinsics))

    def _beside(self) -> ThreadPoolExecutor:
        """Return the thread beside the caller's: image motion, and in :meth:`run` the descriptions.

        One thread, so its tasks run in the order they were given.
        """
        if self._motion_thread is None:
            self._motion_thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="depthgram-motion")
        return self._motion_thread

    def _describe(
        self,
        frame: Frame,
        seg: Segmentation,
        t0: float,
        motion: Future[None] | None,
        helper: ThreadPoolExecutor | None = None,
    ) -> SceneResult:
        """Everything after the segmentation, in frame order: tracks, tree, plan.

        ``motion`` is the tracker's image motion of this frame being found (:meth:`_prepare_motion`);
        ``helper`` a thread for the tracker's core reading, never the one this runs on.
        """
        if motion is not None:
            motion.result()
        cfg = self.config
        motions: dict[int, Motion] = {}
        occluded: tuple[tuple[SceneObject, Motion], ...] = ()
        still = self._still_reason(frame)
        if still and self.track and self.config.stills is not True:
            self._tracker = Tracker(self.config.tracker)  # nothing carries over to the next frames
        if not still:
            # the pixels let the tracker read each object's depth change from its core
            use_core = cfg.tracker.depth_from == "core"
            pixels = FramePixels(frame.depth, seg.labels, frame.intrinsics) if use_core else None
            try:
                update = self._tracker.update(seg.objects, frame.time_s, frame.size, pixels, helper=helper)
            except InputError as exc:
                # the tracker's words ("tracker frame 1: time_s ... not after ...") name neither
                # the recording nor the frame (issue 32.2: a damaged bag's stamps)
                where = f"{self._where} " if self._where else ""
                raise InputError(f"{where}(frame {frame.index}, {frame.name}): {exc}") from None
            seg = _relabel(seg, {oid: m.track_id for oid, m in update.motions.items()})
            motions = {m.track_id: m for m in update.motions.values()}
            occluded = tuple((dataclasses.replace(t.last, id=t.id), _occluded_motion(t)) for t in update.occluded)
        # the supports' kinds by gravity, after the tracker (which reads the segmentation's own
        # kinds: a compound's depth is its nearest part's), before the tree and the plan
        down = frame.gravity.vector if frame.gravity is not None else None
        cam = frame.intrinsics or default_intrinsics(frame.depth.shape)
        seg = self._kinds(seg, frame.depth, cam, down, related=not still, sensor=self._known_sensor(frame))
        estimate = None if self._kinds.estimated is None else Gravity(tuple(self._kinds.estimated), "estimated")
        if estimate is not None and not self._warned_gravity:
            self._warned_gravity = True
            warnings.warn(
                f"{frame.name or f'frame {frame.index}'}: no gravity given: estimated from the scene's supports "
                f"(the camera looks {estimate.tilt_deg:.0f} degrees down); the floor, table tops, walls and "
                "ceiling are named by it. Give it with --gravity X Y Z or --tilt DEG (in Python: gravity= or "
                "tilt_deg=) to be sure",
                GravityWarning,
                stacklevel=2,
            )
        tree = build_tree(seg.objects, frame.size, motion=motions or None, config=cfg.tree, labels=seg.labels)
        action_plan = plan_scene(tree, frame, config=cfg.act)
        camera: dict[str, Any] | None = self.camera_record(frame)
        if camera == self._said_camera:
            camera = None
        else:
            self._said_camera = camera
        return SceneResult(
            frame=frame,
            segmentation=seg,
            tree=tree,
            motions=motions,
            occluded=occluded,
            plan=action_plan,
            latency_s=time.perf_counter() - t0,
            still=still,
            camera=camera,
            gravity_estimate=estimate,
        )

    def run(self, frames: Iterable[Frame], *, read_ahead: int = 2, workers: int = 1) -> Iterator[SceneResult]:
        """Process frames one at a time (memory stays flat however long the recording).

        ``read_ahead`` frames are read (decoded) in a background thread while the pipeline
        works, as a sensor delivers them; 0 reads on the caller's thread, as does a live camera
        (a source with ``live`` true), whose queued frames would be stale. Frames that depend on
        earlier results (a closed loop, e.g. a simulator steered by the plan) need 0: up to
        ``read_ahead + 1`` frames are made before the result of the current one is known. Why,
        and what it gained: docs/design-notes.md (the real-time loop).

        ``workers`` > 1 segments that many frames at once in worker processes (the
        segmentation of a frame needs nothing from the others: the sensor model is estimated
        here and sent along), while this process tracks, builds the trees and plans, in frame
        order. The results are the same as with one; throughput grows with the cores, latency
        does not fall (docs/design-notes.md). At most ``workers + 1`` frames are in flight.
        """
        if workers < 1:
            raise InputError(f"pipeline: workers must be >= 1, got {workers}")
        self._where = getattr(frames, "name", "") or ""  # named in the tracker's errors
        if workers > 1:
            yield from self._run_parallel(prefetch(frames, ahead=read_ahead), workers)
        elif read_ahead == 0 or getattr(frames, "live", False):
            # a frame's result is due before the next frame is taken
            for frame in prefetch(frames, ahead=read_ahead):
                yield self.process(frame)
        else:
            yield from self._run_overlapped(prefetch(frames, ahead=read_ahead))

    def _run_overlapped(self, frames: Iterator[Frame]) -> Iterator[SceneResult]:
        """:meth:`run` of a recording: each frame described (tracks, tree, plan) beside the next one's segmentation.

        The description runs on the thread beside (:meth:`_beside`), after the frame's image
        motion and before the next frame's, so the tracker sees the frames in order and the
        results are those of :meth:`process`. A result is given once the next frame is
        segmented: for a recording read ahead, not for a live camera, whose results would wait
        for its next frame (:meth:`run` takes this route only for frames read ahead).
        """
        pending: Future[SceneResult] | None = None
        try:
            for frame in frames:
                segmented = self._segmented(frame)
                if pending is not None:
                    # cleared first: a description that failed is raised once, not again below
                    done, pending = pending, None
                    yield done.result()
                pending = self._beside().submit(self._describe, *segmented)
        except Exception:
            # a frame that cannot be read or segmented: the frame before it is still given,
            # as one frame at a time would have given it, before the error
            if pending is not None:
                done, pending = pending, None
                yield done.result()
            raise
        finally:
            if pending is not None and not pending.done():
                # closed early: the description in flight still owns the tracker
                pending.exception()
        if pending is not None:
            yield pending.result()

    def _run_parallel(self, frames: Iterator[Frame], workers: int) -> Iterator[SceneResult]:
        """:meth:`run` with the segmentation in ``workers`` processes."""
        # forkserver: a fork of a process with threads running (the reader) may copy a held
        # lock; spawn would import depthgram again in every worker. The server imports it once.
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["depthgram.pipeline"])
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx)
        pending: deque[tuple[Frame, Future[Segmentation], float]] = deque()
        try:
            for raw in frames:
                frame = self._calibrated(raw)
                args = _segment_args(frame, self.config.segment, self._sensor_model(frame))
                pending.append((frame, pool.submit(_segment, *args, True), time.perf_counter()))
                if len(pending) > workers:
                    yield self._finish(*pending.popleft())
            while pending:
                yield self._finish(*pending.popleft())
        finally:
            pool.shutdown(wait=True, cancel_futures=True)

    def _finish(self, frame: Frame, segmented: Future[Segmentation], t0: float) -> SceneResult:
        """:meth:`_describe` a frame segmented by a worker, its image motion found meanwhile."""
        motion = self._prepare_motion(frame)
        return self._describe(frame, segmented.result(), t0, motion, helper=self._beside())


def _segment_args(
    frame: Frame, config: SegmentConfig, sensor: SensorModel | None
) -> tuple[NDArray[np.floating], NDArray[np.bool_], Intrinsics | None, SegmentConfig, SensorModel | None]:
    """Return the arguments of :func:`_segment` for one frame: what a worker process needs of it."""
    return (frame.depth, frame.valid, frame.intrinsics, config, sensor)


def _segment(
    depth: NDArray[np.floating],
    valid: NDArray[np.bool_],
    intrinsics: Intrinsics | None,
    config: SegmentConfig,
    sensor: SensorModel | None,
    copy: bool = False,
) -> Segmentation:
    """Segment one frame; module level, so that a worker process can run it.

    A worker passes ``copy``: an unpickled array lies inside the message's bytes, aligned
    differently from one numpy allocates; numpy's vectorised sums then add in another order
    and an object's mean depth differed in its last bit from the same frame segmented in the
    main process (seen as 0.1 mm/s in one printed velocity in 100 frames of 7-Scenes). A copy
    is allocated as the main process's arrays are.
    """
    if copy:
        depth, valid = np.array(depth), np.array(valid)
    return segment(depth, valid=valid, intrinsics=intrinsics, config=config, sensor=sensor)


def _occluded_motion(track: Any) -> Motion:
    m = getattr(track, "motion", None)
    if isinstance(m, Motion):
        return dataclasses.replace(m, status="occluded")
    return Motion(track_id=int(track.id), status="occluded")


def _relabel(seg: Segmentation, new_ids: Mapping[int, int]) -> Segmentation:
    """Give objects (and their pixels) their track ids."""
    if not new_ids or all(k == v for k, v in new_ids.items()):
        return seg
    top = max(max(new_ids), int(seg.labels.max(initial=0)))
    lut: NDArray[np.int32] = np.zeros(top + 1, np.int32)
    for old, new in new_ids.items():
        lut[old] = new
    objects = tuple(
        sorted((dataclasses.replace(o, id=new_ids.get(o.id, o.id)) for o in seg.objects), key=lambda o: o.id)
    )
    # the compiled pass, not numpy's lut[labels] gather (docs/design-notes.md)
    return dataclasses.replace(seg, labels=relabel(seg.labels, lut), objects=objects)


def describe(
    depth_mm: Any,
    *,
    intrinsics: Any = None,
    config: Config | None = None,
) -> SceneResult:
    """Describe one depth image (mm; 0 or NaN invalid): objects, tree, sentence and plan.

    A convenience for a single still; use :class:`Pipeline` for sequences (range flow).

    Parameters
    ----------
    depth_mm : ndarray, shape (H, W), or Frame
        Depth (mm), or a :class:`~depthgram.frame.Frame` from :func:`depthgram.read`, whose
        validity mask and intrinsics are used (``intrinsics`` overrides them). A bare array
        that cannot be millimetres warns (:class:`~depthgram.frame.UnitsWarning`).
    intrinsics : Intrinsics, optional
        Camera intrinsics (px).
    config : Config, optional
        Settings; defaults when omitted.
    """
    import dataclasses

    from depthgram.frame import Frame, make_frame

    if isinstance(depth_mm, Frame):
        frame = (
            depth_mm
            if intrinsics is None
            else dataclasses.replace(depth_mm, intrinsics=intrinsics, intrinsics_source="given")
        )
    else:
        frame = make_frame(depth_mm, intrinsics=intrinsics, name="array")
    return Pipeline(config, track=False).process(frame)
