"""How scene attributes become sound: a selectable, documented mapping with named presets.

The cues follow what studies with blind users of sonification devices support: stereo pan for
horizontal position, loudness and the repetition rate of a short beep for nearness, pitch for
height, timbre for size. Only the few parsed objects sound, never the pixels: users of
pixel-scanning devices report overload. See ``docs/sound-mapping.md`` for the listener's table.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from depthgram.errors import InputError

__all__ = ["PRESETS", "SCANS", "SoundMapping"]

#: Order in which a frame's objects first sound: by column, by depth, or all at once.
SCANS = ("left_to_right", "nearest_first", "none")


@dataclass(frozen=True)
class SoundMapping:
    """The mapping from object attributes to sound cues.

    Parameters
    ----------
    name : str
        Preset name this mapping came from (informative only).
    near_mm, far_mm : float
        Depth range (mm) over which nearness goes from 1 (at ``near_mm`` or nearer) to 0 (at
        ``far_mm`` or farther).
    gain_near_db, gain_far_db : float
        Loudness (dB relative to full voice) of the nearest and the farthest object.
    rate_near_hz, rate_far_hz : float
        Beep repetition rate (Hz) of the nearest and the farthest object.
    ttc_alert : float
        Time to collision (s, or frames) below which an approaching object's pulse speeds up:
        its rate becomes at least ``rate_near_hz * ttc_alert / ttc``.
    rate_max_hz : float
        Ceiling on the beep rate (Hz), however near or fast the object.
    pitch_low_hz, pitch_high_hz : float
        Pitch (Hz) of an object at the bottom and at the top of the image; log scale between.
    beep_min_s, beep_max_s : float
        Beep length (s) of the smallest and of the largest object (by area).
    harmonics_max : int
        Harmonics (1/k amplitudes) of the largest object; the smallest is a pure tone.
    area_full : float
        Area fraction of the frame at which an object counts as largest.
    duty_max : float
        Longest beep as a share of the pulse period, so that beeps stay separate.
    glide_gain_db : float
        Loudness (dB) of the gliding tone of oblique surfaces (walls, floor, compounds) relative
        to an object at the same nearness.
    glide_octaves : float
        Pitch span (octaves) of the glide of a surface running from ``near_mm`` to ``far_mm``.
    glide_period_s : float
        Time (s) of one glide from the surface's near end to its far end and back.
    pan_width : float
        Stereo width: 1 uses the full left-right range, 0 puts everything in the middle.
    scan : str
        One of :data:`SCANS`: the order in which objects start within ``scan_s`` after they
        appear (left to right by default).
    scan_s : float
        Spread (s) of those first onsets.
    max_voices : int
        Most objects that sound at once (the nearest ones).
    max_glides : int
        Most oblique surfaces that sound at once (the nearest ones).
    master_gain : float
        Linear gain of one full voice before the soft limiter (headroom for several voices), in
        (0, 1]: above full scale the limiter turns every voice into a loud square wave.
    ramp_s : float
        Time (s) over which a voice's parameters move to a new frame's values, and a new or
        vanishing voice fades; keeps the stream free of clicks.
    ttc_floor_s : float
        Time to collision (s) at which the warning's beep rate reaches ``rate_max_hz``: between
        ``ttc_alert`` and this the rate keeps rising (geometrically), so the last second before
        an impact still changes.
    pan_azimuth_deg : float
        Azimuth (degrees from straight ahead) heard hard left or right when the camera's
        intrinsics are known; nearer directions pan in proportion.
    confirm_frames : int
        Frames in a row a tracked object must be seen before it gets a voice in a stream (an
        approaching object gets one at once).
    facing_area : float
        Fraction of the view from which an object is a surface facing the camera (a wall
        ahead): in a stream it hums steadily among the surfaces instead of beeping.
    hold_frames : int
        Frames a stream's voice waits, on its last parameters, for its lost object to be found
        again (by the tracker, or as a new track where it was) before it fades out.
    min_semitones, min_pan, min_rate_ratio : float
        Two voices sounding together differ by at least ``min_semitones`` in pitch, or
        ``min_pan`` in pan position (0 left .. 1 right), or a factor ``min_rate_ratio`` in beep
        rate; in a stream, pitch moves on a ladder of ``min_semitones`` steps to keep them apart.
    elevation_range_deg : float
        When the camera's gravity is known, pitch follows each direction's elevation above the
        horizon (degrees) instead of its image row: ``pitch_high_hz`` at this elevation and above,
        ``pitch_low_hz`` as far below (:meth:`pitch_elevation`).
    """

    name: str = "default"
    near_mm: float = 300.0
    far_mm: float = 4000.0
    gain_near_db: float = 0.0
    gain_far_db: float = -24.0
    rate_near_hz: float = 8.0
    rate_far_hz: float = 1.5
    ttc_alert: float = 3.0
    rate_max_hz: float = 16.0
    pitch_low_hz: float = 220.0
    pitch_high_hz: float = 880.0
    beep_min_s: float = 0.03
    beep_max_s: float = 0.12
    harmonics_max: int = 4
    area_full: float = 0.25
    duty_max: float = 0.6
    glide_gain_db: float = -10.0
    glide_octaves: float = 1.0
    glide_period_s: float = 1.0
    pan_width: float = 1.0
    scan: str = "left_to_right"
    scan_s: float = 0.25
    max_voices: int = 4
    max_glides: int = 3
    master_gain: float = 0.35
    ramp_s: float = 0.02
    ttc_floor_s: float = 0.5
    pan_azimuth_deg: float = 45.0
    confirm_frames: int = 3
    hold_frames: int = 10
    facing_area: float = 0.4
    min_semitones: float = 3.0
    min_pan: float = 0.2
    min_rate_ratio: float = 1.5
    elevation_range_deg: float = 30.0

    def __post_init__(self) -> None:
        def bad(what: str) -> InputError:
            return InputError(f"sound mapping {self.name!r}: {what}")

        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.type in ("float", "int") and (
                isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
            ):
                raise bad(f"{f.name} must be a finite number, got {v!r}")
        for name in (
            "near_mm",
            "rate_near_hz",
            "rate_far_hz",
            "ttc_alert",
            "rate_max_hz",
            "pitch_low_hz",
            "beep_min_s",
            "area_full",
            "glide_period_s",
            "master_gain",
            "ramp_s",
            "ttc_floor_s",
            "min_semitones",
            "elevation_range_deg",
        ):
            if getattr(self, name) <= 0:
                raise bad(f"{name} must be > 0, got {getattr(self, name)!r}")
        if self.master_gain > 1.0:
            # above full scale every voice is clipped into a square wave at full level: a hearing risk
            raise bad(f"master_gain must be at most 1 (full scale), got {self.master_gain!r}")
        if self.far_mm <= self.near_mm:
            raise bad(f"far_mm ({self.far_mm}) must exceed near_mm ({self.near_mm})")
        if self.pitch_high_hz <= self.pitch_low_hz or self.pitch_high_hz > 8000:
            raise bad(f"pitch range must be low < high <= 8000 Hz, got {self.pitch_low_hz}..{self.pitch_high_hz}")
        if self.beep_max_s < self.beep_min_s or self.beep_max_s > 1.0:
            raise bad(f"beep length must be min <= max <= 1 s, got {self.beep_min_s}..{self.beep_max_s}")
        if not max(self.rate_near_hz, self.rate_far_hz) <= self.rate_max_hz <= 50:
            raise bad(f"rate_max_hz must be in [max(rate_near_hz, rate_far_hz), 50], got {self.rate_max_hz}")
        if not 1 <= self.harmonics_max <= 16 or int(self.harmonics_max) != self.harmonics_max:
            raise bad(f"harmonics_max must be an integer in 1..16, got {self.harmonics_max!r}")
        if not 0 < self.duty_max < 1:
            raise bad(f"duty_max must be in (0, 1), got {self.duty_max}")
        if not 0 <= self.pan_width <= 1:
            raise bad(f"pan_width must be in [0, 1], got {self.pan_width}")
        if self.gain_near_db > 0 or self.gain_far_db > self.gain_near_db or self.glide_gain_db > 0:
            raise bad("gains must satisfy gain_far_db <= gain_near_db <= 0 and glide_gain_db <= 0 (dB)")
        if self.glide_octaves < 0 or self.scan_s < 0:
            raise bad("glide_octaves and scan_s must be >= 0")
        if self.ttc_floor_s >= self.ttc_alert:
            raise bad(f"ttc_floor_s ({self.ttc_floor_s}) must be under ttc_alert ({self.ttc_alert})")
        if not 0 < self.pan_azimuth_deg <= 90:
            raise bad(f"pan_azimuth_deg must be in (0, 90], got {self.pan_azimuth_deg}")
        if int(self.confirm_frames) != self.confirm_frames or not 1 <= self.confirm_frames <= 300:
            raise bad(f"confirm_frames must be an integer in 1..300, got {self.confirm_frames!r}")
        if int(self.hold_frames) != self.hold_frames or not 0 <= self.hold_frames <= 300:
            raise bad(f"hold_frames must be an integer in 0..300, got {self.hold_frames!r}")
        if not 0 < self.facing_area <= 1:
            raise bad(f"facing_area must be in (0, 1], got {self.facing_area}")
        if not 0 <= self.min_pan <= 1 or self.min_rate_ratio < 1:
            raise bad(f"min_pan must be in [0, 1] and min_rate_ratio >= 1, got {self.min_pan}, {self.min_rate_ratio}")
        if self.scan not in SCANS:
            raise bad(f"scan must be one of {SCANS}, got {self.scan!r}")
        for name in ("max_voices", "max_glides"):
            v = getattr(self, name)
            if int(v) != v or not 0 <= v <= 32:
                raise bad(f"{name} must be an integer in 0..32, got {v!r}")

    @classmethod
    def preset(cls, name: str) -> SoundMapping:
        """Return a named preset: ``default``, ``calm`` or ``detailed`` (see :data:`PRESETS`)."""
        try:
            values = PRESETS[name]
        except KeyError:
            raise InputError(f"unknown sound preset {name!r}; expected one of {sorted(PRESETS)}") from None
        return cls(name=name, **values)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SoundMapping:
        """Build from a dict (a TOML table).

        ``preset`` (or ``name``) picks the base preset, the other keys override it; unknown keys
        are errors.
        """
        d = dict(data)
        base = str(d.pop("preset", d.get("name", "default")))
        fields = {f.name for f in dataclasses.fields(cls)}
        unknown = set(d) - fields
        if unknown:
            raise InputError(f"sound mapping: unknown setting(s) {sorted(unknown)}; known: {sorted(fields)}")
        values = {**PRESETS.get(base, {}), **d} if base in PRESETS else None
        if values is None:
            raise InputError(f"unknown sound preset {base!r}; expected one of {sorted(PRESETS)}")
        values.setdefault("name", base)
        return cls(**values)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of every setting (round-trips through :meth:`from_dict`)."""
        return dataclasses.asdict(self)

    # -- the cue functions: one place that says what each attribute sounds like -----------

    def nearness(self, depth_mm: float) -> float:
        """1 at ``near_mm`` or nearer, 0 at ``far_mm`` or farther, linear between."""
        return min(max((self.far_mm - depth_mm) / (self.far_mm - self.near_mm), 0.0), 1.0)

    def gain(self, depth_mm: float) -> float:
        """Linear amplitude of a voice at this depth (mm)."""
        db = self.gain_far_db + (self.gain_near_db - self.gain_far_db) * self.nearness(depth_mm)
        return float(10.0 ** (db / 20.0))  # float ** float is typed Any (it may be complex)

    def rate(self, depth_mm: float, ttc: float | None = None) -> float:
        """Beep repetition rate (Hz) at this depth (mm), sped up by a short time to collision."""
        r = self.rate_far_hz + (self.rate_near_hz - self.rate_far_hz) * self.nearness(depth_mm)
        if ttc is not None and 0 < ttc < self.ttc_alert:
            # Geometric from rate_near_hz at ttc_alert to rate_max_hz at ttc_floor_s: every halving
            # of the time left speeds the beep by the same ratio, down to the floor.
            k = math.log(self.rate_max_hz / self.rate_near_hz) / math.log(self.ttc_alert / self.ttc_floor_s)
            r = max(r, self.rate_near_hz * (self.ttc_alert / max(ttc, self.ttc_floor_s)) ** k)
        return min(r, self.rate_max_hz)

    def pitch(self, y: float, height: int) -> float:
        """Pitch (Hz) of an image row: ``pitch_high_hz`` at the top row, ``pitch_low_hz`` at the bottom."""
        up = 1.0 - min(max(y / max(height - 1, 1), 0.0), 1.0)
        return float(self.pitch_low_hz * (self.pitch_high_hz / self.pitch_low_hz) ** up)

    def pitch_elevation(self, elevation_deg: float) -> float:
        """Pitch (Hz) of a direction's elevation above the horizon (degrees).

        ``pitch_high_hz`` at ``elevation_range_deg`` above the horizon and higher, ``pitch_low_hz``
        as far below, the geometric middle on the horizon: height heard against the world, not
        against the image, so tilting the camera does not move the pitch of what stays put.
        """
        up = 0.5 + 0.5 * min(max(elevation_deg / self.elevation_range_deg, -1.0), 1.0)
        return float(self.pitch_low_hz * (self.pitch_high_hz / self.pitch_low_hz) ** up)

    def pan(self, x: float, width: int) -> tuple[float, float]:
        """Equal-power (left, right) amplitudes of an image column."""
        p = min(max(x / max(width - 1, 1), 0.0), 1.0)
        p = 0.5 + (p - 0.5) * self.pan_width
        return math.cos(p * math.pi / 2), math.sin(p * math.pi / 2)

    def pan_azimuth(self, azimuth_rad: float) -> tuple[float, float]:
        """Equal-power (left, right) amplitudes of a direction (rad, positive to the right)."""
        a = math.degrees(azimuth_rad) / self.pan_azimuth_deg
        p = 0.5 + 0.5 * min(max(a, -1.0), 1.0) * self.pan_width
        return math.cos(p * math.pi / 2), math.sin(p * math.pi / 2)

    def weight(self, area_fraction: float) -> tuple[int, float]:
        """(harmonics, beep length in s) of an object covering this fraction of the frame."""
        s = math.sqrt(min(max(area_fraction / self.area_full, 0.0), 1.0))
        return 1 + round(s * (self.harmonics_max - 1)), self.beep_min_s + s * (self.beep_max_s - self.beep_min_s)


