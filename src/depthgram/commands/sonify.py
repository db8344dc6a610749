"""depthgram sonify: the scene as stereo sound, at the recording's real time; a still as a scan."""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from depthgram.commands._common import add_pipeline_arguments, load_config, pipeline_results

if TYPE_CHECKING:
    from depthgram.pipeline import SceneResult
    from depthgram.sound import Sonifier, SoundMapping

NAME = "sonify"
HELP = "render the scene to stereo audio for a listener (WAV): a recording at its real time, a still as a scan"

#: The sound presets, for --preset: depthgram.sound.PRESETS's names (a test holds them equal),
#: written out because importing the sound package would slow every command's start.
PRESETS = ("calm", "default", "detailed")

#: Silence (s) before each still after the first, so that one scene is heard ending.
GAP_S = 0.3


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.epilog = (
        "A recording plays at its own rate (its timestamps, its stated rate or --fps); frames with no "
        "rate and no timestamps are refused: give --fps, or --stills for unrelated pictures. A still "
        "image, or each picture of a folder of stills, plays for long enough to hear every object at "
        "least twice. The cues: docs/sound-mapping.md; learn them with 'depthgram lesson DIR'."
    )
    add_pipeline_arguments(p)
    p.add_argument("--wav", required=True, metavar="OUT.wav", help="audio file to write ('-': standard output)")
    p.add_argument(
        "--preset",
        default=None,
        choices=PRESETS,
        help="sound mapping preset (overrides the config's [sound]): %(choices)s",
    )
    p.add_argument("--samplerate", type=int, default=22050, help="samples per second")
    p.add_argument(
        "--still-duration",
        type=float,
        default=None,
        metavar="S",
        help="seconds of sound per still image (default: long enough to hear every object twice)",
    )


