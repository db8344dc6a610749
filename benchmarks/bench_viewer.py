"""Does the live viewer keep up? Its drops beside ``depthgram run``'s, in the same conditions, back to back.

Usage::

    python benchmarks/bench_viewer.py [SPEC] [--fps RATE] [--page ws|chromium|both] [--repeat N]
                                      [--compress] [--sound] [--no-run]

For each repeat, ``depthgram run SPEC --fps RATE`` is run (a subprocess, as a user runs it) and
then the viewer plays the same recording once (no loop) on a real uvicorn server on a free
loopback port, read from its source as ``depthgram view`` reads it. The page is either a
WebSocket client that acknowledges each frame on arrival (``ws``: the server's own cost) or the
viewer's page in headless Chromium (``chromium``: the server and the page together, on the same
cores). Frames are counted as ``run`` counts them: shown, or dropped (by the server's pacer,
which is ``run``'s rule, or because the page was still drawing).

Wall times depend on the machine's load (printed with each line); the **thread CPU time** per
frame of the viewer's own work does not: ``pack`` (the page's arrays and JSON header, in the
player's thread), ``send`` (on the event loop) and the event loop's whole CPU time per frame
(``loop``: WebSocket framing, HTTP, scheduling), beside the pipeline's, which ``run`` spends
too. Speed is measured here, never asserted in tests.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from depthgram.cli import build_parser
from depthgram.commands._common import load_config, open_input
from depthgram.views.server import Player, ViewerConfig, create_app, recording_name
from depthgram.views.wire import unpack_frame

CHROMIUM = Path("/usr/bin/chromium")


def _load() -> str:
    return "load {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def run_command(spec: str, fps: float) -> tuple[int, int, float]:
    """``depthgram run SPEC --fps RATE``: frames, dropped and median latency (ms) from its summary."""
    cmd = [sys.executable, "-m", "depthgram.cli", "run", spec, "--fps", f"{fps:g}", "--quiet"]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    m = re.search(r"(\d+) frames played .*?: (\d+) processed, (\d+) dropped", out)
    lat = re.search(r"latency per frame: median ([\d.]+) ms", out)
    if m is None or lat is None:
        raise RuntimeError(f"unexpected output of {' '.join(cmd)}:\n{out}")
    return int(m.group(1)), int(m.group(3)), float(lat.group(1))


async def _ws_page(url: str, sound: bool) -> dict[str, Any]:
    import websockets

    shown = 0
    last: dict[str, Any] = {}
    async with websockets.connect(url, max_size=None) as ws:
        hello = json.loads(await ws.recv())
        ask: asyncio.Task[None] | None = None
        if sound:
            await ws.send(json.dumps({"type": "sound", "on": True}))
            block = hello.get("samplerate", 22050) // 50

            async def pull() -> None:
                # As the page's AudioWorklet: 20 ms of sound asked for every 20 ms of (wall) audio clock.
                while True:
                    await ws.send(json.dumps({"type": "audio", "need": block}))
                    await asyncio.sleep(0.02)

            ask = asyncio.get_running_loop().create_task(pull())
        while True:
            raw = await ws.recv()
            msg = unpack_frame(raw)[0] if isinstance(raw, bytes) else json.loads(raw)
            if msg["type"] == "end":
                break
            if msg["type"] != "frame":
                continue
            await ws.send(json.dumps({"type": "ack", "index": msg["index"]}))
            shown += 1
            last = msg
        if ask is not None:
            ask.cancel()
    return {"shown": shown, "dropped": last.get("dropped", 0)}


def _ws_page_process(url: str, sound: bool) -> dict[str, Any]:
    """The WebSocket page in a process of its own, as a browser is: it must not take the server's GIL."""
    cmd = [sys.executable, __file__, "--client", url] + (["--sound"] if sound else [])
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return dict(json.loads(out.strip().splitlines()[-1]))


def _tree_cpu_s(root: Any) -> float:
    """CPU time (s) of a process and its descendants still running (the browser's processes)."""
    import psutil

    total = 0.0
    for proc in [root, *root.children(recursive=True)]:
        try:
            t = proc.cpu_times()
        except psutil.Error:
            continue
        total += t.user + t.system
    return total


def _chromium_page(url: str, player: Player) -> dict[str, Any]:
    """The viewer's page in headless Chromium, started as a user starts a browser.

    Not through Playwright: it follows the page's WebSocket over the DevTools protocol, which
    copies every frame (about 1 MB) to its driver as base64 and doubled the browser's CPU time.
    The page's drops are counted by the server, which knows what it sent and what the page
    acknowledged.
    """
    import tempfile

    import psutil

    with tempfile.TemporaryDirectory() as profile:
        args = [
            str(CHROMIUM),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--window-size=1280,900",
            f"--user-data-dir={profile}",
            url,
        ]
        proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            root = psutil.Process(proc.pid)
            deadline = time.monotonic() + 600
            while player.processed == 0 and time.monotonic() < deadline:
                time.sleep(0.02)
            cpu0, shown0 = _tree_cpu_s(root), player.processed
            while not player.ended and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(0.3)  # the last frame's acknowledgement
            cpu = _tree_cpu_s(root) - cpu0
            pages = list(player.clients)
            page_dropped = sum(c.dropped for c in pages)
        finally:
            proc.terminate()
            proc.wait(10)
    return {
        "dropped": player.dropped + page_dropped,
        "browser_cpu_ms": cpu / max(player.processed - shown0, 1) * 1e3,
    }


