"""depthgram lesson: each cue alone, decodable, with a line that matches the mapping."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from depthgram.cli import main
from depthgram.sound import SoundMapping
from sound_decode import listen


def test_lesson_writes_each_cue_with_its_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["lesson", str(tmp_path / "calm"), "--preset", "calm"]) == 0
    m = SoundMapping.preset("calm")
    lines = (tmp_path / "calm" / "lesson.txt").read_text().splitlines()[1:]
    names = [ln.split(":")[0] for ln in lines]
    assert names == sorted(p.name for p in (tmp_path / "calm").glob("*.wav")) and len(names) == 8
    assert capsys.readouterr().out.count(".wav:") == 8
    sr = 22050

    def wav(name: str) -> np.ndarray:
        data, rate = sf.read(tmp_path / "calm" / f"{name}.wav", dtype="float64")
        assert rate == sr
        return data

    pan = listen(wav("01-left-right"), sr, m.pitch(239.5, 480))
    # Left, centre, right in turn: the pan angle of the beeps rises over the file.
    angles = [
        math.atan2(*reversed(wav("01-left-right")[round(t * sr) - 200 : round(t * sr) + 200].std(axis=0)))
        for t in pan.times
    ]
    assert angles[0] < 0.3 and angles[-1] > math.pi / 2 - 0.3
    near_far = wav("02-near-far")
    assert f"{m.rate(m.near_mm):.1f}" in lines[1] and f"{m.rate(m.far_mm):.1f}" in lines[1]
    assert listen(near_far, sr, m.pitch(239.5, 480)).times.size >= 8
    assert f"{m.pitch(0, 480):.0f} Hz" in lines[2]
    for y in (0, 479):
        assert listen(wav("03-height"), sr, m.pitch(y, 480)).times.size >= 2
    approach = wav("07-approaching")
    hz = m.pitch(239.5, 480)
    assert listen(approach[: 2 * sr], sr, hz).times.size <= 4  # far: 1 to 2 beeps per second
    # The last second (time to collision 1.4 -> 0.4 s) is a rattle that still quickens: about
    # 11 beeps/s in its first half, 13 to 16 in its second (a short window resolves a rattle).
    halves = [listen(approach[len(approach) - k * sr // 2 :][: sr // 2], sr, hz, window_s=0.03) for k in (2, 1)]
    assert halves[0].rate_hz == pytest.approx(m.rate(1150.0, 1.15), rel=0.15)
    assert halves[1].rate_hz == pytest.approx(m.rate(650.0, 0.65), rel=0.15)
    assert halves[1].rate_hz > 1.15 * halves[0].rate_hz
