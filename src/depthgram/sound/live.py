"""Live sound: the scene played on an audio device as frames arrive.

The synthesis runs in the audio device's callback, one block at a time. A new frame only
swaps the voices' targets (a reference assignment, atomic under the interpreter lock); the
callback ramps every voice toward whatever targets it finds. A slow frame therefore freezes
the scene for a moment but never delays the sound, and nothing queues behind a stall.

:class:`LiveSonifier` is the device-free part (feed trees, pull blocks); :class:`LivePlayer`
drives it from a PortAudio stream through ``sounddevice`` (extra ``[listen]``).
"""

from __future__ import annotations

import math
import os
import queue
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError
from depthgram.scene.tree import SceneTree
from depthgram.segmentation.objects import SceneObject
from depthgram.sound.binaural import HRIRSet
from depthgram.sound.choose import Chooser
from depthgram.sound.mapping import SoundMapping
from depthgram.sound.slot import TargetSlot, Update
from depthgram.sound.synth import Voice, VoiceBank

#: Seconds the audio process has to fade out, stop its device and report.
STOP_TIMEOUT_S = 15.0

#: Priority (SCHED_FIFO, 1..99) asked for the audio callback's thread when it is not realtime already.
RT_PRIORITY = 70

#: Seconds between two relays of the callback's block events to the pipeline's process. The
#: events only feed the log and the latency figures, which need them in order, not at once;
#: every wake-up of the relaying thread costs the audio process its interpreter's time.
RELAY_S = 0.1

__all__ = [
    "RELAY_S",
    "RT_PRIORITY",
    "STOP_TIMEOUT_S",
    "AudioProcess",
    "BlockEvent",
    "LivePlayer",
    "LiveSonifier",
    "percentiles",
]


class LiveSonifier:
    """A scene's sound rendered block by block while new scenes replace the targets.

    Parameters
    ----------
    mapping : SoundMapping, optional
        The cue mapping (default preset when None).
    samplerate : int
        Samples per second (Hz).
    frame_size : tuple of int, optional
        (width, height) of the frames (px); each tree's own when omitted.
    hrirs : HRIRSet, optional
        Head-related impulse responses at ``samplerate``: each voice is then rendered binaurally
        from its direction (:mod:`depthgram.sound.binaural`) instead of panned.

    Notes
    -----
    :meth:`update` may be called from any thread, :meth:`render` from one other (the audio
    callback). Voices are chosen by a :class:`~depthgram.sound.choose.Chooser`, so a voice
    belongs to a tracked object and keeps its place while the object stays.

    Examples
    --------
    >>> live = LiveSonifier(SoundMapping(), 48000, (640, 480))
    >>> live.update(tree, objects)  # doctest: +SKIP
    >>> block = live.render(256)  # (256, 2) float32, from the audio callback
    """

    def __init__(
        self,
        mapping: SoundMapping | None = None,
        samplerate: int = 48000,
        frame_size: tuple[int, int] | None = None,
        hrirs: HRIRSet | None = None,
    ) -> None:
        if not isinstance(samplerate, (int, np.integer)) or not 4000 <= samplerate <= 192000:
            raise InputError(f"samplerate must be an integer in 4000..192000 Hz, got {samplerate!r}")
        self.mapping = mapping or SoundMapping()
        self.samplerate = int(samplerate)
        self.frame_size = frame_size
        self._bank = VoiceBank(self.mapping, self.samplerate, hrirs)
        self._chooser = Chooser(self.mapping)
        self._next: Update | None = None  # written by update(), taken by render()
        self._targets: dict[tuple[str, int], Voice] = {}
        self.superseded = 0  # frames replaced by a newer one before any block carried them

    def update(
        self,
        tree: SceneTree,
        objects: Sequence[SceneObject] = (),
        *,
        frame: int = -1,
        arrival_s: float | None = None,
        intrinsics: Any = None,
        gravity: Any = None,
    ) -> None:
        """Make a new scene the voices' targets; the next block starts ramping toward it.

        Parameters
        ----------
        tree : SceneTree
        objects : sequence of SceneObject, optional
            The segmentation's objects, for the real extent of surfaces.
        frame : int
            The frame's index, reported back by :meth:`render_block` when a block first carries it.
        arrival_s : float, optional
            When the frame was captured or arrived (s, ``time.perf_counter`` clock), for latency.
        intrinsics : Intrinsics, optional
            The camera's, for the direction (azimuth) of each voice; image columns without them.
        gravity : Gravity, optional
            The frame's: pitch then follows elevation above the horizon (with the intrinsics).
        """
        size = self.frame_size or tree.frame_size
        if size is None:
            raise InputError("LiveSonifier: the tree does not carry the frame size; give frame_size=(width, height)")
        targets = self._chooser.voices(tree, size, objects, intrinsics, gravity)
        self.set_targets(targets, frame=frame, arrival_s=arrival_s)

    def set_targets(
        self,
        targets: dict[tuple[str, int], Voice],
        *,
        frame: int = -1,
        arrival_s: float | None = None,
        sent_s: float | None = None,
    ) -> None:
        """Make ``targets`` (voice key -> Voice, as :meth:`Chooser.voices` makes) the voices' targets.

        ``sent_s`` is when the targets were made (s, ``time.perf_counter``; now when omitted):
        the log splits the latency there.
        """
        pending = self._next
        if pending is not None:
            self.superseded += 1
        sent = time.perf_counter() if sent_s is None else sent_s
        self._next = Update(dict(targets), frame, arrival_s, sent)

    def warm_up(self) -> None:
        """Compile the synthesis kernels now, not in the first block of a live stream."""
        self._bank.warm_up()

    def clear(self) -> None:
        """Silence every voice (they fade out over the ramp)."""
        self._next = Update({}, -1, None)

    def render_block(self, n: int) -> tuple[NDArray[np.float32], Update | None]:
        """Return ``n`` stereo samples and the update this block is the first to carry (or None)."""
        taken = self._next
        if taken is not None:
            self._next = None
            self._targets = taken.targets
        return self._bank.render(self._targets, n).astype(np.float32), taken

    def render(self, n: int) -> NDArray[np.float32]:
        """Return the next ``n`` stereo samples (float32, shape (n, 2), in -1..1)."""
        return self.render_block(n)[0]

    @property
    def voices(self) -> dict[tuple[str, int], Voice]:
        """The targets of the voices sounding now (key -> parameters)."""
        return dict(self._targets)


