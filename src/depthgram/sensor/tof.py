"""Continuous-wave time-of-flight physics as plain functions over numpy arrays (paper section 2).

The light source is modulated at ``f_mod_hz``; each pixel correlates the returned light with
four gate signals shifted by 0°, 90°, 180° and 270° and integrates charge (electrons) over
the exposure. The phase of the returned light, and from it the distance, follows from the
four samples (paper eq. 6 and 7). Everything here works element-wise on arrays of any shape;
the four samples are stacked on a leading axis of length 4.

Distances here are *radial* (along the ray, what light travels), in millimetres. The
simulator converts them to depth along the optical axis afterwards, as the sensor's embedded
processing does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from depthgram.errors import InputError
from depthgram.frame import depth_from_8bit, depth_to_8bit

__all__ = [
    "C_MM_PER_S",
    "PHASE_OFFSETS",
    "ToFConfig",
    "ambiguity_range_mm",
    "amplitude_e",
    "correlation_samples",
    "demodulate",
    "depth_to_phase",
    "measure",
    "phase_to_depth_mm",
    "quantize",
    "sample_noise",
    "unwrap_two_frequencies",
]

#: Speed of light in vacuum (mm/s).
C_MM_PER_S = 299_792_458_000.0

#: Gate phase offsets of the four correlation samples (rad): 0°, 90°, 180°, 270°.
PHASE_OFFSETS = np.array([0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi])

#: Integration time (s) at which :attr:`ToFConfig.amplitude_at_1m_e` and
#: :attr:`ToFConfig.ambient_e` are stated; both scale linearly with the integration time.
REFERENCE_INTEGRATION_S = 0.01


@dataclass(frozen=True)
class ToFConfig:
    """Sensor model of a continuous-wave ToF camera.

    Attributes
    ----------
    f_mod_hz : float
        Modulation frequency (Hz). 50 MHz as in the paper: ambiguity range about 2998 mm.
    f_mod2_hz : float or None
        Second modulation frequency (Hz) for two-frequency phase unwrapping, e.g. 40e6
        (50 and 40 MHz together are unambiguous to c / (2 * 10 MHz), about 15 m). None: one
        frequency, distances beyond the ambiguity range wrap around.
    amplitude_at_1m_e : float
        Modulated signal amplitude (electrons per sample) returned by a surface of
        reflectivity 1 at 1 m, at 10 ms integration. Falls with distance squared.
    ambient_e : float
        Unmodulated ambient light (electrons per sample) at 10 ms integration. It adds shot
        noise but no phase: the paper's "ambient light is not affecting the sensor operation".
    read_noise_e : float
        Gaussian read noise (electrons rms per sample).
    integration_s : float
        Exposure time (s). Scales signal and ambient, and sets the motion blur that mixes
        surfaces at moving edges.
    min_amplitude_e : float
        Pixels whose demodulated amplitude (electrons) is below this are invalid.
    bits : int
        Output quantization: 16 (millimetres, as most depth PNGs) or 8 (the paper's 0-255 over
        ``near_8bit_mm`` .. ``far_8bit_mm``).
    near_8bit_mm, far_8bit_mm : float
        Range (mm) of the 8-bit code. ``far_8bit_mm`` None means the range read without
        wrap-around (:attr:`range_mm`): the ambiguity range of ``f_mod_hz`` with one
        frequency, a step of about 11.8 mm at 50 MHz (the paper's "order of one centimeter").
    mixed_pixels : bool
        Simulate pixels on moving edges that see two surfaces during the exposure and
        average their correlation samples, giving an in-between depth.
    motion_substeps : int
        Number of instants the exposure is sampled at for mixed pixels (>= 1).
    """

    f_mod_hz: float = 50e6
    f_mod2_hz: float | None = None
    amplitude_at_1m_e: float = 8000.0
    ambient_e: float = 500.0
    read_noise_e: float = 10.0
    integration_s: float = 0.01
    min_amplitude_e: float = 20.0
    bits: int = 16
    near_8bit_mm: float = 0.0
    far_8bit_mm: float | None = None
    mixed_pixels: bool = True
    motion_substeps: int = 4

    def __post_init__(self) -> None:
        def bad(what: str) -> InputError:
            return InputError(f"ToFConfig: {what}")

        for name, f in (("f_mod_hz", self.f_mod_hz), ("f_mod2_hz", self.f_mod2_hz)):
            if f is not None and not (1e5 <= f <= 1e9):
                raise bad(f"{name} must be between 100 kHz and 1 GHz, got {f}")
        if self.f_mod2_hz is not None and self.f_mod2_hz == self.f_mod_hz:
            raise bad("f_mod2_hz must differ from f_mod_hz for unwrapping")
        if not (self.amplitude_at_1m_e > 0 and np.isfinite(self.amplitude_at_1m_e)):
            raise bad(f"amplitude_at_1m_e must be a positive number of electrons, got {self.amplitude_at_1m_e}")
        for name, v in (
            ("ambient_e", self.ambient_e),
            ("read_noise_e", self.read_noise_e),
            ("min_amplitude_e", self.min_amplitude_e),
        ):
            if not (v >= 0 and np.isfinite(v)):
                raise bad(f"{name} must be >= 0 electrons, got {v}")
        if not (0 < self.integration_s <= 1.0):
            raise bad(f"integration_s must be in (0, 1] s, got {self.integration_s}")
        if self.bits not in (8, 16):
            raise bad(f"bits must be 8 or 16, got {self.bits}")
        if self.far_8bit_mm is not None and not self.far_8bit_mm > self.near_8bit_mm >= 0:
            raise bad(f"8-bit range must have far > near >= 0 mm, got {self.near_8bit_mm}..{self.far_8bit_mm}")
        if not (1 <= self.motion_substeps <= 64):
            raise bad(f"motion_substeps must be 1..64, got {self.motion_substeps}")

    @property
    def range_mm(self) -> float:
        """Largest distance (mm) read without wrap-around with this configuration."""
        if self.f_mod2_hz is None:
            return ambiguity_range_mm(self.f_mod_hz)
        return unambiguous_range_two_mm(self.f_mod_hz, self.f_mod2_hz)


def ambiguity_range_mm(f_mod_hz: float) -> float:
    """Ambiguity range c / (2 f) in mm: about 2998 mm at 50 MHz.

    Light travels to the surface and back, so one modulation period of phase covers half a
    wavelength of distance.
    """
    return C_MM_PER_S / (2.0 * f_mod_hz)


def unambiguous_range_two_mm(f1_hz: float, f2_hz: float) -> float:
    """Unambiguous range (mm) of two modulation frequencies: c / (2 gcd(f1, f2)), the beat.

    Frequencies are rounded to whole hertz for the common divisor.
    """
    g = float(np.gcd(round(f1_hz), round(f2_hz)))
    return C_MM_PER_S / (2.0 * g)


def phase_to_depth_mm(phase: ArrayLike, f_mod_hz: float) -> NDArray[np.float64]:
    """Distance D = c φ / (4 π f_m) in mm for a phase φ in radians (paper eq. 7).

    The paper prints eq. 7 as ``D = c φ / 4 π f_m t``; the trailing ``t`` is a stray
    symbol: the equation is dimensionally a distance only without it.
    """
    return C_MM_PER_S * np.asarray(phase, dtype=np.float64) / (4.0 * np.pi * f_mod_hz)


def depth_to_phase(depth_mm: ArrayLike, f_mod_hz: float) -> NDArray[np.float64]:
    """Phase delay φ = 4 π f_m D / c (rad) of a distance D (mm), not wrapped to [0, 2π)."""
    return 4.0 * np.pi * f_mod_hz * np.asarray(depth_mm, dtype=np.float64) / C_MM_PER_S


def amplitude_e(distance_mm: ArrayLike, reflectivity: ArrayLike, cfg: ToFConfig) -> NDArray[np.float64]:
    """Return the modulated amplitude (electrons): reflectivity / distance² times the 1 m value.

    Distance 0 (no surface) returns 0 amplitude.
    """
    d_m = np.asarray(distance_mm, dtype=np.float64) / 1000.0
    scale = cfg.amplitude_at_1m_e * cfg.integration_s / REFERENCE_INTEGRATION_S
    with np.errstate(divide="ignore", invalid="ignore"):
        a = scale * np.asarray(reflectivity, dtype=np.float64) / (d_m * d_m)
    return np.where(d_m > 0, a, 0.0)


def correlation_samples(
    distance_mm: ArrayLike, amplitude: ArrayLike, f_mod_hz: float, ambient: ArrayLike = 0.0
) -> NDArray[np.float64]:
    """Return the expected (noise-free) charge of the four gates, shape (4, ...), in electrons.

    ``A_k = ambient + a (1 + cos(φ - θ_k))`` with θ_k in :data:`PHASE_OFFSETS`: a 50 % duty
    square source correlated with a gate shifted by θ_k, low-passed to its fundamental. Then
    ``A0 - A180 = 2 a cos φ`` and ``A90 - A270 = 2 a sin φ`` (the paper's V0 and V90).
    """
    phi = depth_to_phase(distance_mm, f_mod_hz)
    a = np.asarray(amplitude, dtype=np.float64)
    theta = PHASE_OFFSETS.reshape((4,) + (1,) * phi.ndim)
    out: NDArray[np.float64] = np.asarray(ambient, dtype=np.float64) + a * (1.0 + np.cos(phi - theta))
    return out


def sample_noise(samples: NDArray[np.float64], read_noise_e: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """Shot noise plus Gaussian read noise on correlation samples (electrons).

    Shot noise is Poisson with variance equal to the charge; every sample holds at least the
    ambient charge (hundreds of electrons), where the Gaussian of the same variance is an
    accurate stand-in and several times cheaper to draw, so one normal draw of variance
    ``charge + read_noise_e²`` covers both.
    """
    sigma = np.sqrt(np.clip(samples, 0.0, None) + read_noise_e * read_noise_e)
    return samples + sigma * rng.standard_normal(samples.shape)


def demodulate(samples: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Phase in [0, 2π) and amplitude (electrons) from the four samples (paper eq. 6).

    φ = arctan2(A90 - A270, A0 - A180), written with the quadrant-aware arctangent so that
    the full period is recovered, and a = sqrt((A90 - A270)² + (A0 - A180)²) / 2.
    """
    s = np.asarray(samples, dtype=np.float64)
    if s.shape[0] != 4:
        raise InputError(f"demodulate: expected 4 correlation samples on the first axis, got shape {s.shape}")
    v90 = s[1] - s[3]
    v0 = s[0] - s[2]
    phase = np.mod(np.arctan2(v90, v0), 2.0 * np.pi)
    return phase, 0.5 * np.hypot(v90, v0)


def unwrap_two_frequencies(
    phase1: ArrayLike, f1_hz: float, phase2: ArrayLike, f2_hz: float, max_range_mm: float | None = None
) -> NDArray[np.float64]:
    """Distance (mm) from the wrapped phases of two modulation frequencies.

    The classic search over wrap counts: for each candidate count n1 of the first frequency
    (up to the combined unambiguous range), the distance d1 = (φ1 + 2π n1) c / (4π f1) is
    compared with the nearest candidate of the second frequency; the pair that agrees best
    wins, and the two candidates are averaged with weights f² (the higher frequency has the
    finer phase-to-distance scale, so its noise in mm is smaller).

    Parameters
    ----------
    phase1, phase2 : array_like
        Wrapped phases (rad) measured at ``f1_hz`` and ``f2_hz``.
    f1_hz, f2_hz : float
        The two modulation frequencies (Hz).
    max_range_mm : float, optional
        Search range (mm); default the unambiguous range c / (2 gcd(f1, f2)).

    Returns
    -------
    ndarray of float64
        Unwrapped distance (mm).
    """
    p1 = np.asarray(phase1, dtype=np.float64)
    p2 = np.asarray(phase2, dtype=np.float64)
    r1, r2 = ambiguity_range_mm(f1_hz), ambiguity_range_mm(f2_hz)
    limit = unambiguous_range_two_mm(f1_hz, f2_hz) if max_range_mm is None else max_range_mm
    d1_base = phase_to_depth_mm(np.mod(p1, 2 * np.pi), f1_hz)
    d2_base = phase_to_depth_mm(np.mod(p2, 2 * np.pi), f2_hz)
    counts = np.arange(int(np.ceil(limit / r1)), dtype=np.float64).reshape((-1,) + (1,) * p1.ndim)
    d1 = d1_base + counts * r1  # (K, ...)
    n2 = np.rint((d1 - d2_base) / r2)
    d2 = d2_base + n2 * r2
    err = np.abs(d1 - d2)
    best = np.argmin(err, axis=0)[None]
    b1 = np.take_along_axis(d1, best, axis=0)[0]
    b2 = np.take_along_axis(d2, best, axis=0)[0]
    w1, w2 = f1_hz**2, f2_hz**2
    out: NDArray[np.float64] = (w1 * b1 + w2 * b2) / (w1 + w2)
    return out


def quantize(depth_mm: ArrayLike, cfg: ToFConfig) -> NDArray[np.float32]:
    """Depth (mm) as the sensor outputs it: whole millimetres (16-bit) or the 8-bit code.

    0 stays 0 (no reading). The 8-bit path goes through :func:`depthgram.frame.depth_to_8bit`
    and back so that the simulator and the frame reader agree on the code.
    """
    d = np.asarray(depth_mm, dtype=np.float64)
    if cfg.bits == 16:
        return np.where(d > 0, np.clip(np.rint(d), 1, 65535), 0).astype(np.float32)
    far = cfg.range_mm if cfg.far_8bit_mm is None else cfg.far_8bit_mm
    codes = depth_to_8bit(d, cfg.near_8bit_mm, far)
    return depth_from_8bit(codes, cfg.near_8bit_mm, far)


def measure(
    samples: NDArray[np.float64],
    samples2: NDArray[np.float64] | None,
    cfg: ToFConfig,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Radial distance (mm) and amplitude (electrons) read from (noisy) correlation samples.

    ``samples2`` holds the samples at ``cfg.f_mod2_hz`` when unwrapping is on. With one
    frequency the distance is wrapped into [0, ambiguity range). Pixels below
    ``cfg.min_amplitude_e`` get distance 0 (invalid).
    """
    phase, amp = demodulate(samples)
    if cfg.f_mod2_hz is None or samples2 is None:
        dist = phase_to_depth_mm(phase, cfg.f_mod_hz)
    else:
        phase2, amp2 = demodulate(samples2)
        dist = unwrap_two_frequencies(phase, cfg.f_mod_hz, phase2, cfg.f_mod2_hz)
        amp = np.minimum(amp, amp2)
    ok = amp >= max(cfg.min_amplitude_e, 1e-9)
    return np.where(ok, dist, 0.0), amp
