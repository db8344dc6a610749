"""The live viewer's server: page, static files, frame stream, controls and bad requests."""

from __future__ import annotations

import asyncio
import base64
import itertools
import json
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("httpx")

from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from depthgram.errors import InputError
from depthgram.frame import make_frame
from depthgram.pipeline import Config, Pipeline
from depthgram.sensor import simulate
from depthgram.sources import open_source
from depthgram.views.server import Player, ViewerConfig, create_app, recording_name, tree_lines
from depthgram.views.wire import unpack_frame

SPEC = "sim:table?frames=4"
WS = "ws://127.0.0.1:8765"  # full URL: the test client's WebSocket otherwise says Host: testserver


def _sim_player(**viewer: Any) -> Player:
    src = open_source(SPEC)
    return Player(
        lambda: iter(src), recording_name(SPEC), Config(), ViewerConfig(**viewer), frames=len(src), fps=src.fps
    )


def _client(app: Any) -> TestClient:
    # The app answers only to loopback host names (DNS rebinding), so the client says 127.0.0.1.
    return TestClient(app, base_url="http://127.0.0.1:8765")


def _recv(ws: Any) -> dict[str, Any]:
    """Next message: JSON text, or a binary frame whose arrays come as ``_depth`` and ``_labels``."""
    m = ws.receive()
    if m.get("bytes") is not None:
        header, depth, labels = unpack_frame(m["bytes"])
        return {**header, "_depth": depth, "_labels": labels}
    return dict(json.loads(m["text"]))


def _frame(ws: Any, *, ack: bool = True, end: bool = False) -> dict[str, Any]:
    """Next frame message (or end of recording when ``end``), acknowledged like the page does."""
    while True:
        msg = _recv(ws)
        if end and msg["type"] == "end":
            return msg
        # fail loudly rather than wait forever for a frame that will not come
        assert msg["type"] != "error", msg["message"]
        assert msg["type"] != "end", "the recording ended"
        if msg["type"] == "frame":
            if ack:
                ws.send_text(json.dumps({"type": "ack", "index": msg["index"]}))
            return msg


def test_recording_name_and_tree_lines() -> None:
    assert recording_name("sim:table?frames=4") == "sim-table"
    assert recording_name("../shared/data/7scenes_redkitchen_seq/") == "7scenes_redkitchen_seq"
    assert recording_name("C:\\rec\\a b.bag") == "a-b.bag"
    tree = {
        "nodes": [
            {"id": 0, "kind": "scene", "parent": None, "depth": None, "area": 100},
            {"id": 1, "kind": "object", "parent": 0, "depth": 900.0, "area": 40},
            {"id": 3, "kind": "object", "parent": 1, "depth": 950.0, "area": 5},
            {"id": 2, "kind": "floor", "parent": 0, "depth": 2000.0, "area": 30},
        ]
    }
    assert [(n["id"], n["level"]) for n in tree_lines(tree)] == [(0, 0), (1, 1), (3, 2), (2, 1)]


@pytest.mark.parametrize(
    "kwargs", [{"speed": 0}, {"speed": 17}, {"fps": -1}, {"seek_history": -1}, {"samplerate": 10}, {"min_width_px": 0}]
)
def test_viewer_config_refuses_absurd_values(kwargs: dict[str, Any]) -> None:
    with pytest.raises(InputError):
        ViewerConfig(**kwargs)


def test_index_page_and_static_files() -> None:
    with _client(create_app(_sim_player(playing=False))) as client:
        page = client.get("/")
        assert page.status_code == 200 and "text/html" in page.headers["content-type"]
        assert 'id="view"' in page.text and "data-objects" in page.text and "/static/viewer.js" in page.text
        js = client.get("/static/viewer.js")
        assert js.status_code == 200 and "javascript" in js.headers["content-type"]
        assert "WebSocket" in js.text
        assert client.get("/static/viewer.css").status_code == 200
        assert client.get("/static/nothing.js").status_code == 404


@pytest.mark.parametrize(
    "path",
    [
        "/static/../../pyproject.toml",
        "/static/..%2F..%2Fpyproject.toml",
        "/static/%2e%2e/%2e%2e/pyproject.toml",
        "/static/%2e%2e%2f%2e%2e%2fpyproject.toml",
        "/static/%252e%252e%252fpyproject.toml",
        "/static/viewer.js/../../../../pyproject.toml",
        "/static/..\\..\\pyproject.toml",
        "/static//etc/passwd",
    ],
)
def test_static_never_leaves_its_folder(path: str) -> None:
    with _client(create_app(_sim_player(playing=False))) as client:
        r = client.get(path)
        assert r.status_code == 404
        assert "[project]" not in r.text and "root:" not in r.text
        assert "error" in r.json()