def _schedule_callback(realtime: bool) -> str:
    """How the calling thread (the audio callback's) is scheduled; with ``realtime``, ask for SCHED_FIFO first.

    Returns
    -------
    str
        A one-line note for the user: realtime (and who set it) or normal priority (and why).
    """
    if not hasattr(os, "sched_getscheduler"):
        return "normal priority (no POSIX thread scheduling here)"
    # On Linux, pid 0 names the calling thread, not the whole process.
    given = os.sched_getparam(0).sched_priority if os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR) else 0
    if not realtime or given >= RT_PRIORITY:
        return f"realtime, set by the audio server (priority {given})" if given else "normal priority"
    try:
        # Above the audio process's helpers (they take the interpreter lock too); a server's
        # client priority (JACK's default is 5) is raised for the same reason.
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(RT_PRIORITY))
    except OSError as exc:  # no CAP_SYS_NICE and no rtprio limit: play on as the server set it
        why = f"realtime scheduling not permitted: {exc.strerror}"
        return f"realtime, set by the audio server (priority {given}; {why})" if given else f"normal priority ({why})"
    return f"realtime (SCHED_FIFO {RT_PRIORITY}, asked by depthgram" + (f"; the server gave {given})" if given else ")")


def _schedule_helpers() -> None:
    """Make the audio process's own threads realtime too (below the callback), where permitted.

    Every thread of the audio process takes the interpreter lock, the callback's included: a
    thread at normal priority preempted by another program while it holds the lock would stall
    a realtime callback (a priority inversion) for as long as that program runs. The helpers
    (relaying events, writing ``--wav``) hold it for microseconds at a time. Threads started
    after this call inherit the policy. A short switch interval bounds how long the callback
    waits for a helper that is running Python.
    """
    import sys

    sys.setswitchinterval(0.0005)
    if hasattr(os, "sched_setscheduler"):
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(max(1, RT_PRIORITY - 10)))
        except OSError:  # not permitted: the callback's note says so
            pass
    if sys.platform.startswith("linux"):
        # Keep the audio process's memory resident (mlockall(MCL_CURRENT | MCL_FUTURE)), as
        # audio servers do: a page fault in the callback waits for the disk, whatever the priority.
        import ctypes
        import ctypes.util

        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
            libc.mlockall(1 | 2)  # not permitted (RLIMIT_MEMLOCK): play on unlocked
        except (OSError, AttributeError):
            pass


