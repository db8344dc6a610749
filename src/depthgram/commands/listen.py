"""depthgram listen: play the scene on the audio device as the frames arrive."""

from __future__ import annotations

import argparse
import gc
import itertools
import json
import sys
import time
from pathlib import Path

from depthgram.commands._common import add_pipeline_arguments, load_config, make_pipeline, open_input

NAME = "listen"
HELP = "play the scene's sound live on the audio device, from a camera, a recording at its own rate or sim:"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.epilog = (
        "The sound is made in the audio device's callback; each new frame only moves the voices' "
        "targets, so a slow frame freezes the scene for a moment but never delays the sound. A "
        "recording plays at its own rate (late frames are dropped as a live sensor loses them). "
        "Needs pip install 'depthgram[listen]' and PortAudio (Debian: libportaudio2)."
    )
    add_pipeline_arguments(p, workers=False)  # one frame at a time: latency is the point
    p.add_argument("--device", default=None, metavar="NAME_OR_INDEX", help="output device (default: the system's)")
    p.add_argument("--block", type=int, default=256, metavar="N", help="samples per audio block (default 256)")
    p.add_argument("--samplerate", type=int, default=48000, metavar="HZ", help="samples per second (default 48000)")
    p.add_argument("--preset", default=None, help="sound mapping preset (overrides the config's [sound])")
    p.add_argument(
        "--log",
        default=None,
        metavar="FILE",
        help="one JSON line per frame heard: frame, latency_ms (= pipeline_ms + wait_ms + dac_ms), "
        "underflows, callback_ms",
    )
    p.add_argument("--wav", default=None, metavar="FILE", help="also write exactly what was played to this WAV")
    p.add_argument("--seconds", type=float, default=None, metavar="S", help="stop after S seconds (a camera)")
    p.add_argument(
        "--decimate",
        default="auto",
        metavar="N",
        help="read every N-th pixel of every N-th row (default auto: the largest N that keeps at least "
        "320 pixels a row; 1 reads them all). The ear cannot tell the directions apart that a finer "
        "image would, and the loop's CPU share falls with the pixels",
    )
    p.add_argument(
        "--binaural",
        nargs="?",
        const="kemar",
        default=None,
        metavar="SOFA",
        help="for headphones: every voice through measured head-related impulse responses, from its "
        "direction (the KEMAR set the 'slab' package ships, or this SOFA file); needs "
        "pip install 'depthgram[binaural]'",
    )
    p.add_argument(
        "--no-realtime",
        dest="realtime",
        action="store_false",
        help="leave the audio callback at normal priority (by default it asks for realtime scheduling "
        "and falls back to normal priority where that is not permitted)",
    )


def _device(text: str | None) -> int | str | None:
    if text is None:
        return None
    return int(text) if text.strip().lstrip("-").isdigit() else text