#: Named presets: the overrides of each on the defaults above.
PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    # Fewer, slower, softer cues for long use; pure tones in one octave.
    "calm": {
        "rate_near_hz": 4.0,
        "rate_far_hz": 1.0,
        "rate_max_hz": 8.0,
        "pitch_low_hz": 262.0,
        "pitch_high_hz": 523.0,
        "harmonics_max": 1,
        "beep_max_s": 0.15,
        "beep_min_s": 0.06,
        "gain_far_db": -18.0,
        "glide_gain_db": -16.0,
        "max_voices": 3,
        "max_glides": 1,
        "scan_s": 0.4,
        "pan_width": 0.8,
    },
    # More objects, three octaves of pitch and richer timbre for trained listeners.
    "detailed": {
        "rate_near_hz": 12.0,
        "rate_far_hz": 1.0,
        "rate_max_hz": 20.0,
        "pitch_low_hz": 165.0,
        "pitch_high_hz": 1320.0,
        "harmonics_max": 6,
        "gain_far_db": -30.0,
        "glide_gain_db": -8.0,
        "glide_octaves": 1.5,
        "max_voices": 10,
        "max_glides": 4,
        "beep_min_s": 0.02,
        "beep_max_s": 0.1,
        "master_gain": 0.3,
    },
}
