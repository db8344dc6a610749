"""A live viewer in the browser: one recording played through the pipeline, pushed frame by frame.

Session model (kept simple on purpose): **one server plays one recording with one shared
player**. A single background task reads the recording, runs the :class:`~depthgram.pipeline.Pipeline`
and hands each frame's payload to every open page. All pages therefore see the same playback
and share its controls (play, pause, step, speed, segmentation parameters). Each page has its
own delivery slot holding only the newest frame: a page that has not yet acknowledged the last
frame it drew gets the newest one when it is ready, and the frames it missed are counted as
dropped for that page. The player itself skips frames (and counts them) when it falls behind
the recording's rate and skipping can catch up, i.e. when reading a frame is cheaper than its
period; the recording's last frame is always shown, even when behind, so that playback ends on
the last scene and the sound covers the whole recording. A pause likewise shows the newest frame
read, so that a step after it shows the very next frame of the recording. The player only runs
while at least one page is connected.

HTTP interface (all JSON errors are ``{"error": message}`` with a 4xx status):

- ``GET /``: the page; ``GET /static/NAME``: its files, only those present in the static folder
  when the server started (so no path ever leaves that folder);
- ``GET /api/recordings``: the one recording; ``GET /api/recordings/{name}``: its state;
- ``POST /api/recordings/{name}/play|pause|step``; ``PUT /api/recordings/{name}/speed``
  (``{"value": 2}``) and ``PUT /api/recordings/{name}/params`` (``{"method": "threshold",
  "min_area": 50}``: settings of the ``[segment]`` section, effective on the next frame);
- ``WS /ws/{name}``: JSON text messages ``hello`` (the state), ``frame`` (picture as a PNG data
  URL, the record of :meth:`~depthgram.pipeline.SceneResult.to_record`, the tree as an indented
  list, the plan of :func:`depthgram.act.plan_to_dict`, drop counts and, for pages with sound on,
  the audio as base64 little-endian PCM16 stereo), ``end`` and ``error``. The page answers
  ``{"type": "ack"}`` after drawing each frame and ``{"type": "sound", "on": true}`` for audio.

Sound is rendered on the server by :class:`depthgram.sound.Sonifier`, the same code as
``depthgram sonify``, rather than re-synthesised in Web Audio: one mapping, one implementation,
and what is heard in the browser is what the WAV file holds. It costs about 2.9 kB of PCM16 per
frame at 22050 samples/s and 30 frames/s.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import gc
import json
import math
import re
import statistics
import time
from collections import deque
from collections.abc import AsyncIterator, Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from fastapi import FastAPI, Request, WebSocket, WebSocketDisconnect
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from depthgram.errors import InputError
from depthgram.frame import Frame
from depthgram.pipeline import Config, Pipeline, SceneResult
from depthgram.segmentation import METHODS
from depthgram.sources.prefetch import prefetch
from depthgram.views.guard import (
    LOOPBACK_HOSTS,
    MAX_BODY_BYTES,
    TOKEN_COOKIE,
    BodyTooLarge,
    Guard,
    JSONBodyError,
    parse_json,
    same_origin,
)
from depthgram.views.wire import colour_table, depth_range_mm, pack_body, pack_frame

__all__ = ["LOOPBACK_HOSTS", "STATIC_DIR", "Player", "ViewerConfig", "create_app", "recording_name", "tree_lines"]

#: The page's files. Only files present here when the app is created are ever served.
STATIC_DIR = Path(__file__).with_name("static")

_MAX_SPEED = 16.0
_COLOURS = colour_table()


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
        _check_speed(self.speed)
        if not 1 <= self.min_width_px <= 8192:
            raise InputError(f"viewer: min_width_px must be in [1, 8192] px, got {self.min_width_px}")
        if not 0 <= self.read_ahead <= 64:
            raise InputError(f"viewer: read_ahead must be in [0, 64] frames, got {self.read_ahead}")
        if not 0 <= self.seek_history <= 1000:
            raise InputError(f"viewer: seek_history must be in [0, 1000] frames, got {self.seek_history}")
        if not 4000 <= self.samplerate <= 96000:
            raise InputError(f"viewer: samplerate must be in [4000, 96000] samples/s, got {self.samplerate}")


def _check_speed(value: Any) -> float:
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
    """The scene tree as an indented list: ``{"level", "id", "kind", "depth", "area"}`` per node.

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