def decimation(text: str, width: int) -> int:
    """Return the step of ``--decimate`` for frames ``width`` pixels wide (``auto`` keeps >= 320 a row)."""
    from depthgram.errors import InputError

    if text == "auto":
        return max(1, width // 320)
    try:
        step = int(text)
    except ValueError:
        step = 0
    if step < 1:
        raise InputError(f"--decimate must be 'auto' or an integer >= 1, got {text!r}")
    return step


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from depthgram._optional import needs_extra
    from depthgram.errors import InputError
    from depthgram.pacing import Pacer
    from depthgram.sound import SoundMapping
    from depthgram.sound.live import AudioProcess, percentiles
    from depthgram.sources.base import decimated
    from depthgram.sources.prefetch import prefetch

    if not 8000 <= args.samplerate <= 192000:
        raise InputError(f"--samplerate must be between 8000 and 192000 Hz, got {args.samplerate}")
    if not 16 <= args.block <= 16384:
        raise InputError(f"--block must be between 16 and 16384 samples, got {args.block}")
    if args.seconds is not None and args.seconds <= 0:
        raise InputError(f"--seconds must be > 0, got {args.seconds}")
    for opt, path in (("--log", args.log), ("--wav", args.wav)):
        if path is not None and not Path(path).resolve().parent.is_dir():
            raise InputError(f"{opt} {path}: folder {Path(path).resolve().parent} does not exist")
    mapping = SoundMapping.preset(args.preset) if args.preset else load_config(args).sound
    src = open_input(args)
    pipe = make_pipeline(args)
    fps = getattr(src, "fps", None) or args.fps
    period = 1.0 / fps if fps else 1.0 / 30  # a source with no rate (a camera) is taken as it comes
    decimation(args.decimate, 1)  # a bad value fails before the source is read
    raw = iter(src)
    whole = next(raw, None)
    if whole is None:
        raise InputError(f"{args.input}: no frame to play")
    step = decimation(args.decimate, whole.size[0])
    first = whole.decimated(step)
    if step > 1:
        print(
            f"listen: reads every {step} pixels of every {step} rows: {whole.size[0]}x{whole.size[1]} "
            f"as {first.size[0]}x{first.size[1]} (--decimate 1 reads them all)",
            file=sys.stderr,
        )
    frames = prefetch(decimated(raw, step), ahead=2)
    pipe.warm_up(first)

    log = open(args.log, "w", encoding="utf-8") if args.log else None  # closed in the finally below
    if args.wav:
        with needs_extra("sound", "writing the played sound (--wav)"):
            import soundfile  # noqa: F401 - the audio process writes it; fail here, before the device opens
    audio = AudioProcess(
        mapping,
        args.samplerate,
        first.size,
        _device(args.device),
        args.block,
        args.wav,
        realtime=args.realtime,
        binaural=args.binaural,
    )
    print(f"audio callback: {audio.priority}; PortAudio output latency {1e3 * audio.latency_s:.1f} ms", file=sys.stderr)
    parts: dict[str, list[float]] = {"latency_ms": [], "pipeline_ms": [], "wait_ms": [], "dac_ms": []}
    played = dropped = 0

    def write_events() -> None:
        for ev in audio.drain():
            rec = ev.record()
            for name, values in parts.items():
                if rec[name] is not None:
                    values.append(rec[name])
            if log is not None:
                log.write(json.dumps(rec) + "\n")

    gc.freeze()  # modules and kernels loaded so far live as long as the process: no full collection stalls
    try:
        pacer = Pacer(period, clock=time.perf_counter)
        start = pacer.due
        stream = itertools.chain([first], frames)
        i = -1
        while True:
            t_read = time.perf_counter()
            frame = next(stream, None)
            if frame is None:
                break
            i += 1
            # A source slower than its own rate (a simulator on a busy machine) is played as it
            # comes rather than dropped frame after frame (the viewer's rule).
            pacer.note_read(time.perf_counter() - t_read)
            if args.seconds is not None and time.perf_counter() - start >= args.seconds:
                break
            if fps:
                if not pacer.admit(frame.time_s if frame.time_s is not None else i * period):
                    dropped += 1
                    continue
            # A recording's frame "arrives" when it is due, as a camera's would, even when the loop
            # reaches it later; one from a source slower than its rate (or a camera) when it is read.
            arrival = pacer.due if fps and not pacer.slow_source else time.perf_counter()
            result = pipe.process(frame)
            audio.update(
                result.tree,
                result.segmentation.objects,
                frame=frame.index,
                arrival_s=arrival,
                intrinsics=frame.intrinsics,
                gravity=frame.gravity,
            )
            played += 1
            write_events()
        time.sleep(period)  # the last frame is heard for its period, as every other
    finally:
        gc.unfreeze()
        try:
            stats = audio.stop()
        finally:
            write_events()
            if log is not None:
                log.close()
    lat = percentiles(parts["latency_ms"])
    split = {k: percentiles(parts[k])["p50"] for k in ("pipeline_ms", "wait_ms", "dac_ms")}
    cb = percentiles([1e3 * s for s in stats["callback_s"]])
    print(
        f"played {played} frame(s), dropped {dropped} late, {stats['superseded']} replaced before they were heard; "
        f"{stats['underflows']} underflow(s) in {stats['blocks']} blocks of {args.block} samples "
        f"at {args.samplerate} Hz"
    )
    print(
        f"latency frame -> DAC: p50 {lat['p50']:.1f} ms, p95 {lat['p95']:.1f} ms, max {lat['max']:.1f} ms; "
        f"callback p50 {cb['p50']:.3f} ms, max {cb['max']:.3f} ms; {audio.chooser.distinct} distinct voice(s)"
    )
    print(
        f"latency p50 by part: pipeline {split['pipeline_ms']:.1f} ms, to the next block {split['wait_ms']:.1f} ms, "
        f"device buffer {split['dac_ms']:.1f} ms"
    )
    if args.wav:
        print(f"wrote {args.wav}: what was played")
    sys.stdout.flush()
    return 0
