"""The live viewer's web application: the page, the controls as HTTP routes, the frames over a WebSocket.

The playback itself is :class:`depthgram.views.player.Player` (one recording, one shared
player for every page, an explicit state machine in its own thread); who may connect is
:mod:`depthgram.views.guard`; the frame message's layout is :mod:`depthgram.views.wire`.

HTTP interface (all JSON errors are ``{"error": message}`` with a 4xx status):

- ``GET /``: the page; ``GET /static/NAME``: its files, only those present in the static folder
  when the server started (so no path ever leaves that folder);
- ``GET /api/recordings``: the one recording; ``GET /api/recordings/{name}``: its state;
- ``POST /api/recordings/{name}/play|pause|step|seek`` (seek: ``{"index": 12}``);
  ``PUT /api/recordings/{name}/speed`` (``{"value": 2}``) and ``PUT /api/recordings/{name}/params``
  (``{"method": "threshold", "min_area": 50}``: settings of the ``[segment]`` section, effective
  on the next frame);
- ``WS /ws/{name}``: JSON text messages ``hello`` (the state and the depth colours), ``end``,
  ``error`` and ``sound``, and one binary message per frame (:mod:`depthgram.views.wire`: a
  JSON header with the record of :meth:`~depthgram.pipeline.SceneResult.to_record`, the tree
  as an indented list, the plan of :func:`depthgram.act.plan_to_dict`, drop counts and, for
  pages with sound on, then the depth and label images). The page answers ``{"type": "ack"}``
  after drawing each frame and ``{"type": "sound", "on": true}`` for audio; with sound on it
  asks for blocks, ``{"type": "audio", "need": N}`` (samples), and gets ``{"type": "audio",
  "samplerate", "channels": 2, "pcm": base64 little-endian PCM16 stereo, "frame": the newest
  frame whose voices the block carries}``.

Sound is rendered on the server by the live renderer of ``depthgram listen``
(:class:`depthgram.sound.live.LiveSonifier`), not re-synthesised in Web Audio: one mapping, one
implementation. Each frame only swaps the page's voices' targets, which the renderer ramps
toward; the page's AudioWorklet plays the blocks and asks for more as its own audio clock
consumes them, keeping about ``AUDIO_AHEAD_S`` (page side) buffered. So the audio clock paces
the synthesis: no drift between the server's clock and the speaker's, and no catch-up queue (a
stall of the server freezes the scene; the page counts the blocks it ran dry).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from collections.abc import AsyncIterator, Sequence
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request, WebSocket, WebSocketDisconnect
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from depthgram.errors import InputError
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
from depthgram.views.player import Player, ViewerConfig, pcm16_b64, recording_name, tree_lines
from depthgram.views.wire import colour_table, pack_frame

# Player, ViewerConfig, recording_name and tree_lines are re-exported: they lived here before the split.
__all__ = ["LOOPBACK_HOSTS", "STATIC_DIR", "Player", "ViewerConfig", "create_app", "recording_name", "tree_lines"]

#: The page's files. Only files present here when the app is created are ever served.
STATIC_DIR = Path(__file__).with_name("static")

_COLOURS = colour_table()


def _json_error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


def create_app(
    player: Player,
    *,
    allowed_hosts: Sequence[str] | None = LOOPBACK_HOSTS,
    token: str | None = None,
    max_body: int = MAX_BODY_BYTES,
) -> FastAPI:
    """Return the FastAPI application serving one :class:`Player`.

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
                    on = bool(msg.get("on"))
                    if on and client.live is None and player.sound_available:
                        client.live = await asyncio.to_thread(player.new_live)
                    if not on:
                        client.silence()
                        client.audio_need = 0
                    client.sound = on
                    client.notify({"type": "sound", "on": client.sound, "available": player.sound_available})
                elif kind == "audio":
                    need = msg.get("need")
                    if type(need) is int and need > 0 and client.sound and client.live is not None:
                        # Never more than half a second at once: a page cannot make the server
                        # render ahead of the scene.
                        client.audio_need = min(client.audio_need + need, player.viewer.samplerate // 2)
                        client.wake.set()

        reader = asyncio.get_running_loop().create_task(receive())
        try:
            while not reader.done():
                client.wake.clear()
                if client.audio_need > 0 and client.live is not None:
                    # Sound first: the page's audio clock is waiting for it, a frame can wait.
                    n, client.audio_need = client.audio_need, 0
                    block, taken = client.live.render_block(n)
                    if taken is not None:
                        client.heard = taken.frame
                    client.audio_sent += n
                    sr = player.viewer.samplerate
                    msg = {"type": "audio", "samplerate": sr, "channels": 2, "pcm": pcm16_b64(block)}
                    await ws.send_text(json.dumps({**msg, "frame": client.heard}))
                    continue
                if client.slot is not None and client.ready.is_set():
                    t0, c0 = time.perf_counter(), time.thread_time()
                    frame, client.slot = client.slot, None
                    client.ready.clear()
                    # The header was serialised once for every page: only this page's counts are added.
                    mine = {"dropped": client.dropped + frame.header["server_dropped"], "page_dropped": client.dropped}
                    head = frame.head + "," + json.dumps(mine, separators=(",", ":"))[1:]
                    await ws.send_bytes(pack_frame(head, frame.body))
                    player._timed("send", t0, c0)
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