def test_stream_delivers_the_table_scene_with_its_true_objects() -> None:
    sim = next(iter(simulate("table", 1)))
    reference = Pipeline().process(sim.frame)
    with _client(create_app(_sim_player(playing=False))) as client:
        with client.websocket_connect(WS + "/ws/sim-table") as ws:
            hello = _recv(ws)
            assert hello["type"] == "hello" and hello["frames"] == 4 and hello["fps"] == pytest.approx(30.0)
            assert {"slices", "threshold", "region"} <= set(hello["methods"])
            assert client.post("/api/recordings/sim-table/step").json()["index"] == 0
            msg = _frame(ws)
    assert msg["index"] == 0 and msg["size"] == [176, 132] and msg["scale"] == 2
    assert msg["objects"] == len(reference.segmentation.objects) == len(msg["record"]["objects"])
    assert msg["record"]["sentence"] == reference.sentence
    # The page gets the depth (uint16 mm, 0 where invalid) and the label image as they are.
    expect_depth = np.where(sim.frame.valid, np.rint(sim.frame.depth), 0)
    assert np.array_equal(msg["_depth"], expect_depth)
    assert np.array_equal(msg["_labels"], reference.segmentation.labels)
    lo, hi = msg["depth_range_mm"]
    assert lo == pytest.approx(np.percentile(sim.frame.depth[sim.frame.valid], 1), rel=0.02)
    assert hi == pytest.approx(np.percentile(sim.frame.depth[sim.frame.valid], 99), rel=0.02)
    # Every compact true object (cup, box, ball, bottle) is on the page: one object whose
    # center is within 6 px of the truth and whose area is within 40 % of it.
    objects = msg["record"]["objects"]
    for t in sim.truth:
        if t.kind != "object" or t.area > 0.1 * 176 * 132:
            continue
        tx, ty = t.center_xy
        near = [
            o
            for o in objects
            if np.hypot(o["center_xy"][0] - tx, o["center_xy"][1] - ty) < 6 and abs(o["area"] - t.area) < 0.4 * t.area
        ]
        assert len(near) == 1, (t.name, t.center_xy, t.area)
    assert {"actions", "channel", "warnings"} <= set(msg["plan"])
    assert msg["tree"][0]["level"] == 0 and all(n["level"] >= 1 for n in msg["tree"][1:])


def test_play_pause_step_round_trip() -> None:
    with _client(create_app(_sim_player(playing=True, loop=True))) as client:
        with client.websocket_connect(WS + "/ws/sim-table") as ws:
            _recv(ws)
            first = _frame(ws)
            second = _frame(ws)
            assert second["index"] == (first["index"] + 1) % 4 or second["dropped"] > first["dropped"]
            state = client.post("/api/recordings/sim-table/pause").json()
            assert state["playing"] is False
            # pause returns once the frame in progress is pushed: drain up to it, then nothing more
            msg = second
            while msg["index"] != state["index"]:
                msg = _frame(ws)
            stepped = client.post("/api/recordings/sim-table/step").json()
            assert stepped["index"] == (state["index"] + 1) % 4 and stepped["playing"] is False
            after = _frame(ws)
            assert after["index"] == stepped["index"] and after["playing"] is False


def test_parameter_change_takes_effect_on_the_next_frame() -> None:
    frames = list(open_source(SPEC))
    ref, same = Pipeline(), Pipeline()
    ref.process(frames[0])
    same.process(frames[0])
    changed = Config().replace(segment={"method": "threshold", "min_area": 50, "fraction": 0.2, "bin_mm": 20})
    ref.config = changed
    expected = ref.process(frames[1])
    unchanged = same.process(frames[1])
    assert expected.sentence != unchanged.sentence  # else this test could not tell
    with _client(create_app(_sim_player(playing=False))) as client:
        with client.websocket_connect(WS + "/ws/sim-table") as ws:
            _recv(ws)
            client.post("/api/recordings/sim-table/step")
            before = _frame(ws)
            r = client.put(
                "/api/recordings/sim-table/params",
                json={"method": "threshold", "min_area": 50, "fraction": 0.2, "bin_mm": 20},
            )
            assert r.status_code == 200
            assert r.json()["params"] == {"method": "threshold", "min_area": 50, "fraction": 0.2, "bin_mm": 20}
            client.post("/api/recordings/sim-table/step")
            after = _frame(ws)
    assert before["index"] == 0 and after["index"] == 1
    assert after["objects"] == len(expected.segmentation.objects)
    assert after["record"]["sentence"] == expected.sentence


