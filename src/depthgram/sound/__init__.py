"""depthgram.sound: the parsed scene as stereo sound for people who cannot see."""

from depthgram.sound.mapping import PRESETS, SCANS, SoundMapping
from depthgram.sound.synth import OBLIQUE_KINDS, Sonifier, Voice, render_scene, voices
from depthgram.sound.wav import write_wav

__all__ = [
    "OBLIQUE_KINDS",
    "PRESETS",
    "SCANS",
    "Sonifier",
    "SoundMapping",
    "Voice",
    "render_scene",
    "voices",
    "write_wav",
]
