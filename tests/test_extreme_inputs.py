"""No traceback from any frame, however extreme (issue 32.2): a result, or a clear error and exit 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthgram.cli import main
from depthgram.segmentation.noise_model import PROFILES, estimate_sensor

EXTREMES = {
    "all_1e30": np.full((48, 64), 1e30, np.float32),
    "largest_float32": np.full((48, 64), np.finfo(np.float32).max, np.float32),
    "all_nan": np.full((48, 64), np.nan, np.float32),
    "all_inf": np.full((48, 64), np.inf, np.float32),
    "all_zero": np.zeros((48, 64), np.float32),
    "all_negative": np.full((48, 64), -5.0, np.float32),
    "all_65535": np.full((48, 64), 65535, np.uint16),
    "all_beyond_range": np.full((48, 64), 60000, np.uint16),
    "one_pixel": np.full((1, 1), 1000.0, np.float32),
    "one_row": np.full((1, 64), 1000.0, np.float32),
    "one_column": np.full((48, 1), 1000.0, np.float32),
    "two_by_two": np.full((2, 2), 1000, np.uint16),
}


def _ramp_with_far() -> np.ndarray:
    z = np.tile(np.linspace(500, 3000, 64, dtype=np.float32), (48, 1))
    z[::3, ::5] = 1e30
    return z


EXTREMES["ramp_with_1e30_speckle"] = _ramp_with_far()


def test_estimate_sensor_of_readings_too_far_to_be_real_gives_a_model() -> None:
    # issue 32.2: every pixel 1e30 ended in "negative dimensions not allowed"
    d = np.full((48, 64), 1e30, np.float32)
    model = estimate_sensor(d, d > 0)
    assert model == PROFILES["tof"]  # the readings are all equal: no step or noise to read


@pytest.mark.parametrize("name", sorted(EXTREMES))
@pytest.mark.parametrize("command", ["info", "describe", "plan"])
def test_an_extreme_frame_gives_a_result_or_a_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, command: str
) -> None:
    path = tmp_path / f"{name}.npy"
    np.save(path, EXTREMES[name])
    status = main([command, str(path)])  # a traceback fails the test by raising here
    err = capsys.readouterr().err
    assert status in (0, 2), err
    if status == 2:
        assert f"{name}.npy" in err and "error" in err


@pytest.mark.parametrize("name", ["all_1e30", "all_nan", "one_pixel", "ramp_with_1e30_speckle"])
def test_an_extreme_frame_sonifies_or_fails_clearly(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    pytest.importorskip("soundfile")
    path = tmp_path / f"{name}.npy"
    np.save(path, EXTREMES[name])
    status = main(["sonify", str(path), "--wav", str(tmp_path / "out.wav"), "--still-duration", "0.5"])
    err = capsys.readouterr().err
    assert status in (0, 2), err
    assert (status == 0) == (tmp_path / "out.wav").is_file()


@pytest.mark.parametrize("cut", [0, 10, 60, 127, 128, 129, 1000])
def test_a_truncated_npy_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str], cut: int) -> None:
    # issue 32.2: truncated .npy files let an InputError escape main under load
    whole = tmp_path / "whole.npy"
    np.save(whole, np.full((48, 64), 1000, np.uint16))
    cut_to = tmp_path / "cut.npy"
    cut_to.write_bytes(whole.read_bytes()[:cut])
    for command in ("info", "describe"):
        assert main([command, str(cut_to)]) == 2
        err = capsys.readouterr().err
        assert "cut.npy" in err and "Traceback" not in err


def test_readings_beyond_float32_once_in_mm_are_no_readings() -> None:
    from depthgram.frame import make_frame

    raw = np.array([[1.5, 1e300], [np.finfo(np.float32).max, 2.0]])  # float64 metres
    f = make_frame(raw, scale_mm=1000.0, check_units=False)
    assert f.valid.tolist() == [[True, False], [False, True]]
    np.testing.assert_allclose(f.depth, [[1500.0, 0.0], [0.0, 2000.0]])