class _Writer:
    """Writes results to the WAV as they come: recordings streamed, stills as separate scans."""

    def __init__(
        self, wav: Any, mapping: SoundMapping, samplerate: int, fps: float | None, still_s: float | None, where: str
    ) -> None:
        self.wav, self.mapping, self.sr, self.fps, self.still_s, self.where = (
            wav,
            mapping,
            samplerate,
            fps,
            still_s,
            where,
        )
        self.pending: SceneResult | None = None
        self.run = 0  # frames of the current run (recording) so far, the pending one included
        self.stream: Sonifier | None = None
        self.samples = 0
        self.frames = 0
        self.stills: list[tuple[SceneResult, float]] = []
        self.streamed = 0
        self.periods: Counter[str] = Counter()
        self.voiced = 0  # distinct voices of the recordings
        self.most = (0, 0)
        self.left_out: Counter[str] = Counter()
        self._last_period = 0.0

    def add(self, r: SceneResult) -> None:
        if self.pending is not None:
            if r.still:
                self._end_run()
            else:
                self._stream(self.pending, self._period(self.pending, r))
        self.pending = r
        self.run = 1 if r.still or self.run == 0 else self.run + 1

    def close(self) -> None:
        if self.pending is not None:
            self._end_run()
            self.pending = None

    def _period(self, a: SceneResult, b: SceneResult) -> float:
        if self.fps:
            self.periods[f"{self.fps:g} frames/s"] += 1
            return 1.0 / self.fps
        ta, tb = a.frame.time_s, b.frame.time_s
        if ta is not None and tb is not None and tb > ta:
            self.periods["the timestamps"] += 1
            return tb - ta
        from depthgram.errors import InputError

        raise InputError(
            f"{self.where}: frames {a.frame.name} and {b.frame.name} look like one recording but carry no "
            "timestamps and no frame rate, so the sound cannot keep to their real time; give --fps RATE "
            "(e.g. --fps 30 for a Kinect), or --stills if they are unrelated pictures"
        )

    def _end_run(self) -> None:
        r = self.pending
        assert r is not None
        if self.run == 1:
            self._still(r)
            return
        self._stream(r, self._last_period, fade=True)
        self.stream = None

    def _stream(self, r: SceneResult, period: float, *, fade: bool = False) -> None:
        from depthgram.sound import Sonifier, select

        self._last_period = period
        if self.stream is None:
            self.stream = Sonifier(self.mapping, self.sr, r.frame.size)
        audio = self.stream.push(r.tree, period, r.segmentation.objects, r.frame.intrinsics, r.frame.gravity)
        if fade:  # the run ends: fade out over the ramp, so that it lasts as long as it did and ends without a click
            k = min(len(audio), max(1, round(self.mapping.ramp_s * self.sr)))
            audio[len(audio) - k :] *= np.linspace(1.0, 0.0, k, dtype=np.float32)[:, None]
        self._write(audio)
        self.frames += 1
        self.streamed += 1
        sel = select(r.tree, self.mapping)
        now = self.stream.voices_now
        self.most = max(self.most, (sum(k[0] == "o" for k in now), sum(k[0] == "g" for k in now)))
        if fade:
            self.voiced += self.stream.chooser.distinct
        self.left_out.update(why.split("(")[-1].rstrip(")") for _, why in sel.left_out)

    def _still(self, r: SceneResult) -> None:
        from depthgram.sound import render_scene

        if self.samples:
            self._write(np.zeros((round(GAP_S * self.sr), 2), np.float32))
        audio = render_scene(
            r.tree,
            r.frame.size,
            mapping=self.mapping,
            duration_s=self.still_s,
            samplerate=self.sr,
            objects=r.segmentation.objects,
        )
        self._write(audio)
        self.frames += 1
        self.stills.append((r, len(audio) / self.sr))

    def _write(self, audio: np.ndarray) -> None:
        self.wav.write(audio)
        self.samples += len(audio)

    def summary(self, out: str) -> list[str]:
        from depthgram.sound.words import hearing

        lines = [
            f"wrote {out}: {self.samples / self.sr:.1f} s of stereo audio at {self.sr} Hz, "
            f"{self.frames} frame(s): {self.streamed} of recordings, {len(self.stills)} still(s)"
        ]
        if self.streamed:
            rates = ", ".join(f"{n} frame periods from {src}" for src, n in self.periods.most_common())
            lines.append(
                f"  recordings at their real time ({rates or 'one frame'}); up to {self.most[0]} "
                f"object(s) beeping and {self.most[1]} surface(s) humming at once, "
                f"{self.voiced} distinct object voice(s) in all"
            )
            for why, n in self.left_out.most_common():
                lines.append(f"  {n} time(s) a node was left out: {why}")
        for r, seconds in self.stills:
            why = f" ({r.still})" if r.still and r.still != "stills setting" else ""
            lines.append(f"  still {r.frame.name}: {seconds:.1f} s{why}")
            lines += [f"    {h}" for h in hearing(r.tree, r.frame.size, self.mapping, r.segmentation.objects)]
        return lines


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    import shutil
    import tempfile
    from contextlib import ExitStack

    import soundfile as sf

    from depthgram.atomic import atomic_open, atomic_path, writes_in_place
    from depthgram.errors import InputError
    from depthgram.sound import SoundMapping

    if not 4000 <= args.samplerate <= 192000:
        raise InputError(f"--samplerate must be between 4000 and 192000, got {args.samplerate}")
    if args.still_duration is not None and not 0 < args.still_duration <= 60:
        raise InputError(f"--still-duration must be in (0, 60] s, got {args.still_duration}")
    to_stdout = args.wav == "-"
    out_dir = Path(args.wav).resolve().parent
    if not to_stdout and not out_dir.is_dir():
        raise InputError(f"{args.wav}: cannot write the audio, folder {out_dir} does not exist")
    mapping = SoundMapping.preset(args.preset) if args.preset else load_config(args).sound
    src, results = pipeline_results(args, NAME)
    fps = getattr(src, "fps", None) or args.fps
    # Streamed to disk frame by frame: a long recording never sits in memory as audio. Under a
    # temporary name renamed when complete, so a failure leaves no half file that looks like a
    # result. A FIFO, a device, a socket or standard output is never replaced nor removed (issue
    # 32.1): a WAV header is completed by seeking back, so the audio goes to an anonymous
    # temporary file first and is copied through at the end.
    with ExitStack() as stack:
        target: Any = (
            stack.enter_context(tempfile.TemporaryFile())
            if to_stdout or writes_in_place(args.wav)
            else stack.enter_context(atomic_path(args.wav))
        )
        with sf.SoundFile(target, "w", samplerate=args.samplerate, channels=2, subtype="PCM_16", format="WAV") as wav:
            w = _Writer(wav, mapping, args.samplerate, fps, args.still_duration, args.input)
            for result in results:
                w.add(result)
            w.close()
        if not w.frames:
            raise InputError(f"{args.input}: no frame to sonify")
        if to_stdout:
            target.seek(0)
            shutil.copyfileobj(target, sys.stdout.buffer)
            sys.stdout.flush()
            print("\n".join(w.summary("standard output")), file=sys.stderr)
            return 0
        if not isinstance(target, Path):
            target.seek(0)
            with atomic_open(args.wav, "wb") as out:
                shutil.copyfileobj(target, out)
    print("\n".join(w.summary(args.wav)))
    return 0
