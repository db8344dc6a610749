"""Sonification: decode the written audio and check each cue of the mapping against its formula."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from scipy.ndimage import maximum_filter1d

from depthgram.errors import InputError
from depthgram.scene.tree import Node, SceneTree
from depthgram.segmentation.objects import SceneObject
from depthgram.sound import PRESETS, Sonifier, SoundMapping, render_scene, voices, write_wav

W, H = 176, 132
SR = 22050


def tree_of(*nodes: Node) -> SceneTree:
    return SceneTree(Node(0, "Bkg", -1, 0.0, W * H, (W / 2, H / 2), children=nodes))


def obj(x: float, y: float, depth: float, *, i: int = 1, area: int = 40, ttc: float | None = None) -> Node:
    return Node(i, "object", 0, depth, area, (x, y), ttc=ttc)


def decoded(tmp_path: Path, audio: np.ndarray, name: str = "a.wav") -> np.ndarray:
    """Write as 16-bit WAV and read it back, as a listener's player would."""
    p = write_wav(tmp_path / name, audio, SR)
    data, sr = sf.read(p, dtype="float64")
    assert sr == SR and data.shape == audio.shape
    return data


def onsets(mono: np.ndarray, *, rel: float = 0.2) -> np.ndarray:
    """Sample indices where the beep envelope rises through ``rel`` of its peak."""
    env = maximum_filter1d(np.abs(mono), size=int(0.006 * SR))
    on = env > rel * env.max()
    return np.flatnonzero(on[1:] & ~on[:-1]) + 1


def dominant_hz(mono: np.ndarray) -> float:
    spec = np.abs(np.fft.rfft(mono * np.hanning(mono.size)))
    return float(np.fft.rfftfreq(mono.size, 1 / SR)[np.argmax(spec)])


def test_object_on_the_left_is_louder_left_with_equal_power_pan(tmp_path: Path) -> None:
    a = decoded(tmp_path, render_scene(tree_of(obj((W - 1) / 3, 60, 1500)), (W, H), samplerate=SR))
    rms_l, rms_r = np.sqrt((a**2).mean(axis=0))
    assert rms_l > rms_r
    # Equal power at p = 1/3: cos(30 deg) / sin(30 deg) = sqrt(3).
    assert rms_l / rms_r == pytest.approx(math.sqrt(3), rel=0.01)
    hard_left = decoded(tmp_path, render_scene(tree_of(obj(0, 60, 1500)), (W, H), samplerate=SR))
    assert np.abs(hard_left[:, 1]).max() == 0.0 and np.abs(hard_left[:, 0]).max() > 0.05


def test_nearer_object_is_louder_by_the_mapping(tmp_path: Path) -> None:
    near = decoded(tmp_path, render_scene(tree_of(obj(87.5, 65.5, 1000)), (W, H), samplerate=SR))
    far = decoded(tmp_path, render_scene(tree_of(obj(87.5, 65.5, 3000)), (W, H), samplerate=SR))
    db = 20 * math.log10(np.abs(near).max() / np.abs(far).max())
    # Default mapping: -24 dB at 4000 mm to 0 dB at 300 mm, so 24 * 2000 / 3700 dB apart.
    assert db == pytest.approx(24 * 2000 / 3700, abs=0.3)


def test_beep_rate_follows_nearness_and_ttc() -> None:
    m = SoundMapping()
    assert m.rate(2150.0) == pytest.approx(1.5 + 6.5 * 0.5)
    # sped up by ttc, geometrically from 8 Hz at 3 s to 16 Hz at 0.5 s: 8 * (3 / ttc) ** (ln 2 / ln 6)
    assert m.rate(2150.0, ttc=2.0) == pytest.approx(8.0 * 1.5 ** (math.log(2) / math.log(6)))
    assert m.rate(2150.0, ttc=0.5) == pytest.approx(m.rate_max_hz)
    assert m.rate(2150.0, ttc=0.1) == m.rate_max_hz
    # still rising between 1.5 s and 0.5 s to collision (the last second before impact changes)
    ladder = [m.rate(2150.0, ttc=t) for t in (1.5, 1.2, 1.0, 0.8, 0.6, 0.5)]
    assert all(b > a * 1.05 for a, b in itertools.pairwise(ladder))
    assert m.rate(2150.0, ttc=5.0) == pytest.approx(4.75)  # ttc above the alert: no change
    audio = render_scene(tree_of(obj(87.5, 65.5, 2150)), (W, H), duration_s=2.0, samplerate=SR)
    # First beep at t = 0, one every 1 / 4.75 s: floor(2 * 4.75) + 1 = 10 beeps in 2 s.
    assert len(onsets(audio.sum(axis=1))) == 10


