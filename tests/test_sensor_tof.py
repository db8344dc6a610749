"""ToF physics against values hand-computed from the paper's equations (section 2)."""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.sensor.tof import (
    C_MM_PER_S,
    ToFConfig,
    ambiguity_range_mm,
    amplitude_e,
    correlation_samples,
    demodulate,
    depth_to_phase,
    measure,
    phase_to_depth_mm,
    quantize,
    sample_noise,
    unwrap_two_frequencies,
)


def test_ambiguity_range_is_half_a_modulation_wavelength() -> None:
    # c / (2 f) = 299792458 m/s / 1e8 /s = 2.99792458 m
    assert ambiguity_range_mm(50e6) == pytest.approx(2997.92458)
    assert ambiguity_range_mm(40e6) == pytest.approx(3747.4057)


def test_quarter_period_samples_read_749_5_mm() -> None:
    # A0 = A180 (cos φ = 0) and A90 - A270 = 200 > 0 (sin φ = 1): φ = π/2; D = c/(8 f) = 749.48 mm.
    phase, amp = demodulate(np.array([100.0, 200.0, 100.0, 0.0]))
    assert phase == pytest.approx(np.pi / 2)
    assert amp == pytest.approx(100.0)
    assert phase_to_depth_mm(phase, 50e6) == pytest.approx(749.4811, abs=1e-3)


def test_samples_of_each_quadrant_give_their_phase() -> None:
    # A0-A180 = 2a cos φ, A90-A270 = 2a sin φ: φ = 3π/2 -> 2248.4 mm, φ = π -> 1499.0 mm.
    phase, _ = demodulate(np.array([[100.0, 50.0], [0.0, 100.0], [100.0, 150.0], [200.0, 100.0]]))
    np.testing.assert_allclose(phase, [1.5 * np.pi, np.pi])
    np.testing.assert_allclose(phase_to_depth_mm(phase, 50e6), [2248.4434, 1498.9623], atol=1e-3)


def test_phase_depth_round_trip() -> None:
    d = np.array([0.0, 10.0, 1234.5, 2997.0])
    np.testing.assert_allclose(phase_to_depth_mm(depth_to_phase(d, 50e6), 50e6), d)
    assert depth_to_phase(C_MM_PER_S / (4 * 50e6), 50e6) == pytest.approx(np.pi)


def test_noise_free_samples_recover_distance_and_amplitude() -> None:
    d = np.array([300.0, 1000.0, 2500.0])
    s = correlation_samples(d, np.array([50.0, 500.0, 5000.0]), 50e6, ambient=800.0)
    assert s.shape == (4, 3)
    phase, amp = demodulate(s)
    np.testing.assert_allclose(phase_to_depth_mm(phase, 50e6), d, atol=1e-6)
    np.testing.assert_allclose(amp, [50.0, 500.0, 5000.0])


def test_wrap_around_beyond_the_ambiguity_range() -> None:
    s = correlation_samples(np.array([4000.0]), np.array([1000.0]), 50e6)
    phase, _ = demodulate(s)
    # 4000 - 2997.92 = 1002.08 mm
    assert phase_to_depth_mm(phase, 50e6)[0] == pytest.approx(1002.0754, abs=1e-3)


def test_two_frequency_unwrapping_recovers_4000_mm_and_more() -> None:
    d = np.array([4000.0, 150.0, 2998.5, 7777.0, 12000.0, 14900.0])
    p1, _ = demodulate(correlation_samples(d, 1000.0, 50e6))
    p2, _ = demodulate(correlation_samples(d, 1000.0, 40e6))
    assert phase_to_depth_mm(p1, 50e6)[0] == pytest.approx(1002.08, abs=0.01)  # wrapped alone
    np.testing.assert_allclose(unwrap_two_frequencies(p1, 50e6, p2, 40e6), d, atol=1e-6)


def test_unwrapping_tolerates_phase_noise() -> None:
    rng = np.random.default_rng(1)
    d = rng.uniform(100.0, 14000.0, 2000)
    sigma = 0.02  # rad, about 10 mm at 50 MHz
    p1 = depth_to_phase(d, 50e6) + rng.normal(0, sigma, d.size)
    p2 = depth_to_phase(d, 40e6) + rng.normal(0, sigma, d.size)
    err = unwrap_two_frequencies(p1, 50e6, p2, 40e6) - d
    assert np.max(np.abs(err)) < 60.0  # no wrong wrap count: those are metres off