def _pcm16_b64(audio: np.ndarray) -> str:
    """Interleaved stereo float32 (n, 2) in [-1, 1] as little-endian PCM16, base64."""
    pcm = np.clip(np.rint(np.asarray(audio, np.float32) * 32767.0), -32768, 32767).astype("<i2")
    return base64.b64encode(np.ascontiguousarray(pcm).tobytes()).decode("ascii")


class _Client:
    """One open page: its newest undelivered payload, what it missed, whether it wants sound."""

    def __init__(self) -> None:
        self.slot: tuple[dict[str, Any], bytes] | None = None  # a frame's header and body
        self.audio: list[str] = []
        self.ready = asyncio.Event()  # set when the page may receive the next frame
        self.ready.set()
        self.wake = asyncio.Event()  # set when the slot is filled or the ack arrives
        self.dropped = 0
        self.sound = False
        self.notices: list[dict[str, Any]] = []  # sent after the newest frame, never dropped

    def offer(self, payload: tuple[dict[str, Any], bytes], audio: str | None) -> None:
        if self.slot is not None:
            self.dropped += 1  # the page is behind: the older frame is never sent
        self.slot = payload
        if audio is not None and self.sound:
            # Audio is kept across dropped frames so that the sound stays continuous.
            self.audio.append(audio)
        self.wake.set()

    def notify(self, message: dict[str, Any]) -> None:
        self.notices.append(message)
        self.wake.set()


