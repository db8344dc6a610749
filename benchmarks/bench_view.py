"""Does the live viewer keep up? One pass of a recording, counted frame by frame, as ``depthgram run`` counts.

Usage::

    python benchmarks/bench_view.py [SPEC] [--fps RATE] [--page ws|chromium] [--compress] [--sound]

The recording is played once (no loop) by a real uvicorn server on a free loopback port, read
from its source as ``depthgram view`` reads it. The page is either a WebSocket client that
acknowledges each frame on arrival (``ws``: the server's own cost) or the viewer's page in
headless Chromium (``chromium``: the server and the page together). Prints frames shown and
dropped (by the server, by the page) out of the recording's frames, the pipeline's latency and
the server's time per stage of a frame; compare with ``depthgram run SPEC --fps RATE`` run just
before or after (the machine's speed drifts). Speed is measured here, never asserted in tests.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import socket
import statistics
import threading
import time
from pathlib import Path
from typing import Any

from depthgram.pipeline import Config
from depthgram.sources import open_source
from depthgram.views.server import Player, ViewerConfig, create_app, recording_name
from depthgram.views.wire import unpack_frame

CHROMIUM = Path("/usr/bin/chromium")


async def _ws_page(url: str, sound: bool) -> dict[str, Any]:
    import websockets

    shown = 0
    latencies: list[float] = []
    last: dict[str, Any] = {}
    async with websockets.connect(url, max_size=None) as ws:
        await ws.recv()  # hello
        if sound:
            await ws.send(json.dumps({"type": "sound", "on": True}))
        while True:
            raw = await ws.recv()
            msg = unpack_frame(raw)[0] if isinstance(raw, bytes) else json.loads(raw)
            if msg["type"] == "end":
                break
            if msg["type"] != "frame":
                continue
            await ws.send(json.dumps({"type": "ack", "index": msg["index"]}))
            shown += 1
            latencies.append(msg["latency_ms"])
            last = msg
    return {
        "shown": shown,
        "server_dropped": last.get("server_dropped", 0),
        "page_dropped": last.get("page_dropped", 0),
        "latency_ms": statistics.median(latencies),
    }


def _chromium_page(url: str, sound: bool) -> dict[str, Any]:
    from playwright.sync_api import sync_playwright

    args = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking"]
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=args)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.add_init_script("window.__shown = 0;")
            page.goto(url)
            page.wait_for_function(
                "document.getElementById('view').dataset.ended === 'true'", timeout=600_000, polling=200
            )
            got = page.evaluate(
                "() => ({shown: window.__depthgramShown || 0,"
                " dropped: Number(document.getElementById('view').dataset.dropped),"
                " page_ms: window.__depthgramDrawMs || []})"
            )
        finally:
            browser.close()
    ms = got["page_ms"]
    return {
        "shown": got["shown"],
        "dropped": got["dropped"],
        "page_draw_ms": statistics.median(ms) if ms else float("nan"),
    }


def main(argv: list[str] | None = None) -> None:
    import uvicorn

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("spec", nargs="?", default="../shared/data/7scenes_redkitchen_seq")
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--page", choices=("ws", "chromium"), default="ws")
    p.add_argument("--compress", action="store_true")
    p.add_argument("--sound", action="store_true")
    args = p.parse_args(argv)
    src = open_source(args.spec)
    n = len(src)  # type: ignore[arg-type]
    viewer = ViewerConfig(fps=args.fps, loop=False, playing=True, compress=args.compress)
    player = Player(
        lambda: iter(src), recording_name(args.spec), Config(), viewer, frames=n, fps=getattr(src, "fps", None)
    )
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(create_app(player), log_level="warning", ws_per_message_deflate=False))
    thread = threading.Thread(target=lambda: asyncio.run(server.serve(sockets=[sock])), daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.05)
    try:
        if args.page == "ws":
            r = asyncio.run(_ws_page(f"ws://127.0.0.1:{port}/ws/{player.name}", args.sound))
            dropped = r["server_dropped"] + r["page_dropped"]
        else:
            r = _chromium_page(f"http://127.0.0.1:{port}/", args.sound)
            dropped = r["dropped"]
        stages = player.stage_ms()
    finally:
        server.should_exit = True
        thread.join(10)
    print(
        f"{args.spec}: {n} frames at {args.fps:g} frames/s, page {args.page}, "
        f"{'compressed' if args.compress else 'raw'}{', sound' if args.sound else ''}"
    )
    print(f"  {r['shown']} shown, {dropped} dropped (server {player.dropped}); processed {player.processed}")
    print("  server per frame (median ms): " + ", ".join(f"{k} {v:.1f}" for k, v in stages.items()))
    print("  server total (s): " + ", ".join(f"{k} {sum(v):.2f}" for k, v in player._stage_s.items()))
    if "page_draw_ms" in r:
        print(f"  page per frame (median ms): draw {r['page_draw_ms']:.1f}")


if __name__ == "__main__":
    main()