@dataclass(frozen=True)
class BlockEvent:
    """The audio block that first carried a frame.

    Attributes
    ----------
    frame : int
        The frame's index.
    latency_ms : float or None
        From the frame's arrival to the DAC time of the block (ms); None without an arrival time.
    underflows : int
        Output underflows reported by the device so far.
    callback_ms : float
        Time spent in that block's callback (ms).
    sample : int
        Position of the block's first sample in the stream (samples since it started): where
        the frame starts in a copy of what was played.
    pipeline_ms : float or None
        The first part of the latency: from the frame's arrival to its voices leaving the
        pipeline (segmentation, tracking, choosing the voices) (ms).
    wait_ms : float or None
        From the voices leaving the pipeline to the start of the first callback that took them
        (crossing to the audio process and waiting for the next block) (ms).
    dac_ms : float or None
        From that callback's start to the DAC time of its block: the device's buffering (ms).
    """

    frame: int
    latency_ms: float | None
    underflows: int
    callback_ms: float
    sample: int = 0
    pipeline_ms: float | None = None
    wait_ms: float | None = None
    dac_ms: float | None = None

    def record(self) -> dict[str, Any]:
        """Return the JSON line of ``depthgram listen --log``."""

        def ms(x: float | None) -> float | None:
            return None if x is None else round(x, 3)

        return {
            "frame": self.frame,
            "latency_ms": ms(self.latency_ms),
            "underflows": self.underflows,
            "callback_ms": round(self.callback_ms, 4),
            "sample": self.sample,
            "pipeline_ms": ms(self.pipeline_ms),
            "wait_ms": ms(self.wait_ms),
            "dac_ms": ms(self.dac_ms),
        }


