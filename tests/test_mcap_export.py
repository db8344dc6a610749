"""describe --mcap: the scene stream as MCAP with Foxglove's schemas, read back with the mcap reader (issue 16, 8)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

pytest.importorskip("mcap_protobuf")

from mcap.decoder import DecoderFactory as McapDecoderFactory
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from depthgram.cli import main
from depthgram.export.mcap_file import TOPICS, McapWriter
from depthgram.frame import Intrinsics, make_frame
from depthgram.pipeline import Pipeline
from depthgram.sources import read


class _JsonDecoder(McapDecoderFactory):
    """The JSON topic, decoded as Foxglove does: the message is a JSON document."""

    def decoder_for(self, message_encoding: str, schema: object) -> object:
        return (lambda data: json.loads(data)) if message_encoding == "json" else None


def _read(path: Path) -> tuple[dict[str, tuple[str, int]], dict[str, list[tuple[int, Any]]]]:
    """Topic -> (schema, count) from the summary, and topic -> [(log time ns, decoded message)]."""
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory(), _JsonDecoder()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        counts = {
            c.topic: (summary.schemas[c.schema_id].name, summary.statistics.channel_message_counts[c.id])
            for c in summary.channels.values()
        }
        decoded: dict[str, list[tuple[int, Any]]] = {}
        for _, channel, message, proto in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append((message.log_time, proto))
    return counts, decoded


def test_describe_mcap_has_every_topic_once_per_frame(tmp_path: Path) -> None:
    out, js = tmp_path / "approach.mcap", tmp_path / "approach.jsonl"
    n = 6
    assert main(["describe", f"sim:approach?frames={n}", "--mcap", str(out), "--json", str(js), "--quiet"]) == 0
    counts, decoded = _read(out)
    assert counts == {topic: (schema, n) for topic, schema in TOPICS.items()}
    records = [json.loads(x) for x in js.read_text().splitlines()]
    # message times are the frames' times (sim: 30 frames/s)
    frames = list(read(f"sim:approach?frames={n}"))
    for topic in TOPICS:
        assert [t for t, _ in decoded[topic]] == [round(f.time_s * 1e9) for f in frames]
    # the depth image is the frame in mm, 16UC1
    for (_, img), f in zip(decoded["/depthgram/depth"], frames, strict=True):
        assert (img.encoding, img.width, img.height, img.step) == ("16UC1", 176, 132, 352)
        assert np.array_equal(np.frombuffer(img.data, "<u2").reshape(132, 176), np.rint(f.depth).astype(np.uint16))
    # the sentence log and the JSON topic are describe's own output
    assert [m.message for _, m in decoded["/depthgram/sentence"]] == [r["sentence"] for r in records]
    assert [m for _, m in decoded["/depthgram/scene"]] == records
    # one label per object, outlines in the object's colour
    for (_, ann), rec in zip(decoded["/depthgram/objects"], records, strict=True):
        assert sorted(int(t.text.split()[0][1:]) for t in ann.texts) == sorted(o["id"] for o in rec["objects"])
        assert len(ann.points) >= len([o for o in rec["objects"] if o["area"] >= 4])
    k = frames[0].intrinsics
    assert k is not None
    _, cal = decoded["/depthgram/calibration"][0]
    assert list(cal.K) == pytest.approx([k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1])


def test_outlines_and_boxes_match_a_known_square(tmp_path: Path) -> None:
    # a wall at 2 m and a 40 x 40 px square at 1 m; fx = fy = 200 px: the square is 0.2 m wide
    depth = np.full((120, 160), 2000.0, np.float32)
    depth[40:80, 60:100] = 1000.0
    k = Intrinsics(200.0, 200.0, 79.5, 59.5)
    frame = make_frame(depth, intrinsics=k, time_s=0.5, name="square")
    result = Pipeline(track=False).process(frame)
    square = next(o for o in result.segmentation.objects if abs(o.depth - 1000.0) < 1)
    out = tmp_path / "square.mcap"
    with McapWriter(out, source="square") as w:
        w.add(result)
    counts, decoded = _read(out)
    assert all(c == 1 for _, c in counts.values())
    _, ann = decoded["/depthgram/objects"][0]
    polys = [np.array([(p.x, p.y) for p in a.points], np.float32) for a in ann.points]
    inside = [p for p in polys if cv2.pointPolygonTest(p, (80.0, 60.0), False) >= 0 and cv2.contourArea(p) < 2000]
    assert len(inside) == 1
    xs, ys = inside[0][:, 0], inside[0][:, 1]
    assert (xs.min(), ys.min(), xs.max(), ys.max()) == (60, 40, 99, 79)  # the boundary pixels of the square
    _, update = decoded["/depthgram/boxes"][0]
    assert update.deletions[0].type == update.deletions[0].Type.ALL  # objects gone from view leave the 3-D view
    cube = next(e for e in update.entities if e.id == str(square.id)).cubes[0]
    assert cube.pose.position.z == pytest.approx(1.0, abs=0.002)
    assert (cube.pose.position.x, cube.pose.position.y) == pytest.approx((0.0025, 0.0025), abs=0.003)
    # pixel centres 60..99 at 1 m: 39 px / 200 px = 0.195 m, less the 2 % trimmed at each side
    assert cube.size.x == pytest.approx(0.195 * 0.96, abs=0.01) and cube.size.y == pytest.approx(0.187, abs=0.01)
    _, log = decoded["/depthgram/sentence"][0]
    assert log.message == result.sentence and log.level == log.Level.INFO
    assert decoded["/depthgram/sentence"][0][0] == 500_000_000  # the frame's time, ns


def test_an_unwritable_mcap_is_a_message(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "no" / "x.mcap"
    assert main(["describe", "sim:table", "--mcap", str(bad), "--quiet"]) == 2
    assert f"--mcap {bad}: cannot write" in capsys.readouterr().err
