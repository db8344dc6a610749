"""Simulated ToF and structured-light frames of named scenes, with per-pixel and per-object ground truth."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError
from depthgram.frame import Frame, Gravity
from depthgram.sensor import structured
from depthgram.sensor.geometry import cast_times, static_hits
from depthgram.sensor.scenes import SceneSpec, build_scene
from depthgram.sensor.structured import StructuredLightConfig
from depthgram.sensor.tof import (
    REFERENCE_INTEGRATION_S,
    ToFConfig,
    amplitude_e,
    correlation_samples,
    measure,
    quantize,
    sample_noise,
)

__all__ = ["MAX_PIXELS", "SENSORS", "SimFrame", "TruthObject", "sensor_name", "simulate"]

#: Sensor names :func:`simulate` takes, with their aliases.
SENSORS: dict[str, str] = {
    "tof": "tof",
    "structured-light": "structured-light",
    "structured_light": "structured-light",
    "sl": "structured-light",
}

#: Largest image simulated (pixels): 4096 x 4096.
MAX_PIXELS = 4096 * 4096


@dataclass(frozen=True)
class TruthObject:
    """Ground truth of one body visible in a simulated frame.

    Attributes
    ----------
    id : int
        Instance id: the value of its pixels in :attr:`SimFrame.instances`.
    name : str
        "cup", "table", "floor", "left_wall", "hand", ...
    kind : str
        "object", "floor", "wall" or "ceiling" (a table top is an "object").
    area : int
        Visible pixels: those of the instance map with a valid measured depth.
    center_xy : tuple of float
        (x, y) mean column and row of those pixels (px).
    depth : float
        Mean true depth along the optical axis of those pixels (mm).
    v_radial : float
        True radial velocity (mm/s), positive receding: the body's velocity projected on the
        optical axis, computed analytically from its pose velocity. For a rigidly
        translating body this is the rate of change of the depth of every surface point,
        hence of its mean visible depth as long as the set of visible surface points stays
        the same (occlusion and the shrinking visible cap of a curved body approaching
        make the mean pixel depth drift slightly from it).
    parent : int or None
        Id of the support it stands on (cup -> table, table -> floor), None otherwise.
    touches_border : bool
        True when a visible pixel lies on the image border.
    """

    id: int
    name: str
    kind: str
    area: int
    center_xy: tuple[float, float]
    depth: float
    v_radial: float
    parent: int | None
    touches_border: bool


@dataclass(frozen=True, eq=False)
class SimFrame:
    """One simulated frame and its ground truth.

    Attributes
    ----------
    frame : Frame
        What the sensor gives: measured depth (mm, 0 invalid), valid mask, index,
        ``time_s = index / fps``, intrinsics, ``name = "sim:<scene>#<index>"``; ``meta``
        holds ``scene``, ``fps`` and ``seed`` (None when noise-free).
    true_depth : ndarray of float32, shape (H, W)
        True depth along the optical axis (mm) at the frame's instant, 0 where no surface.
    instances : ndarray of int32, shape (H, W)
        Ground-truth body id per pixel; 0 where no surface or the measurement is invalid.
    truth : tuple of TruthObject
        The bodies with at least one visible pixel, by id.
    amplitude : ndarray of float32, shape (H, W) or None
        Demodulated amplitude (electrons), the ToF sensor's confidence image; None for
        structured light.
    shadow : ndarray of bool, shape (H, W) or None
        Structured light: pixels with a surface that the projector cannot light (read
        invalid). None for ToF.
    gravity : Gravity or None
        Which way is down in the camera's frame, exact (the camera's pitch). Truth, like the
        rest: the frame itself carries no gravity, as a camera without an IMU gives none
        (``Pipeline(gravity=sim.gravity)`` hands it over).
    """

    frame: Frame
    true_depth: NDArray[np.float32]
    instances: NDArray[np.int32]
    truth: tuple[TruthObject, ...]
    amplitude: NDArray[np.float32] | None = None
    shadow: NDArray[np.bool_] | None = None
    gravity: Gravity | None = None


def sensor_name(sensor: str) -> str:
    """Return the canonical name of a sensor spelling (``tof``, ``structured-light``; ``sl`` too).

    Raises
    ------
    InputError
        For an unknown sensor; the message lists the known ones.
    """
    try:
        return SENSORS[sensor.strip().lower()]
    except KeyError:
        raise InputError(f"unknown sensor {sensor!r}; known sensors: tof, structured-light (or sl)") from None


def _check(scene: str, frames: int, size: tuple[int, int], fps: float) -> None:
    if frames < 1:
        raise InputError(f"simulate {scene!r}: frames must be >= 1, got {frames}")
    if len(size) != 2:
        raise InputError(f"simulate {scene!r}: size must be (width, height), got {size!r}")
    w, h = size
    if int(w) != w or int(h) != h or w < 8 or h < 8:
        raise InputError(f"simulate {scene!r}: size must be whole pixels of at least 8 x 8, got {w} x {h}")
    if w * h > MAX_PIXELS:
        raise InputError(f"simulate {scene!r}: size {w} x {h} exceeds the {MAX_PIXELS}-pixel limit (4096 x 4096)")
    if not (np.isfinite(fps) and 0.1 <= fps <= 10000):
        raise InputError(f"simulate {scene!r}: fps must be in 0.1..10000 frames per second, got {fps}")


def simulate(
    scene: str,
    frames: int = 1,
    *,
    size: tuple[int, int] = (176, 132),
    fps: float = 30.0,
    seed: int = 0,
    tof: ToFConfig | None = None,
    noise: bool = True,
    sensor: str = "tof",
    structured_light: StructuredLightConfig | None = None,
) -> Iterator[SimFrame]:
    """Simulate ``frames`` depth frames of a named scene with ground truth.

    Parameters
    ----------
    scene : str
        One of :data:`depthgram.sensor.SCENES`.
    frames : int
        Number of frames (>= 1); frame k is at ``k / fps`` seconds.
    size : tuple of int
        (width, height) in pixels; 176 x 132 like the paper's sensor, any size on request.
    fps : float
        Frame rate (frames per second).
    seed : int
        Noise seed; the same seed gives the same frames. Frame k draws from its own stream
        (seeded by ``(seed, k)``), so it does not depend on which frames were drawn before.
    tof : ToFConfig, optional
        Sensor model; default the scene's own (:class:`ToFConfig` defaults, plus a 40 MHz
        second frequency for ``corridor``).
    noise : bool
        False: no shot or read noise (mixed pixels, wrap-around, quantization remain); for
        structured light, no disparity noise (quantisation, shadows and holes remain).
    sensor : str
        ``tof`` (default) or ``structured-light`` (``sl``): a Kinect v1 / Xtion-like camera,
        see :mod:`depthgram.sensor.structured`. Ground truth is the same for both.
    structured_light : StructuredLightConfig, optional
        The structured-light model (Kinect v1 defaults when omitted); only with that sensor.

    Returns
    -------
    iterator of SimFrame

    Raises
    ------
    InputError
        Unknown scene or sensor (the message lists the known ones), frames < 1, absurd size
        or fps. Raised at the call, not at the first frame.
    """
    _check(scene, frames, size, fps)
    kind = sensor_name(sensor)
    spec = build_scene(scene, size)
    cfg: ToFConfig | StructuredLightConfig
    if kind == "structured-light":
        cfg = structured_light or StructuredLightConfig()
    else:
        if structured_light is not None:
            raise InputError(f"simulate {scene!r}: structured_light config given for the {kind} sensor")
        cfg = spec.tof if tof is None else tof
    return _frames(spec, cfg, frames, float(fps), seed, noise)


def _frames(
    spec: SceneSpec, cfg: ToFConfig | StructuredLightConfig, frames: int, fps: float, seed: int, noise: bool
) -> Iterator[SimFrame]:
    still = static_hits(spec.camera, spec.bodies)
    for k in range(frames):
        rng = np.random.default_rng([seed, k]) if noise else None
        if isinstance(cfg, StructuredLightConfig):
            sim = render_structured(spec, cfg, k, fps, rng, still)
        else:
            sim = render(spec, cfg, k, fps, rng, still)
        sim.frame.meta["seed"] = seed if noise else None
        yield sim


def render_structured(
    spec: SceneSpec,
    cfg: StructuredLightConfig,
    index: int,
    fps: float,
    rng: np.random.Generator | None,
    still: list[NDArray[np.float64]] | None = None,
) -> SimFrame:
    """Render frame ``index`` of ``spec`` through a structured-light camera; ``rng`` None: noise-free.

    The camera casts its rays as for ToF (exact truth); then every surface point is joined to
    the projector, ``baseline_mm`` beside the optical centre along the image x axis, and is in
    shadow when a body lies between them. Measured depth: disparity noise and quantisation
    (:func:`depthgram.sensor.structured.measure`), invalid in shadow and in the registration
    holes.
    """
    cam = spec.camera
    t = index / fps
    (nominal,) = cast_times(cam, spec.bodies, (t,), still)
    h, w = nominal.depth.shape
    dirs, _ = cam.rays()
    origin = np.asarray(cam.position, dtype=np.float64)
    hit = nominal.depth.ravel() > 0
    shadow = np.zeros(h * w, bool)
    if cfg.shadow and hit.any():
        points = origin + dirs[hit] * nominal.depth.ravel()[hit, None]
        # The camera's x axis is world +x (the camera only pitches), so the projector is there.
        projector = origin + np.array([cfg.projector_side * cfg.baseline_mm, 0.0, 0.0])
        to_point = points - projector
        nearest = np.full(len(points), np.inf)
        for b in spec.bodies:
            nearest = np.minimum(nearest, b.intersect(projector, to_point, t))
        # Parameter 1 is the point itself; anything clearly before it blocks the light.
        shadow[np.flatnonzero(hit)[nearest < 1.0 - 1e-6]] = True
    shadow = shadow.reshape(h, w)
    true_depth = nominal.depth.astype(np.float32)
    depth = structured.measure(true_depth, cfg, rng)
    depth[shadow | structured.registration_holes((h, w), cfg.registration_scale)] = 0.0
    valid = depth > 0
    instances = np.where(valid, nominal.instances, 0).astype(np.int32)
    frame = Frame(
        depth=depth,
        valid=valid,
        index=index,
        time_s=t,
        intrinsics=cam.intrinsics,
        name=f"sim:{spec.name}#{index}",
        meta={"scene": spec.name, "fps": fps, "sensor": "structured-light"},
    )
    truth = _truth(spec, instances, true_depth, t)
    return SimFrame(frame, true_depth, instances, truth, None, shadow, gravity=spec.gravity)


def render(
    spec: SceneSpec,
    cfg: ToFConfig,
    index: int,
    fps: float,
    rng: np.random.Generator | None,
    still: list[NDArray[np.float64]] | None = None,
) -> SimFrame:
    """Render frame ``index`` of ``spec``; ``rng`` None means noise-free.

    ``still`` is :func:`~depthgram.sensor.geometry.static_hits` of the scene, shared by
    all frames of a sequence.
    """
    cam = spec.camera
    t = index / fps
    moving = any(b.moving for b in spec.bodies)
    n_sub = cfg.motion_substeps if (cfg.mixed_pixels and moving) else 1
    if n_sub == 1:
        (nominal,) = cast_times(cam, spec.bodies, (t,), still)
        hits = [nominal]
    else:
        # The exposure is centred on the frame's instant; a pixel that sees two surfaces
        # during it accumulates the charge of both, which is what makes mixed pixels.
        offsets = ((np.arange(n_sub) + 0.5) / n_sub - 0.5) * cfg.integration_s
        nominal, *hits = cast_times(cam, spec.bodies, (t, *(t + float(dt) for dt in offsets)), still)
    refl = np.zeros(max(b.id for b in spec.bodies) + 1)
    for b in spec.bodies:
        refl[b.id] = b.reflectivity
    ambient = cfg.ambient_e * cfg.integration_s / REFERENCE_INTEGRATION_S
    freqs = [cfg.f_mod_hz] if cfg.f_mod2_hz is None else [cfg.f_mod_hz, cfg.f_mod2_hz]
    samples = []
    for f in freqs:
        s = np.mean(
            [
                correlation_samples(h.distance, amplitude_e(h.distance, refl[h.instances], cfg), f, ambient)
                for h in hits
            ],
            axis=0,
        )
        samples.append(s if rng is None else sample_noise(s, cfg.read_noise_e, rng))
    dist, amp = measure(samples[0], samples[1] if len(samples) > 1 else None, cfg)
    _, lengths = cam.rays()
    depth = quantize(dist / lengths.reshape(dist.shape), cfg)
    valid = depth > 0
    instances = np.where(valid, nominal.instances, 0).astype(np.int32)
    true_depth = nominal.depth.astype(np.float32)
    frame = Frame(
        depth=depth,
        valid=valid,
        index=index,
        time_s=t,
        intrinsics=cam.intrinsics,
        name=f"sim:{spec.name}#{index}",
        meta={"scene": spec.name, "fps": fps},
    )
    truth = _truth(spec, instances, true_depth, t)
    return SimFrame(frame, true_depth, instances, truth, amp.astype(np.float32), gravity=spec.gravity)


def _truth(
    spec: SceneSpec, instances: NDArray[np.int32], true_depth: NDArray[np.float32], t: float
) -> tuple[TruthObject, ...]:
    h, w = instances.shape
    n = max(b.id for b in spec.bodies) + 1
    flat = instances.ravel()
    rows, cols = np.indices((h, w))
    area = np.bincount(flat, minlength=n)
    sx = np.bincount(flat, weights=cols.ravel(), minlength=n)
    sy = np.bincount(flat, weights=rows.ravel(), minlength=n)
    sd = np.bincount(flat, weights=true_depth.ravel().astype(np.float64), minlength=n)
    border = np.zeros((h, w), bool)
    border[0, :] = border[-1, :] = border[:, 0] = border[:, -1] = True
    on_border = np.bincount(flat[border.ravel()], minlength=n) > 0
    forward = spec.camera.forward
    out = []
    for b in spec.bodies:
        a = int(area[b.id])
        if a == 0 or b.id == 0:
            continue
        out.append(
            TruthObject(
                id=b.id,
                name=b.name,
                kind=b.kind,
                area=a,
                center_xy=(float(sx[b.id] / a), float(sy[b.id] / a)),
                depth=float(sd[b.id] / a),
                v_radial=float(b.motion.velocity(t) @ forward),
                parent=b.parent,
                touches_border=bool(on_border[b.id]),
            )
        )
    return tuple(out)