class LivePlayer:
    """Plays a :class:`LiveSonifier` on a PortAudio output device.

    Parameters
    ----------
    live : LiveSonifier
    device : int or str, optional
        PortAudio device index or (part of) its name; the default output when None.
    block : int
        Samples per callback (the audio block).
    copy : callable, optional
        Called from a writer thread with each block played (float32, (n, 2)), in order: a copy
        of exactly what went to the device (``depthgram listen --wav``).
    poll : callable, optional
        Called at the start of every callback, before the block is rendered: where the callback
        takes new targets from another process (:meth:`TargetSlot.take`).
    realtime : bool
        Ask for realtime scheduling (``SCHED_FIFO``, :data:`RT_PRIORITY`) of the callback's
        thread on its first block when the device did not give it; :attr:`priority` says what
        the thread got.

    Notes
    -----
    The DAC time of a block is read from the stream's clock and mapped onto
    ``time.perf_counter`` once per callback, so latencies compare with arrival times taken
    with that clock.
    """

    def __init__(
        self,
        live: LiveSonifier,
        device: int | str | None = None,
        block: int = 256,
        copy: Callable[[NDArray[np.float32]], None] | None = None,
        poll: Callable[[], None] | None = None,
        realtime: bool = False,
    ) -> None:
        from depthgram._optional import needs_extra

        if not isinstance(block, int) or not 16 <= block <= 16384:
            raise InputError(f"block must be an integer number of samples in 16..16384, got {block!r}")
        with needs_extra("listen", "playing sound live"):
            import sounddevice as sd

        self.live = live
        self.block = block
        self.underflows = 0
        self.blocks = 0
        self.samples = 0  # samples played so far
        self.callback_s: list[float] = []  # time spent in each callback (s)
        self.events: queue.SimpleQueue[BlockEvent] = queue.SimpleQueue()
        self._copy = copy
        self._poll = poll
        self._realtime = realtime
        self.priority = "not started"  # how the callback's thread is scheduled (set by its first block)
        self._copies: queue.SimpleQueue[NDArray[np.float32] | None] = queue.SimpleQueue()
        self._writer: threading.Thread | None = None
        self._error: BaseException | None = None
        try:
            self.stream = sd.OutputStream(
                samplerate=live.samplerate,
                blocksize=block,
                device=device,
                channels=2,
                dtype="float32",
                latency="low",
                callback=self._callback,
            )
        except (sd.PortAudioError, ValueError) as exc:
            raise InputError(
                f"cannot open audio output device {device if device is not None else '(default)'} at "
                f"{live.samplerate} Hz, {block}-sample blocks: {exc}; list devices with "
                "'python -m sounddevice'"
            ) from exc

    def _callback(self, outdata: Any, frames: int, time_info: Any, status: Any) -> None:
        t0 = time.perf_counter()
        if self.blocks == 0:
            self.priority = _schedule_callback(self._realtime)
        if status.output_underflow:
            self.underflows += 1
        if self._poll is not None:
            self._poll()
        audio, taken = self.live.render_block(frames)
        outdata[:] = audio
        t1 = time.perf_counter()
        self.callback_s.append(t1 - t0)
        self.blocks += 1
        at = self.samples
        self.samples += frames
        if self._copy is not None:
            self._copies.put(audio)
        if taken is not None and taken.frame >= 0:
            now_dev = time_info.currentTime
            ahead = time_info.outputBufferDacTime - now_dev if now_dev > 0 else self.stream.latency
            lat = None if taken.arrival_s is None else (t0 + ahead - taken.arrival_s) * 1e3
            pipe = None if taken.arrival_s is None or taken.sent_s is None else (taken.sent_s - taken.arrival_s) * 1e3
            wait = None if taken.sent_s is None else (t0 - taken.sent_s) * 1e3
            self.events.put(BlockEvent(taken.frame, lat, self.underflows, (t1 - t0) * 1e3, at, pipe, wait, ahead * 1e3))

    def _write_copies(self) -> None:
        assert self._copy is not None
        while (block := self._copies.get()) is not None:
            try:
                self._copy(block)
            except BaseException as exc:  # reported by stop(); the stream must not die with it
                self._error = exc
                return

    def start(self) -> None:
        """Render one block first (compiling the kernels), then start the device."""
        self.live.warm_up()
        if self._copy is not None:
            self._writer = threading.Thread(target=self._write_copies, name="depthgram-listen-wav", daemon=True)
            self._writer.start()
        self.stream.start()

    def stop(self, fade_s: float = 0.05) -> None:
        """Fade out, stop the device and finish the copy."""
        if self.stream.active:
            self.live.clear()
            time.sleep(max(fade_s, self.live.mapping.ramp_s) + 2 * self.block / self.live.samplerate)
            self.stream.stop()
        self.stream.close()
        if self._writer is not None:
            self._copies.put(None)
            self._writer.join()
        if self._error is not None:
            raise self._error

    def drain(self) -> list[BlockEvent]:
        """Return the events posted by the callback since the last call."""
        out = []
        while True:
            try:
                out.append(self.events.get_nowait())
            except queue.Empty:
                return out

    def __enter__(self) -> LivePlayer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _serve(
    conn: Connection,
    shared: Any,
    mapping: SoundMapping,
    samplerate: int,
    device: int | str | None,
    block: int,
    wav: str | None,
    realtime: bool,
    binaural: str | None = None,
) -> None:
    """Play the targets found in the shared slot; send back block events and, at the end, statistics."""
    import gc
    import signal

    # Ctrl-C reaches the whole process group: the pipeline's process decides when to stop (it
    # sends "stop"), so the sound fades out instead of breaking off mid-block.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    slot = TargetSlot(shared)

    def poll() -> None:
        update = slot.take()
        if update is not None:
            live.set_targets(update.targets, frame=update.frame, arrival_s=update.arrival_s, sent_s=update.sent_s)

    try:
        out: Any = None
        if wav is not None:
            import soundfile as sf

            out = sf.SoundFile(wav, "w", samplerate=samplerate, channels=2, subtype="FLOAT")
        hrirs = None
        if binaural is not None:
            from depthgram.sound.binaural import load_hrirs

            hrirs = load_hrirs(binaural, samplerate)
        live = LiveSonifier(mapping, samplerate, (2, 2), hrirs)
        live.warm_up()
        if realtime:
            # Only now: loading the HRIRs and compiling the kernels take seconds of CPU, which
            # at a realtime priority would hold off everything else on that core.
            _schedule_helpers()
        player = LivePlayer(
            live, device, block, copy=out.write if out is not None else None, poll=poll, realtime=realtime
        )
        player.start()
        # Whatever the kernels and the device allocated so far lives as long as the process: a
        # full collection then never walks it from inside the callback.
        gc.freeze()
        deadline = time.monotonic() + 2.0
        while player.blocks == 0 and time.monotonic() < deadline:  # the first block sets its priority
            time.sleep(0.005)
    except BaseException as exc:
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    conn.send(("ready", (float(player.stream.latency), player.priority)))
    try:
        # This thread only relays the callback's events and waits for "stop": it sleeps in
        # poll() (no interpreter lock held) all but a few microseconds every RELAY_S.
        while not conn.poll(RELAY_S):
            events = player.drain()
            if events:
                conn.send(("events", events))
    except EOFError:  # the pipeline's process is gone: stop too
        pass
    finally:
        player.stop()
        if out is not None:
            out.close()
        stats = {
            "underflows": player.underflows,
            "blocks": player.blocks,
            "callback_s": player.callback_s,
            "superseded": slot.superseded + live.superseded,
            "priority": player.priority,
        }
        try:
            conn.send(("events", player.drain()))
            conn.send(("done", stats))
        except OSError:  # nobody left to tell
            pass


