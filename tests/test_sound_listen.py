"""`depthgram listen` and the live renderer, played through a real clocked device: JACK's dummy driver.

The tests start their own JACK server (``jackd --no-realtime -d dummy``) under a name of their
own, so PortAudio's JACK host API plays to it; ``jack_rec`` records what reached JACK. They
skip with the reason when jackd, jack_rec, PortAudio or sounddevice is missing.
"""

from __future__ import annotations

import io
import itertools
import json
import multiprocessing
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import soundfile as sf
from numpy.testing import assert_allclose

from depthgram.scene.tree import Node, SceneTree
from depthgram.sound import SoundMapping
from depthgram.sound.choose import Chooser, distinguishable
from depthgram.sound.live import LiveSonifier
from depthgram.sound.slot import TargetSlot
from depthgram.sound.synth import Voice, VoiceBank
from sound_decode import listen

SR = 48000
W, H = 176, 132


def _jack_ready(env: dict[str, str], proc: subprocess.Popen[bytes]) -> bool:
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and proc.poll() is None:
        out = subprocess.run(["jack_lsp"], env=env, capture_output=True, text=True, timeout=10)
        if "system:playback_1" in out.stdout:
            return True
        time.sleep(0.1)
    return False


@pytest.fixture(scope="module")
def jack() -> Iterator[dict[str, str]]:
    """A running JACK dummy server; yields the environment that points clients at it."""
    for tool in ("jackd", "jack_rec", "jack_lsp"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not installed (Debian package jackd2; .ci/run installs it)")
    sd = pytest.importorskip("sounddevice", reason="sounddevice not installed: pip install 'depthgram[listen]'")
    env = {**os.environ, "JACK_DEFAULT_SERVER": f"depthgram-test-{os.getpid()}", "JACK_NO_AUDIO_RESERVATION": "1"}
    proc = subprocess.Popen(
        ["jackd", "--no-realtime", "-d", "dummy", "-r", str(SR), "-p", "256"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        if not _jack_ready(env, proc):
            proc.kill()
            err = proc.communicate()[1].decode(errors="replace")[-400:]
            pytest.skip(f"jackd --no-realtime -d dummy did not start: {err}")
        probe = subprocess.run(
            [sys.executable, "-c", "import sounddevice as sd; print([a['name'] for a in sd.query_hostapis()])"],
            env=env,
            capture_output=True,
            text=True,
            timeout=60,
        )
        if "JACK" not in probe.stdout:
            pytest.skip(f"PortAudio {sd.get_portaudio_version()[1]} has no JACK host API: {probe.stdout.strip()}")
        yield env
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


def _tree(*nodes: Node) -> SceneTree:
    return SceneTree(Node(0, "Bkg", -1, 0.0, W * H, ((W - 1) / 2, (H - 1) / 2), children=tuple(nodes)))


def _obj(i: int, x: float, y: float, depth: float, ttc: float | None = None, area: int = 300) -> Node:
    return Node(i, "object", i, depth, area, (x, y), v_radial=-1000.0 if ttc else None, ttc=ttc)


def test_listen_plays_the_approach_through_jack(jack: dict[str, str], tmp_path: Path) -> None:
    log, copy, rec = tmp_path / "listen.jsonl", tmp_path / "played.wav", tmp_path / "jack.wav"
    cmd = [sys.executable, "-m", "depthgram.cli", "listen", "sim:approach?frames=75&fps=15"]
    cmd += ["--log", str(log), "--wav", str(copy), "--block", "256", "--samplerate", str(SR)]
    player = subprocess.Popen(cmd, env=jack, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Record, with a second JACK client, what PortAudio's client sends to JACK, once it is there.
    deadline = time.monotonic() + 60
    ports: list[str] = []
    while time.monotonic() < deadline and player.poll() is None and len(ports) < 2:
        lsp = subprocess.run(["jack_lsp"], env=jack, capture_output=True, text=True, timeout=10).stdout.split()
        ports = [p for p in lsp if p.startswith("PortAudio") and "out" in p]
        time.sleep(0.05)
    assert len(ports) == 2, f"PortAudio's output ports never appeared in JACK: {player.communicate()}"
    recorder = subprocess.Popen(
        ["jack_rec", "-f", str(rec), "-d", "2", "-b", "32", *ports[:2]],
        env=jack,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    out, err = player.communicate(timeout=300)
    recorder.wait(timeout=30)
    assert player.returncode == 0, err

    played, sr = sf.read(copy, dtype="float64")
    # 75 frames at 15 frames/s: 5 s of wall time, fewer samples when a busy machine makes JACK skip cycles
    assert sr == SR and len(played) > 2.5 * SR
    # What JACK received is what listen says it played: one stretch of the copy, sample for sample.
    heard, rsr = sf.read(rec, dtype="float64")
    assert rsr == SR and np.abs(heard).max() > 0.01, "JACK received silence"

    # Where each stretch of 1024 samples starts in the copy: among the samples equal to its
    # first, one whose next 1023 match too (a tone repeats, so a correlation peak would be
    # ambiguous). On a busy machine JACK may drop a cycle (an xrun), so most, not all, match.
    def found(chunk: np.ndarray) -> bool:
        starts = np.flatnonzero(np.abs(played[: len(played) - len(chunk), 0] - chunk[0, 0]) < 1e-6)
        return any(np.abs(played[a : a + len(chunk)] - chunk).max() < 1e-6 for a in starts)

    n = 1024
    loud = [heard[k : k + n] for k in range(0, len(heard) - n, n) if np.abs(heard[k : k + n]).max() > 0.01]
    assert len(loud) >= 20, "JACK received silence"
    matched = sum(found(c) for c in loud)
    assert matched >= 0.5 * len(loud), f"{matched} of {len(loud)} stretches recorded from JACK are in the copy"

    lines = [json.loads(x) for x in log.read_text().splitlines()]
    at = {x["frame"]: x["sample"] for x in lines}  # where each frame starts in the copy

    def span(first: int, last: int) -> np.ndarray:
        # the frames heard around [first, last]: on a busy machine listen drops late frames (it
        # plays the newest), so some are not in the log; the span holds the whole range anyway
        before = [f for f in at if f <= first]
        after = [f for f in at if f >= last]
        a = at[max(before) if before else min(at)]
        b = at[min(after) if after else max(at)]
        assert b - a >= 0.2 * SR, f"frames {first}-{last}: {sorted(at)} heard"
        return played[a:b]

    # The hand beeps at the middle row's pitch, in the middle, faster as its time to collision
    # falls: 2.4 -> 1.9 s over frames 8 to 16, 1.4 -> 0.9 s over frames 24 to 32; it turns back at
    # frame 30 and then beeps by its nearness alone. The wall filling the view behind it hums
    # at the same pitch (a steady tone, no beeps: a surface facing the camera).
    m = SoundMapping()
    hz = 440.0  # the middle row: the ladder's step at 440 Hz
    early, late, back = (listen(span(a, b), SR, hz, window_s=0.02) for a, b in ((8, 16), (22, 30), (36, 52)))
    assert early.times.size >= 3 and abs(early.pitch_hz - hz) < 0.02 * hz
    assert early.pan_angle == pytest.approx(np.pi / 4, abs=0.05)
    assert early.rate_hz == pytest.approx(m.rate(1300, 2.15), rel=0.12)
    assert late.rate_hz == pytest.approx(m.rate(740, 1.15), rel=0.12)
    assert back.rate_hz == pytest.approx(m.rate(1100), rel=0.12) and back.rate_hz < late.rate_hz / 1.3

    assert [x["frame"] for x in lines] == sorted(x["frame"] for x in lines)
    # Every frame is in the log but those dropped late or replaced before a block carried them.
    counts = re.search(r"played (\d+) frame\(s\), dropped (\d+) late, (\d+) replaced", out)
    assert counts, out
    played_n, dropped_n, replaced_n = map(int, counts.groups())
    assert played_n + dropped_n == 75 and len(lines) == played_n - replaced_n
    assert all(x["latency_ms"] > 0 for x in lines)  # the DAC plays a frame after it arrived
    # The latency is split where it goes: the pipeline, the wait for the next block, the device.
    for x in lines:
        assert x["pipeline_ms"] > 0 and x["wait_ms"] >= 0 and x["dac_ms"] >= 0, x
        assert x["pipeline_ms"] + x["wait_ms"] + x["dac_ms"] == pytest.approx(x["latency_ms"], abs=0.01)
    assert "audio callback:" in err and "latency p50 by part: pipeline" in out
    under = [x["underflows"] for x in lines]
    assert under == sorted(under) and all(isinstance(u, int) for u in under)
    total = re.search(r"(\d+) underflow\(s\) in (\d+) blocks", out)
    assert total and int(total.group(1)) >= under[-1], out  # the summary counts to the end
    assert all(x["callback_ms"] > 0 for x in lines)


def test_bank_ramps_across_blocks_as_in_one_call() -> None:
    m = SoundMapping()
    a = Voice(("o", 1), 440.0, 440.0, 0.5, 0.5, (0.9, 0.4), (0.9, 0.4), 6.0, 0.05, 2, 0.0)
    b = Voice(("o", 1), 660.0, 660.0, 0.8, 0.8, (0.4, 0.9), (0.4, 0.9), 9.0, 0.08, 3, 0.0)
    g = Voice(("g", 2), 500.0, 300.0, 0.2, 0.1, (0.7, 0.7), (0.9, 0.3), 0.0, 0.0, 1, 0.0)
    g2 = Voice(("g", 2), 520.0, 280.0, 0.3, 0.1, (0.6, 0.8), (0.9, 0.3), 0.0, 0.0, 1, 0.0)
    one, blocks = VoiceBank(m, SR), VoiceBank(m, SR)
    whole = [one.render({a.key: a, g.key: g}, 4800), one.render({b.key: b, g.key: g2}, 4800)]
    # The ramp (20 ms = 960 samples) spans several 256-sample blocks: it must go on, not jump.
    parts = [blocks.render({a.key: a, g.key: g}, 256) for _ in range(4800 // 256)]
    parts.append(blocks.render({a.key: a, g.key: g}, 4800 % 256))
    parts += [blocks.render({b.key: b, g.key: g2}, 256) for _ in range(4800 // 256)]
    parts.append(blocks.render({b.key: b, g.key: g2}, 4800 % 256))
    assert_allclose(np.concatenate(parts), np.concatenate(whole), atol=1e-9)


def test_live_sonifier_takes_the_newest_frame_and_reports_the_block_that_carries_it() -> None:
    live = LiveSonifier(SoundMapping(confirm_frames=1), SR, (W, H))
    assert live.render_block(256)[1] is None  # nothing fed: silence, no frame carried
    live.update(_tree(_obj(1, 20, 20, 1000)), frame=0, arrival_s=1.0)
    live.update(_tree(_obj(1, 20, 20, 900)), frame=1, arrival_s=2.0)  # before any block took frame 0
    audio, carried = live.render_block(256)
    assert carried is not None and carried.frame == 1 and carried.arrival_s == 2.0
    assert live.superseded == 1 and audio.shape == (256, 2) and audio.dtype == np.float32
    assert live.render_block(256)[1] is None  # the next block carries no new frame


def test_chooser_keeps_concurrent_voices_apart() -> None:
    m = SoundMapping(confirm_frames=1)
    c = Chooser(m)
    # Three objects side by side in one row at one depth: same pitch, pan within 0.2, same rate.
    tree = _tree(_obj(1, 80, 60, 1500), _obj(2, 86, 61, 1500), _obj(3, 92, 59, 1500))
    vs = list(c.voices(tree, (W, H)).values())
    assert len(vs) == 3
    for i, a in enumerate(vs):
        for b in vs[i + 1 :]:
            assert distinguishable(a, b, m)
            semis = abs(12 * np.log2(a.freq_a / b.freq_a))
            assert semis >= 3 - 1e-9
    # The same scene next frame: every voice keeps its pitch (no warble between steps).
    again = list(c.voices(tree, (W, H)).values())
    assert [v.freq_a for v in again] == [v.freq_a for v in vs]


def test_chooser_voice_goes_on_when_the_tracker_renames_its_object() -> None:
    m = SoundMapping(confirm_frames=3)
    c = Chooser(m)
    for _ in range(3):
        first = c.voices(_tree(_obj(7, 100, 50, 2000)), (W, H))
    assert list(first) == [("o", 1)]
    # The tracker loses id 7 and finds id 9 a few pixels away at about the same depth.
    renamed = c.voices(_tree(_obj(9, 104, 52, 2050)), (W, H))
    assert list(renamed) == [("o", 1)] and c.distinct == 1
    # A different object far to the left waits its confirm_frames, then gets a voice of its own.
    assert list(c.voices(_tree(_obj(9, 104, 52, 2050), _obj(11, 5, 50, 800)), (W, H))) == [("o", 1)]


def test_chooser_counts_a_thing_whose_voice_ends_and_comes_back_once() -> None:
    m = SoundMapping(confirm_frames=1, hold_frames=2)
    c = Chooser(m)
    c.voices(_tree(_obj(7, 100, 50, 2000)), (W, H))
    for _ in range(m.hold_frames + 1):  # gone longer than its voice is held: the voice ends
        gone = c.voices(_tree(), (W, H))
    assert gone == {}
    back = c.voices(_tree(_obj(7, 100, 50, 2000)), (W, H))
    assert list(back) == [("o", 2)]  # a voice of its own again, the same thing to the ear
    assert c.distinct == 1
    c.voices(_tree(_obj(7, 100, 50, 2000), _obj(8, 10, 50, 900)), (W, H))
    assert c.distinct == 2  # another thing is counted


def test_chooser_gives_an_approaching_object_a_place_at_once() -> None:
    m = SoundMapping(confirm_frames=3, max_voices=2)
    c = Chooser(m)
    calm = [_obj(1, 20, 30, 1000), _obj(2, 150, 30, 1200)]
    for _ in range(3):
        c.voices(_tree(*calm), (W, H))
    vs = c.voices(_tree(*calm, _obj(3, 88, 100, 2500, ttc=1.2)), (W, H))
    # The new object warns (ttc 1.2 s < 3 s): it takes the place of the farther calm voice.
    kept = {k: v for k, v in vs.items()}
    assert len(kept) == 2
    rates = sorted(v.rate for v in kept.values())
    assert rates[-1] == pytest.approx(m.rate(2500, 1.2))


def test_warning_stops_the_frame_the_object_turns_back() -> None:
    m = SoundMapping(confirm_frames=1)
    c = Chooser(m)
    # Approaching at 1.2 m/s (30 frames/s), nearest at frame 5, then receding; the tracker's
    # slope still gives a time to collision for two frames after the turn.
    depths = [1500, 1460, 1420, 1380, 1340, 1300, 1340, 1380, 1420]
    ttcs = [1.25, 1.22, 1.18, 1.15, 1.12, 1.08, 1.1, 1.2, None]
    heard = [c.voices(_tree(_obj(2, 88, 66, d, t)), (W, H)) for d, t in zip(depths, ttcs, strict=True)]
    rates = [next(iter(v.values())).rate for v in heard]
    assert_allclose(rates[:6], [m.rate(d, t) for d, t in zip(depths[:6], ttcs[:6], strict=True)])
    assert_allclose(rates[6:], [m.rate(d) for d in depths[6:]])  # no warning from the first frame receding


def test_a_hand_held_recording_sounds_like_a_few_steady_things(shared_data: Path, tmp_path: Path) -> None:
    # 7-Scenes red kitchen, 10 s hand-held at 30 frames/s: some 9 objects a frame and 159
    # track ids in all. Heard: at most 4 beeping at once, at most 16 things voiced over the 10 s
    # (a track whose voice ends and comes back counted once; 14 voices with the former crease
    # span, which lost the cup on the table: design notes, 4 December 2026).
    seq = shared_data / "7scenes_redkitchen_seq"
    if not seq.is_dir():
        pytest.skip(f"{seq} not found")
    out = subprocess.run(
        [sys.executable, "-m", "depthgram.cli", "sonify", str(seq), "--fps", "30", "--wav", "-"],
        capture_output=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr.decode()[-2000:]
    audio, sr = sf.read(io.BytesIO(out.stdout))  # the WAV came on standard output
    assert sr == 22050 and len(audio) == 10 * sr
    summary = out.stderr.decode()
    m = re.search(r"up to (\d+) object\(s\) beeping .* (\d+) distinct object voice\(s\)", summary)
    assert m, summary
    assert int(m.group(1)) <= 4 and int(m.group(2)) <= 16, summary


@pytest.mark.parametrize(
    ("name", "opts"),
    [
        ("azure_kinect_tof_mug_single/depth.png", {}),
        ("ycbv_0000_labelled", {"scale_mm": 0.1}),
        ("sim:approach?frames=60", {}),
    ],
)
def test_every_pair_of_concurrent_voices_can_be_told_apart(name: str, opts: dict[str, float], request: Any) -> None:
    from depthgram import Pipeline, read

    path = name if name.startswith("sim:") else request.getfixturevalue("shared_data") / name
    if not name.startswith("sim:") and not Path(path).exists():
        pytest.skip(f"{path} not found")
    m = SoundMapping()
    c = Chooser(m)
    heard = 0
    for r in Pipeline().run(read(path, **opts)):
        vs = list(c.voices(r.tree, r.frame.size, r.segmentation.objects, r.frame.intrinsics).values())
        heard = max(heard, len(vs))
        for a, b in itertools.combinations(vs, 2):
            assert distinguishable(a, b, m), f"{name} frame {r.frame.index}: {a} and {b} sound alike"
    assert heard >= 2


def test_listen_names_a_missing_folder_before_opening_any_device(tmp_path: Path, capsys: Any) -> None:
    from depthgram.cli import main

    missing = tmp_path / "nowhere" / "log.jsonl"
    assert main(["listen", "sim:table?frames=2", "--log", str(missing)]) == 2
    err = capsys.readouterr().err
    assert f"--log {missing}" in err and "does not exist" in err
    assert main(["listen", "sim:table?frames=2", "--block", "8"]) == 2
    assert "--block must be between 16 and 16384" in capsys.readouterr().err


def _voices() -> dict[tuple[str, int], Voice]:
    beep = Voice(("o", 7), 440.0, 440.0, 0.5, 0.5, (0.8, 0.6), (0.8, 0.6), 5.0, 0.06, 3, 0.25, -12.5, 4.0)
    glide = Voice(("g", 2), 600.0, 400.0, 0.2, 0.1, (0.9, 0.3), (0.4, 0.9), 0.0, 0.0, 1, 0.0)  # no direction
    return {beep.key: beep, glide.key: glide}


def test_binaural_listen_plays_a_voice_on_the_left_then_on_the_right(jack: dict[str, str], tmp_path: Path) -> None:
    pytest.importorskip("slab", reason="the KEMAR set ships with slab: pip install 'depthgram[binaural]'")
    copy = tmp_path / "played.wav"
    code = f"""
import sys, time
from depthgram.sound.live import AudioProcess
from depthgram.sound.synth import Voice

def main():
    audio = AudioProcess(None, {SR}, (640, 480), None, 256, {str(copy)!r}, binaural="kemar")
    for i, az in enumerate((-60.0, 60.0)):
        v = Voice(("o", 1), 220.0, 220.0, 0.5, 0.5, (0.7, 0.7), (0.7, 0.7), 6.0, 0.06, 4, 0.0, az, 0.0)
        audio.set_targets({{v.key: v}}, frame=i)
        time.sleep(1.5)
    print(sorted(e.frame for e in audio.drain()), audio.stop()["blocks"])

if __name__ == "__main__":
    main()
"""
    script = tmp_path / "play.py"
    script.write_text(code)
    run = subprocess.run([sys.executable, str(script)], env=jack, capture_output=True, text=True, timeout=180)
    assert run.returncode == 0, run.stderr
    played, sr = sf.read(copy, dtype="float64")
    # Each half of what the device played: the louder and earlier ear is the voice's side.
    half = len(played) // 2
    for part, side in ((played[int(0.3 * sr) : half - int(0.2 * sr)], -1), (played[half + int(0.3 * sr) :], 1)):
        left, right = part[:, 0], part[:, 1]
        ild = 10 * np.log10((right**2).mean() / (left**2).mean())
        lags = np.arange(-48, 49)
        lag = lags[int(np.argmax([np.dot(left[48:-48], np.roll(right, -k)[48:-48]) for k in lags]))]
        assert side * ild > 2.0 and -side * lag / SR * 1e3 > 0.4, (side, ild, lag)


def test_target_slot_carries_the_newest_voices_across_processes_memory() -> None:
    ctx = multiprocessing.get_context("spawn")
    writer = TargetSlot.create(ctx, 4)
    reader = TargetSlot(writer.shared)  # what the audio process makes of the memory it is handed
    assert reader.take() is None  # nothing written yet
    writer.put(_voices(), 3, 10.0, 10.02)
    got = reader.take()
    assert got is not None and got.targets == _voices() and (got.frame, got.arrival_s, got.sent_s) == (3, 10.0, 10.02)
    assert reader.take() is None  # taken once
    # Two writes before the reader looks: the newest is voiced, the older counted as superseded.
    writer.put({}, 4, None, 11.0)
    writer.put(_voices(), 5, 11.5, 11.6)
    got = reader.take()
    assert got is not None and got.frame == 5 and reader.superseded == 1 and reader.taken == 2
    writer.put({}, 6, None, 12.0)
    got = reader.take()
    assert got is not None and got.targets == {} and got.arrival_s is None


def test_target_slot_reader_skips_a_write_caught_half_done() -> None:
    ctx = multiprocessing.get_context("spawn")
    writer = TargetSlot.create(ctx, 4)
    reader = TargetSlot(writer.shared)
    writer.put(_voices(), 1, 1.0, 1.0)
    a = np.frombuffer(writer.shared, dtype=np.float64)
    a[0] += 1  # a writer is under way: odd sequence
    assert reader.take() is None
    a[0] += 1  # finished, but the body does not match its checksum (torn)
    a[-1] = a[0]
    a[8] += 1.0
    assert reader.take() is None and reader.retries == 1
    writer.put(_voices(), 2, 2.0, 2.0)  # the next whole write is taken
    got = reader.take()
    assert got is not None and got.frame == 2


def test_target_slot_names_what_does_not_fit() -> None:
    writer = TargetSlot.create(multiprocessing.get_context("spawn"), 1)
    with pytest.raises(Exception, match="at most 1"):
        writer.put(_voices(), 0, None, 0.0)
    with pytest.raises(Exception, match="kind must be one of"):
        writer.put({("x", 1): next(iter(_voices().values()))}, 0, None, 0.0)


@pytest.mark.parametrize("spec", ["sim:approach?size=640x480&frames=40", "sim:table?size=640x480&frames=4"])
def test_every_second_pixel_gives_the_ear_the_same_voices(spec: str) -> None:
    """listen's default decimation (640 -> 320 pixels a row) changes no voice a listener could tell."""
    from depthgram import read
    from depthgram.pipeline import Pipeline
    from depthgram.sound.choose import pan_position

    def voices(step: int) -> list[list[Voice]]:
        pipe, chooser, out = Pipeline(), Chooser(SoundMapping()), []
        for f in read(spec):
            f = f.decimated(step)
            r = pipe.process(f)
            vs = chooser.voices(r.tree, f.size, r.segmentation.objects, f.intrinsics, f.gravity)
            out.append(sorted(vs.values(), key=lambda v: (v.rate > 0, pan_position(v), v.freq_a)))
        return out

    full, half = voices(1), voices(2)
    assert sum(map(len, full)) >= len(full)
    for k, (a, b) in enumerate(zip(full, half, strict=True)):
        assert len(a) == len(b), f"frame {k}: {len(a)} voices read whole, {len(b)} decimated"
        for va, vb in zip(a, b, strict=True):
            # well under the 3 semitones / 0.2 pan / 1.5x rate that tell two voices apart
            assert abs(12 * np.log2(vb.freq_a / va.freq_a)) < 0.5, (k, va, vb)
            assert abs(pan_position(vb) - pan_position(va)) < 0.05, (k, va, vb)
            assert_allclose(vb.rate, va.rate, rtol=0.1)


def test_listen_reads_a_large_frame_decimated_and_says_so(jack: dict[str, str], tmp_path: Path) -> None:
    log = tmp_path / "listen.jsonl"
    cmd = [sys.executable, "-m", "depthgram.cli", "listen", "sim:approach?size=640x480&frames=20&fps=15"]
    done = subprocess.run([*cmd, "--log", str(log)], env=jack, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "reads every 2 pixels of every 2 rows: 640x480 as 320x240 (--decimate 1 reads them all)" in done.stderr
    assert len(log.read_text().splitlines()) >= 5
    whole = subprocess.run([*cmd, "--decimate", "1"], env=jack, capture_output=True, text=True, timeout=300)
    assert whole.returncode == 0 and "reads every" not in whole.stderr, whole.stderr
    bad = subprocess.run([*cmd, "--decimate", "0"], env=jack, capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--decimate must be 'auto' or an integer >= 1, got '0'" in bad.stderr
