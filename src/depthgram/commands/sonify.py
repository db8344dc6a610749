"""depthgram sonify: the scene as stereo sound, at the recording's real time."""

from __future__ import annotations

import argparse
from pathlib import Path

from depthgram.commands._common import add_pipeline_arguments, load_config, pipeline_results

NAME = "sonify"
HELP = "render the scene to stereo audio for a listener (WAV), one scan per frame at the recording's rate"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_pipeline_arguments(p)
    p.add_argument("--wav", required=True, metavar="OUT.wav", help="audio file to write")
    p.add_argument("--preset", default=None, help="sound mapping preset (overrides the config's [sound])")
    p.add_argument("--samplerate", type=int, default=22050, help="samples per second")
    p.add_argument("--still-duration", type=float, default=1.0, metavar="S",
                   help="seconds of sound for a single still frame, or per frame when no rate is known")


def run(args: argparse.Namespace) -> int:
    from depthgram._optional import needs_extra
    from depthgram.atomic import atomic_path
    from depthgram.errors import InputError

    with needs_extra("sound", "writing WAV files"):
        import soundfile as sf

    from depthgram.sound import Sonifier, SoundMapping

    if not 4000 <= args.samplerate <= 192000:
        raise InputError(f"--samplerate must be between 4000 and 192000, got {args.samplerate}")
    if not 0 < args.still_duration <= 60:
        raise InputError(f"--still-duration must be in (0, 60] s, got {args.still_duration}")
    out_dir = Path(args.wav).resolve().parent
    if not out_dir.is_dir():
        raise InputError(f"{args.wav}: cannot write the audio, folder {out_dir} does not exist")
    mapping = SoundMapping.preset(args.preset) if args.preset else load_config(args).sound
    src, results = pipeline_results(args, NAME)
    fps = getattr(src, "fps", None) or args.fps
    sonifier: Sonifier | None = None
    pending = None  # (tree, time_s) of the frame whose duration is known only when the next one arrives
    last_duration = 1.0 / fps if fps else args.still_duration
    # Streamed to disk frame by frame: a long recording never sits in memory as audio.
    # under a temporary name until the last frame: a failure leaves no WAV that looks complete
    with atomic_path(args.wav) as tmp, sf.SoundFile(
        tmp, "w", samplerate=args.samplerate, channels=2, subtype="PCM_16"
    ) as wav:
        for result in results:
            f = result.frame
            if sonifier is None:
                sonifier = Sonifier(mapping, args.samplerate, f.size)
            if pending is not None:
                tree, t_prev = pending
                if not fps and t_prev is not None and f.time_s is not None and f.time_s > t_prev:
                    last_duration = f.time_s - t_prev
                wav.write(sonifier.push(tree, last_duration))
            pending = (result.tree, f.time_s)
        if pending is None or sonifier is None:
            raise InputError(f"{args.input}: no frame to sonify")
        wav.write(sonifier.push(pending[0], last_duration))
    return 0
