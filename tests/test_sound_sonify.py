"""depthgram sonify: durations a listener can rely on, and what it says it wrote."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from depthgram.cli import main
from depthgram.pipeline import Config, Pipeline
from depthgram.sensor.simulate import simulate
from depthgram.sound import SoundMapping, still_seconds, voices
from depthgram.sources import open_source
from sound_decode import listen


def read(p: Path) -> tuple[np.ndarray, int]:
    data, sr = sf.read(p, dtype="float64")
    return data, sr


def test_a_still_plays_long_enough_to_hear_every_object_twice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "still.wav"
    assert main(["sonify", "sim:table?frames=1", "--wav", str(out), "--quiet"]) == 0
    said = capsys.readouterr().out
    audio, sr = read(out)
    r = next(iter(Pipeline(Config(), track=False).run(open_source("sim:table?frames=1"))))
    m = SoundMapping()
    vs = voices(r.tree, r.frame.size, m, r.segmentation.objects)
    assert len(audio) == round(still_seconds(vs, m) * sr) and len(audio) / sr >= 1.0
    for v in vs:
        if v.rate:
            assert listen(audio, sr, v.freq_a).times.size >= 2, v
    assert f"wrote {out}: {len(audio) / sr:.1f} s" in said and "1 still(s)" in said
    assert said.count("beeps") == sum(v.rate > 0 for v in vs)


def test_a_recording_lasts_as_long_as_it_did(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "rec.wav"
    assert main(["sonify", "sim:approach?frames=30", "--wav", str(out), "--quiet"]) == 0
    audio, sr = read(out)
    assert len(audio) == round(1.0 * sr)  # 30 frames at 30/s
    assert "30 frame(s): 30 of recordings" in capsys.readouterr().out


def test_frames_without_rate_are_refused_or_played_at_the_given_rate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    stack = tmp_path / "approach.npy"
    np.save(stack, np.stack([s.frame.depth for s in simulate("approach", 4)]).astype(np.uint16))
    out = tmp_path / "a.wav"
    assert main(["sonify", str(stack), "--wav", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "no timestamps and no frame rate" in err and "--fps" in err and not out.exists()
    assert main(["sonify", str(stack), "--wav", str(out), "--quiet", "--fps", "10"]) == 0
    audio, sr = read(out)
    assert len(audio) == round(0.4 * sr)
    assert "3 frame periods from 10 frames/s" in capsys.readouterr().out
    assert main(["sonify", str(stack), "--wav", str(out), "--quiet", "--stills"]) == 0
    assert "4 still(s)" in capsys.readouterr().out


def test_a_tilted_camera_is_heard_against_the_horizon(tmp_path: Path) -> None:
    # sonify hands the frame's gravity to the synthesis: under --tilt an object's pitch follows
    # its elevation above the horizon, not its image row
    from depthgram.frame import Gravity
    from depthgram.sound import Sonifier

    src = "sim:approach?frames=30"
    r = list(Pipeline(Config()).run(open_source(src)))[-1]

    def beep_hz(gravity: Gravity | None) -> float:
        son = Sonifier(SoundMapping(), 22050, r.frame.size)
        son.push(r.tree, 1 / 30, r.segmentation.objects, r.frame.intrinsics, gravity)
        (hz,) = [v.freq_a for v in son.voices_now.values() if v.rate > 0]
        return hz

    level_hz, tilted_hz = beep_hz(None), beep_hz(Gravity.from_tilt(30.0))
    # looking 30 degrees down, the object ahead sits below the horizon: a lower pitch
    assert 12 * np.log2(level_hz / tilted_hz) >= 3
    for args, hz, other in (([], level_hz, tilted_hz), (["--tilt", "30"], tilted_hz, None)):
        out = tmp_path / "a.wav"
        assert main(["sonify", src, "--wav", str(out), "--quiet", *args]) == 0
        audio, sr = read(out)
        heard = listen(audio, sr, hz)
        assert heard.times.size >= 3, args
        np.testing.assert_allclose(heard.pitch_hz, hz, rtol=0.01)
        if other is not None:  # (the level pitch is a harmonic of the tilted one: not checked)
            assert listen(audio, sr, other).times.size == 0, args
