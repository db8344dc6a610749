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
    assert names == sorted(p.name for p in (tmp_path / "calm").glob("*.wav")) and len(names) == 10
    assert capsys.readouterr().out.count(".wav:") == 10
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
    # The wall ahead hums: one steady tone at the middle row's pitch, no beeps, level all along.
    # Height against the horizon: the same object with the camera level and tilted 20 degrees
    # down sounds at one pitch (the middle of the range); one 20 degrees above eye level higher.
    tilt = wav("10-tilted-camera")
    part = len(tilt) // 3
    level, tilted, higher = (tilt[i * part : (i + 1) * part] for i in range(3))
    hz_eye = float(lines[9].split("level (")[1].split(" Hz")[0])
    hz_up = float(lines[9].split("eye level (")[1].split(" Hz")[0])
    assert hz_eye == pytest.approx(m.pitch_elevation(0.0), rel=0.1)  # the middle of the range, on the ladder
    assert hz_up >= 2 ** (m.min_semitones / 12) * hz_eye - 1
    for part_audio, hz in ((level, hz_eye), (tilted, hz_eye), (higher, hz_up)):
        heard = listen(part_audio, sr, hz, window_s=0.1)
        assert heard.times.size >= 2 and heard.pitch_hz == pytest.approx(hz, rel=0.02)
    ahead = wav("09-wall-ahead")
    assert "steady hum" in lines[8]
    body = ahead[sr // 10 : -sr // 10, 0]
    frames = np.abs(body[: len(body) // 512 * 512]).reshape(-1, 512).max(axis=1)
    assert frames.min() > 0.9 * frames.max() > 0  # a hum, not beeps
    spectrum = np.abs(np.fft.rfft(body * np.hanning(len(body))))
    assert np.fft.rfftfreq(len(body), 1 / sr)[np.argmax(spectrum)] == pytest.approx(m.pitch(239.5, 480), rel=0.01)