def test_approaching_object_pulse_rate_rises(tmp_path: Path) -> None:
    m = SoundMapping()
    s = Sonifier(m, SR, (W, H))
    chunks, rates = [], []
    for i in range(90):  # 3 s at 30 fps, approaching at 1 m/s from 3.5 m
        depth = 3500.0 - 1000.0 * i / 30
        rates.append(m.rate(depth, depth / 1000.0))
        chunks.append(s.push(tree_of(obj(87.5, 65.5, depth, ttc=depth / 1000.0)), 1 / 30))
    mono = decoded(tmp_path, np.concatenate(chunks)).sum(axis=1)
    # Known truth: a beep starts each time the pulse phase (the integral of the rate) passes
    # an integer, the first at t = 0.
    phase = np.concatenate(([0.0], np.cumsum(rates) / 30))
    counts = []
    for sec in range(3):
        seg = mono[sec * SR : (sec + 1) * SR]
        expected = np.floor(phase[30 * (sec + 1)] - 1e-9) - np.floor(phase[30 * sec] - 1e-9)
        counts.append(len(onsets(seg)))
        assert abs(counts[-1] - (expected + (sec == 0))) <= 1
    assert counts[0] < counts[1] < counts[2]
    assert counts[2] >= 2 * counts[0]


@pytest.mark.parametrize(("y", "hz"), [(0.0, 880.0), ((H - 1) / 2, 440.0), (H - 1.0, 220.0)])
def test_height_sets_pitch(tmp_path: Path, y: float, hz: float) -> None:
    a = decoded(tmp_path, render_scene(tree_of(obj(87.5, y, 1000)), (W, H), duration_s=1.0, samplerate=SR))
    assert dominant_hz(a.sum(axis=1)) == pytest.approx(hz, abs=3.0)


