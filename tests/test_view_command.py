"""``depthgram view`` as a user runs it: a real server process on a free loopback port."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

import pytest

from depthgram.cli import main

pytest.importorskip("uvicorn")


def test_view_refuses_bad_arguments_with_a_message(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["view", "sim:table?frames=2", "--port", "70000", "--no-browser"]) == 2
    assert "--port must be in 0..65535" in capsys.readouterr().err
    assert main(["view", "sim:table?frames=2", "--speed", "0", "--no-browser"]) == 2
    assert "speed must be in (0, 16]" in capsys.readouterr().err
    assert main(["view", "no_such_recording_dir/", "--no-browser"]) == 2


def test_view_serves_the_page_and_the_api_on_loopback() -> None:
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "depthgram.cli",
            "view",
            "sim:table?frames=3",
            "--port",
            "0",
            "--no-browser",
            "--method",
            "threshold",
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None
        line = ""
        deadline = time.monotonic() + 60
        while "http://" not in line:
            assert time.monotonic() < deadline and proc.poll() is None, f"viewer did not start: {line}"
            line = proc.stderr.readline()
        url = line[line.index("http://") :].split()[0]
        assert url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url, timeout=10) as r:
            assert "depthgram view" in r.read().decode()
        with urllib.request.urlopen(url + "api/recordings", timeout=10) as r:
            rec = json.loads(r.read())["recordings"][0]
        assert rec["name"] == "sim-table" and rec["frames"] == 3 and rec["params"]["method"] == "threshold"
        with pytest.raises(urllib.error.HTTPError) as info:
            urllib.request.urlopen(url + "api/recordings/other", timeout=10)
        assert info.value.code == 404
        # Traversal attempts sent byte for byte (no client-side normalisation of "..").
        host, port = url[len("http://") :].rstrip("/").split(":")
        for target in (
            "/static/../../pyproject.toml",
            "/static/%2e%2e/%2e%2e/pyproject.toml",
            "/static/..%2f..%2fpyproject.toml",
            "/static/%2E%2E%5C%2E%2E%5Cpyproject.toml",
        ):
            with socket.create_connection((host, int(port)), timeout=10) as conn:
                conn.sendall(f"GET {target} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
                reply = b""
                while chunk := conn.recv(65536):
                    reply += chunk
            assert reply.startswith(b"HTTP/1.1 404"), (target, reply[:80])
            assert b"[project]" not in reply
    finally:
        proc.terminate()
        proc.wait(10)
