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
import json
import math
import re
import time
from collections.abc import AsyncIterator, Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import cv2
import numpy as np
from fastapi import FastAPI, Request, WebSocket, WebSocketDisconnect
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from depthgram.errors import InputError
from depthgram.frame import Frame
from depthgram.pipeline import Config, Pipeline, SceneResult
from depthgram.segmentation import METHODS

__all__ = ["LOOPBACK_HOSTS", "STATIC_DIR", "Player", "ViewerConfig", "create_app", "recording_name", "tree_lines"]

#: The page's files. Only files present here when the app is created are ever served.
STATIC_DIR = Path(__file__).with_name("static")

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
        The frame picture is up-scaled by a whole factor to at least this width (px), so that
        object outlines stay one screen pixel thin on a 176 x 132 frame.
    image_format : str
        ``png`` (lossless outlines) or ``jpeg`` (about 4 x smaller, for slow links).
    samplerate : int
        Audio sample rate (samples/s) of the sonification sent to pages that turn sound on.
    playing : bool
        Start playing as soon as a page connects.
    """

    fps: float | None = None
    speed: float = 1.0
    loop: bool = True
    min_width_px: int = 352
    image_format: str = "png"
    samplerate: int = 22050
    playing: bool = True

    def __post_init__(self) -> None:
        if self.fps is not None and not (math.isfinite(self.fps) and 0 < self.fps <= 1000):
            raise InputError(f"viewer: fps must be in (0, 1000] frames/s, got {self.fps}")
        _check_speed(self.speed)
        if not 1 <= self.min_width_px <= 8192:
            raise InputError(f"viewer: min_width_px must be in [1, 8192] px, got {self.min_width_px}")
        if self.image_format not in ("png", "jpeg"):
            raise InputError(f"viewer: image_format must be 'png' or 'jpeg', got {self.image_format!r}")
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
        out.append({"level": lv, "id": n["id"], "kind": n.get("kind"), "depth": n.get("depth"),
                    "area": n.get("area")})
    return out


def _encode_image(rgb: np.ndarray, fmt: str) -> str:
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    if fmt == "jpeg":
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 90])
        mime = "image/jpeg"
    else:
        # Level 1: a third of the default's time for a few percent more bytes on loopback.
        ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
        mime = "image/png"
    if not ok:  # pragma: no cover - OpenCV fails only on empty images
        raise RuntimeError("could not encode the frame picture")
    return f"data:{mime};base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def _pcm16_b64(audio: np.ndarray) -> str:
    """Interleaved stereo float32 (n, 2) in [-1, 1] as little-endian PCM16, base64."""
    pcm = np.clip(np.rint(np.asarray(audio, np.float32) * 32767.0), -32768, 32767).astype("<i2")
    return base64.b64encode(np.ascontiguousarray(pcm).tobytes()).decode("ascii")


class _Client:
    """One open page: its newest undelivered payload, what it missed, whether it wants sound."""

    def __init__(self) -> None:
        self.slot: dict[str, Any] | None = None
        self.audio: list[str] = []
        self.ready = asyncio.Event()  # set when the page may receive the next frame
        self.ready.set()
        self.wake = asyncio.Event()  # set when the slot is filled or the ack arrives
        self.dropped = 0
        self.sound = False
        self.notices: list[dict[str, Any]] = []  # sent after the newest frame, never dropped

    def offer(self, payload: dict[str, Any], audio: str | None) -> None:
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
    ) -> None:
        self.open_frames = open_frames
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
        self._read_s = 0.0  # running mean time to read one frame (s)
        self._sonifier: Any = None
        self._sound_error: str | None = None
        self._task: asyncio.Task[None] | None = None

    # -- controls -----------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        """JSON-ready playback state."""
        seg = self.config.segment
        return {
            "name": self.name,
            "frames": self.frames,
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
            "params": {"method": seg.method, "min_area": seg.min_area, "fraction": seg.fraction,
                       "bin_mm": seg.bin_mm},
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

    def set_speed(self, value: Any) -> None:
        """Speed factor in (0, 16]; raises InputError otherwise."""
        self.speed = _check_speed(value)
        self._wake.set()

    def set_params(self, values: Any) -> None:
        """Change ``[segment]`` settings from the next frame on; raises InputError on bad values."""
        if not isinstance(values, dict) or not values:
            raise InputError("params must be a JSON object of [segment] settings, e.g. {\"min_area\": 50}")
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

    def _next_frame(self) -> Frame | None:
        """Next frame, starting over at the end when looping; None at the end otherwise."""
        t0 = time.perf_counter()
        if self._iter is None:
            self._iter = iter(self.open_frames())
        frame = next(self._iter, None)
        if frame is None:
            if not self.viewer.loop:
                return None
            self._iter = iter(self.open_frames())
            self.pipeline.reset()
            frame = next(self._iter, None)
        dt = time.perf_counter() - t0
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
                self._iter = None
                tail = None
                self.pipeline.reset()
            frame = None
            if want:
                try:
                    frame = await asyncio.to_thread(self._next_frame)
                except Exception as exc:  # a broken file mid-recording: say so, keep serving
                    self._fail(f"{self.name}: reading the frame after {self.index}: {exc}")
                    continue
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
            now = loop_clock()
            if not last and not stepping and not settling and now - due > period and self._read_s < period:
                # Behind the recording: skipping catches up only because reading is cheaper
                # than a period; otherwise (a slow source) playback slows down instead.
                self.dropped += 1
                due += period
                tail = frame
                continue
            if self.config is not self.pipeline.config:
                self.pipeline.config = self.config  # tracks survive a parameter change
            # Sound only while playing: a step or a pause has no duration to fill.
            sound = not stepping and not settling and any(c.sound for c in self.clients)
            try:
                payload, audio = await asyncio.to_thread(self._render, frame, advanced / (self.fps * self.speed),
                                                         sound)
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
            elif self._read_s >= period:
                # Skipping cannot help a source slower than real time: play slower, no backlog.
                due = max(due + period, now - period)
            else:
                due += period
            if stepping:
                self._finish_steps(1)

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

    def _render(self, frame: Frame, duration_s: float, with_sound: bool) -> tuple[dict[str, Any], str | None]:
        """Process one frame and build what the pages get (runs in a worker thread)."""
        from depthgram.act import plan_to_dict
        from depthgram.scene import tree_to_dict
        from depthgram.views.pictures import overlay_image

        result: SceneResult = self.pipeline.process(frame)
        self.latency_ms = round(result.latency_s * 1e3, 2)
        w = frame.size[0]
        scale = max(1, math.ceil(self.viewer.min_width_px / w))
        image = _encode_image(overlay_image(frame, result.segmentation, scale=scale), self.viewer.image_format)
        record = result.to_record()
        payload = {
            "type": "frame",
            "index": frame.index,
            "frames": self.frames,
            "time_s": frame.time_s,
            "size": list(frame.size),
            "scale": scale,
            "image": image,
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
        audio = None
        if with_sound:
            audio = self._sonify(result, duration_s)
        return payload, audio

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


#: Host names that reach this machine only; the default set of allowed ``Host`` headers.
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


def _host_name(host_header: str) -> str:
    """``Host`` header without its port: ``[::1]:8765`` -> ``::1``, ``localhost:8765`` -> ``localhost``."""
    h = host_header.strip().lower()
    if h.startswith("["):
        return h[1:].partition("]")[0]
    return h.rpartition(":")[0] if h.count(":") == 1 else h


def _same_origin(headers: Any) -> bool:
    """True when a request carries no ``Origin`` (not from a web page) or comes from this server's own page.

    Browsers let any web site open a WebSocket to 127.0.0.1 or send a simple POST there; the
    Origin they attach is the only way to tell our page from someone else's.
    """
    origin = headers.get("origin")
    if origin is None:
        return True
    return bool(urlsplit(origin).netloc.lower() == str(headers.get("host", "")).lower())


class _AllowedHosts:
    """Refuse requests whose ``Host`` is not one of ours (DNS rebinding: a foreign name that
    resolves to 127.0.0.1 would otherwise reach the viewer with the browser's blessing)."""

    def __init__(self, app: Any, hosts: Sequence[str]) -> None:
        self.app = app
        self.hosts = {h.lower().strip("[]") for h in hosts}

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] in ("http", "websocket"):
            host = dict(scope["headers"]).get(b"host", b"").decode("latin-1")
            if _host_name(host) not in self.hosts:
                if scope["type"] == "websocket":
                    await send({"type": "websocket.close", "code": 4400, "reason": "host not allowed"})
                    return
                response = _json_error(400, f"host {host!r} is not served here; use {sorted(self.hosts)[0]}")
                await response(scope, receive, send)
                return
        await self.app(scope, receive, send)


