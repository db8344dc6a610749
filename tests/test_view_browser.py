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
    pytest.skip(
        "headless browser test needs Debian's chromium at /usr/bin/chromium (apt-get install -y chromium)",
        allow_module_level=True,
    )
pytest.importorskip("playwright.sync_api", reason="needs the playwright Python package (pip install playwright)")
uvicorn = pytest.importorskip("uvicorn")

from playwright.sync_api import sync_playwright  # noqa: E402

from depthgram.pipeline import Config, Pipeline  # noqa: E402
from depthgram.sources import open_source  # noqa: E402
from depthgram.views.server import Player, ViewerConfig, create_app, recording_name  # noqa: E402

SPEC = "sim:table?frames=12"
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
SCREENSHOT = Path(os.environ.get("TMPDIR", "/tmp")) / "depthgram_view.png"


@pytest.fixture
def server() -> Iterator[str]:
    """The viewer on a free loopback port in a background thread; yields its URL."""
    src = open_source(SPEC)
    player = Player(
        lambda: iter(src),
        recording_name(SPEC),
        Config(),
        ViewerConfig(playing=False, loop=True),
        frames=len(src),
        fps=src.fps,
    )
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
            # Sound on, play: the page's AudioWorklet plays the server's live blocks and asks for
            # more as its audio clock consumes them; the blocks carry the frames' voices.
            page.check("#sound")
            page.click("#play")
            page.wait_for_function("Number(document.getElementById('view').dataset.audioPlayed) > 0.5", timeout=30000)
            page.wait_for_function("Number(document.getElementById('view').dataset.audioFrame) >= 0", timeout=10000)
            received = float(page.get_attribute("#view", "data-audio") or 0)
            played = float(page.get_attribute("#view", "data-audio-played") or 0)
            # Paced by the audio clock: what was received is what was played plus at most the
            # little the page keeps buffered (no catch-up queue).
            assert played <= received <= played + 0.5, (played, received)
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


def _downloads(page: Any, click: str, n: int) -> list[Any]:
    got: list[Any] = []
    page.on("download", lambda d: got.append(d))
    page.click(click)
    deadline = time.monotonic() + 20
    while len(got) < n:
        assert time.monotonic() < deadline, f"{len(got)} of {n} downloads"
        page.wait_for_timeout(50)
    return got


def test_colour_bar_hover_timeline_back_point_cloud_and_snapshot(server: str, tmp_path: Path) -> None:
    import numpy as np

    from depthgram.views.wire import colour_table, depth_range_mm

    frames = list(open_source(SPEC))
    pipe = Pipeline()
    results = [pipe.process(f) for f in frames]
    errors: list[str] = []
    with sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=str(CHROMIUM), args=[*ARGS, "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
        )
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 1100}, accept_downloads=True)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.goto(server + "/")
            page.wait_for_function("document.getElementById('recording').textContent.includes('sim-table')")
            page.click("#step")
            page.wait_for_function("document.getElementById('view').dataset.frame === '0'", timeout=20000)

            # Colour bar: the frame's robust range in mm, near (top) in the colour map's warm end.
            lo, hi = depth_range_mm(frames[0].depth, frames[0].valid)
            assert float(page.get_attribute("#colourbar", "data-lo") or "nan") == pytest.approx(lo, abs=0.06)
            assert float(page.get_attribute("#colourbar", "data-hi") or "nan") == pytest.approx(hi, abs=0.06)
            top = page.evaluate(
                "Array.from(document.getElementById('colourbar').getContext('2d')"
                ".getImageData(10, 8, 1, 1).data.slice(0, 3))"
            )
            bottom = page.evaluate(
                "(() => { const c = document.getElementById('colourbar');"
                " return Array.from(c.getContext('2d').getImageData(10, c.height - 9, 1, 1)"
                ".data.slice(0, 3)); })()"
            )
            table = colour_table()
            assert top == table[255] and bottom == table[0]

            # Hover: the depth and object under the mouse, at a pixel inside the largest object.
            seg = results[0].segmentation
            big = max(seg.objects, key=lambda o: o.area)
            ys, xs = np.nonzero(seg.labels == big.id)
            k = len(xs) // 2
            x, y = int(xs[k]), int(ys[k])
            box = page.locator("#canvas").bounding_box()
            assert box is not None
            s = box["width"] / 176
            page.mouse.move(box["x"] + (x + 0.5) * s, box["y"] + (y + 0.5) * s)
            page.wait_for_function(f"document.getElementById('view').dataset.hoverObject === '{big.id}'")
            assert page.get_attribute("#view", "data-hover-depth") == str(int(np.rint(frames[0].depth[y, x])))
            assert f"object #{big.id}" in page.inner_text("#hover")

            # Timeline: jump to frame 5, then one back to frame 4, each as it was played.
            assert page.get_attribute("#timeline", "max") == "11"
            page.eval_on_selector("#timeline", "el => { el.value = '5'; el.dispatchEvent(new Event('change')); }")
            page.wait_for_function("document.getElementById('view').dataset.frame === '5'", timeout=20000)
            assert page.inner_text("#sentence") == results[5].sentence
            page.click("#back")
            page.wait_for_function("document.getElementById('view').dataset.frame === '4'", timeout=20000)
            assert page.inner_text("#sentence") == results[4].sentence
            assert _state(server)["index"] == 4 and _state(server)["playing"] is False

            # The point cloud: one point per valid pixel, drawn, coloured by object.
            page.check("#show3d")
            page.wait_for_function("document.getElementById('cloud').dataset.frame === '4'", timeout=20000)
            assert page.get_attribute("#cloud", "data-error") is None
            assert int(page.get_attribute("#cloud", "data-points") or 0) == int(frames[4].valid.sum())
            assert page.evaluate("cloud.coverage()") > 2000
            n_colours = page.evaluate(
                "(() => { const c = document.getElementById('cloud');"
                " const gl = c.getContext('webgl');"
                " const px = new Uint8Array(c.width * c.height * 4);"
                " gl.readPixels(0, 0, c.width, c.height, gl.RGBA, gl.UNSIGNED_BYTE, px);"
                " const seen = new Set(); for (let i = 0; i < px.length; i += 4)"
                " seen.add((px[i] << 16) | (px[i + 1] << 8) | px[i + 2]); return seen.size; })()"
            )
            assert n_colours >= 1 + len(results[4].segmentation.objects) // 2

            # Snapshot: the picture as PNG and the frame's results as JSON, named after the frame.
            got = _downloads(page, "#snapshot", 2)
            names = sorted(d.suggested_filename for d in got)
            assert names == ["sim-table_frame000004.json", "sim-table_frame000004.png"]
            paths = {d.suggested_filename: tmp_path / d.suggested_filename for d in got}
            for d in got:
                d.save_as(paths[d.suggested_filename])
            png = paths["sim-table_frame000004.png"].read_bytes()
            assert png[:8] == b"\x89PNG\r\n\x1a\n"
            width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
            assert (width, height) == (page.evaluate("canvas.width"), page.evaluate("canvas.height"))
            snap = json.loads(paths["sim-table_frame000004.json"].read_text())
            assert snap["index"] == 4 and snap["record"]["sentence"] == results[4].sentence
            assert snap["depth_range_mm"] == pytest.approx(
                list(depth_range_mm(frames[4].depth, frames[4].valid)), abs=0.06
            )
        finally:
            browser.close()
    assert not errors, errors
