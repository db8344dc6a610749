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