class Player:
    """The shared playback loop of one recording.

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
        self.playing = self.viewer.playing
        self.ended = False
        self.index: int | None = None  # index of the last frame pushed
        self.processed = 0
        self.dropped = 0  # frames the player skipped because it was behind
        self.latency_ms: float | None = None
        self.error: str | None = None  # why playback last stopped on its own, if it did
        self.clients: set[_Client] = set()
        self._iter: Iterator[Frame] | None = None
        self._wake = asyncio.Event()
        self._idle = asyncio.Event()
        self._steps: list[asyncio.Future[None]] = []
        self._seek: tuple[int, asyncio.Future[None]] | None = None
        self._read_s = 0.0  # running mean time to read one frame (s)
        self._sonifier: Any = None
        self._sound_error: str | None = None
        self._task: asyncio.Task[None] | None = None
        self._frozen = False
        self._stage_s: dict[str, deque[float]] = {}  # recent time per stage of a frame (s)

    def stage_ms(self) -> dict[str, float]:
        """Median time (ms) of each stage over the recent frames.

        ``read`` (one frame), ``loop-read`` (reading and skipping, as the loop waited for it),
        ``pipeline``, ``encode``, ``record``, ``loop-render`` (as waited for) and ``send`` (one page).
        """
        return {k: statistics.median(v) * 1e3 for k, v in self._stage_s.items() if v}

    def _timed(self, stage: str, t0: float) -> float:
        t1 = time.perf_counter()
        self._stage_s.setdefault(stage, deque(maxlen=600)).append(t1 - t0)
        return t1

    # -- controls -----------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """JSON-ready playback state."""
        seg = self.config.segment
        return {
            "name": self.name,
            "frames": self.frames,
            "seekable": self.seekable,
            "fps": self.fps,
            "speed": self.speed,
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
            "methods": list(METHODS),
        }

    @property
    def sound_available(self) -> bool:
        """False once the sound stage failed to load (the picture plays on without it)."""
        return self._sound_error is None

    def play(self) -> None:
        """Resume (from the start again when the recording had ended)."""
        self.playing = True
        self.error = None
        self._wake.set()

    async def pause(self) -> None:
        """Stop after the frame in progress, which is still delivered; return once it is.

        A frame read but skipped because playback was behind counts as in progress: the page
        ends on the newest frame read, so that a step then shows the very next one.
        """
        self.playing = False
        # The loop may be idle waiting for a frame's due time with a skipped frame in hand:
        # wait for it to wake and settle rather than answer with the frame before.
        self._idle.clear()
        self._wake.set()
        await self._idle.wait()

    async def step(self) -> None:
        """Pause, then process and push exactly one more frame; return once it is pushed."""
        self.playing = False
        self.error = None
        fut: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._steps.append(fut)
        self._wake.set()
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
        self.playing = False
        self.error = None
        if self._seek is not None and not self._seek[1].done():
            self._seek[1].set_result(None)  # superseded by this one (a dragged timeline)
        fut: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._seek = (index, fut)
        self._wake.set()
        await fut

    def set_speed(self, value: Any) -> None:
        """Speed factor in (0, 16]; raises InputError otherwise."""
        self.speed = _check_speed(value)
        self._wake.set()

    def set_params(self, values: Any) -> None:
        """Change ``[segment]`` settings from the next frame on; raises InputError on bad values."""
        if not isinstance(values, dict) or not values:
            raise InputError('params must be a JSON object of [segment] settings, e.g. {"min_area": 50}')
        self.config = self.config.replace(segment=values)

    # -- clients ------------------------------------------------------------------------

    def connect(self) -> _Client:
        client = _Client()
        self.clients.add(client)
        self._wake.set()
        return client

    def disconnect(self, client: _Client) -> None:
        self.clients.discard(client)

    # -- the loop -----------------------------------------------------------------------

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._run())

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        with contextlib.suppress(ValueError):  # a read still running in its thread ends on its own
            self._close()

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
        dt = self._timed("read", t0) - t0
        self._read_s = dt if self._read_s == 0 else 0.9 * self._read_s + 0.1 * dt
        return frame

    async def _wait(self, timeout: float | None) -> None:
        self._wake.clear()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self._wake.wait(), timeout)

    async def _run(self) -> None:
        while True:
            try:
                await self._play_loop()
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # never leave pause/step waiting on a dead loop
                self._fail(f"{self.name}: playback stopped after frame {self.index}: {exc}")

    async def _play_loop(self) -> None:
        loop_clock = time.monotonic
        due = loop_clock()
        advanced = 0  # frames of the recording since the last pushed one (for the audio duration)
        fresh = True  # the next frame is the first since playback (re)started
        tail = None  # the newest frame skipped since the last one pushed
        while True:
            if self._seek is not None:
                target, fut = self._seek
                self._seek = None
                try:
                    await self._show_seek(target)
                finally:
                    if not fut.done():
                        fut.set_result(None)
                due, fresh, advanced, tail = loop_clock(), True, 0, None
                continue
            want = bool(self._steps) or (self.playing and bool(self.clients))
            if not want and tail is None:
                self._idle.set()
                await self._wait(None)
                due = loop_clock()
                fresh = True
                continue
            period = 1.0 / (self.fps * self.speed)
            if want and not self._steps:
                wait = due - loop_clock()
                if wait > 0:
                    self._idle.set()
                    await self._wait(wait)
                    continue  # re-check: paused, stepped or speed changed meanwhile
            self._idle.clear()
            if self.ended:
                self.ended = False
                self._close()
                tail = None
                self.pipeline.reset()
            frame = None
            if want:
                try:
                    t_r = time.perf_counter()
                    frame, tail, due, skipped = await asyncio.to_thread(self._read_due, due, period, tail)
                    self._timed("loop-read", t_r)
                except Exception as exc:  # a broken file mid-recording: say so, keep serving
                    self._fail(f"{self.name}: reading the frame after {self.index}: {exc}")
                    continue
                advanced += skipped
            stepping = bool(self._steps)  # a step may have been asked for during the read
            # Paused (before or during the read): the frame in hand is shown rather than kept
            # or dropped, so the page ends on the newest frame read and a step shows the very
            # next one; a source cannot be rewound to a frame skipped earlier.
            settling = not stepping and not self.playing
            last = False
            if frame is None and tail is not None:
                # The recording ended, or playback paused, just after skipping: the newest
                # frame read is shown rather than dropped, so the page ends on the recording's
                # last scene and the sound lasts as long as the recording.
                frame, tail, last = tail, None, True
                self.dropped -= 1
            if frame is None:
                self.ended = True
                self.playing = False
                self._finish_steps()
                for c in self.clients:
                    c.notify({"type": "end", **self.state()})
                continue
            if not last:
                advanced += 1
            if self.config is not self.pipeline.config:
                self.pipeline.config = self.config  # tracks survive a parameter change
            # Sound only while playing: a step or a pause has no duration to fill.
            sound = not stepping and not settling and any(c.sound for c in self.clients)
            try:
                t_r = time.perf_counter()
                payload, audio = await asyncio.to_thread(self._render, frame, advanced / (self.fps * self.speed), sound)
                self._timed("loop-render", t_r)
            except Exception as exc:
                self._fail(f"{frame.name or self.name}: frame {frame.index}: {exc}")
                continue
            advanced = 0
            tail = None
            self.index = frame.index
            self.processed += 1
            for c in self.clients:
                c.offer(payload, audio)
            now = loop_clock()
            if fresh:
                # The clock starts once the first frame is out: start-up costs (imports, compiled
                # kernels) are not a backlog to skip through.
                due, fresh = now + period, False
                if not self._frozen:
                    # As `depthgram run` does: what is loaded by now lives as long as the server,
                    # and full collections then no longer walk it mid-playback (a stall of tens of ms).
                    gc.freeze()
                    self._frozen = True
            elif self._read_s >= period:
                # Skipping cannot help a source slower than real time: play slower, no backlog.
                due = max(due + period, now - period)
            else:
                due += period
            if stepping:
                self._finish_steps(1)

    def _behind(self, due: float, period: float) -> bool:
        """Skip the frame in hand? Only while playing, behind the recording, and when skipping
        catches up, i.e. reading is cheaper than a period; otherwise (a slow source) playback
        slows down instead."""
        return self.playing and not self._steps and time.monotonic() - due > period and self._read_s < period

    def _read_due(self, due: float, period: float, tail: Frame | None) -> tuple[Frame | None, Frame | None, float, int]:
        """Read the next frame to show, skipping (and counting) those whose time has passed.

        Runs in a worker thread, so that a run of skipped frames costs one hand-over between
        threads rather than two per frame: on a loaded machine each hand-over waits for a time
        slice, and that waiting, not the reading, was what made the viewer fall behind.

        Returns the frame to show (None at the end, or when playback paused just after a skip),
        the newest skipped frame, the updated due time (s, monotonic) and the number skipped.
        """
        skipped = 0
        while True:
            frame = self._next_frame()
            if frame is None or not self._behind(due, period):
                return frame, tail, due, skipped
            self.dropped += 1
            due += period
            tail = frame
            skipped += 1
            if not self.playing:  # paused just after a skip: the newest frame read is shown
                return None, tail, due, skipped

    async def _show_seek(self, target: int) -> None:
        try:
            frame = await asyncio.to_thread(self._rewind, target)
        except Exception as exc:
            self._fail(f"{self.name}: re-reading up to frame {target}: {exc}")
            return
        if frame is None:
            self._fail(f"{self.name}: the recording ended before frame {target}")
            return
        self.ended = False
        try:
            (payload, body), _ = await asyncio.to_thread(self._render, frame, 0.0, False)
        except Exception as exc:
            self._fail(f"{frame.name or self.name}: frame {frame.index}: {exc}")
            return
        self.index = frame.index
        self.processed += 1
        for c in self.clients:
            c.offer((payload, body), None)

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
        self.error = message
        self.playing = False
        self._finish_steps()
        for c in self.clients:
            c.notify({"type": "error", "message": message})

    def _finish_steps(self, n: int | None = None) -> None:
        done = self._steps if n is None else self._steps[:n]
        self._steps = [] if n is None else self._steps[n:]
        for fut in done:
            if not fut.done():
                fut.set_result(None)

    def _render(
        self, frame: Frame, duration_s: float, with_sound: bool
    ) -> tuple[tuple[dict[str, Any], bytes], str | None]:
        """Process one frame and build what the pages get (runs in a worker thread)."""
        from depthgram.act import plan_to_dict
        from depthgram.scene import tree_to_dict

        t = time.perf_counter()
        result: SceneResult = self.pipeline.process(frame)
        t = self._timed("pipeline", t)
        self.latency_ms = round(result.latency_s * 1e3, 2)
        w = frame.size[0]
        scale = max(1, math.ceil(self.viewer.min_width_px / w))
        lo, hi = depth_range_mm(frame.depth, frame.valid)
        body, labels_dtype = pack_body(frame.depth, frame.valid, result.segmentation.labels, self.viewer.compress)
        t = self._timed("encode", t)
        record = result.to_record()
        k = frame.intrinsics
        payload = {
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
        self._timed("record", t)
        audio = None
        if with_sound:
            audio = self._sonify(result, duration_s)
        return (payload, body), audio

    def _sonify(self, result: SceneResult, duration_s: float) -> str | None:
        if self._sound_error is not None:
            return None
        if self._sonifier is None:
            try:
                from depthgram.sound import Sonifier
            except ImportError as exc:  # the sound stage is optional for the picture
                self._sound_error = f"sound unavailable: {exc}"
                return None
            self._sonifier = Sonifier(self.config.sound, self.viewer.samplerate, result.frame.size)
        return _pcm16_b64(self._sonifier.push(result.tree, duration_s))


def _json_error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


def create_app(
    player: Player,
    *,
    allowed_hosts: Sequence[str] | None = LOOPBACK_HOSTS,
    token: str | None = None,
    max_body: int = MAX_BODY_BYTES,
) -> FastAPI:
    """The FastAPI application serving one :class:`Player`.

    The player's loop starts with the app (its lifespan) and stops with it.

    Parameters
    ----------
    player : Player
        The recording's player.
    allowed_hosts : sequence of str or None
        Host names accepted in the ``Host`` header (any port); None accepts any (behind a
        proxy, or in tests). Requests from another site's page (a foreign ``Origin``) are
        refused either way.
    token : str or None
        Access token every request must carry instead (see :mod:`depthgram.views.guard`);
        the page opened as ``/?token=...`` keeps it in a cookie.
    max_body : int
        Largest request body (bytes).
    """
    # A whitelist taken once: a request names a file, it is never joined to a path.
    static_files = {p.name: p for p in STATIC_DIR.iterdir() if p.is_file()} if STATIC_DIR.is_dir() else {}
    media = {".js": "text/javascript", ".css": "text/css", ".html": "text/html", ".svg": "image/svg+xml"}

    @contextlib.asynccontextmanager
    async def lifespan(_app: Any) -> AsyncIterator[None]:
        player.start()
        try:
            yield
        finally:
            await player.stop()

    app = FastAPI(title="depthgram view", lifespan=lifespan, docs_url=None, redoc_url=None, openapi_url=None)
    app.add_middleware(
        Guard, hosts=None if allowed_hosts is None else tuple(allowed_hosts), token=token, max_body=max_body
    )

    def ours(request: Request) -> None:
        if not same_origin(request.headers, request.url.scheme):
            raise StarletteHTTPException(403, f"requests from {request.headers.get('origin')} are not allowed")

    @app.exception_handler(StarletteHTTPException)
    async def http_error(_r: Request, exc: StarletteHTTPException) -> JSONResponse:
        return JSONResponse({"error": str(exc.detail)}, status_code=exc.status_code)

    @app.exception_handler(RequestValidationError)
    async def validation_error(_r: Request, exc: RequestValidationError) -> JSONResponse:
        return JSONResponse({"error": f"bad request: {exc.errors()}"}, status_code=422)

    def known(name: str) -> None:
        if name != player.name:
            raise StarletteHTTPException(404, f"unknown recording {name!r}; this server plays {player.name!r}")

    async def body(request: Request) -> Any:
        try:
            return parse_json(await request.body())
        except BodyTooLarge:
            raise StarletteHTTPException(413, f"request body over {max_body} bytes") from None
        except JSONBodyError as exc:
            raise StarletteHTTPException(400, str(exc)) from None

    @app.get("/", response_class=HTMLResponse)
    async def index(request: Request) -> Any:
        page = static_files.get("index.html")
        if page is None:
            return _json_error(500, "the viewer's page is missing from the installation")
        response = FileResponse(page, media_type="text/html")
        if token is not None and request.query_params.get("token") == token:
            # The page's own later requests (files, API, WebSocket) carry it for this origin only.
            response.set_cookie(TOKEN_COOKIE, token, httponly=True, samesite="strict")
        return response

    @app.get("/static/{name}")
    async def static(name: str) -> Any:
        path = static_files.get(name)
        if path is None:
            return _json_error(404, f"no such file {name!r}")
        return FileResponse(path, media_type=media.get(path.suffix, "application/octet-stream"))

    @app.get("/api/recordings")
    async def recordings() -> Any:
        return {"recordings": [player.state()]}

    @app.get("/api/recordings/{name}")
    async def get_state(name: str) -> Any:
        known(name)
        return player.state()

    @app.post("/api/recordings/{name}/{action}")
    async def control(name: str, action: str, request: Request) -> Any:
        ours(request)
        known(name)
        if action == "play":
            player.play()
        elif action == "pause":
            await player.pause()
        elif action == "step":
            await player.step()
        elif action == "seek":
            data = await body(request)
            try:
                await player.seek(data.get("index") if isinstance(data, dict) else data)
            except InputError as exc:
                return _json_error(422, str(exc))
        else:
            return _json_error(404, f"unknown action {action!r}; expected play, pause, step or seek")
        return player.state()

    @app.put("/api/recordings/{name}/speed")
    async def speed(name: str, request: Request) -> Any:
        ours(request)
        known(name)
        data = await body(request)
        try:
            player.set_speed(data.get("value") if isinstance(data, dict) else data)
        except InputError as exc:
            return _json_error(422, str(exc))
        return player.state()

    @app.put("/api/recordings/{name}/params")
    async def params(name: str, request: Request) -> Any:
        ours(request)
        known(name)
        try:
            player.set_params(await body(request))
        except InputError as exc:
            return _json_error(422, str(exc))
        return player.state()

    @app.websocket("/ws/{name}")
    async def stream(ws: WebSocket, name: str) -> None:
        if not same_origin(ws.headers, ws.url.scheme):
            await ws.close(code=4403, reason="connections from other sites' pages are not allowed")
            return
        if name != player.name:
            await ws.close(code=4404, reason=f"unknown recording {name!r}")
            return
        await ws.accept()
        client = player.connect()
        await ws.send_text(json.dumps({"type": "hello", **player.state(), "colours": _COLOURS}))

        async def receive() -> None:
            while True:
                text = await ws.receive_text()
                if len(text) > max_body:
                    continue  # not from our page (it sends a few dozen bytes); nothing to answer
                try:
                    msg = parse_json(text)
                except JSONBodyError:
                    continue
                kind = msg.get("type") if isinstance(msg, dict) else None
                if kind == "ack":
                    client.ready.set()
                    client.wake.set()
                elif kind == "sound":
                    client.sound = bool(msg.get("on"))
                    client.notify({"type": "sound", "on": client.sound, "available": player.sound_available})

        reader = asyncio.get_running_loop().create_task(receive())
        try:
            while not reader.done():
                client.wake.clear()
                if client.slot is not None and client.ready.is_set():
                    (header, body), client.slot = client.slot, None
                    audio, client.audio = client.audio, []
                    client.ready.clear()
                    msg = {
                        **header,
                        "dropped": client.dropped + header["server_dropped"],
                        "page_dropped": client.dropped,
                    }
                    if audio:
                        msg["audio"] = {"samplerate": player.viewer.samplerate, "channels": 2, "chunks": audio}
                    t0 = time.perf_counter()
                    await ws.send_bytes(pack_frame(msg, body))
                    player._timed("send", t0)
                    continue
                if client.notices and client.slot is None:
                    await ws.send_text(json.dumps(client.notices.pop(0)))
                    continue
                waiter = asyncio.ensure_future(client.wake.wait())
                await asyncio.wait({waiter, reader}, return_when=asyncio.FIRST_COMPLETED)
                waiter.cancel()
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            player.disconnect(client)
            reader.cancel()
            with contextlib.suppress(BaseException):
                await reader

    return app