def test_a_page_that_is_behind_gets_the_newest_frame_and_the_count_of_missed_ones() -> None:
    with _client(create_app(_sim_player(playing=False))) as client:
        with client.websocket_connect(WS + "/ws/sim-table") as ws:
            _recv(ws)
            client.post("/api/recordings/sim-table/step")
            first = _frame(ws, ack=False)  # the page is still drawing frame 0 ...
            for _ in range(2):  # ... while frames 1 and 2 are ready
                client.post("/api/recordings/sim-table/step")
            ws.send_text(json.dumps({"type": "ack", "index": 0}))
            newest = _frame(ws)
    assert first["index"] == 0 and first["dropped"] == 0
    assert newest["index"] == 2 and newest["page_dropped"] == 1 and newest["dropped"] == 1


def _cheap_frames(n: int) -> Iterator[Any]:
    yy, xx = np.mgrid[0:30, 0:40]
    for i in range(n):
        depth = np.where((xx - 10 - i % 20) ** 2 + (yy - 15) ** 2 < 36, 800.0, 2000.0).astype(np.float32)
        yield make_frame(depth, index=i, time_s=i / 1000.0, name=f"cheap#{i}")


def test_server_skips_frames_when_behind_and_counts_every_one() -> None:
    # 1000 frames/s: processing a frame takes longer than its 1 ms period, reading one does not.
    player = Player(
        lambda: _cheap_frames(120), "cheap", Config(), ViewerConfig(fps=1000.0, loop=False, min_width_px=40), frames=120
    )
    seen = []
    with _client(create_app(player)) as client:
        with client.websocket_connect(WS + "/ws/cheap") as ws:
            _recv(ws)
            while (msg := _frame(ws, end=True))["type"] == "frame":
                seen.append(msg)
            state = client.get("/api/recordings/cheap").json()
    assert msg["ended"] is True and state["ended"] is True
    assert seen[-1]["index"] == 119  # the last frame is shown even when behind
    # every frame not shown is counted
    gaps = sum(b["index"] - a["index"] - 1 for a, b in itertools.pairwise(seen))
    gaps += seen[0]["index"] + 119 - seen[-1]["index"]
    assert seen[-1]["dropped"] > 0
    assert seen[-1]["dropped"] == seen[-1]["server_dropped"] + seen[-1]["page_dropped"]
    assert gaps == state["dropped"] + seen[-1]["page_dropped"]
    assert state["processed"] + state["dropped"] == 120


def test_a_pause_while_behind_ends_on_the_newest_frame_read_and_a_step_shows_the_next() -> None:
    # At 1000 frames/s the player skips frames; the read of the first frame after a skipped one
    # waits until the test has asked for a pause, so the pause arrives with a skipped frame
    # behind it and a fresh one in hand (what a CI run on a slow spell hit in the browser).
    reading, release = threading.Event(), threading.Event()
    player = Player(
        lambda: frames(), "cheap", Config(), ViewerConfig(fps=1000.0, loop=False, min_width_px=40), frames=120
    )

    def frames() -> Iterator[Any]:
        for f in _cheap_frames(120):
            if not reading.is_set() and player.index is not None and player.index < f.index - 1:
                reading.set()  # frame f.index - 1 was read and skipped
                release.wait(10)
            yield f

    async def run() -> tuple[int, int, int, dict[str, Any]]:
        player.start()
        page = player.connect()
        player.play()
        assert await asyncio.to_thread(reading.wait, 20), "the player never skipped a frame"
        pause = asyncio.create_task(player.pause())
        await asyncio.sleep(0)  # the pause is asked for while the frame is being read
        release.set()
        await asyncio.wait_for(pause, 20)
        k, shown = player.index, page.slot.header["index"] if page.slot else None
        await asyncio.wait_for(player.step(), 20)
        state = player.state()
        await player.stop()
        assert k is not None and shown is not None and page.slot is not None
        return k, shown, page.slot.header["index"], state

    k, shown, stepped, state = asyncio.run(run())
    assert shown == k  # the page ends on the frame the pause reports ...
    assert stepped == k + 1  # ... and a step shows the very next one
    assert state["processed"] + state["dropped"] == k + 2  # every frame read is shown or counted