class AudioProcess:
    """A :class:`LivePlayer` in a process of its own, fed the targets a :class:`Chooser` makes here.

    The audio callback needs Python's interpreter lock every block (5.3 ms at 256 samples and
    48 kHz); in the pipeline's process a busy thread holds it for milliseconds and the device
    underflows. In its own process the callback competes with nothing but a loop that mostly
    waits on a pipe. Scenes are chosen here and only their voices (a few hundred bytes) cross,
    through a :class:`TargetSlot` the callback reads itself at the start of every block.

    Parameters
    ----------
    mapping : SoundMapping, optional
    samplerate : int
        Samples per second (Hz).
    frame_size : tuple of int, optional
        (width, height) of the frames (px); each tree's own when omitted.
    device : int or str, optional
        PortAudio output device; the default one when None.
    block : int
        Samples per audio block.
    wav : str, optional
        File to write a copy of exactly what was played to (32-bit float WAV).
    realtime : bool
        Ask for realtime scheduling of the audio callback (falls back to normal priority where
        it is not permitted; :attr:`priority` says which).
    binaural : str, optional
        ``"kemar"`` or a SOFA file's path: render every voice through those head-related
        impulse responses (:func:`depthgram.sound.binaural.load_hrirs`), loaded in the audio process.

    Attributes
    ----------
    latency_s : float
        The output latency the device reports (s).
    priority : str
        How the audio callback's thread is scheduled (one line, for the user).
    """

    def __init__(
        self,
        mapping: SoundMapping | None = None,
        samplerate: int = 48000,
        frame_size: tuple[int, int] | None = None,
        device: int | str | None = None,
        block: int = 256,
        wav: str | None = None,
        realtime: bool = True,
        binaural: str | None = None,
    ) -> None:
        import importlib.util
        import multiprocessing
        import sys

        # Only looked for, not imported: importing it starts PortAudio (and a JACK client) in
        # this process too, which the audio process alone needs.
        if sys.modules.get("sounddevice", ...) is None or importlib.util.find_spec("sounddevice") is None:
            from depthgram.errors import MissingExtraError

            raise MissingExtraError(
                "playing sound live needs the optional package 'sounddevice': pip install 'depthgram[listen]'"
            )

        if binaural is not None:
            _check_binaural(binaural)
        self.mapping = mapping or SoundMapping()
        self.samplerate = samplerate
        self.frame_size = frame_size
        self.chooser = Chooser(self.mapping)
        self._inbox: list[BlockEvent] = []  # received by stop(), not yet returned by drain()
        self.stats: dict[str, Any] = {}
        ctx = multiprocessing.get_context("spawn")  # no fork of a process with threads
        self._conn, child = ctx.Pipe()
        # Room for every voice the chooser may make, with a margin for a mapping changed later.
        self._slot = TargetSlot.create(ctx, 2 * (self.mapping.max_voices + self.mapping.max_glides) + 8)
        self._proc = ctx.Process(
            target=_serve,
            args=(child, self._slot.shared, self.mapping, samplerate, device, block, wav, realtime, binaural),
            name="depthgram-audio",
        )
        self._proc.start()
        child.close()
        kind, value = self._recv()
        if kind == "error":
            self._proc.join()
            raise InputError(f"audio output: {value}")
        self.latency_s = float(value[0])
        self.priority = str(value[1])

    def _recv(self) -> tuple[str, Any]:
        try:
            msg = self._conn.recv()
        except EOFError:
            raise InputError(f"the audio process ended unexpectedly (exit status {self._proc.exitcode})") from None
        return msg[0], msg[1]

    def update(
        self,
        tree: SceneTree,
        objects: Sequence[SceneObject] = (),
        *,
        frame: int = -1,
        arrival_s: float | None = None,
        intrinsics: Any = None,
        gravity: Any = None,
    ) -> None:
        """Send a new scene's voices to the audio process (see :meth:`LiveSonifier.update`)."""
        size = self.frame_size or tree.frame_size
        if size is None:
            raise InputError("AudioProcess: the tree does not carry the frame size; give frame_size=(width, height)")
        targets = self.chooser.voices(tree, size, objects, intrinsics, gravity)
        self.set_targets(targets, frame=frame, arrival_s=arrival_s)

    def set_targets(
        self, targets: dict[tuple[str, int], Voice], *, frame: int = -1, arrival_s: float | None = None
    ) -> None:
        """Put ``targets`` in the slot the audio callback reads (see :meth:`LiveSonifier.set_targets`)."""
        self._slot.put(targets, frame, arrival_s, time.perf_counter())

    def drain(self) -> list[BlockEvent]:
        """Return the block events received since the last call."""
        out, self._inbox = self._inbox, []
        while not self._conn.closed and not self.stats and self._conn.poll():
            kind, value = self._recv()
            if kind == "events":
                out += value
            elif kind == "done":
                self.stats = value
        return out

    def stop(self) -> dict[str, Any]:
        """Fade out, stop the device, wait for the process; return its statistics.

        Returns
        -------
        dict
            ``underflows``, ``blocks``, ``callback_s`` (time in each callback, s), ``superseded``
            (frames replaced by a newer one before a block carried them), ``priority``.
        """
        if self._proc.is_alive() and not self.stats:
            self._conn.send(("stop",))
            deadline = time.monotonic() + STOP_TIMEOUT_S
            while not self.stats:
                if not self._conn.poll(max(0.0, deadline - time.monotonic())):
                    self._proc.kill()
                    self._proc.join()
                    raise InputError(
                        f"the audio process did not stop within {STOP_TIMEOUT_S:g} s (is the audio device stuck?)"
                    )
                kind, value = self._recv()
                if kind == "events":
                    self._inbox += value
                elif kind == "done":
                    self.stats = value
        self._proc.join()
        return self.stats


