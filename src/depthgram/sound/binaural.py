"""Binaural rendering: each voice through a measured head-related impulse response (HRIR).

With headphones, a voice filtered by the impulse responses measured in a dummy head's ears for
its direction is heard from that direction: left/right from the interaural time and level
differences, up/down and front from the pinna's spectral notches. This module holds a set of
HRIRs (:class:`HRIRSet`), read from the KEMAR measurements the ``slab`` package ships (MIT,
Gardner and Martin 1994, 710 directions, elevation -40..90 degrees) or from any SOFA file
(read with ``netCDF4``); :class:`depthgram.sound.synth.VoiceBank` convolves each voice with the
nearest direction's pair (extra ``[binaural]``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError

__all__ = ["HRIRSet", "kemar", "load_hrirs", "read_sofa"]

#: Taps kept of each impulse response at the rendering rate, after its common leading silence:
#: 5.3 ms at 48 kHz, past the interaural delay (under 0.8 ms) and the pinna's reflections.
TAPS = 256


@dataclass(frozen=True)
class HRIRSet:
    """Head-related impulse responses measured for a set of directions.

    Attributes
    ----------
    samplerate : int
        Samples per second of the responses (Hz).
    azimuth_deg : ndarray, shape (k,)
        Direction of each measurement (degrees): positive to the right of straight ahead, -180..180.
    elevation_deg : ndarray, shape (k,)
        Degrees above the horizontal plane through the ears.
    irs : ndarray, shape (k, 2, taps)
        Left and right ear responses (float64).
    source : str
        Where they come from (for the user).
    """

    samplerate: int
    azimuth_deg: NDArray[np.float64]
    elevation_deg: NDArray[np.float64]
    irs: NDArray[np.float64]
    source: str

    def __post_init__(self) -> None:
        k = len(self.azimuth_deg)
        if self.irs.ndim != 3 or self.irs.shape[:2] != (k, 2) or len(self.elevation_deg) != k or k == 0:
            raise InputError(
                f"HRIR set {self.source}: expected irs of shape (directions, 2, taps) with one azimuth and "
                f"elevation per direction, got irs {self.irs.shape}, {k} azimuths, {len(self.elevation_deg)} elevations"
            )

    @property
    def taps(self) -> int:
        """Length of each response (samples)."""
        return int(self.irs.shape[2])

    def nearest(self, azimuth_deg: float, elevation_deg: float) -> int:
        """Return the index of the measured direction nearest (by angle) to the one given (degrees)."""
        units = self.__dict__.get("_units")
        if units is None:  # computed once: this is called for every voice of every audio block
            units = _unit(self.azimuth_deg, self.elevation_deg)
            object.__setattr__(self, "_units", units)
        return int(np.argmax(units @ _unit(azimuth_deg, elevation_deg)))

    def at_rate(self, samplerate: int, taps: int = TAPS) -> HRIRSet:
        """Return the set resampled to ``samplerate`` (Hz), cut to ``taps`` after the common onset.

        The level is normalised so that straight ahead each ear gets the power an equal-power
        centre pan gives it (1/2): switching the binaural mode on changes where, not how loud.
        """
        from scipy.signal import resample_poly

        g = math.gcd(int(samplerate), int(self.samplerate))
        irs = self.irs
        if samplerate != self.samplerate:
            irs = resample_poly(irs, samplerate // g, self.samplerate // g, axis=2)
        env = np.abs(irs).max(axis=(0, 1))
        onset = int(np.argmax(env > 0.05 * env.max()))
        start = max(0, onset - 8)  # a few samples before the earliest ear's onset, for its rise
        irs = irs[:, :, start : start + taps]
        ahead = self.nearest(0.0, 0.0)
        power = float((irs[ahead] ** 2).sum(axis=1).mean())
        irs = irs * math.sqrt(0.5 / power)
        return HRIRSet(int(samplerate), self.azimuth_deg, self.elevation_deg, np.ascontiguousarray(irs), self.source)


def _unit(azimuth_deg: Any, elevation_deg: Any) -> NDArray[np.float64]:
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "depthgram"


def kemar() -> HRIRSet:
    """Return the KEMAR responses ``slab`` ships (normal pinna, 44.1 kHz, 710 directions).

    Reading slab's file takes seconds (it unpickles slab's own objects); the arrays are kept in
    the user's cache folder (``$XDG_CACHE_HOME/depthgram``) for the next time.
    """
    from depthgram._optional import needs_extra

    with needs_extra("binaural", "binaural sound with the KEMAR responses"):
        import slab

    version = getattr(slab, "__version__", "unknown")
    cached = _cache_dir() / f"kemar-slab-{version}.npz"
    if cached.is_file():
        with np.load(cached) as z:
            return HRIRSet(int(z["samplerate"]), z["azimuth"], z["elevation"], z["irs"], f"KEMAR (slab {version})")
    h = slab.HRTF.kemar()
    polar = np.asarray(h.sources.vertical_polar, dtype=np.float64)
    # SOFA's azimuth turns to the left (90 = left ear); ours is positive to the right.
    az = (-polar[:, 0] + 180.0) % 360.0 - 180.0
    irs = np.stack([np.asarray(f.data, dtype=np.float64).T for f in h.data])  # (k, 2, taps)
    out = HRIRSet(int(h.samplerate), az, polar[:, 1].copy(), irs, f"KEMAR (slab {version})")
    try:
        cached.parent.mkdir(parents=True, exist_ok=True)
        tmp = cached.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, samplerate=out.samplerate, azimuth=out.azimuth_deg, elevation=out.elevation_deg, irs=out.irs)
        os.replace(tmp, cached)
    except OSError:  # a read-only home: read slab's file again next time
        pass
    return out


def read_sofa(path: str | Path) -> HRIRSet:
    """Return the responses of a SOFA file (convention SimpleFreeFieldHRIR), read with ``netCDF4``.

    A SOFA file is a netCDF-4 file: ``Data.IR`` (directions, 2 ears, taps), ``SourcePosition``
    (azimuth and elevation in degrees, or x, y, z with ``Type = "cartesian"``) and
    ``Data.SamplingRate``. (``sofar`` reads it too, but its wheel installs a top-level ``tests``
    package that shadows a project's own.)
    """
    from depthgram._optional import needs_extra

    with needs_extra("binaural", "reading a SOFA file"):
        import netCDF4

    p = Path(path)
    if not p.is_file():
        raise InputError(f"SOFA file {p} does not exist")
    try:
        with netCDF4.Dataset(str(p), "r") as ds:
            ds.set_auto_mask(False)
            var = ds.variables
            missing = [k for k in ("Data.IR", "SourcePosition", "Data.SamplingRate") if k not in var]
            if missing:
                raise InputError(f"{p}: not a SOFA HRIR file: no variable {', '.join(missing)}")
            ir = np.asarray(var["Data.IR"][:], dtype=np.float64)
            pos = np.asarray(var["SourcePosition"][:], dtype=np.float64)
            kind = str(getattr(var["SourcePosition"], "Type", "spherical")).lower()
            sr = round(float(np.asarray(var["Data.SamplingRate"][:]).ravel()[0]))
    except OSError as exc:  # netCDF4 says so for a file that is not netCDF
        raise InputError(f"{p}: not a readable SOFA (netCDF-4) file: {exc}") from exc
    if pos.ndim == 1:
        pos = pos[None, :]
    if pos.shape[0] == 1 and len(ir) > 1:
        pos = np.repeat(pos, len(ir), axis=0)
    if ir.ndim != 3 or ir.shape[1] != 2 or pos.ndim != 2 or len(pos) != len(ir) or pos.shape[1] < 2:
        raise InputError(
            f"{p}: expected Data.IR of shape (directions, 2 ears, taps) and one SourcePosition per direction "
            f"(convention SimpleFreeFieldHRIR), got {ir.shape} and {pos.shape}"
        )
    if "cartesian" in kind:
        x, y, z = pos[:, 0], pos[:, 1], pos[:, 2]
        az_left, el = np.degrees(np.arctan2(y, x)), np.degrees(np.arctan2(z, np.hypot(x, y)))
    else:
        az_left, el = pos[:, 0], pos[:, 1]
    az = (-az_left + 180.0) % 360.0 - 180.0  # SOFA's azimuth turns to the left
    return HRIRSet(sr, az, np.asarray(el, dtype=np.float64), ir, str(p))


def load_hrirs(spec: str, samplerate: int) -> HRIRSet:
    """Return the responses named by ``spec`` (``kemar`` or a SOFA file's path) at ``samplerate`` (Hz)."""
    raw = kemar() if spec.lower() == "kemar" else read_sofa(spec)
    return raw.at_rate(samplerate)