def create_app(player: Player, *, allowed_hosts: Sequence[str] | None = LOOPBACK_HOSTS) -> FastAPI:
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
    if allowed_hosts is not None:
        app.add_middleware(_AllowedHosts, hosts=tuple(allowed_hosts))

    def ours(request: Request) -> None:
        if not _same_origin(request.headers):
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
            return await request.json()
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise StarletteHTTPException(400, "request body must be JSON") from None

    @app.get("/", response_class=HTMLResponse)
    async def index() -> Any:
        page = static_files.get("index.html")
        if page is None:
            return _json_error(500, "the viewer's page is missing from the installation")
        return FileResponse(page, media_type="text/html")

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
        else:
            return _json_error(404, f"unknown action {action!r}; expected play, pause or step")
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
        if not _same_origin(ws.headers):
            await ws.close(code=4403, reason="connections from other sites' pages are not allowed")
            return
        if name != player.name:
            await ws.close(code=4404, reason=f"unknown recording {name!r}")
            return
        await ws.accept()
        client = player.connect()
        await ws.send_text(json.dumps({"type": "hello", **player.state()}))

        async def receive() -> None:
            while True:
                try:
                    msg = json.loads(await ws.receive_text())
                except json.JSONDecodeError:
                    continue  # not from our page; nothing to answer
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
                    payload, client.slot = client.slot, None
                    audio, client.audio = client.audio, []
                    client.ready.clear()
                    msg = {**payload, "dropped": client.dropped + payload["server_dropped"],
                           "page_dropped": client.dropped}
                    if audio:
                        msg["audio"] = {"samplerate": player.viewer.samplerate, "channels": 2, "chunks": audio}
                    await ws.send_text(json.dumps(msg))
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