def _check_binaural(spec: str) -> None:
    """Fail here, before any process or device starts, when the HRIRs named cannot be read."""
    import importlib.util
    import sys
    from pathlib import Path

    from depthgram.errors import MissingExtraError

    def missing(name: str) -> bool:
        return sys.modules.get(name, ...) is None or importlib.util.find_spec(name) is None

    if spec.lower() == "kemar":
        if missing("slab"):
            raise MissingExtraError(
                "binaural sound with the KEMAR responses needs the optional package 'slab': "
                "pip install 'depthgram[binaural]'"
            )
        return
    if not Path(spec).is_file():
        raise InputError(f"--binaural {spec}: expected 'kemar' or the path of a SOFA file; there is no such file")
    if missing("netCDF4"):
        raise MissingExtraError(
            "reading a SOFA file needs the optional package 'netCDF4': pip install 'depthgram[binaural]'"
        )


def percentiles(values: Sequence[float]) -> dict[str, float]:
    """p50, p95 and max of ``values`` (NaN for none)."""
    if not values:
        return {"p50": math.nan, "p95": math.nan, "max": math.nan}
    a = np.asarray(values, dtype=np.float64)
    return {"p50": float(np.median(a)), "p95": float(np.percentile(a, 95)), "max": float(a.max())}
