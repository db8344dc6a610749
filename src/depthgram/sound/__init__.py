"""depthgram.sound: the parsed scene as stereo sound for people who cannot see."""

from depthgram.sound.mapping import PRESETS, SCANS, SoundMapping
from depthgram.sound.synth import (
    BEEP_KINDS,
    OBLIQUE_KINDS,
    Selection,
    Sonifier,
    Voice,
    render_scene,
    select,
    still_seconds,
    voices,
)
from depthgram.sound.wav import write_wav

__all__ = [
    "BEEP_KINDS",
    "OBLIQUE_KINDS",
    "PRESETS",
    "SCANS",
    "Selection",
    "Sonifier",
    "SoundMapping",
    "Voice",
    "render_scene",
    "select",
    "still_seconds",
    "voices",
    "write_wav",
]
