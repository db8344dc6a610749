"""The simulator as a source: ``sim:SCENE?frames=30&size=176x132&seed=0&fps=30&sensor=tof``.

Defaults follow the paper's camera: 176 x 132 pixels; 30 frames at 30 frames/s (one still of a
scene where nothing moves: ``table``, ``corridor``, ``ball_wall``, ``touching``, ``arm_down``,
``arm_45``), seed 0, a ToF sensor (``sensor=sl`` or ``sensor=structured-light``: a Kinect v1 / Xtion-like camera).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any, cast
from urllib.parse import parse_qs

from depthgram.errors import InputError
from depthgram.frame import Frame, Intrinsics
from depthgram.sources.base import Source

__all__ = ["SimSource", "SimSpec", "parse_sim_spec", "scene_names", "simulator"]


@dataclass(frozen=True)
class SimSpec:
    """A parsed ``sim:`` spec.

    Attributes
    ----------
    scene : str
        Scene name known to :func:`depthgram.sensor.simulate`.
    frames : int
        Number of frames.
    size : (int, int)
        (width, height) in pixels.
    seed : int
        Noise seed.
    fps : float
        Frame rate (frames/s).
    sensor : str
        ``tof`` or ``structured-light`` (``sl``).
    """

    scene: str
    frames: int = 30
    size: tuple[int, int] = (176, 132)
    seed: int = 0
    fps: float = 30.0
    sensor: str = "tof"

    def __post_init__(self) -> None:
        if not self.scene:
            raise InputError("sim: needs a scene name, e.g. sim:table?frames=30")
        if self.frames < 1:
            raise InputError(f"sim:{self.scene}: frames must be >= 1, got {self.frames}")
        if min(self.size) < 2 or max(self.size) > 8192:
            raise InputError(f"sim:{self.scene}: size must be WxH between 2 and 8192 px, got {self.size}")
        if not (0 < self.fps <= 100_000):
            raise InputError(f"sim:{self.scene}: fps must be positive, got {self.fps}")
        if self.sensor.lower() not in ("tof", "structured-light", "structured_light", "sl"):
            raise InputError(f"sim:{self.scene}: unknown sensor {self.sensor!r}; expected tof or structured-light (sl)")


#: The simulator's scenes where nothing moves: without ``frames=`` their spec gives one still
#: (a test holds the set to the simulator's scenes).
STILL_SCENES = frozenset({"table", "corridor", "ball_wall", "touching", "arm_down", "arm_45"})


def parse_sim_spec(spec: str, fps: float | None = None) -> SimSpec:
    """Parse ``sim:SCENE?frames=N&size=WxH&seed=S&fps=F&sensor=tof|sl`` (every query key optional).

    ``fps`` (the ``fps=`` option of :func:`open_source`) wins over the query's.
    """
    body = spec[4:] if spec.startswith("sim:") else spec
    scene, _, query = body.partition("?")
    kw: dict[str, object] = {"scene": scene}
    allowed = {"frames", "size", "seed", "fps", "sensor"}
    for key, values in parse_qs(query, keep_blank_values=True, strict_parsing=False).items():
        if key not in allowed:
            raise InputError(f"{spec}: unknown sim option {key!r}; expected {', '.join(sorted(allowed))}")
        v = values[-1]
        try:
            if key == "size":
                w, h = v.lower().split("x")
                kw["size"] = (int(w), int(h))
            elif key == "fps":
                kw["fps"] = float(v)
            elif key == "sensor":
                kw["sensor"] = v
            else:
                kw[key] = int(v)
        except ValueError:
            raise InputError(f"{spec}: bad value {v!r} for {key} (size is WxH, e.g. 176x132)") from None
    if fps is not None:
        kw["fps"] = fps
    if "frames" not in kw and scene in STILL_SCENES:
        kw["frames"] = 1  # one still, as the README and the demo show it (issue 32.6)
    return SimSpec(**kw)  # type: ignore[arg-type]


def simulator() -> Callable[..., Iterable[Any]]:
    """:func:`depthgram.sensor.simulate`, whether the package re-exports it or only its module has it."""
    import importlib

    try:
        fn = getattr(importlib.import_module("depthgram.sensor"), "simulate", None)
        if fn is None or not callable(fn):
            fn = importlib.import_module("depthgram.sensor.simulate").simulate
    except (ImportError, AttributeError):
        raise InputError("the simulator (depthgram.sensor.simulate) is not available") from None
    return cast(Callable[..., Iterable[Any]], fn)


def scene_names() -> tuple[str, ...]:
    """Scene names the simulator knows (empty when it is not available)."""
    import importlib

    for mod in ("depthgram.sensor", "depthgram.sensor.scenes"):
        try:
            names = getattr(importlib.import_module(mod), "SCENES", None)
        except ImportError:
            continue
        if names:
            return tuple(names)
    return ()


class SimSource(Source):
    """Frames of :func:`depthgram.sensor.simulate`.

    Parameters
    ----------
    spec : SimSpec
        Scene, frame count, size, seed, frame rate.
    name : str
        The spec text.
    """

    kind = "sim"
    intrinsics_source = "simulator"  # exact: the scene was rendered through them

    def __init__(self, spec: SimSpec, *, name: str, intrinsics: Intrinsics | None = None) -> None:
        self.spec = spec
        self.name = name
        self.fps = spec.fps
        # One rendered frame (a few ms at the paper's size) checks the scene name at open time
        # and gives the intrinsics before iteration, through the simulator's public API only.
        first = next(iter(simulator()(spec.scene, 1, **self._options())))
        self.intrinsics = intrinsics or first.frame.intrinsics

    def __len__(self) -> int:
        return self.spec.frames

    def __iter__(self) -> Iterator[Frame]:
        simulate = simulator()
        s = self.spec
        for sim_frame in simulate(s.scene, s.frames, **self._options()):
            yield self.calibrated(sim_frame.frame)

    def _options(self) -> dict[str, Any]:
        s = self.spec
        opts: dict[str, Any] = {"size": s.size, "fps": s.fps, "seed": s.seed}
        if s.sensor.lower() != "tof":  # a simulator without the option still serves ToF specs
            opts["sensor"] = s.sensor
        return opts
