"""The viewer's player: a recording played in real time for every open page.

:class:`Player` is the viewer's state machine around :class:`depthgram.pacing.Pacer` (the drop
rule it shares with ``depthgram run`` and ``depthgram listen``), in its own thread: **one player plays
one recording** for every open page (all pages see the same playback and share its controls).

States (:class:`Mode`) and what moves between them:

============ ======================================================================================
``playing``  frames are read, processed and handed to the pages at the recording's rate (times the
             speed) while a page is connected; late frames are dropped by the :class:`Pacer`
             (``pause`` -> paused, ``step`` -> paused, ``seek`` -> seeking, end -> ended)
``paused``   nothing is read; ``step`` processes exactly one more frame (``play`` -> playing)
``seeking``  the recording is re-read up to the target frame (-> paused once it is shown)
``ended``    the last frame was shown (``play`` or ``step`` start again from the first frame;
             with ``loop`` the recording starts again on its own instead of ending)
============ ======================================================================================

Each page has its own delivery slot holding only the newest frame: a page that has not yet
acknowledged the last frame it drew gets the newest one when it is ready, and the frames it
missed are counted as dropped for that page. The recording's last frame is always shown, even
when behind, so that playback ends on the last scene and the sound covers the whole recording.
A pause likewise shows the newest frame read, so that a step after it shows the very next frame.

The loop runs in one thread of its own, reading, processing and packing each frame as
``depthgram run`` does; the event loop only delivers what it hands over. A loop that handed
each frame to worker threads and back waited for a time slice at every hand-over, and on a
loaded machine that waiting, not the work, made the viewer drop more frames than ``run``.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import enum
import gc
import json
import math
import re
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from depthgram.errors import InputError
from depthgram.frame import Frame
from depthgram.pacing import Pacer
from depthgram.pipeline import Config, Pipeline, SceneResult
from depthgram.segmentation import METHODS
from depthgram.sources.prefetch import prefetch
from depthgram.views.pages import Delivery, Page
from depthgram.views.wire import depth_range_mm, pack_body

__all__ = ["Mode", "Player", "ViewerConfig", "recording_name", "tree_lines"]

_MAX_SPEED = 16.0


@dataclass(frozen=True)
class ViewerConfig:
    """Settings of the live viewer.

    Parameters
    ----------
    fps : float or None
        Playback rate of the recording at speed 1 (frames/s); None takes the source's own rate,
        or 30 frames/s (the paper's sensor) when the source has none.
    speed : float
        Initial speed factor, in (0, 16].
    loop : bool
        Start again (forgetting all tracks) at the end of the recording; otherwise pause there.
    min_width_px : int
        The page draws the frame up-scaled by a whole factor to at least this width (px), so
        that object outlines stay one screen pixel thin on a 176 x 132 frame.
    compress : bool
        Compress each frame's depth and labels with zlib (level 1): about 3 x smaller, for slow
        links, at a few milliseconds per frame; off on loopback, where it only costs time.
    samplerate : int
        Audio sample rate (samples/s) of the sonification sent to pages that turn sound on.
    playing : bool
        Start playing as soon as a page connects.
    seek_history : int
        Frames processed unseen before the target of a seek, so that its tracks have their
        motion (range flow needs a few frames).
    read_ahead : int
        Frames decoded ahead in a thread beside the pipeline, as ``depthgram run --read-ahead``
        (0 reads on the player's own turn; a live source is never read ahead).
    """

    fps: float | None = None
    speed: float = 1.0
    loop: bool = True
    min_width_px: int = 352
    compress: bool = False
    samplerate: int = 22050
    playing: bool = True
    seek_history: int = 8
    read_ahead: int = 2

    def __post_init__(self) -> None:
        if self.fps is not None and not (math.isfinite(self.fps) and 0 < self.fps <= 1000):
            raise InputError(f"viewer: fps must be in (0, 1000] frames/s, got {self.fps}")
        check_speed(self.speed)
        if not 1 <= self.min_width_px <= 8192:
            raise InputError(f"viewer: min_width_px must be in [1, 8192] px, got {self.min_width_px}")
        if not 0 <= self.read_ahead <= 64:
            raise InputError(f"viewer: read_ahead must be in [0, 64] frames, got {self.read_ahead}")
        if not 0 <= self.seek_history <= 1000:
            raise InputError(f"viewer: seek_history must be in [0, 1000] frames, got {self.seek_history}")
        if not 4000 <= self.samplerate <= 96000:
            raise InputError(f"viewer: samplerate must be in [4000, 96000] samples/s, got {self.samplerate}")


def check_speed(value: Any) -> float:
    """Return a speed factor in (0, 16] as a float; :class:`InputError` otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"speed must be a number, got {value!r}")
    if not 0 < value <= _MAX_SPEED:
        raise InputError(f"speed must be in (0, {_MAX_SPEED:g}] (1 = the recording's rate), got {value!r}")
    return float(value)


def recording_name(spec: str) -> str:
    """URL-safe name of a recording: the file or folder name, or ``sim-SCENE`` for the simulator."""
    base = str(spec).split("?", 1)[0].rstrip("/\\")
    base = re.split(r"[/\\]", base)[-1] or "recording"
    return re.sub(r"[^\w.-]+", "-", base).strip("-.") or "recording"


def tree_lines(tree_dict: dict[str, Any]) -> list[dict[str, Any]]:
    """Return the scene tree as an indented list: ``{"level", "id", "kind", "depth", "area"}`` per node.

    ``tree_dict`` is :func:`depthgram.scene.tree_to_dict`'s output, whose nodes are already in
    depth-first order, so each node's level is its parent's plus one.
    """
    level: dict[Any, int] = {}
    out = []
    for n in tree_dict["nodes"]:
        lv = 0 if n.get("parent") is None else level.get(n["parent"], 0) + 1
        level[n["id"]] = lv
        out.append({"level": lv, "id": n["id"], "kind": n.get("kind"), "depth": n.get("depth"), "area": n.get("area")})
    return out


def pcm16_b64(audio: np.ndarray) -> str:
    """Interleaved stereo float32 (n, 2) in [-1, 1] as little-endian PCM16, base64."""
    pcm = np.clip(np.rint(np.asarray(audio, np.float32) * 32767.0), -32768, 32767).astype("<i2")
    return base64.b64encode(np.ascontiguousarray(pcm).tobytes()).decode("ascii")


class Mode(enum.Enum):
    """The player's state."""

    PLAYING = "playing"
    PAUSED = "paused"
    SEEKING = "seeking"
    ENDED = "ended"


#: Allowed moves between states; anything else is a bug in the player.
_MOVES = {
    Mode.PLAYING: {Mode.PAUSED, Mode.SEEKING, Mode.ENDED},
    Mode.PAUSED: {Mode.PLAYING, Mode.SEEKING, Mode.ENDED},
    Mode.SEEKING: {Mode.PAUSED, Mode.PLAYING},
    Mode.ENDED: {Mode.PLAYING, Mode.PAUSED, Mode.SEEKING},
}


class Player:
    """The shared playback of one recording, in a thread of its own.

    Parameters
    ----------
    open_frames : callable
        Returns a fresh iterator over the recording's frames (called again to loop).
    name : str
        The recording's name in URLs.
    config : Config
        Pipeline settings at start.
    viewer : ViewerConfig
        Viewer settings.
    frames : int or None
        Number of frames, when known.
    fps : float or None
        The source's own rate (frames/s), used when ``viewer.fps`` is None.
    seekable : bool
        Whether :meth:`seek` may re-open the recording (False for a live camera).

    Notes
    -----
    The controls (:meth:`play`, :meth:`pause`, :meth:`step`, :meth:`seek`, ...) and the pages
    (:meth:`connect`) belong to the event loop that called :meth:`start`; the frames are read,
    processed and packed in the player's thread and handed to the pages on that loop.
    """

    def __init__(
        self,
        open_frames: Callable[[], Iterator[Frame]],
        name: str,
        config: Config | None = None,
        viewer: ViewerConfig | None = None,
        *,
        frames: int | None = None,
        fps: float | None = None,
        seekable: bool = True,
    ) -> None:
        self.open_frames = open_frames
        self.seekable = seekable
        self.name = name
        self.viewer = viewer or ViewerConfig()
        self.config = config or Config()
        self.pipeline = Pipeline(self.config)
        self.frames = frames
        self.fps = float(self.viewer.fps or fps or 30.0)
        self.speed = self.viewer.speed
        self.mode = Mode.PLAYING if self.viewer.playing else Mode.PAUSED
        self.index: int | None = None  # index of the last frame pushed
        self.processed = 0
        self.dropped = 0  # frames the player skipped because it was behind
        self.latency_ms: float | None = None
        self.error: str | None = None  # why playback last stopped on its own, if it did
        self.clients: set[Page] = set()
        self.pacer = Pacer(1.0 / (self.fps * self.speed))
        self._iter: Iterator[Frame] | None = None
        self._finished = False  # the recording was read to its end and not yet re-opened
        self._cv = threading.Condition()  # guards the requests below; the thread waits on it
        self._steps: list[asyncio.Future[None]] = []
        self._settles: list[asyncio.Future[None]] = []  # pauses waiting for the frame in progress
        self._seek: tuple[int, asyncio.Future[None]] | None = None
        self._chooser: Any = None  # picks each frame's voices for every page with sound on
        self._sound_error: str | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stopping = False
        self._frozen = False
        self._stage_s: dict[str, deque[float]] = {}  # recent wall time per stage of a frame (s)
        self._cpu_s: dict[str, deque[float]] = {}  # recent thread CPU time per stage of a frame (s)

    # -- measurements -------------------------------------------------------------------

    def stage_ms(self) -> dict[str, float]:
        """Median wall time (ms) of each stage over the recent frames.

        ``read`` (one frame), ``pipeline``, ``pack`` (the page's arrays and JSON header) and
        ``send`` (one page, on the event loop).
        """
        return {k: statistics.median(v) * 1e3 for k, v in list(self._stage_s.items()) if v}

    def cpu_ms(self) -> dict[str, float]:
        """Median CPU time (ms) of the thread doing each stage, over the recent frames.

        Unlike wall time, the load of other processes on the machine does not inflate it.
        """
        return {k: statistics.median(v) * 1e3 for k, v in list(self._cpu_s.items()) if v}

    def _timed(self, stage: str, t0: float, c0: float | None = None) -> float:
        t1 = time.perf_counter()
        self._stage_s.setdefault(stage, deque(maxlen=600)).append(t1 - t0)
        if c0 is not None:
            self._cpu_s.setdefault(stage, deque(maxlen=600)).append(time.thread_time() - c0)
        return t1

    # -- state --------------------------------------------------------------------------

    @property
    def playing(self) -> bool:
        """Whether frames are being played (mode ``playing``)."""
        return self.mode is Mode.PLAYING

    @property
    def ended(self) -> bool:
        """Whether the recording's last frame was shown (mode ``ended``)."""
        return self.mode is Mode.ENDED

    def _to(self, mode: Mode) -> None:
        if mode is not self.mode:
            assert mode in _MOVES[self.mode], f"player: {self.mode.value} -> {mode.value}"
            self.mode = mode

    def state(self) -> dict[str, Any]:
        """JSON-ready playback state."""
        seg = self.config.segment
        return {
            "name": self.name,
            "frames": self.frames,
            "seekable": self.seekable,
            "fps": self.fps,
            "speed": self.speed,
            "mode": self.mode.value,
            "playing": self.playing,
            "ended": self.ended,
            "index": self.index,
            "processed": self.processed,
            "dropped": self.dropped,
            "clients": len(self.clients),
            "latency_ms": self.latency_ms,
            "error": self.error,
            "params": {"method": seg.method, "min_area": seg.min_area, "fraction": seg.fraction, "bin_mm": seg.bin_mm},
            "sound_available": self.sound_available,
            "samplerate": self.viewer.samplerate,
            "methods": list(METHODS),
        }

    @property
    def sound_available(self) -> bool:
        """False once the sound stage failed to load (the picture plays on without it)."""
        return self._sound_error is None

    # -- controls (on the event loop) ----------------------------------------------------

    def play(self) -> None:
        """Resume (from the start again when the recording had ended)."""
        with self._cv:
            self._to(Mode.PLAYING)
            self.error = None
            self._cv.notify_all()

    async def pause(self) -> None:
        """Stop after the frame in progress, which is still delivered; return once it is.

        A frame read but skipped because playback was behind counts as in progress: the page
        ends on the newest frame read, so that a step then shows the very next one.
        """
        fut = self._future()
        with self._cv:
            if self.mode is Mode.PLAYING:
                self._to(Mode.PAUSED)
            self._settles.append(fut)
            self._cv.notify_all()
        await fut
        for c in self.clients:
            c.silence()

    async def step(self) -> None:
        """Pause, then process and push exactly one more frame; return once it is pushed."""
        fut = self._future()
        with self._cv:
            self._to(Mode.PAUSED)
            self.error = None
            self._steps.append(fut)
            self._cv.notify_all()
        await fut

    async def seek(self, index: Any) -> None:
        """Pause and show frame ``index`` (0 = the recording's first); return once it is pushed.

        A source cannot be rewound, so the recording is re-read from its start: the frames
        before ``index`` are decoded and dropped, except the last ``viewer.seek_history``, which
        go through the pipeline unseen so that tracks and their motion are as they were when
        played (an object seen only earlier than that starts a new track). A seek to frame k
        therefore costs k reads and ``seek_history`` pipeline frames; a step after it shows k + 1.
        """
        if not self.seekable:
            raise InputError(f"{self.name}: a live source cannot be rewound")
        if isinstance(index, bool) or not isinstance(index, int) or index < 0:
            raise InputError(f"seek: index must be a whole frame number >= 0, got {index!r}")
        if self.frames is not None and index >= self.frames:
            raise InputError(f"seek: {self.name} has frames 0..{self.frames - 1}, got {index}")
        fut = self._future()
        with self._cv:
            self._to(Mode.SEEKING)
            self.error = None
            if self._seek is not None and not self._seek[1].done():
                self._seek[1].set_result(None)  # superseded by this one (a dragged timeline)
            self._seek = (index, fut)
            self._cv.notify_all()
        await fut

    def set_speed(self, value: Any) -> None:
        """Speed factor in (0, 16]; raises InputError otherwise."""
        with self._cv:
            self.speed = check_speed(value)
            self._cv.notify_all()

    def set_params(self, values: Any) -> None:
        """Change ``[segment]`` settings from the next frame on; raises InputError on bad values."""
        if not isinstance(values, dict) or not values:
            raise InputError('params must be a JSON object of [segment] settings, e.g. {"min_area": 50}')
        self.config = self.config.replace(segment=values)

    def connect(self) -> Page:
        """Add and return a new page: it gets every frame from now on."""
        page = Page()
        with self._cv:
            self.clients.add(page)
            self._cv.notify_all()
        return page

    def disconnect(self, page: Page) -> None:
        """Stop sending frames to ``page``."""
        with self._cv:
            self.clients.discard(page)

    def _future(self) -> asyncio.Future[None]:
        return asyncio.get_running_loop().create_future()

    # -- the thread's life ---------------------------------------------------------------

    def start(self) -> None:
        """Start the player's thread; the pages are served on the running event loop."""
        if self._thread is None:
            self._loop = asyncio.get_running_loop()
            self._stopping = False
            self._thread = threading.Thread(target=self._run, name=f"depthgram-player-{self.name}", daemon=True)
            self._thread.start()

    async def stop(self) -> None:
        """Stop the thread after the frame in progress; whoever waits on a control is answered."""
        thread, self._thread = self._thread, None
        if thread is not None:
            with self._cv:
                self._stopping = True
                self._cv.notify_all()
            await asyncio.to_thread(thread.join, 10.0)
        with self._cv:
            pending = self._steps + self._settles + ([self._seek[1]] if self._seek else [])
            self._steps, self._settles, self._seek = [], [], None
        for fut in pending:
            if not fut.done():
                fut.set_result(None)
        with contextlib.suppress(ValueError):  # a read still running in its thread ends on its own
            self._close()

    def _post(self, fn: Callable[..., None], *args: Any) -> None:
        """Run ``fn(*args)`` on the event loop, after everything posted before."""
        loop = self._loop
        if loop is not None:
            with contextlib.suppress(RuntimeError):  # the loop has closed: nobody is listening
                loop.call_soon_threadsafe(fn, *args)

    @staticmethod
    def _resolve(futures: list[asyncio.Future[None]]) -> None:
        for fut in futures:
            if not fut.done():
                fut.set_result(None)

    def _run(self) -> None:
        while not self._stopping:
            try:
                self._play_loop()
            except Exception as exc:  # never leave pause/step waiting on a dead loop
                self._fail(f"{self.name}: playback stopped after frame {self.index}: {exc}")

    # -- the loop (in the player's thread) -----------------------------------------------

    def _reopen(self) -> None:
        """Start reading the recording from its first frame, decoded ahead in a thread as ``run`` does."""
        self._close()
        self._iter = prefetch(self.open_frames(), ahead=self.viewer.read_ahead)

    def _close(self) -> None:
        it, self._iter = self._iter, None
        close = getattr(it, "close", None)
        if close is not None:
            close()  # stops the reading thread

    def _next_frame(self) -> Frame | None:
        """Next frame, starting over at the end when looping; None at the end otherwise."""
        t0 = time.perf_counter()
        if self._iter is None:
            self._reopen()
            assert self._iter is not None
        frame = next(self._iter, None)
        if frame is None:
            if not self.viewer.loop:
                return None
            self._reopen()
            self.pipeline.reset()
            frame = next(self._iter, None)
        self.pacer.note_read(self._timed("read", t0) - t0)
        return frame

    def _idle(self) -> None:
        """Answer the pauses waiting for the frame in progress: there is none now. Holds the lock."""
        if self._settles:
            self._post(self._resolve, self._settles)
            self._settles = []

    def _play_loop(self) -> None:
        fresh = True  # the next frame is the first since playback (re)started
        tail = None  # the newest frame skipped since the last one pushed
        while True:
            with self._cv:
                if self._stopping:
                    return
                seek, self._seek = self._seek, None
                want = bool(self._steps) or (self.playing and bool(self.clients))
                if seek is None and not want and tail is None:
                    self._idle()
                    self._cv.wait()
                    fresh = True
                    continue
                self.pacer.period = period = 1.0 / (self.fps * self.speed)
                if fresh:
                    self.pacer.start()
                if seek is None and want and not self._steps:
                    wait = self.pacer.wait_s()
                    if wait > 0:
                        self._idle()
                        self._cv.wait(wait)
                        continue  # re-check: paused, stepped or speed changed meanwhile
            if seek is not None:
                target, fut = seek
                try:
                    self._show_seek(target)
                finally:
                    with self._cv:
                        if self.mode is Mode.SEEKING and self._seek is None:
                            self._to(Mode.PAUSED)
                    self._post(self._resolve, [fut])
                fresh, tail = True, None
                continue
            if self._finished:
                self._finished = False
                self._close()
                tail = None
                self.pipeline.reset()
            frame = None
            if want:
                try:
                    frame, tail, _skipped = self._read_due(tail)
                except Exception as exc:  # a broken file mid-recording: say so, keep serving
                    self._fail(f"{self.name}: reading the frame after {self.index}: {exc}")
                    continue
            with self._cv:
                step = self._steps.pop(0) if self._steps else None  # maybe asked for during the read
                # Paused (before or during the read): the frame in hand is shown rather than
                # kept or dropped, so the page ends on the newest frame read and a step shows
                # the very next one; a source cannot be rewound to a frame skipped earlier.
                settling = step is None and not self.playing
            if frame is None and tail is not None:
                # The recording ended, or playback paused, just after skipping: the newest
                # frame read is shown rather than dropped, so the page ends on the recording's
                # last scene.
                frame, tail = tail, None
                self.dropped -= 1
            if frame is None:
                self._end(step)
                continue
            if self.config is not self.pipeline.config:
                self.pipeline.config = self.config  # tracks survive a parameter change
            # Voices only while playing: a step or a pause is silent.
            listening = any(c.sound for c in tuple(self.clients))
            sound = step is None and not settling and listening
            try:
                delivery, targets = self._render(frame, sound)
            except Exception as exc:
                if step is not None:
                    self._post(self._resolve, [step])
                self._fail(f"{frame.name or self.name}: frame {frame.index}: {exc}")
                continue
            tail = None
            if targets is None and listening:
                targets = {}
            self._post(self._deliver, delivery, targets)
            if step is not None:
                self._post(self._resolve, [step])
            if fresh:
                # The clock starts once the first frame is out: start-up costs (imports, compiled
                # kernels) are not a backlog to skip through.
                self.pacer.start(self.pacer.clock() + period)
                fresh = False
                if not self._frozen:
                    # As `depthgram run` does: what is loaded by now lives as long as the server,
                    # and full collections then no longer walk it mid-playback (a stall of tens of ms).
                    gc.freeze()
                    self._frozen = True
            else:
                self.pacer.advance()

    def _deliver(self, delivery: Delivery, targets: dict[Any, Any] | None) -> None:
        """Hand a frame, and its voices, to every page (on the event loop)."""
        self.index = delivery.header["index"]
        self.processed += 1
        for c in self.clients:
            c.offer(delivery, targets)

    def _end(self, step: asyncio.Future[None] | None) -> None:
        """Mark the recording ended (not looping): tell the pages, answer the steps waiting for a frame."""
        self._finished = True
        with self._cv:
            if self.mode is not Mode.SEEKING:
                self._to(Mode.ENDED)
            steps = ([step] if step else []) + self._steps
            self._steps = []
        self._post(self._resolve, steps)

        def tell() -> None:
            for c in self.clients:
                c.silence()
                c.notify({"type": "end", **self.state()})

        self._post(tell)

    def _behind(self) -> bool:
        """Skip the frame in hand? Only while playing, not stepping, and when the pacer says it is lost."""
        return self.playing and not self._steps and self.pacer.late()

    def _read_due(self, tail: Frame | None) -> tuple[Frame | None, Frame | None, int]:
        """Read the next frame to show, skipping (and counting) those whose time has passed.

        Returns the frame to show (None at the end, or when playback paused just after a skip),
        the newest skipped frame and the number skipped.
        """
        skipped = 0
        while True:
            frame = self._next_frame()
            if frame is None or not self._behind():
                return frame, tail, skipped
            self.dropped += 1
            self.pacer.advance()
            tail = frame
            skipped += 1
            if not self.playing:  # paused just after a skip: the newest frame read is shown
                return None, tail, skipped

    def _show_seek(self, target: int) -> None:
        try:
            frame = self._rewind(target)
        except Exception as exc:
            self._fail(f"{self.name}: re-reading up to frame {target}: {exc}")
            return
        if frame is None:
            self._fail(f"{self.name}: the recording ended before frame {target}")
            return
        self._finished = False
        try:
            delivery, _ = self._render(frame, False)
        except Exception as exc:
            self._fail(f"{frame.name or self.name}: frame {frame.index}: {exc}")
            return
        self._post(self._deliver, delivery, {})  # a sought frame is shown, not heard

    def _rewind(self, target: int) -> Frame | None:
        """Re-open the recording and return its frame ``target``, the pipeline primed with the frames before."""
        self._reopen()
        assert self._iter is not None
        self.pipeline.reset()
        if self.config is not self.pipeline.config:
            self.pipeline.config = self.config
        first_seen = target - self.viewer.seek_history
        for i in range(target):
            frame = next(self._iter, None)
            if frame is None:
                return None
            if i >= first_seen:
                self.pipeline.process(frame)
        return next(self._iter, None)

    def _fail(self, message: str) -> None:
        """Pause and tell every page why; the server stays up for another try."""
        with self._cv:
            self.error = message
            if self.mode is not Mode.PAUSED:
                self._to(Mode.PAUSED)
            steps, self._steps = self._steps, []
        self._post(self._resolve, steps)

        def tell() -> None:
            for c in self.clients:
                c.silence()
                c.notify({"type": "error", "message": message})

        self._post(tell)

    def _render(self, frame: Frame, with_sound: bool) -> tuple[Delivery, dict[Any, Any] | None]:
        """Process one frame and build what the pages get."""
        from depthgram.act import plan_to_dict
        from depthgram.scene import tree_to_dict

        t, c = time.perf_counter(), time.thread_time()
        result: SceneResult = self.pipeline.process(frame)
        t, c = self._timed("pipeline", t, c), time.thread_time()
        self.latency_ms = round(result.latency_s * 1e3, 2)
        w = frame.size[0]
        scale = max(1, math.ceil(self.viewer.min_width_px / w))
        lo, hi = depth_range_mm(frame.depth, frame.valid)
        body, labels_dtype = pack_body(frame.depth, frame.valid, result.segmentation.labels, self.viewer.compress)
        record = result.to_record()
        k = frame.intrinsics
        header = {
            "type": "frame",
            "index": frame.index,
            "frames": self.frames,
            "time_s": frame.time_s,
            "size": list(frame.size),
            "scale": scale,
            "depth_range_mm": [round(lo, 1), round(hi, 1)],
            "labels_dtype": labels_dtype,
            "compressed": self.viewer.compress,
            "intrinsics": None if k is None else {"fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy},
            "record": record,
            "objects": len(record["objects"]),
            "tree": tree_lines(tree_to_dict(result.tree)),
            "plan": plan_to_dict(result.plan),
            "latency_ms": self.latency_ms,
            "error": self.error,
            "server_dropped": self.dropped,
            "playing": self.playing,
            "speed": self.speed,
        }
        head = json.dumps(header, separators=(",", ":"))[:-1]
        t, c = self._timed("pack", t, c), time.thread_time()
        targets = None
        if with_sound:
            targets = self._voices(result)
            self._timed("sound", t, c)
        return Delivery(header, head, body), targets

    def _voices(self, result: SceneResult) -> dict[Any, Any] | None:
        """Return the frame's voices, chosen once for every page (None when the sound stage is missing)."""
        if self._sound_error is not None:
            return None
        if self._chooser is None:
            try:
                from depthgram.sound.choose import Chooser
            except ImportError as exc:  # the sound stage is optional for the picture
                self._sound_error = f"sound unavailable: {exc}"
                return None
            self._chooser = Chooser(self.config.sound)
        # With the objects' extents and the camera's intrinsics, as sonify and listen hear them.
        frame = result.frame
        voices: dict[Any, Any] = self._chooser.voices(
            result.tree, frame.size, result.segmentation.objects, frame.intrinsics, frame.gravity
        )
        return voices

    def new_live(self) -> Any:
        """Return a live renderer for one page's sound, kernels compiled (None when the sound stage cannot load).

        Called off the event loop (it may compile): ``await asyncio.to_thread(player.new_live)``.
        """
        try:
            from depthgram.sound.live import LiveSonifier

            live = LiveSonifier(self.config.sound, self.viewer.samplerate, (2, 2))
            live.warm_up()
        except ImportError as exc:  # the sound stage is optional for the picture
            self._sound_error = f"sound unavailable: {exc}"
            return None
        return live
