"""Decoding helpers for the sound tests: find a voice's beeps in a stereo signal."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks, stft


@dataclass(frozen=True)
class Heard:
    """What the signal holds at one pitch: beep times (s), their rate (Hz) and the pan angle."""

    times: np.ndarray
    rate_hz: float
    pitch_hz: float  # strongest frequency within 6 % of the one listened for, at the beep times
    pan_angle: float  # atan2(right, left) amplitude: 0 hard left, pi/4 centre, pi/2 hard right


def listen(audio: np.ndarray, sr: int, hz: float, *, window_s: float = 0.06) -> Heard:
    """Beeps at ``hz`` in a stereo signal: peaks of the short-time amplitude at that pitch."""
    n = round(window_s * sr)
    hop = max(1, n // 16)
    f, t, z = stft(audio.T, fs=sr, nperseg=n, noverlap=n - hop, boundary=None)
    k = int(np.argmin(np.abs(f - hz)))
    band = np.abs(z[:, k, :])  # (2, frames)
    env = band.sum(axis=0)
    loudest = float(np.abs(z).sum(axis=0).max(initial=0.0))
    # A beep is a peak standing well above what sounds at that pitch between beeps, and not a
    # leak of another voice's spectrum (at least 10 % of the loudest component of the signal).
    peaks, _ = find_peaks(
        env,
        prominence=0.5 * env.max() if env.max() > 0 else 1.0,
        height=0.1 * loudest,
        distance=max(1, int(0.04 * sr / hop)),
    )
    times = t[peaks]
    rate = float(1.0 / np.median(np.diff(times))) if times.size >= 2 else 0.0
    left, right = band[0, peaks].sum(), band[1, peaks].sum()
    pitch = 0.0
    if peaks.size:
        spec = np.abs(z[:, :, peaks]).sum(axis=(0, 2))
        sel = np.flatnonzero(np.abs(f - hz) <= 0.06 * hz)
        j = int(sel[np.argmax(spec[sel])])
        a, b, c = np.log(spec[j - 1 : j + 2] + 1e-12)
        pitch = float(f[j] + 0.5 * (a - c) / (a - 2 * b + c) * (f[1] - f[0]))  # parabolic peak
    return Heard(times, rate, pitch, float(np.arctan2(right, left)))
