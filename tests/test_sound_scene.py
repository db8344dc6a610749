"""Every object of a scene is heard: decode the written WAV at each object's pitch and pan."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from depthgram.pipeline import Config, Pipeline
from depthgram.scene.tree import Node, SceneTree
from depthgram.sound import SoundMapping, render_scene, select, still_seconds, voices, write_wav
from depthgram.sources import open_source
from sound_decode import listen

SR = 22050
W, H = 176, 132
# Pure tones over four octaves: every object's pitch stands apart in the decoded spectrum.
DECODE = SoundMapping.from_dict({"pitch_low_hz": 150.0, "pitch_high_hz": 2400.0, "harmonics_max": 1})


def written(tmp_path: Path, audio: np.ndarray) -> np.ndarray:
    data, sr = sf.read(write_wav(tmp_path / "scene.wav", audio, SR), dtype="float64")
    assert sr == SR
    return data


def pan_angle(pan: tuple[float, float]) -> float:
    return math.atan2(pan[1], pan[0])


def assert_every_beep_heard(audio: np.ndarray, mapping: SoundMapping, tree: SceneTree, objects: tuple = ()) -> None:
    size = tree.frame_size
    assert size is not None
    beeping = [v for v in voices(tree, size, mapping, objects) if v.rate > 0]
    for v in beeping:
        heard = listen(audio, SR, v.freq_a)
        assert heard.times.size >= 2, f"object {v.key[1]} at {v.freq_a:.0f} Hz heard {heard.times.size} times"
        assert heard.rate_hz == pytest.approx(v.rate, rel=0.1), f"object {v.key[1]}"
        assert heard.pan_angle == pytest.approx(pan_angle(v.pan_a), abs=0.05), f"object {v.key[1]}"
        assert heard.pitch_hz == pytest.approx(v.freq_a, rel=0.01), f"object {v.key[1]}"


def table_tree() -> SceneTree:
    # A compound table top whose slices have depth labels 0..3: labels that are also the ids
    # of the objects standing on it (the case that silenced them: labels taken for node ids).
    objs = (
        Node(1, "object", 1, 900.0, 300, (30.0, 40.0)),
        Node(2, "object", 1, 1000.0, 400, (80.0, 60.0)),
        Node(3, "object", 2, 1200.0, 250, (120.0, 30.0)),
        Node(4, "object", 2, 1400.0, 350, (160.0, 75.0)),
    )
    table = Node(5, "compound", 0, 1100.0, 6000, (88.0, 95.0), parts=(0, 1, 2, 3), children=objs)
    return SceneTree(Node(0, "Bkg", -1, 0.0, W * H, ((W - 1) / 2, (H - 1) / 2), children=(table,)))


def test_objects_on_a_compound_support_all_beep(tmp_path: Path) -> None:
    tree = table_tree()
    sel = select(tree, DECODE)
    assert [n.id for n in sel.beeps] == [1, 2, 3, 4] and [n.id for n in sel.glides] == [5]
    assert sel.left_out == ()
    audio = written(tmp_path, render_scene(tree, mapping=DECODE, samplerate=SR))
    assert_every_beep_heard(audio, DECODE, tree)


def test_max_voices_keeps_the_nearest_and_says_who_is_left_out(tmp_path: Path) -> None:
    m = SoundMapping.from_dict({**DECODE.to_dict(), "max_voices": 2, "max_glides": 0})
    tree = table_tree()
    sel = select(tree, m)
    assert [n.id for n in sel.beeps] == [1, 2]  # nearest first
    assert [(n.id, why) for n, why in sel.left_out] == [
        (5, "0 nearer surfaces already sound (max_glides = 0)"),
        (3, "2 nearer objects already sound (max_voices = 2)"),
        (4, "2 nearer objects already sound (max_voices = 2)"),
    ]
    audio = written(tmp_path, render_scene(tree, mapping=m, samplerate=SR))
    assert_every_beep_heard(audio, m, tree)
    for n in (3, 4):  # the left-out ones are not in the signal
        node = next(x for x in tree.nodes() if x.id == n)
        assert listen(audio, SR, m.pitch(node.center_xy[1], H)).times.size == 0


def test_every_object_of_the_simulated_table_is_heard(tmp_path: Path) -> None:
    result = next(iter(Pipeline(Config(), track=False).run(open_source("sim:table"))))
    objects = [n for n in result.tree.nodes() if n.kind == "object"]
    on_table = [n for n in result.tree.nodes() if n.kind == "compound" for _ in n.children]
    assert len(objects) >= 4 and on_table, "the table scene has objects standing on its compound table"
    six = SoundMapping.from_dict({**DECODE.to_dict(), "max_voices": 6})  # the default is 4
    sel = select(result.tree, six)
    assert {n.id for n in sel.beeps} == {n.id for n in objects}  # up to max_voices = 6: all of them
    audio = written(
        tmp_path, render_scene(result.tree, mapping=six, samplerate=SR, objects=result.segmentation.objects)
    )
    assert_every_beep_heard(audio, six, result.tree, result.segmentation.objects)


def test_still_is_long_enough_to_hear_each_object_twice() -> None:
    tree = table_tree()
    slow = SoundMapping.from_dict({**DECODE.to_dict(), "rate_near_hz": 1.0, "rate_far_hz": 0.5, "max_glides": 0})
    vs = voices(tree, (W, H), slow)
    seconds = still_seconds(vs, slow)
    # The last object of the scan starts at scan_s and beeps every 2.x s: two beeps need over 2 s.
    last = max(vs, key=lambda v: v.order)
    assert seconds >= last.order * slow.scan_s + 1 / last.rate + last.beep_s
    audio = render_scene(tree, mapping=slow, samplerate=SR)
    assert len(audio) == round(seconds * SR)
    assert_every_beep_heard(audio, slow, tree)


def test_the_mug_on_the_real_azure_frame_beeps(shared_data: Path, tmp_path: Path) -> None:
    src = open_source(str(shared_data / "azure_kinect_tof_mug_single" / "depth.png"))
    result = next(iter(Pipeline(Config(), track=False).run(src)))
    # The mug is the nearest thing in view (0.25-0.30 m) in the lower left quarter.
    mug = min((n for n in result.tree.nodes() if n.kind == "object"), key=lambda n: n.depth)
    assert 200 <= mug.depth <= 350 and mug.center_xy[0] < 320
    m = SoundMapping()
    assert mug.id in {n.id for n in select(result.tree, m).beeps}
    audio = written(tmp_path, render_scene(result.tree, mapping=m, samplerate=SR, objects=result.segmentation.objects))
    (v,) = [v for v in voices(result.tree, result.frame.size, m, result.segmentation.objects) if v.key == ("o", mug.id)]
    heard = listen(audio, SR, v.freq_a)
    assert heard.times.size >= 2 and heard.rate_hz == pytest.approx(m.rate_near_hz, rel=0.1)
    assert heard.pan_angle < math.pi / 4  # on the left
