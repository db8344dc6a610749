"""depthgram lesson: learn the sound mapping, one cue per short WAV with a line saying what it means."""

from __future__ import annotations

import argparse

from depthgram.commands._common import add_config_arguments
from depthgram.commands.sonify import PRESETS

NAME = "lesson"
HELP = (
    "write one short WAV per sound cue (left/right, near/far, height, size, glides, approach, height against "
    "the horizon) with a line each"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.add_argument("folder", metavar="DIR", help="folder to write the WAVs and lesson.txt into (made if missing)")
    add_config_arguments(p)
    p.add_argument(
        "--preset",
        default=None,
        choices=PRESETS,
        help="sound mapping preset (overrides the config's [sound]): %(choices)s",
    )
    p.add_argument("--samplerate", type=int, default=22050, help="samples per second")


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from depthgram.commands._common import load_config
    from depthgram.errors import InputError
    from depthgram.sound import SoundMapping
    from depthgram.sound.lesson import write_lesson

    if not 4000 <= args.samplerate <= 192000:
        raise InputError(f"--samplerate must be between 4000 and 192000, got {args.samplerate}")
    mapping = SoundMapping.preset(args.preset) if args.preset else load_config(args).sound
    for path, text in write_lesson(args.folder, mapping, args.samplerate):
        print(f"{path}: {text}")
    return 0
