"""view --foxglove: a live Foxglove WebSocket server on the MCAP file's topics, checked with a client (issue 16, 8)."""

from __future__ import annotations

import asyncio
import json
import re
import struct
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("foxglove", reason="needs the foxglove-sdk package (pip install 'depthgram[foxglove]')")
websockets = pytest.importorskip("websockets")

from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations  # noqa: E402
from foxglove_schemas_protobuf.Log_pb2 import Log  # noqa: E402
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage  # noqa: E402
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate  # noqa: E402

from depthgram.cli import main  # noqa: E402
from depthgram.export.foxglove_live import FoxgloveServer  # noqa: E402
from depthgram.export.mcap_file import TOPICS  # noqa: E402
from depthgram.export.messages import object_outlines  # noqa: E402
from depthgram.pipeline import Pipeline  # noqa: E402
from depthgram.sources import read  # noqa: E402

SPEC = "sim:table?frames=3"
SUBPROTOCOL = "foxglove.sdk.v1"


async def _advertised(ws: Any) -> dict[str, dict[str, Any]]:
    """Topic -> advertised channel, from the server's first messages."""
    channels: dict[str, dict[str, Any]] = {}
    while len(channels) < len(TOPICS):
        msg = json.loads(await asyncio.wait_for(ws.recv(), 10))
        if msg["op"] == "advertise":
            channels.update({c["topic"]: c for c in msg["channels"]})
    return channels


def _data(raw: bytes) -> tuple[int, int, bytes]:
    """A binary message-data frame: (subscription id, log time ns, payload)."""
    assert raw[0] == 0x01  # opcode: message data
    sub, t_ns = struct.unpack_from("<IQ", raw, 1)
    return sub, t_ns, raw[13:]


def test_a_client_sees_every_topic_and_gets_each_frames_messages() -> None:
    results = [r for r in Pipeline().run(read(SPEC))]
    with FoxgloveServer("127.0.0.1", 0) as server:
        assert server.port > 0 and not server.watched

        async def client() -> tuple[dict[str, dict[str, Any]], dict[str, list[tuple[int, bytes]]]]:
            url = f"ws://127.0.0.1:{server.port}"
            async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
                channels = await _advertised(ws)
                subs = [{"id": i, "channelId": c["id"]} for i, c in enumerate(channels.values())]
                await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                topic_of = {i: t for i, t in enumerate(channels)}
                for _ in range(100):  # the subscription reaches the server's channels
                    if server.watched:
                        break
                    await asyncio.sleep(0.02)
                # frames published from another thread, as the command's loop does
                sent = threading.Thread(
                    target=lambda: [server.publish(r, t_ns=1_000 + i) for i, r in enumerate(results)]
                )
                sent.start()
                got: dict[str, list[tuple[int, bytes]]] = {}
                while sum(len(v) for v in got.values()) < len(TOPICS) * len(results):
                    raw = await asyncio.wait_for(ws.recv(), 10)
                    if isinstance(raw, bytes):
                        sub, t_ns, payload = _data(raw)
                        got.setdefault(topic_of[sub], []).append((t_ns, payload))
                sent.join()
                return channels, got

        channels, got = asyncio.run(client())
        assert server.published == len(results)
    # the MCAP file's topics and schema names; protobuf with its descriptors, the scene as JSON
    assert {t: c["schemaName"] for t, c in channels.items()} == TOPICS
    for topic, c in channels.items():
        assert c["encoding"] == ("json" if topic == "/depthgram/scene" else "protobuf")
    assert {t: [ts for ts, _ in v] for t, v in got.items()} == {t: [1000, 1001, 1002] for t in TOPICS}
    for i, r in enumerate(results):
        img = RawImage.FromString(got["/depthgram/depth"][i][1])
        depth = np.frombuffer(img.data, "<u2").reshape(img.height, img.width)
        assert img.encoding == "16UC1" and np.array_equal(depth, np.minimum(np.rint(r.frame.depth), 65535))
        log = Log.FromString(got["/depthgram/sentence"][i][1])
        assert log.message == r.sentence and log.line == r.frame.index
        scene = json.loads(got["/depthgram/scene"][i][1])
        assert scene["sentence"] == r.sentence and len(scene["objects"]) == len(r.segmentation.objects)
        # one outline per connected part of each object, one label per object
        ann = ImageAnnotations.FromString(got["/depthgram/objects"][i][1])
        objects = r.segmentation.objects
        assert len(ann.texts) == len(objects)
        outlines = sum(len(object_outlines(r.segmentation.labels, o.id, o.bbox_xy)) for o in objects)
        assert len(ann.points) == outlines
        boxes = SceneUpdate.FromString(got["/depthgram/boxes"][i][1])
        assert sorted(int(e.id) for e in boxes.entities) == sorted(o.id for o in objects)


def test_nothing_is_built_while_nobody_watches() -> None:
    result = next(iter(Pipeline().run(read(SPEC))))
    with FoxgloveServer("127.0.0.1", 0) as server:
        assert server.publish(result) is False and server.published == 0


def test_view_foxglove_plays_the_recording_and_says_where(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["view", SPEC, "--foxglove", "--port", "0", "--no-loop"]) == 0
    err = capsys.readouterr().err
    assert "to Foxglove at ws://127.0.0.1:" in err and "Foxglove WebSocket" in err
    # no client: every frame is processed or dropped as late (by the machine's load), none is built
    m = re.search(r"(\d+) frames processed, (\d+) dropped, 0 published", err)
    assert m is not None and int(m.group(1)) + int(m.group(2)) == 3 and int(m.group(1)) >= 1


def test_view_foxglove_on_a_port_in_use(capsys: pytest.CaptureFixture[str]) -> None:
    with FoxgloveServer("127.0.0.1", 0) as busy:
        port = busy.port
        assert main(["view", SPEC, "--foxglove", "--port", str(port), "--no-loop"]) == 2
    err = capsys.readouterr().err
    assert f"127.0.0.1:{port}" in err and "already in use" in err and "--port 0" in err and "Traceback" not in err


def test_view_foxglove_without_the_extra_names_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "foxglove", None)  # import fails as without the extra
    assert main(["view", SPEC, "--foxglove", "--port", "0", "--no-loop"]) == 2
    err = capsys.readouterr().err
    assert "pip install 'depthgram[foxglove]'" in err and "Traceback" not in err
