"""The cues of a sound mapping one at a time: short WAVs and a line each, to learn before use."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from depthgram.scene.tree import Node, SceneTree
from depthgram.sound.mapping import SoundMapping
from depthgram.sound.synth import Sonifier, render_scene
from depthgram.sound.wav import write_wav

__all__ = ["Cue", "lesson", "write_lesson"]

_W, _H = 640, 480
_PAUSE_S = 0.25


@dataclass(frozen=True)
class Cue:
    """One cue of the lesson: its file name, the line that says what it means, its audio."""

    name: str
    text: str
    audio: NDArray[np.float32]


def _tree(*nodes: Node) -> SceneTree:
    return SceneTree(Node(0, "Bkg", -1, 0.0, _W * _H, ((_W - 1) / 2, (_H - 1) / 2), children=nodes))


def _obj(x: float, y: float, depth: float, area: int = 4000, ttc: float | None = None, i: int = 1) -> Node:
    return Node(i, "object", 0, depth, area, (x, y), ttc=ttc)


def _steps(m: SoundMapping, sr: int, trees: list[SceneTree], each_s: float) -> NDArray[np.float32]:
    pause = np.zeros((round(_PAUSE_S * sr), 2), np.float32)
    parts: list[NDArray[np.float32]] = []
    for t in trees:
        parts += [render_scene(t, mapping=m, duration_s=each_s, samplerate=sr), pause]
    return np.concatenate(parts)


def lesson(mapping: SoundMapping, samplerate: int = 22050) -> list[Cue]:
    """Return the cues of ``mapping``, each alone: pan, nearness, height, size, glides, approach, scan, walls, tilt.

    Parameters
    ----------
    mapping : SoundMapping
    samplerate : int
        Samples per second (Hz).

    Returns
    -------
    list of Cue
    """
    m, sr = mapping, samplerate
    mid, d = _H / 2, 1000.0
    each = max(1.0, 2.0 / m.rate(d))
    cues = [
        Cue(
            "01-left-right",
            f"One object at the left edge, in the middle, then at the right edge: the beep moves "
            f"from your left ear to your right ear (stereo pan, width {m.pan_width:g}).",
            _steps(m, sr, [_tree(_obj(x, mid, d)) for x in (0, (_W - 1) / 2, _W - 1)], each),
        ),
        Cue(
            "02-near-far",
            "One object at "
            + ", ".join(f"{z / 1000:g} m" for z in (m.near_mm, 1000, 2000, m.far_mm))
            + ": nearer is faster and louder, "
            + ", ".join(f"{m.rate(z):.1f}" for z in (m.near_mm, 1000, 2000, m.far_mm))
            + " beeps per second.",
            _steps(
                m,
                sr,
                [_tree(_obj(_W / 2, mid, z)) for z in (m.near_mm, 1000.0, 2000.0, m.far_mm)],
                max(1.0, 2.0 / m.rate(m.far_mm)),
            ),
        ),
        Cue(
            "03-height",
            f"One object at the top of the view, the middle, then the bottom: high is up "
            f"({m.pitch(0, _H):.0f} Hz), low is down ({m.pitch(_H - 1, _H):.0f} Hz).",
            _steps(m, sr, [_tree(_obj(_W / 2, y, d)) for y in (0, (_H - 1) / 2, _H - 1)], each),
        ),
        Cue(
            "04-size",
            f"A small object, then a big one (a quarter of the view): the big one sounds fuller "
            f"({m.weight(m.area_full)[0]} harmonics) and longer ({1000 * m.weight(m.area_full)[1]:.0f} ms "
            f"against {1000 * m.weight(0.001)[1]:.0f} ms).",
            _steps(m, sr, [_tree(_obj(_W / 2, mid, d, area=a)) for a in (300, int(m.area_full * _W * _H))], each),
        ),
    ]
    wall = Node(2, "wall", 0, 2000.0, 60000, (60.0, mid))
    floor = Node(3, "floor", 0, 2000.0, 80000, (_W / 2, _H - 60.0))
    cues += [
        Cue(
            "05-wall",
            f"A wall along your left running into the distance: no beeps, a hum whose pitch glides from "
            f"its near end (higher) to its far end (lower) and back every {m.glide_period_s:g} s.",
            render_scene(_tree(wall), mapping=m, duration_s=2 * m.glide_period_s, samplerate=sr),
        ),
        Cue(
            "06-floor",
            "The floor ahead: the same kind of glide, low in pitch because it is at the bottom of the view.",
            render_scene(_tree(floor), mapping=m, duration_s=2 * m.glide_period_s, samplerate=sr),
        ),
    ]
    # Approach: an object closing from 5 m at 1 m/s; its beeps speed up as time to collision drops.
    son = Sonifier(m, sr, (_W, _H))
    fps, chunks = 20.0, []
    for k in range(int(4.6 * fps)):
        z = 5000.0 - 1000.0 * k / fps
        chunks.append(son.push(_tree(_obj(_W / 2, mid, z, ttc=z / 1000.0)), 1 / fps))
    cues.append(
        Cue(
            "07-approaching",
            f"An object coming at you at 1 m/s from 5 m to 0.4 m: under {m.ttc_alert:g} s to "
            f"collision its beeps accelerate into a rattle that keeps quickening until {m.ttc_floor_s:g} s "
            f"before impact (up to {m.rate_max_hz:g} per second).",
            np.concatenate(chunks),
        )
    )
    three = _tree(*(_obj(x, mid, d, i=i + 1) for i, x in enumerate((80.0, _W / 2, _W - 80.0))))
    cues.append(
        Cue(
            "08-scan",
            f"Three objects appear together: their first beeps sweep {m.scan.replace('_', ' ')} "
            f"within {m.scan_s:g} s, then each keeps its own beat.",
            render_scene(three, mapping=m, duration_s=2.0, samplerate=sr),
        )
    )
    ahead = _obj(_W / 2, mid, 2000.0, area=int(0.6 * _W * _H))
    cues.append(
        Cue(
            "09-wall-ahead",
            f"A wall straight ahead, facing you ({100 * m.facing_area:.0f} % of the view or more): no beeps, a "
            "steady hum, as one surface at one distance; louder as you come nearer.",
            render_scene(_tree(ahead), mapping=m, duration_s=2.0, samplerate=sr),
        )
    )
    cues.append(_tilt_cue(m, sr, d))
    return cues


def _tilt_cue(m: SoundMapping, sr: int, depth: float) -> Cue:
    """Height against the horizon: the same object with the camera level, then tilted; then one higher."""
    from depthgram.frame import Gravity, Intrinsics

    k = Intrinsics(fx=525.0, fy=525.0, cx=(_W - 1) / 2, cy=(_H - 1) / 2)
    up20 = k.cy - k.fy * math.tan(math.radians(20.0))  # the row 20 degrees above the optical axis
    steps = [  # (row, camera tilt down in degrees): eye level level, eye level tilted, 20 degrees up level
        (k.cy, 0.0),
        (up20, 20.0),
        (up20, 0.0),
    ]
    pause = np.zeros((round(_PAUSE_S * sr), 2), np.float32)
    parts: list[NDArray[np.float32]] = []
    hz: list[float] = []
    for row, tilt in steps:
        son = Sonifier(m, sr, (_W, _H))
        g = Gravity.from_tilt(tilt)
        for _ in range(25):  # 1.25 s at 20 frames/s: a voice takes a few frames to enter
            parts.append(son.push(_tree(_obj(_W / 2, row, depth)), 0.05, intrinsics=k, gravity=g))
        hz.append(next(iter(son.voices_now.values())).freq_a)
        parts.append(pause)
    return Cue(
        "10-tilted-camera",
        f"When the camera knows which way is down (a RealSense's IMU, --gravity or --tilt), height is heard "
        f"against the horizon, not the picture: one object straight ahead at eye level with the camera level "
        f"({hz[0]:.0f} Hz), the same object with the camera tilted 20 degrees down, where it shows near the "
        f"top of the picture ({hz[1]:.0f} Hz: the same pitch), then an object 20 degrees above eye level "
        f"({hz[2]:.0f} Hz: higher).",
        np.concatenate(parts),
    )


def write_lesson(folder: str | Path, mapping: SoundMapping, samplerate: int = 22050) -> list[tuple[Path, str]]:
    """Write each cue as ``NN-name.wav`` and all lines as ``lesson.txt`` into ``folder``.

    Returns
    -------
    list of (Path, str)
        Each WAV written and its line.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    written = [(write_wav(out / f"{c.name}.wav", c.audio, samplerate), c.text) for c in lesson(mapping, samplerate)]
    (out / "lesson.txt").write_text(
        f"Sound mapping '{mapping.name}': one cue per file, play them in order.\n"
        + "".join(f"{p.name}: {t}\n" for p, t in written),
        encoding="utf-8",
    )
    return written