def _glide_track(audio: np.ndarray, sr: int, lo: float, hi: float) -> np.ndarray:
    """The strongest frequency (Hz) between ``lo`` and ``hi`` in successive 64-ms windows."""
    n, pad = round(0.064 * sr), 1 << 15
    f = np.fft.rfftfreq(pad, 1 / sr)
    band = np.flatnonzero((f >= lo) & (f <= hi))
    out = []
    for a in range(0, len(audio) - n, n // 2):
        spec = np.abs(np.fft.rfft(audio[a : a + n].sum(axis=1) * np.hanning(n), pad))
        j = int(band[np.argmax(spec[band])])
        p, q, r = np.log(spec[j - 1 : j + 2] + 1e-12)
        out.append(f[j] + 0.5 * (p - r) / (p - 2 * q + r) * (f[1] - f[0]))
    return np.asarray(out)


def test_sound_is_the_live_renderer_paced_by_the_page_and_glides_over_the_surfaces_extent() -> None:
    pytest.importorskip("depthgram.sound", reason="the sound stage is not installed")
    from dataclasses import replace

    from depthgram.sound import SoundMapping
    from depthgram.sound.choose import Chooser

    sr = 16000
    mapping = SoundMapping(max_voices=0, max_glides=1)  # the nearest surface alone: its glide is read back
    src = open_source(SPEC)
    config = replace(Config(), sound=mapping)
    player = Player(
        lambda: iter(src),
        recording_name(SPEC),
        config,
        ViewerConfig(playing=False, loop=True, samplerate=sr),
        frames=len(src),
        fps=src.fps,
    )
    asked = got = 0
    blocks: list[np.ndarray] = []
    heard: list[int] = []

    def pull(ws: Any, n: int) -> np.ndarray:
        # As the page's AudioWorklet does: ask for n samples, take frames (acknowledged) meanwhile.
        nonlocal asked, got
        ws.send_text(json.dumps({"type": "audio", "need": n}))
        asked += n
        while (msg := _recv(ws))["type"] != "audio":
            if msg["type"] == "frame":
                ws.send_text(json.dumps({"type": "ack", "index": msg["index"]}))
        assert msg["samplerate"] == sr and msg["channels"] == 2
        pcm = np.frombuffer(base64.b64decode(msg["pcm"]), "<i2").reshape(-1, 2) / 32768.0
        got += len(pcm)
        heard.append(msg["frame"])
        return pcm

    with _client(create_app(player)) as client:
        with client.websocket_connect(WS + "/ws/sim-table") as ws:
            hello = _recv(ws)
            assert hello["samplerate"] == sr
            ws.send_text(json.dumps({"type": "sound", "on": True}))
            assert _recv(ws) == {"type": "sound", "on": True, "available": True}
            client.post("/api/recordings/sim-table/play")
            while not heard or heard[-1] < 0:  # blocks are silence until the first frame's voices
                pull(ws, 320)
            blocks = [pull(ws, 320) for _ in range(150)]  # 3 s, in 20-ms blocks as a page asks
            client.post("/api/recordings/sim-table/pause")
            after = np.concatenate([pull(ws, 320) for _ in range(15)])
    # Exactly what was asked for, never a catch-up: the page's audio clock paces the synthesis.
    assert got == asked
    assert set(heard[-165:-15]) <= {0, 1, 2, 3}  # while playing, every block carries a frame's voices
    # The surface glides between its real near and far ends (the objects' extents reach the
    # page's sound, as in `sonify`'s WAV), not over the extent assumed without them.
    first = next(iter(open_source(SPEC)))
    r = Pipeline(config).process(first)
    with_extent = Chooser(mapping).voices(r.tree, first.size, r.segmentation.objects, first.intrinsics)
    assumed = Chooser(mapping).voices(r.tree, first.size, (), first.intrinsics)
    (v,), (u,) = with_extent.values(), assumed.values()
    span, span_assumed = v.freq_a / v.freq_b, u.freq_a / u.freq_b
    assert abs(span_assumed / span - 1) > 0.03  # the test tells them apart
    audio = np.concatenate(blocks)[int(0.1 * sr) :]
    track = _glide_track(audio, sr, 0.8 * min(v.freq_a, v.freq_b), 1.25 * max(v.freq_a, v.freq_b))
    assert track.max() == pytest.approx(v.freq_a, rel=0.01) and track.min() == pytest.approx(v.freq_b, rel=0.01)
    assert abs(track.max() / track.min() - span) < 0.3 * abs(span_assumed - span), (track.max(), track.min())
    # Paused: the voices fade out over the ramp and the blocks go on, silent.
    assert np.abs(after[int(0.1 * sr) :]).max() < 1e-3


def test_a_broken_frame_pauses_playback_and_tells_the_page_which_frame() -> None:
    def broken() -> Iterator[Any]:
        frames = _cheap_frames(3)
        yield next(frames)
        yield next(frames)
        raise InputError("cheap/frame-2.png: truncated PNG, expected 40 x 30 uint16")

    player = Player(broken, "broken", Config(), ViewerConfig(fps=30.0, loop=False, min_width_px=40), frames=3)
    with _client(create_app(player)) as client:
        with client.websocket_connect(WS + "/ws/broken") as ws:
            _recv(ws)
            shown = []
            while (msg := _recv(ws))["type"] == "frame":
                shown.append(msg["index"])
                ws.send_text(json.dumps({"type": "ack"}))
            ws.send_text("not json")  # ignored, the connection stays open
            state = client.get("/api/recordings/broken").json()
    assert shown == [0, 1]
    assert msg["type"] == "error" and "frame-2.png: truncated PNG" in msg["message"] and "after 1" in msg["message"]
    assert state["playing"] is False and state["error"] == msg["message"]


@pytest.mark.parametrize(
    ("method", "path", "body", "status", "needle"),
    [
        ("get", "/api/recordings/nope", None, 404, "unknown recording"),
        ("post", "/api/recordings/nope/play", None, 404, "unknown recording"),
        ("post", "/api/recordings/sim-table/rewind", None, 404, "unknown action"),
        ("put", "/api/recordings/sim-table/params", {"min_area": -1}, 422, "min_area"),
        ("put", "/api/recordings/sim-table/params", {"method": "x"}, 422, "method"),
        ("put", "/api/recordings/sim-table/params", {"no_such": 1}, 422, "unknown setting"),
        ("put", "/api/recordings/sim-table/params", {}, 422, "params"),
        ("put", "/api/recordings/sim-table/speed", {"value": 0}, 422, "speed"),
        ("put", "/api/recordings/sim-table/speed", {"value": "fast"}, 422, "speed"),
        ("put", "/api/recordings/sim-table/speed", b"{not json", 400, "JSON"),
        # issue 18.8: nesting past the parser's recursion limit is the sender's error, not a 500
        ("put", "/api/recordings/sim-table/params", b"[" * 30000 + b"]" * 30000, 400, "nested too deeply"),
        (
            "put",
            "/api/recordings/sim-table/speed",
            b'{"value": ' + b"[" * 30000 + b"]" * 30000 + b"}",
            400,
            "nested too deeply",
        ),
        # ... and bodies far larger than any control needs are refused before they are read
        ("put", "/api/recordings/sim-table/params", b" " * 70000 + b"{}", 413, "over 65536 bytes"),
        ("post", "/api/recordings/sim-table/seek", {"index": 4}, 422, "frames 0..3"),
        ("post", "/api/recordings/sim-table/seek", {"index": -1}, 422, "index"),
        ("post", "/api/recordings/sim-table/seek", {"index": 1.5}, 422, "index"),
    ],
)
def test_bad_requests_get_a_clear_json_error(method: str, path: str, body: Any, status: int, needle: str) -> None:
    with _client(create_app(_sim_player(playing=False))) as client:
        if isinstance(body, bytes):
            r = client.request(method.upper(), path, content=body)
        elif body is not None:
            r = client.request(method.upper(), path, json=body)
        else:
            r = client.request(method.upper(), path)
        assert r.status_code == status, r.text
        assert needle in r.json()["error"]
        # a refused change leaves the settings as they were
        state = client.get("/api/recordings/sim-table").json()
        assert state["params"]["method"] == "surfaces" and state["speed"] == 1.0


def test_unknown_recording_stream_is_refused() -> None:
    with _client(create_app(_sim_player(playing=False))) as client:
        with pytest.raises(WebSocketDisconnect) as info, client.websocket_connect(WS + "/ws/nope") as ws:
            ws.receive_text()
        assert info.value.code == 4404


def test_real_recording_streams_at_its_own_size_with_the_pipeline_objects(shared_data: Any) -> None:
    seq = shared_data / "7scenes_redkitchen_seq"
    src = open_source(seq)
    frames = [f for _, f in zip(range(2), src, strict=False)]
    pipe = Pipeline()
    expected = [pipe.process(f) for f in frames]
    player = Player(
        lambda: iter(src), recording_name(str(seq)), Config(), ViewerConfig(playing=False), frames=len(src), fps=src.fps
    )
    with _client(create_app(player)) as client:
        with client.websocket_connect(WS + "/ws/7scenes_redkitchen_seq") as ws:
            hello = _recv(ws)
            shown = []
            for _ in range(2):
                client.post("/api/recordings/7scenes_redkitchen_seq/step")
                shown.append(_frame(ws))
    # PROVENANCE.md: 300 frames of 640 x 480 at 30 Hz
    assert hello["frames"] == 300
    for msg, ref in zip(shown, expected, strict=True):
        assert msg["size"] == [640, 480] and msg["scale"] == 1
        assert msg["objects"] == len(ref.segmentation.objects)
        assert msg["record"]["sentence"] == ref.sentence


def test_other_sites_and_other_host_names_are_refused() -> None:
    with _client(create_app(_sim_player(playing=False))) as client:
        evil = {"Origin": "http://evil.example"}
        r = client.post("/api/recordings/sim-table/play", headers=evil)
        assert r.status_code == 403 and "evil.example" in r.json()["error"]
        assert client.put("/api/recordings/sim-table/speed", json={"value": 2}, headers=evil).status_code == 403
        assert client.get("/api/recordings/sim-table").json()["speed"] == 1.0
        with (
            pytest.raises(WebSocketDisconnect) as info,
            client.websocket_connect(WS + "/ws/sim-table", headers=evil) as ws,
        ):
            ws.receive_text()
        assert info.value.code == 4403
        # the page's own origin is welcome
        own = {"Origin": "http://127.0.0.1:8765"}
        assert client.post("/api/recordings/sim-table/play", headers=own).status_code == 200
    # A foreign name resolving to 127.0.0.1 (DNS rebinding) is refused, [::1] and localhost are not.
    app = create_app(_sim_player(playing=False))
    with TestClient(app, base_url="http://rebound.example:8765") as client:
        r = client.get("/api/recordings")
        assert r.status_code == 400 and "rebound.example" in r.json()["error"]
        with (
            pytest.raises(WebSocketDisconnect) as info,
            client.websocket_connect("ws://rebound.example:8765/ws/sim-table") as ws,
        ):
            ws.receive_text()
        assert info.value.code == 4400
    for base in ("http://[::1]:8765", "http://localhost:8765"):
        with TestClient(create_app(_sim_player(playing=False)), base_url=base) as client:
            assert client.get("/api/recordings").status_code == 200
    with TestClient(create_app(_sim_player(playing=False), allowed_hosts=None)) as client:
        assert client.get("/api/recordings").status_code == 200


def test_a_body_sent_without_a_length_is_cut_off_at_the_limit() -> None:
    def chunks() -> Iterator[bytes]:
        yield b"["
        for _ in range(100):
            yield b" " * 1000  # 100 kB in all, past the 64 kB limit
        yield b"]"

    with _client(create_app(_sim_player(playing=False))) as client:
        r = client.put("/api/recordings/sim-table/params", content=chunks())
        assert r.status_code == 413 and "over 65536 bytes" in r.json()["error"]
        # a page's message larger than any it sends is ignored; the connection stays open
        with client.websocket_connect(WS + "/ws/sim-table") as ws:
            _recv(ws)  # hello
            ws.send_text("[" * 30000 + "]" * 30000)
            ws.send_text(json.dumps({"type": "sound", "on": True}))
            assert _recv(ws)["type"] == "sound"


def test_the_origin_check_compares_the_scheme_too() -> None:
    with _client(create_app(_sim_player(playing=False))) as client:
        for origin in ("https://127.0.0.1:8765", "ws://127.0.0.1:8765", "http://127.0.0.1:8766", "http://127.0.0.1"):
            r = client.post("/api/recordings/sim-table/play", headers={"Origin": origin})
            assert r.status_code == 403, origin
            with (
                pytest.raises(WebSocketDisconnect) as info,
                client.websocket_connect(WS + "/ws/sim-table", headers={"Origin": origin}) as ws,
            ):
                ws.receive_text()
            assert info.value.code == 4403
        assert client.get("/api/recordings/sim-table").json()["playing"] is False
        assert (
            client.post("/api/recordings/sim-table/pause", headers={"Origin": "http://127.0.0.1:8765"}).status_code
            == 200
        )
    # default ports: an origin without a port is port 80 for http
    with TestClient(create_app(_sim_player(playing=False)), base_url="http://localhost") as client:
        assert client.post("/api/recordings/sim-table/pause", headers={"Origin": "http://localhost"}).status_code == 200
        assert (
            client.post("/api/recordings/sim-table/pause", headers={"Origin": "https://localhost"}).status_code == 403
        )


def test_beyond_loopback_every_request_needs_the_token_whatever_its_host() -> None:
    app = create_app(_sim_player(playing=False), allowed_hosts=None, token="s3cret-token")
    with TestClient(app, base_url="http://rebound.example:8765") as client:
        r = client.get("/api/recordings")
        assert r.status_code == 401 and "access token" in r.json()["error"]
        assert client.get("/").status_code == 401
        assert client.get("/api/recordings", headers={"Authorization": "Bearer wrong"}).status_code == 401
        with (
            pytest.raises(WebSocketDisconnect) as info,
            client.websocket_connect("ws://rebound.example:8765/ws/sim-table") as ws,
        ):
            ws.receive_text()
        assert info.value.code == 4401
        # the address printed at start: the page gets the token as a cookie for its own origin
        page = client.get("/?token=s3cret-token")
        assert page.status_code == 200 and "depthgram view" in page.text
        cookie = page.headers["set-cookie"]
        assert "depthgram_token=s3cret-token" in cookie and "HttpOnly" in cookie and "SameSite=strict" in cookie
        assert client.get("/api/recordings").status_code == 200  # the client keeps the cookie
        assert client.get("/static/viewer.js").status_code == 200
        with client.websocket_connect("ws://rebound.example:8765/ws/sim-table") as ws:
            assert _recv(ws)["type"] == "hello"
    app = create_app(_sim_player(playing=False), allowed_hosts=None, token="s3cret-token")
    with TestClient(app, base_url="http://box.lan:8765") as client:
        r = client.get("/api/recordings", headers={"Authorization": "Bearer s3cret-token"})
        assert r.status_code == 200


def test_view_asks_for_host_names_or_a_token_beyond_loopback() -> None:
    from depthgram.commands.view import access

    assert access("127.0.0.1", [], None) == (("127.0.0.1", "localhost", "::1"), None)
    hosts, token = access("0.0.0.0", [], None)
    assert hosts is None and token is not None and len(token) >= 20
    assert access("0.0.0.0", [], None)[1] != token  # made up afresh each time
    assert access("0.0.0.0", [], "mine") == (None, "mine")
    hosts, token = access("192.168.1.20", ["Box.lan", "[fe80::1]"], None)
    assert hosts == ("127.0.0.1", "localhost", "::1", "box.lan", "fe80::1") and token is None


def test_seek_shows_the_frame_as_it_was_played_and_a_step_the_next() -> None:
    # Frame 2 after a seek is what playing frames 0, 1, 2 in order gives (tracks included),
    # because the frames before it go through the pipeline unseen (seek_history >= 2).
    reference = Pipeline()
    sentences = [reference.process(f).sentence for f in open_source(SPEC)]
    with _client(create_app(_sim_player(playing=False))) as client:
        with client.websocket_connect(WS + "/ws/sim-table") as ws:
            _recv(ws)
            assert client.post("/api/recordings/sim-table/step").json()["index"] == 0
            assert _frame(ws)["index"] == 0
            state = client.post("/api/recordings/sim-table/seek", json={"index": 2}).json()
            assert state["index"] == 2 and state["playing"] is False
            msg = _frame(ws)
            assert msg["index"] == 2 and msg["record"]["sentence"] == sentences[2]
            assert client.post("/api/recordings/sim-table/step").json()["index"] == 3
            assert _frame(ws)["record"]["sentence"] == sentences[3]
            # step back: the frame before, again as it was played
            assert client.post("/api/recordings/sim-table/seek", json={"index": 1}).json()["index"] == 1
            assert _frame(ws)["record"]["sentence"] == sentences[1]


def test_a_live_source_cannot_be_rewound() -> None:
    src = open_source(SPEC)
    player = Player(lambda: iter(src), "cam", Config(), ViewerConfig(playing=False), seekable=False)
    with _client(create_app(player)) as client:
        r = client.post("/api/recordings/cam/seek", json={"index": 0})
        assert r.status_code == 422 and "cannot be rewound" in r.json()["error"]
        assert client.get("/api/recordings/cam").json()["seekable"] is False


class _FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_pacer_drops_a_frame_only_when_its_slot_passed_more_than_a_period_ago() -> None:
    from depthgram.pacing import Pacer

    clock = _FakeClock()
    pacer = Pacer(0.1, clock=clock)  # 10 frames/s, clock started at t = 0
    assert pacer.wait_s() == 0.0 and not pacer.late()
    pacer.advance()  # frame 1 due at 0.1 s
    clock.now = 0.05
    assert pacer.wait_s() == pytest.approx(0.05) and not pacer.late()
    clock.now = 0.2  # exactly one period late: still shown
    assert not pacer.late()
    clock.now = 0.2001  # more than a period late: lost, as a live sensor loses it
    assert pacer.late()
    pacer.advance(0.3)  # a timestamp gap: frame due at 0.4 s
    assert pacer.due == pytest.approx(0.4) and not pacer.late()


def test_pacer_never_drops_from_a_source_slower_than_real_time() -> None:
    from depthgram.pacing import Pacer

    clock = _FakeClock()
    pacer = Pacer(0.1, clock=clock)
    pacer.note_read(0.15)  # reading a frame costs more than its period: skipping cannot catch up
    clock.now = 1.0
    assert not pacer.late()
    pacer.advance()  # the backlog is forgotten: the next frame is due at most a period ago
    assert pacer.due == pytest.approx(0.9) and not pacer.late()


def test_player_moves_between_its_states_as_the_controls_say() -> None:
    # playing -> paused (pause) -> seeking -> paused (seek shown) -> ended (the last frame stepped past)
    from depthgram.views.player import Mode

    async def run() -> list[str]:
        player = _sim_player(playing=True, loop=False)
        player.start()
        player.connect()
        seen = [player.mode.value]
        await asyncio.wait_for(player.pause(), 20)
        seen.append(player.mode.value)
        seek = asyncio.create_task(player.seek(3))
        await asyncio.sleep(0)
        seen.append(player.mode.value)
        await asyncio.wait_for(seek, 20)
        seen.append(player.mode.value)
        assert player.index == 3
        await asyncio.wait_for(player.step(), 20)  # there is no frame 4: the recording ends
        await asyncio.sleep(0.05)
        seen.append(player.mode.value)
        assert player.state()["ended"] is True and player.index == 3
        await asyncio.wait_for(player.step(), 20)  # a step after the end starts again at frame 0
        seen.append(player.mode.value)
        assert player.index == 0
        await player.stop()
        return seen

    assert asyncio.run(run()) == [
        Mode.PLAYING.value,
        "paused",
        "seeking",
        "paused",
        "ended",
        "paused",
    ]


def test_the_pacer_admits_frames_on_time_drops_late_ones_and_waits_for_early_ones() -> None:
    from depthgram.pacing import Pacer

    now = [0.0]
    slept: list[float] = []

    def sleep(s: float) -> None:
        slept.append(s)
        now[0] += s

    pacer = Pacer(0.1, clock=lambda: now[0])
    assert pacer.admit(0.0, sleep) and slept == []  # due at once
    now[0] = 0.05
    assert pacer.admit(0.1, sleep)  # early: waits for its slot
    assert slept == [pytest.approx(0.05)]
    now[0] = 0.45  # the consumer was busy: the frame due at 0.2 is more than a period late
    assert not pacer.admit(0.2, sleep)
    assert pacer.admit(0.4, sleep)  # 0.05 late, within a period: taken at once
    assert len(slept) == 1