def test_amplitude_falls_with_distance_squared_and_rises_with_reflectivity() -> None:
    cfg = ToFConfig(amplitude_at_1m_e=8000.0, integration_s=0.01)
    a = amplitude_e(np.array([1000.0, 2000.0, 1000.0, 0.0]), np.array([0.5, 0.5, 1.0, 1.0]), cfg)
    np.testing.assert_allclose(a, [4000.0, 1000.0, 8000.0, 0.0])
    # twice the integration, twice the charge
    assert amplitude_e(1000.0, 1.0, ToFConfig(integration_s=0.02)) == pytest.approx(16000.0)


def test_depth_noise_falls_as_amplitude_rises_as_predicted() -> None:
    # σ_φ = sqrt(Var(A0 - A180)) / (2a) with Var(A0 - A180) = 2 (B + a) + 2 σ_r² (Poisson + read).
    rng = np.random.default_rng(7)
    n, b, read = 20000, 500.0, 10.0
    d = np.full(n, 1200.0)
    stds = []
    for a in (200.0, 800.0, 3200.0):
        s = sample_noise(correlation_samples(d, np.full(n, a), 50e6, ambient=b), read, rng)
        phase, _ = demodulate(s)
        measured = phase_to_depth_mm(phase, 50e6)
        predicted = phase_to_depth_mm(np.sqrt(2 * (b + a) + 2 * read**2) / (2 * a), 50e6)
        assert np.mean(measured) == pytest.approx(1200.0, abs=1.0)
        assert np.std(measured) == pytest.approx(predicted, rel=0.05)
        stds.append(np.std(measured))
    assert stds[0] > stds[1] > stds[2]


def test_low_amplitude_pixels_are_invalid() -> None:
    cfg = ToFConfig(min_amplitude_e=50.0)
    s = correlation_samples(np.array([1000.0, 1000.0]), np.array([49.0, 51.0]), 50e6, ambient=100.0)
    dist, amp = measure(s, None, cfg)
    assert dist[0] == 0.0
    assert dist[1] == pytest.approx(1000.0)
    np.testing.assert_allclose(amp, [49.0, 51.0])


def test_eight_bit_step_is_11_8_mm_over_the_ambiguity_range() -> None:
    cfg = ToFConfig(bits=8)
    d = np.linspace(20.0, 2900.0, 5000)
    q = quantize(d, cfg)
    steps = np.diff(np.unique(q))
    # 2997.92 / 254 codes = 11.803 mm per code
    np.testing.assert_allclose(steps, 2997.92458 / 254, rtol=1e-4)
    assert np.max(np.abs(q - d)) <= 2997.92458 / 254 / 2 + 1e-3
    assert quantize(np.array([0.0]), cfg)[0] == 0.0


def test_sixteen_bit_is_whole_millimetres() -> None:
    q = quantize(np.array([0.0, 0.4, 1000.4, 1000.6, 70000.0]), ToFConfig(bits=16))
    np.testing.assert_array_equal(q, [0.0, 1.0, 1000.0, 1001.0, 65535.0])


def test_mixing_two_equal_surfaces_gives_the_depth_in_between() -> None:
    # Equal amplitudes: the phasor sum points half-way, so 1000 and 1500 mm read 1250 mm.
    s = 0.5 * (
        correlation_samples(np.array([1000.0]), 800.0, 50e6) + correlation_samples(np.array([1500.0]), 800.0, 50e6)
    )
    phase, amp = demodulate(s)
    assert phase_to_depth_mm(phase, 50e6)[0] == pytest.approx(1250.0, abs=1e-6)
    assert amp[0] < 800.0  # partial cancellation


@pytest.mark.parametrize(
    "kwargs",
    [
        {"bits": 12},
        {"f_mod_hz": 0.0},
        {"f_mod2_hz": 50e6},
        {"integration_s": 0.0},
        {"amplitude_at_1m_e": -1.0},
        {"motion_substeps": 0},
        {"far_8bit_mm": -5.0},
    ],
)
def test_config_rejects_absurd_values(kwargs: dict[str, float]) -> None:
    with pytest.raises(InputError, match="ToFConfig"):
        ToFConfig(**kwargs)  # type: ignore[arg-type]


def test_demodulate_wants_four_samples() -> None:
    with pytest.raises(InputError, match="4 correlation samples"):
        demodulate(np.zeros((3, 5)))
