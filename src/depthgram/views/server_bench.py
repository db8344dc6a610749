"""Does the live viewer keep up? Frames delivered per second to a page that draws instantly.

Usage::

    python -m depthgram.views.server_bench [SPEC] [--seconds S] [--fps RATE] [--jpeg] [--sound]

The recording's frames are read into memory first, so that the figures measure the viewer
(pipeline, picture, JSON, WebSocket) and not the source; with the simulator the source alone
costs tens of milliseconds a frame. A real uvicorn server runs on a free loopback port and a
WebSocket client acknowledges each frame on arrival, as the page does after drawing it.
Prints delivered frames/s, frames dropped by the server and by the page, and the pipeline's
latency. Speed is measured here, never asserted in tests.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import socket
import statistics
import time

from depthgram.frame import Frame
from depthgram.pipeline import Config
from depthgram.sources import open_source
from depthgram.views.server import Player, ViewerConfig, create_app, recording_name


async def _measure(url: str, seconds: float, sound: bool) -> dict[str, float]:
    import websockets

    got = 0
    latencies: list[float] = []
    last: dict[str, float] = {}
    async with websockets.connect(url, max_size=None) as ws:
        await ws.recv()  # hello
        if sound:
            await ws.send(json.dumps({"type": "sound", "on": True}))
        t0 = None
        while True:
            msg = json.loads(await ws.recv())
            if msg["type"] != "frame":
                continue
            await ws.send(json.dumps({"type": "ack", "index": msg["index"]}))
            if t0 is None:  # the first frame carries the start-up (imports, compilation)
                t0 = time.perf_counter()
                base = (msg["server_dropped"], msg["page_dropped"])
                continue
            got += 1
            latencies.append(msg["latency_ms"])
            last = {"server": msg["server_dropped"] - base[0], "page": msg["page_dropped"] - base[1]}
            if time.perf_counter() - t0 >= seconds:
                break
        elapsed = time.perf_counter() - t0
    return {"fps": got / elapsed, "frames": got, "server_dropped": last.get("server", 0),
            "page_dropped": last.get("page", 0), "latency_ms": statistics.median(latencies)}


def main(argv: list[str] | None = None) -> None:
    import uvicorn

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("spec", nargs="?", default="sim:approach?frames=60&size=176x132")
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--jpeg", action="store_true")
    p.add_argument("--sound", action="store_true")
    args = p.parse_args(argv)
    frames: list[Frame] = list(open_source(args.spec))
    viewer = ViewerConfig(fps=args.fps, image_format="jpeg" if args.jpeg else "png")
    player = Player(lambda: iter(frames), recording_name(args.spec), Config(), viewer, frames=len(frames))
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(create_app(player), log_level="warning"))

    async def run() -> dict[str, float]:
        task = asyncio.create_task(server.serve(sockets=[sock]))
        while not server.started:
            await asyncio.sleep(0.05)
        try:
            return await _measure(f"ws://127.0.0.1:{port}/ws/{player.name}", args.seconds, args.sound)
        finally:
            server.should_exit = True
            await task

    r = asyncio.run(run())
    w, h = frames[0].size
    print(f"{args.spec}: {w} x {h}, target {args.fps:g} frames/s, {'jpeg' if args.jpeg else 'png'}"
          f"{', sound' if args.sound else ''}")
    print(f"  delivered {r['fps']:.1f} frames/s ({r['frames']:.0f} frames in {args.seconds:g} s); "
          f"dropped by server {r['server_dropped']:.0f}, by page {r['page_dropped']:.0f}; "
          f"pipeline latency median {r['latency_ms']:.1f} ms")


if __name__ == "__main__":
    main()
