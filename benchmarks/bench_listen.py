"""Live sound (`depthgram listen`): frame-to-DAC latency, underflows, callback time and CPU share.

Run: ``.venv/bin/python benchmarks/bench_listen.py [--seconds S] [--device D]`` (``depthgram bench
listen``; ``--quick`` plays 10 s). The whole loop runs as ``depthgram listen`` runs it: a 640x480
recording (7-Scenes red kitchen from ``../shared/data``, looped; ``sim:corridor?size=640x480``
without it) through the pipeline at 30 frames/s, each frame's voices sent to the audio process,
which plays 256-sample blocks at 48 kHz. Without ``--device`` the sound goes to a JACK dummy
server the benchmark starts (``jackd --no-realtime -d dummy``; Debian ``jackd2``), a real clocked
device on a machine with no sound card.

Targets (issue 29): latency p50 <= 60 ms, p95 <= 100 ms, max <= 150 ms; 0 underflows at a
256-sample block; synthesis <= 5 % of one core with 6 voices and 3 surfaces.
"""

from __future__ import annotations

import argparse
import itertools
import os
import re
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SEVEN_SCENES = ROOT.parent / "shared" / "data" / "7scenes_redkitchen_seq"
SR, BLOCK = 48000, 256


def _jack(realtime: bool, log: Path) -> subprocess.Popen[bytes] | None:
    """Start a JACK dummy server for this process and its children; None when jackd is missing.

    ``realtime``: ``jackd -R`` (its driver and clients' process threads SCHED_FIFO), as an audio
    system runs; else ``--no-realtime``, where even an idle client underflows on a loaded machine.
    The server's messages go to ``log`` (:func:`_xruns` reads them).
    """
    if shutil.which("jackd") is None or shutil.which("jack_lsp") is None:
        return None
    os.environ["JACK_DEFAULT_SERVER"] = f"depthgram-bench-{os.getpid()}"
    os.environ["JACK_NO_AUDIO_RESERVATION"] = "1"
    with log.open("wb") as out:
        proc = subprocess.Popen(
            ["jackd", "-R" if realtime else "--no-realtime", "-d", "dummy", "-r", str(SR), "-p", str(BLOCK)],
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    for _ in range(100):
        if "system:playback_1" in subprocess.run(["jack_lsp"], capture_output=True, text=True).stdout:
            return proc
        time.sleep(0.1)
    proc.kill()
    return None


def _control_client() -> subprocess.Popen[bytes] | None:
    """Start ``jack_metro`` (a C client of the jackd2 examples) on the server beside ours, or None.

    A control: a compiled client doing almost nothing, at the same priority. Where it, too, has
    cycles it had not finished, the machine (a virtual one's scheduling), not our callback, is late.
    """
    if shutil.which("jack_metro") is None:
        return None
    return subprocess.Popen(
        ["jack_metro", "-b", "120", "-n", "metro"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )


def _xruns(log: Path) -> dict[str, Any]:
    """What the JACK server logged of its xruns: its dummy driver's late wake-ups and unfinished clients.

    jackd2's timed (dummy) driver logs ``JackTimedDriver::Process XRun = N usec`` when its own
    timer thread woke ``N`` us after the cycle's time, and the engine ``JackEngine::XRun: client
    = NAME was not finished`` for each client still busy when a cycle began. PortAudio reports
    every server xrun to its callback as an output underflow, whichever client (or the driver)
    was late.
    """
    text = log.read_text(errors="replace") if log.exists() else ""
    late = [int(m) for m in re.findall(r"JackTimedDriver::Process XRun = (\d+) usec", text)]
    unfinished = re.findall(r"JackEngine::XRun: client = (.+?) was not finished", text)
    return {
        "driver_late": len(late),
        "driver_late_us": (min(late), max(late)) if late else None,
        "ours_unfinished": sum(1 for c in unfinished if c.startswith("PortAudio")),
        "control_unfinished": sum(1 for c in unfinished if c == "metro"),
    }


def _frames(seconds: float, decimate: str) -> tuple[str, Any, int, Iterator[Any]]:
    """A 640x480 recording looped for ``seconds`` at 30 frames/s: (what, first frame, step, the frames after it).

    The frames after the first are read as ``listen`` reads them (:func:`depthgram.sources.base.decimated`),
    ``decimate`` as its ``--decimate``.
    """
    from depthgram import read
    from depthgram.commands.listen import decimation
    from depthgram.sources.base import decimated

    spec = str(SEVEN_SCENES) if SEVEN_SCENES.is_dir() else "sim:corridor?size=640x480&frames=300"
    n = int(seconds * 30) + 1
    first_pass = iter(read(spec))
    whole = next(first_pass)
    step = decimation(decimate, whole.size[0])

    def loop() -> Iterator[Any]:
        yield from decimated(first_pass, step)
        while True:
            yield from decimated(iter(read(spec)), step)

    return spec, whole, step, itertools.islice(loop(), n - 1)


def synthesis_share(reps: int = 2000, binaural: bool = False) -> dict[str, float]:
    """CPU share of one core (thread time / audio time) to render 6 beeps and 3 glides in 256-sample blocks.

    ``binaural``: through slab's KEMAR responses, each voice from its own direction.
    """
    from depthgram.sound import SoundMapping
    from depthgram.sound.synth import Voice, VoiceBank

    m = SoundMapping(max_voices=6)
    hrirs = None
    if binaural:
        from depthgram.sound.binaural import load_hrirs

        hrirs = load_hrirs("kemar", SR)
    bank = VoiceBank(m, SR, hrirs)
    bank.warm_up()
    targets = {}
    for i in range(6):
        v = Voice(
            ("o", i),
            220.0 * 2 ** (i / 2),
            220.0 * 2 ** (i / 2),
            0.5,
            0.5,
            (0.8, 0.6),
            (0.8, 0.6),
            3.0 + i,
            0.08,
            3,
            0.0,
            -60.0 + 24.0 * i,
            10.0 * (i % 3) - 10.0,
        )
        targets[v.key] = v
    for j in range(3):
        g = Voice(("g", j), 500.0, 300.0, 0.2, 0.1, (0.9, 0.3), (0.3, 0.9), 0.0, 0.0, 1, 0.0, 30.0 * j - 30.0, -20.0)
        targets[g.key] = g
    for _ in range(50):
        bank.render(targets, BLOCK)
    t0 = time.thread_time()
    for k in range(reps):
        if k % 9 == 0:  # a new frame every ~9 blocks (30 frames/s): every voice ramps
            targets = {key: _nudge(v, k) for key, v in targets.items()}
        bank.render(targets, BLOCK)
    cpu = time.thread_time() - t0
    return {"block_us": 1e6 * cpu / reps, "share": cpu / (reps * BLOCK / SR)}


def _nudge(v: Any, k: int) -> Any:
    from dataclasses import replace

    f = 1.0 + 0.001 * (k % 7)
    # The direction moves too: a binaural voice changes filters (a cross-fade) on most frames.
    az = None if v.azimuth is None else v.azimuth + (5.0 if k % 2 else -5.0)
    return replace(v, freq_a=v.freq_a * f, freq_b=v.freq_b * f, gain_a=v.gain_a * 0.999, azimuth=az)


def live(seconds: float, device: int | str | None, realtime: bool = True, decimate: str = "auto") -> dict[str, Any]:
    """Play ``seconds`` of the loop; return the figures.

    ``decimate``: as ``listen --decimate`` (``auto`` reads every 2nd pixel of 640 x 480).
    """
    import gc

    import psutil

    from depthgram.pacing import Pacer
    from depthgram.pipeline import Pipeline
    from depthgram.sound.live import AudioProcess, percentiles
    from depthgram.sources.prefetch import prefetch

    spec, whole, step, frames = _frames(seconds, decimate)
    read_cpu = [0.0]  # CPU of the reader thread: decoding the recording's PNGs, which a camera does not need

    def timed() -> Iterator[Any]:
        while True:
            t = time.thread_time()
            f = next(frames, None)
            if f is None:
                return
            read_cpu[0] += time.thread_time() - t
            yield f

    src = prefetch(timed(), ahead=2)
    first = whole.decimated(step)
    pipe = Pipeline()
    pipe.warm_up(first)
    audio = AudioProcess(None, SR, first.size, device, BLOCK, realtime=realtime)
    child = psutil.Process(audio._proc.pid)
    me = psutil.Process()
    parts: dict[str, list[float]] = {"latency_ms": [], "pipeline_ms": [], "wait_ms": [], "dac_ms": []}
    pipeline_ms: list[float] = []  # pipeline.process alone, every frame

    under_at: list[tuple[float, int]] = []  # (seconds into the stream, underflows so far) at each frame heard

    def collect() -> None:
        for e in audio.drain():
            under_at.append((e.sample / SR, e.underflows))
            rec = e.record()
            for k, vals in parts.items():
                if rec[k] is not None:
                    vals.append(rec[k])

    load0 = os.getloadavg()
    dropped = played = 0
    gc.freeze()
    c0, m0, t0 = child.cpu_times(), me.cpu_times(), time.perf_counter()
    pacer = Pacer(1 / 30, clock=time.perf_counter)
    try:
        for frame in itertools.chain([first], src):
            if played + dropped:
                pacer.advance()
            if pacer.late():
                dropped += 1
                continue
            wait = pacer.wait_s()
            if wait > 0:
                time.sleep(wait)
            arrival = pacer.due  # when a camera would have delivered it, even if the loop comes later
            t_p = time.perf_counter()
            r = pipe.process(frame)
            pipeline_ms.append(1e3 * (time.perf_counter() - t_p))
            audio.update(r.tree, r.segmentation.objects, frame=played, arrival_s=arrival, intrinsics=frame.intrinsics)
            played += 1
            collect()
        c1, m1, t1 = child.cpu_times(), me.cpu_times(), time.perf_counter()
    finally:
        gc.unfreeze()
        stats = audio.stop()
    collect()
    load1 = os.getloadavg()
    wall = t1 - t0
    cb = np.asarray(stats["callback_s"]) * 1e3
    return {
        "input": spec,
        "size": whole.size,
        "read": first.size,
        "seconds": wall,
        "frames": played,
        "dropped": dropped,
        "latency": percentiles(parts["latency_ms"]),
        "parts": {k: percentiles(v) for k, v in parts.items() if k != "latency_ms"},
        "process_ms": percentiles(pipeline_ms),
        "load": (load0, load1),
        "priority": stats["priority"],
        "superseded": stats["superseded"],
        "underflows": stats["underflows"],
        "blocks": stats["blocks"],
        "callback": {"p50": float(np.median(cb)), "p95": float(np.percentile(cb, 95)), "max": float(cb.max())},
        # When it went wrong: the blocks whose callback outran a block, and the underflows by minute.
        "slow_callbacks_s": [round(float(i) * BLOCK / SR, 1) for i in np.flatnonzero(cb > 1e3 * BLOCK / SR)],
        "underflows_by_minute": _by_minute(under_at),
        "callback_share": float(cb.sum() / 1e3 / max(wall, 1e-9)),
        "audio_process_share": (c1.user + c1.system - c0.user - c0.system) / wall,
        "loop_share": (m1.user + m1.system - m0.user - m0.system) / wall,
        "read_share": read_cpu[0] / wall,
        "distinct_voices": audio.chooser.distinct,
    }


def _us(us: int) -> str:
    """A duration in us, written in ms from 1 ms."""
    return f"{us} us" if us < 1000 else f"{us / 1e3:.1f} ms"


def _by_minute(marks: list[tuple[float, int]]) -> list[int]:
    """Underflows in each minute of the stream, from (seconds, count so far) marks."""
    out: list[int] = []
    last = 0
    for t, n in sorted(marks):
        minute = int(t // 60)
        while len(out) <= minute:
            out.append(0)
        out[minute] += n - last
        last = n
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Print the live figures; exit 0 (1 when no audio device could be used)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--quick", action="store_true", help="10 s of play instead of --seconds")
    p.add_argument("--seconds", type=float, default=60.0, help="seconds of play (default 60)")
    p.add_argument("--device", default=None, help="PortAudio output device (default: a JACK dummy server)")
    p.add_argument(
        "--server",
        choices=("realtime", "normal"),
        default="realtime",
        help="the JACK dummy server's scheduling: jackd -R (default) or --no-realtime",
    )
    p.add_argument(
        "--no-realtime-callback",
        dest="realtime",
        action="store_false",
        help="leave the audio callback at normal priority (as `listen --no-realtime`)",
    )
    p.add_argument(
        "--decimate", default="auto", metavar="N", help="as listen --decimate (default auto: 320 pixels a row)"
    )
    p.add_argument(
        "--control",
        action="store_true",
        help="run jack_metro (a C client) beside ours on the dummy server: do its cycles go unfinished as "
        "often as ours? (every client's late cycle is an underflow to all: it adds to the count)",
    )
    args = p.parse_args(argv)
    seconds = 10.0 if args.quick else args.seconds
    syn = synthesis_share()
    print(
        f"synthesis, 6 beeps + 3 glides, {BLOCK}-sample blocks at {SR} Hz: {syn['block_us']:.0f} us a block, "
        f"{100 * syn['share']:.1f} % of one core (target <= 5 %)"
    )
    import importlib.util

    if importlib.util.find_spec("slab") is not None:
        b = synthesis_share(binaural=True)
        print(
            f"  binaural (KEMAR, 256 taps), the same voices: {b['block_us']:.0f} us a block, "
            f"{100 * b['share']:.1f} % of one core"
        )
    jack = control = None
    log = Path(tempfile.mkdtemp(prefix="depthgram-jackd-")) / "jackd.log"
    if args.device is None:
        jack = _jack(args.server == "realtime", log)
        if jack is None:
            print("listen: no --device and no jackd (Debian jackd2) to start a dummy device: live part skipped")
            return 0
        control = _control_client() if args.control else None
    device = int(args.device) if args.device and args.device.isdigit() else args.device
    try:
        r = live(seconds, device, args.realtime, args.decimate)
    finally:
        for proc in (control, jack):
            if proc is not None:
                proc.terminate()
                proc.wait(timeout=10)
    lat, cb = r["latency"], r["callback"]
    mode = "-R" if args.server == "realtime" else "--no-realtime"
    where = args.device or f"JACK dummy (jackd {mode} -d dummy -r 48000 -p 256)"
    (w, h), (rw, rh) = r["size"], r["read"]
    print(f"input {r['input']} ({w}x{h}, read {rw}x{rh}) at 30 frames/s for {r['seconds']:.1f} s to {where}")
    print(
        f"  load average {r['load'][0][0]:.2f} at the start, {r['load'][1][0]:.2f} at the end "
        f"({os.cpu_count()} cores); audio callback {r['priority']}"
    )
    print(
        f"  frames played {r['frames']}, dropped late {r['dropped']}, replaced before heard {r['superseded']}; "
        f"{r['distinct_voices']} distinct voices"
    )
    print(
        f"  latency frame -> DAC: p50 {lat['p50']:.1f} ms, p95 {lat['p95']:.1f} ms, max {lat['max']:.1f} ms "
        "(targets 60 / 100 / 150)"
    )
    parts, proc = r["parts"], r["process_ms"]
    print(
        "  latency by part, p50 / p95 / max (ms): "
        + "; ".join(
            f"{name} {parts[k]['p50']:.1f} / {parts[k]['p95']:.1f} / {parts[k]['max']:.1f}"
            for name, k in (("pipeline", "pipeline_ms"), ("to the next block", "wait_ms"), ("device", "dac_ms"))
        )
        + f" (Pipeline.process alone {proc['p50']:.1f} / {proc['p95']:.1f} / {proc['max']:.1f})"
    )
    print(f"  underflows {r['underflows']} in {r['blocks']} blocks (target 0); by minute {r['underflows_by_minute']}")
    if jack is not None:
        x = _xruns(log)
        span = x["driver_late_us"]
        print(
            f"  the JACK server's log: its dummy driver woke late {x['driver_late']} times"
            + (f" (by {span[0]} us to {_us(span[1])})" if span else "")
            + f"; cycles a client had not finished: ours (PortAudio) {x['ours_unfinished']}, "
            + (
                f"jack_metro (a C client doing nothing, the control) {x['control_unfinished']}"
                if control is not None
                else "no control client (--control runs one)"
            )
        )
    slow = r["slow_callbacks_s"]
    print(f"  callbacks longer than a block: {len(slow)}" + (f", at {slow[:12]} s into the stream" if slow else ""))
    print(
        f"  callback p50 {cb['p50']:.3f} ms, p95 {cb['p95']:.3f} ms, max {cb['max']:.3f} ms; "
        f"callbacks {100 * r['callback_share']:.1f} % of a core, audio process {100 * r['audio_process_share']:.1f} %, "
        f"pipeline process {100 * r['loop_share']:.1f} % (of which reading and decoding the recording "
        f"{100 * r['read_share']:.1f} %)"
    )
    whole = r["loop_share"] + r["audio_process_share"]
    print(
        f"  the whole loop {100 * whole:.1f} % of a core (target <= 50 %); without decoding the recording "
        f"(a camera's frames come decoded) {100 * (whole - r['read_share']):.1f} %"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