def _thread_cpu_s(thread: threading.Thread) -> float:
    """CPU time (s) used so far by another thread of this process."""
    assert thread.ident is not None
    return time.clock_gettime(time.pthread_getcpuclockid(thread.ident))


def view_once(spec: str, fps: float, page: str, compress: bool, sound: bool) -> dict[str, Any]:
    """Play ``spec`` once in the viewer; its counts and costs."""
    import uvicorn

    # The recording and settings exactly as `depthgram view SPEC --fps RATE` opens them (and as
    # `depthgram run` does): with the rate, frames carry times and the tracker its real rate.
    args = build_parser().parse_args(["view", spec, "--fps", f"{fps:g}"])
    src = open_input(args)
    n = len(src)  # type: ignore[arg-type]
    viewer = ViewerConfig(fps=fps, loop=False, playing=True, compress=compress)
    player = Player(
        lambda: iter(src), recording_name(spec), load_config(args), viewer, frames=n, fps=getattr(src, "fps", None)
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
        loop_cpu0, proc_cpu0 = _thread_cpu_s(thread), time.process_time()
        if page == "ws":
            r = _ws_page_process(f"ws://127.0.0.1:{port}/ws/{player.name}", sound)
        else:
            r = _chromium_page(f"http://127.0.0.1:{port}/", player)
        loop_cpu = _thread_cpu_s(thread) - loop_cpu0
        proc_cpu = time.process_time() - proc_cpu0
    finally:
        server.should_exit = True
        thread.join(10)
    processed = max(player.processed, 1)
    return {
        **r,
        "frames": n,
        "server_dropped": player.dropped,
        "processed": player.processed,
        "wall_ms": player.stage_ms(),
        "cpu_ms": player.cpu_ms(),
        "loop_cpu_ms": loop_cpu / processed * 1e3,
        "process_cpu_ms": proc_cpu / processed * 1e3,
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument(
        "spec",
        nargs="?",
        default=os.path.join(os.environ.get("DEPTHGRAM_DATA") or "../shared/data", "7scenes_redkitchen_seq"),
    )
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--page", choices=("ws", "chromium", "both"), default="both")
    p.add_argument("--repeat", type=int, default=1, help="run and viewer pairs, back to back")
    p.add_argument("--compress", action="store_true")
    p.add_argument("--sound", action="store_true")
    p.add_argument("--no-run", action="store_true", help="the viewer only (to profile it)")
    p.add_argument("--client", metavar="URL", help=argparse.SUPPRESS)  # the ws page's own process
    args = p.parse_args(argv)
    if args.client:
        print(json.dumps(asyncio.run(_ws_page(args.client, args.sound))))
        return
    pages = ("ws", "chromium") if args.page == "both" else (args.page,)
    print(
        f"{args.spec} at {args.fps:g} frames/s; {'compressed' if args.compress else 'raw'}"
        f"{', sound' if args.sound else ''}; {os.cpu_count()} cores"
    )
    for rep in range(args.repeat):
        t = time.strftime("%H:%M:%S")
        if not args.no_run:
            frames, run_dropped, run_ms = run_command(args.spec, args.fps)
            print(
                f"[{rep + 1}] {t} run:             {run_dropped:4d} of {frames} dropped ({_load()}); "
                f"pipeline wall ms/frame (median) {run_ms:.1f}"
            )
        for page in pages:
            t = time.strftime("%H:%M:%S")
            r = view_once(args.spec, args.fps, page, args.compress, args.sound)
            print(
                f"[{rep + 1}] {t} view, page {page + ':':9s}{r['dropped']:4d} of {r['frames']} dropped "
                f"(server {r['server_dropped']}, page {r['dropped'] - r['server_dropped']}; {_load()})"
            )
            wall = ", ".join(f"{k} {v:.1f}" for k, v in r["wall_ms"].items())
            cpu = ", ".join(f"{k} {v:.2f}" for k, v in r["cpu_ms"].items())
            print(f"      server wall ms/frame (median): {wall}")
            print(
                f"      server thread CPU ms/frame (median): {cpu}; event loop {r['loop_cpu_ms']:.2f} (mean); "
                f"whole server process {r['process_cpu_ms']:.1f} (mean, pipeline and reading included)"
            )
            if "browser_cpu_ms" in r:
                print(f"      browser CPU ms/frame (all its processes, mean): {r['browser_cpu_ms']:.1f}")


if __name__ == "__main__":
    main()
