"""Binaural rendering: voices through measured head-related impulse responses, decoded at the ears."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthgram.frame import Intrinsics
from depthgram.scene.tree import Node
from depthgram.sound import SoundMapping
from depthgram.sound.live import LiveSonifier
from depthgram.sound.synth import Voice, VoiceBank
from depthgram.sound.voice import beep_voice, direction

SR = 48000


@pytest.fixture(scope="module")
def kemar() -> object:
    pytest.importorskip("slab", reason="the KEMAR set ships with slab: pip install 'depthgram[binaural]'")
    from depthgram.sound.binaural import load_hrirs

    return load_hrirs("kemar", SR)


def _ears(audio: np.ndarray, max_lag: int = 48) -> tuple[float, float]:
    """(level of the right ear over the left in dB, delay of the right ear after the left in ms)."""
    left, right = audio[:, 0], audio[:, 1]
    ild = 10 * np.log10((right**2).mean() / (left**2).mean())
    lags = np.arange(-max_lag, max_lag + 1)  # within +-1 ms: one period of a 220-Hz voice is 4.5 ms
    c = [np.dot(left[max_lag:-max_lag], np.roll(right, -k)[max_lag:-max_lag]) for k in lags]
    return float(ild), float(lags[int(np.argmax(c))] / SR * 1e3)


def _beep(azimuth: float | None, elevation: float | None = 0.0, hz: float = 220.0) -> Voice:
    return Voice(("o", 1), hz, hz, 0.5, 0.5, (0.7, 0.7), (0.7, 0.7), 6.0, 0.06, 4, 0.0, azimuth, elevation)


def test_a_voice_on_the_left_reaches_the_left_ear_first_and_louder(kemar: object) -> None:
    heard = {}
    for az in (-60.0, 0.0, 60.0):
        live = LiveSonifier(SoundMapping(), SR, (2, 2), kemar)  # type: ignore[arg-type]
        v = _beep(az)
        live.set_targets({v.key: v})
        heard[az] = _ears(np.concatenate([live.render(256) for _ in range(200)]))
    (ild_l, itd_l), (ild_c, itd_c), (ild_r, itd_r) = heard[-60.0], heard[0.0], heard[60.0]
    # KEMAR at 60 degrees: the far ear about 0.6 ms later (the head's width) and a few dB softer
    # at 220 Hz (the head shadows little at low pitch); straight ahead both ears alike.
    assert ild_l < -2.0 < 2.0 < ild_r and abs(ild_c) < 0.5
    assert 0.45 < itd_l < 0.8 and -0.8 < itd_r < -0.45 and abs(itd_c) < 0.05
    assert ild_l == pytest.approx(-ild_r, abs=0.5) and itd_l == pytest.approx(-itd_r, abs=0.05)


def test_height_changes_the_spectrum_not_the_sides(kemar: object) -> None:
    # Up and down come from the pinna's filtering: the same voice ahead at -30 and +40 degrees
    # has the same interaural cues but a different spectrum.
    spectra = []
    for el in (-30.0, 40.0):
        bank = VoiceBank(SoundMapping(), SR, kemar)  # type: ignore[arg-type]
        v = _beep(0.0, el, hz=440.0)
        out = np.concatenate([bank.render({v.key: v}, 256) for _ in range(100)])
        assert abs(_ears(out)[0]) < 1.0
        s = np.abs(np.fft.rfft(out[:, 0]))
        spectra.append(s / s.sum())
    f = np.fft.rfftfreq(100 * 256, 1 / SR)
    harmonics = [int(np.argmin(np.abs(f - 440.0 * k))) for k in range(1, 5)]
    ratio = spectra[1][harmonics] / spectra[0][harmonics]
    assert ratio.max() / ratio.min() > 1.25  # the harmonics are weighted differently by elevation


def test_a_voice_moving_across_changes_filters_without_a_click(kemar: object) -> None:
    bank = VoiceBank(SoundMapping(), SR, kemar)  # type: ignore[arg-type]
    glide = Voice(("g", 1), 300.0, 300.0, 0.3, 0.3, (0.7, 0.7), (0.7, 0.7), 0.0, 0.0, 1, 0.0, -40.0, 0.0)
    blocks = []
    for i in range(60):
        blocks.append(bank.render({glide.key: glide}, 256))
        glide = Voice(**{**glide.__dict__, "azimuth": -40.0 + 80.0 * i / 59})
    out = np.concatenate(blocks)[2000:]
    # A steady 300-Hz tone moving left to right: no sample-to-sample step beyond what the tone's
    # slope allows (a click would be a jump at a block edge).
    step = np.abs(np.diff(out, axis=0)).max()
    slope = 2 * np.pi * 300.0 / SR * np.abs(out).max()
    assert step < 2.0 * slope
    first, last = _ears(out[:4800]), _ears(out[-4800:])
    assert first[0] < 0 < last[0]


def test_direction_comes_from_the_intrinsics() -> None:
    k = Intrinsics(fx=500.0, fy=500.0, cx=320.0, cy=240.0)
    az, el = direction(320.0 - 500.0, 240.0, k)
    assert az == pytest.approx(-45.0) and el == pytest.approx(0.0)
    az, el = direction(320.0, 240.0 - 500.0, k)
    assert az == pytest.approx(0.0) and el == pytest.approx(45.0)
    assert direction(10.0, 10.0, None) == (None, None)
    n = Node(1, "object", 1, 1000.0, 300, (100.0, 240.0))
    v = beep_voice(n, (640, 480), SoundMapping(), k)
    assert v.azimuth is not None and v.azimuth < -20 and v.elevation == pytest.approx(0.0)


def _write_sofa(path: Path, ir: np.ndarray, positions: list[list[float]], samplerate: int) -> None:
    """A minimal SimpleFreeFieldHRIR file, as SOFA writers lay it out (netCDF-4)."""
    netCDF4 = pytest.importorskip(
        "netCDF4", reason="SOFA files are read with netCDF4: pip install 'depthgram[binaural]'"
    )
    with netCDF4.Dataset(str(path), "w", format="NETCDF4") as ds:
        ds.Conventions, ds.SOFAConventions = "SOFA", "SimpleFreeFieldHRIR"
        for name, size in (("M", ir.shape[0]), ("R", 2), ("N", ir.shape[2]), ("C", 3), ("I", 1)):
            ds.createDimension(name, size)
        ds.createVariable("Data.IR", "f8", ("M", "R", "N"))[:] = ir
        pos = ds.createVariable("SourcePosition", "f8", ("M", "C"))
        pos.Type, pos.Units = "spherical", "degree, degree, metre"
        pos[:] = positions
        ds.createVariable("Data.SamplingRate", "f8", ("I",))[:] = samplerate


def test_a_sofa_file_is_read_with_the_azimuth_turned_to_the_right(tmp_path: Path) -> None:
    from depthgram.sound.binaural import read_sofa

    ir = np.zeros((2, 2, 64))
    ir[0, 0, 5], ir[0, 1, 20] = 1.0, 0.5  # SOFA azimuth 90: to the left, the left ear first and louder
    ir[1, 0, 20], ir[1, 1, 5] = 0.5, 1.0  # SOFA azimuth 270: to the right
    path = tmp_path / "two.sofa"
    _write_sofa(path, ir, [[90, 0, 1.2], [270, 0, 1.2]], 44100)
    got = read_sofa(path)
    assert got.samplerate == 44100 and got.irs.shape == (2, 2, 64)
    assert got.azimuth_deg.tolist() == pytest.approx([-90.0, 90.0])
    assert got.nearest(-70.0, 0.0) == 0 and got.nearest(80.0, 10.0) == 1
    at48 = got.at_rate(SR, taps=64)
    assert at48.samplerate == SR and at48.irs.shape == (2, 2, 64)
    left = at48.irs[0]
    assert np.abs(left[0]).argmax() < np.abs(left[1]).argmax()  # the left ear first
    # What is not a SOFA HRIR file is named as such.
    bad = tmp_path / "bad.sofa"
    bad.write_bytes(b"not netCDF")
    from depthgram.errors import InputError

    with pytest.raises(InputError, match="not a readable SOFA"):
        read_sofa(bad)


def test_a_missing_sofa_file_is_named() -> None:
    from depthgram.errors import InputError
    from depthgram.sound.live import _check_binaural

    with pytest.raises(InputError, match="expected 'kemar' or the path of a SOFA file"):
        _check_binaural("/nonexistent/head.sofa")


def test_a_tilted_camera_leaves_the_pitch_of_what_stays_put() -> None:
    from depthgram.frame import Gravity

    m = SoundMapping()
    k = Intrinsics(fx=500.0, fy=500.0, cx=320.0, cy=240.0)
    # A point on the horizon straight ahead: at the middle row of a level camera, 20 degrees
    # above the optical axis (row cy - fy tan 20) of a camera tilted 20 degrees down.
    row = 240.0 - 500.0 * np.tan(np.radians(20.0))
    level = beep_voice(
        Node(1, "object", 1, 1500.0, 300, (320.0, 240.0)), (640, 480), m, k, gravity=Gravity.from_tilt(0)
    )
    tilted = Node(1, "object", 1, 1500.0, 300, (320.0, row))
    with_g = beep_voice(tilted, (640, 480), m, k, gravity=Gravity.from_tilt(20.0))
    without = beep_voice(tilted, (640, 480), m, k)
    assert with_g.freq_a == pytest.approx(level.freq_a) and with_g.elevation == pytest.approx(0.0, abs=1e-6)
    assert without.freq_a > 1.5 * level.freq_a  # the image row alone would say "high up"
    # Rolled 30 degrees: a point level with the camera, to the right, stays at elevation 0.
    g = Gravity.from_tilt(0.0, roll_deg=30.0)
    ray = np.array([np.cos(np.radians(30.0)), np.sin(np.radians(30.0)), 0.0]) * 0.5 + np.array([0, 0, 1.0])
    x, y = 320.0 + 500.0 * ray[0] / ray[2], 240.0 + 500.0 * ray[1] / ray[2]
    az, el = direction(x, y, k, g)
    assert el == pytest.approx(0.0, abs=1e-6) and az is not None and az > 20
