"""The live viewer end to end in headless Chromium: page, stream, pause and step, screenshot."""

from __future__ import annotations

import asyncio
import json
import os
import socket
import threading
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = Path("/usr/bin/chromium")
if not CHROMIUM.exists():
    pytest.skip("headless browser test needs Debian's chromium at /usr/bin/chromium "
                "(apt-get install -y chromium)", allow_module_level=True)
pytest.importorskip("playwright.sync_api", reason="needs the playwright Python package (pip install playwright)")
uvicorn = pytest.importorskip("uvicorn")

from playwright.sync_api import sync_playwright  # noqa: E402

from depthgram.pipeline import Config, Pipeline  # noqa: E402
from depthgram.sources import open_source  # noqa: E402
from depthgram.views.server import Player, ViewerConfig, create_app, recording_name  # noqa: E402

SPEC = "sim:table?frames=12"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
SCREENSHOT = Path(os.environ.get("TMPDIR", "/tmp")) / "depthgram_view.png"


@pytest.fixture
def server() -> Iterator[str]:
    """The viewer on a free loopback port in a background thread; yields its URL."""
    src = open_source(SPEC)
    player = Player(lambda: iter(src), recording_name(SPEC), Config(), ViewerConfig(playing=False, loop=True),
                    frames=len(src), fps=src.fps)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    srv = uvicorn.Server(uvicorn.Config(create_app(player), log_level="warning"))
    thread = threading.Thread(target=lambda: asyncio.run(srv.serve(sockets=[sock])), daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not srv.started:
        assert time.monotonic() < deadline, "the viewer did not start"
        time.sleep(0.05)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        srv.should_exit = True
        thread.join(10)
        sock.close()


def _state(url: str) -> dict[str, Any]:
    with urllib.request.urlopen(f"{url}/api/recordings/sim-table", timeout=10) as r:
        return json.loads(r.read())


def test_page_shows_frames_and_pause_then_step_advances_one_frame(server: str) -> None:
    first = next(iter(open_source(SPEC)))
    expected = len(Pipeline().process(first).segmentation.objects)
    errors: list[str] = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("pageerror", lambda e: errors.append(str(e)))
            # The one refused request below (422) is expected; anything else in the console is not.
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" and "422" not in m.text else None)
            page.goto(server + "/")
            page.wait_for_function("document.getElementById('recording').textContent.includes('sim-table')")
            # Step from a paused start: frame 0 with the pipeline's objects is drawn.
            page.click("#step")
            page.wait_for_function("document.getElementById('view').dataset.frame === '0'", timeout=20000)
            assert page.get_attribute("#view", "data-objects") == str(expected)
            assert page.locator("#tracks tbody tr").count() == expected
            assert page.inner_text("#sentence").startswith("Bkg[")
            # Play, then pause: the page ends on the last frame the server pushed.
            page.click("#play")
            page.wait_for_function("Number(document.getElementById('view').dataset.frame) >= 3", timeout=20000)
            page.click("#pause")
            page.wait_for_function("document.getElementById('view').dataset.pausedAt !== undefined")
            k = int(page.get_attribute("#view", "data-paused-at") or -1)
            page.wait_for_function(f"document.getElementById('view').dataset.frame === '{k}'", timeout=10000)
            assert _state(server)["index"] == k and _state(server)["playing"] is False
            page.click("#step")
            nxt = (k + 1) % 12
            page.wait_for_function(f"document.getElementById('view').dataset.frame === '{nxt}'", timeout=10000)
            assert _state(server)["index"] == nxt and _state(server)["playing"] is False
            # Sound on, play: the page schedules the server's audio in Web Audio.
            page.check("#sound")
            page.click("#play")
            page.wait_for_function("Number(document.getElementById('view').dataset.audio) > 0.1", timeout=20000)
            page.click("#pause")
            # The method list comes from the server; choosing one applies from the next frame.
            assert "threshold" in page.locator("#method option").all_inner_texts()
            page.select_option("#method", "threshold")
            page.click("#apply")
            page.wait_for_function("document.getElementById('method').value === 'threshold'")
            deadline = time.monotonic() + 10
            while _state(server)["params"]["method"] != "threshold":
                assert time.monotonic() < deadline, "method change did not reach the server"
                time.sleep(0.05)
            # A bad value typed in the form is refused with the server's message.
            page.fill("#min_area", "-1")
            page.click("#apply")
            page.wait_for_function("document.getElementById('error').textContent.includes('min_area')")
            page.screenshot(path=str(SCREENSHOT), full_page=True)
        finally:
            browser.close()
    assert SCREENSHOT.stat().st_size > 10_000
    assert not errors, errors