def test_area_sets_weight() -> None:
    m = SoundMapping()
    assert m.weight(0.0) == (1, m.beep_min_s)
    assert m.weight(0.25) == (m.harmonics_max, pytest.approx(m.beep_max_s))
    small, big = (voices(tree_of(obj(80, 60, 1000, area=a)), (W, H), m)[0] for a in (20, W * H // 4))
    assert small.harmonics == 1 and big.harmonics == 4 and big.beep_s > small.beep_s


def test_sequence_audio_lasts_as_long_as_the_sequence() -> None:
    s = Sonifier(SoundMapping(), SR, (W, H))
    durations = [1 / 30] * 44 + [0.0, 0.07, 1 / 30, 0.2]
    n = sum(len(s.push(tree_of(obj(80, 60, 1000 + 20 * i)), d)) for i, d in enumerate(durations))
    assert n == round(sum(durations) * SR)
    assert s.seconds == pytest.approx(sum(durations))


def test_stream_has_no_clicks_when_objects_move_appear_and_vanish() -> None:
    m = SoundMapping.from_dict({"pitch_low_hz": 55.0, "pitch_high_hz": 110.0, "harmonics_max": 1, "glide_octaves": 0.5})
    s = Sonifier(m, SR, (W, H))
    chunks = []
    for i in range(40):
        nodes: list[Node] = [obj(20 + 3 * i, 10 + 2 * i, 2500 - 40 * i, i=1)]
        if 5 <= i < 25:
            nodes.append(obj(150 - 2 * i, 100, 900, i=2))
        if i >= 10:
            nodes.append(Node(3, "wall", 1, 1500.0, 3000, (10.0, 60.0)))
        chunks.append(s.push(tree_of(*nodes), 1 / 30))
    a = np.concatenate(chunks).astype(np.float64)
    # Each voice moves by at most A * (2 pi f + pi / beep + 1 / ramp) per sample: a sine at
    # its top frequency under the steepest raised-cosine edge. A hard note edge would jump by A.
    f_top = m.pitch_high_hz * 2 ** (m.glide_octaves / 2)
    per_voice = m.master_gain * (2 * math.pi * f_top + math.pi / m.beep_min_s + 1 / m.ramp_s) / SR
    jumps = np.abs(np.diff(a, axis=0)).max()
    assert jumps <= 3 * per_voice
    assert 3 * per_voice < 0.5 * np.abs(a).max()  # the bound is far below the signal level


def test_voice_phase_is_continuous_across_pushes() -> None:
    m = SoundMapping.from_dict({"harmonics_max": 1})
    tree = tree_of(Node(1, "wall", 0, 2000.0, 3000, (30.0, 60.0)))
    one = Sonifier(m, SR, (W, H)).push(tree, 0.3)
    s = Sonifier(m, SR, (W, H))
    split = np.concatenate([s.push(tree, 0.1), s.push(tree, 0.1), s.push(tree, 0.1)])
    # Same scene in three pushes or one: the same samples (phases carried over).
    np.testing.assert_allclose(split, one, atol=1e-6)


def test_surface_glides_between_its_near_and_far_ends() -> None:
    m = SoundMapping.from_dict({"harmonics_max": 1})

    def so(i: int, kind: str, label: int, depth: float, x: float, parts: tuple[SceneObject, ...] = ()) -> SceneObject:
        return SceneObject(i, kind, label, depth, 10.0, 500, 0.02, (x, 60.0), (0, 50, 80, 70), parts=parts)

    near, far = so(11, "part", 0, 500.0, 10.0), so(12, "part", 3, 3500.0, 70.0)
    wall_obj = so(10, "wall", 0, 2000.0, 30.0, (near, far))
    # The tree carries the parts' depth labels (0, 3), not node ids: their extent comes from the objects.
    wall = Node(10, "wall", 0, 2000.0, 1100, (30.0, 60.0), parts=(0, 3))
    (v,) = voices(tree_of(wall), (W, H), m, [wall_obj])  # the parts are heard in the glide, not alone
    assert v.pan_a == pytest.approx(m.pan(10.0, W)) and v.pan_b == pytest.approx(m.pan(70.0, W))
    fc = m.pitch(60.0, H)
    span = m.glide_octaves * (m.nearness(500.0) - m.nearness(3500.0))
    assert v.freq_a == pytest.approx(fc * 2 ** (span / 2)) and v.freq_b == pytest.approx(fc * 2 ** (-span / 2))
    mono = render_scene(tree_of(wall), (W, H), mapping=m, duration_s=1.2, samplerate=SR, objects=[wall_obj]).sum(axis=1)

    def zc_hz(t: float) -> float:
        seg = mono[int((t - 0.02) * SR) : int((t + 0.02) * SR)]
        return float(np.count_nonzero(np.diff(np.signbit(seg))) / 2 / 0.04)

    # Far end half a glide period in, near end again after a full period.
    assert zc_hz(0.5) == pytest.approx(v.freq_b, rel=0.04)
    assert zc_hz(1.0) == pytest.approx(v.freq_a, rel=0.04)


def test_empty_scene_is_silence_not_an_error(tmp_path: Path) -> None:
    a = decoded(tmp_path, render_scene(tree_of(), (W, H), duration_s=0.25, samplerate=SR))
    assert a.shape == (round(0.25 * SR), 2) and not a.any()


def test_presets_and_dict_loading() -> None:
    assert set(PRESETS) == {"default", "calm", "detailed"}
    assert SoundMapping.preset("default") == SoundMapping()
    calm = SoundMapping.preset("calm")
    assert calm.max_voices == 3 and calm.rate_near_hz == 4.0
    m = SoundMapping.from_dict({"preset": "detailed", "max_voices": 7})
    assert m.name == "detailed" and m.max_voices == 7 and m.harmonics_max == PRESETS["detailed"]["harmonics_max"]
    assert SoundMapping.from_dict(m.to_dict()) == m
    with pytest.raises(InputError, match="unknown sound preset"):
        SoundMapping.preset("loud")
    with pytest.raises(InputError, match="unknown setting"):
        SoundMapping.from_dict({"volume": 3})
    with pytest.raises(InputError, match="far_mm"):
        SoundMapping(near_mm=3000.0, far_mm=1000.0)
    with pytest.raises(InputError, match="scan"):
        SoundMapping(scan="random")


def test_max_voices_keeps_the_nearest() -> None:
    m = SoundMapping.preset("calm")
    nodes = [obj(10 + 15 * i, 60, 500 + 300 * i, i=i + 1) for i in range(8)]
    kept = [v.key[1] for v in voices(tree_of(*nodes), (W, H), m)]
    assert sorted(kept) == [1, 2, 3]


def test_scan_left_to_right_orders_first_beeps() -> None:
    right, left = obj(170, 60, 1000, i=1), obj(5, 60, 1000, i=2)
    a = render_scene(tree_of(right, left), (W, H), samplerate=SR)
    first_l, first_r = onsets(a[:, 0])[0], onsets(a[:, 1])[0]
    assert first_l < first_r  # the left object is heard first
    assert (first_r - first_l) / SR == pytest.approx(SoundMapping().scan_s, abs=0.01)


def test_write_wav_is_16_bit_pcm_and_rejects_bad_audio(tmp_path: Path) -> None:
    audio = (0.5 * np.sin(np.linspace(0, 40 * np.pi, 2000)))[:, None] * np.array([[1.0, -1.0]])
    p = write_wav(tmp_path / "x.wav", audio, SR)
    assert sf.info(p).subtype == "PCM_16"
    back, _ = sf.read(p)
    np.testing.assert_allclose(back, audio, atol=1 / 32768)
    with pytest.raises(InputError, match="shape"):
        write_wav(tmp_path / "y.wav", np.zeros((3, 4, 2)), SR)
    with pytest.raises(InputError, match="NaN"):
        write_wav(tmp_path / "y.wav", np.array([0.0, np.nan]), SR)
    with pytest.raises(InputError, match="does not exist"):
        write_wav(tmp_path / "no" / "y.wav", np.zeros(4), SR)


def test_sonifier_takes_the_frame_size_from_the_tree_not_the_simulator() -> None:
    # Sonifier's frame_size defaulted to the simulator's 176 x 132: a 640 x 480 scene was
    # panned and pitched as if its objects sat 3.6 times further right and down.
    from depthgram.scene import build_tree, parse_sentence, to_sentence
    from depthgram.segmentation import SceneObject

    cup = SceneObject(1, "object", 0, 900.0, 5.0, 400, 400 / (640 * 480), (160.0, 120.0), (150, 110, 170, 130))
    tree = build_tree([cup], (640, 480))
    assert tree.frame_size == (640, 480)
    assert parse_sentence(to_sentence(tree)).frame_size == (640, 480)  # the sentence carries it
    m = SoundMapping()
    implicit = Sonifier(m, SR).push(tree, 0.3)
    np.testing.assert_array_equal(implicit, Sonifier(m, SR, (640, 480)).push(tree, 0.3))
    assert not np.array_equal(implicit, Sonifier(m, SR, (W, H)).push(tree, 0.3))
    left, right = np.abs(implicit).sum(axis=0)
    assert left > right  # x = 160 of 640 is left of centre
    np.testing.assert_array_equal(render_scene(tree), render_scene(tree, (640, 480)))
    # a hand-made root that does not carry the size: ask for it rather than guess
    with pytest.raises(InputError, match="frame_size"):
        Sonifier(m, SR).push(tree_of(obj(40.0, 60.0, 900.0)), 0.1)
