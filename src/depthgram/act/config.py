"""Settings of the action stage: reach, graspable sizes, safety distance, body size, path corridor."""

from __future__ import annotations

import math
from dataclasses import dataclass

from depthgram.errors import InputError

__all__ = ["CHANNEL_CHOICES", "ActConfig"]

#: How the clearance channel is chosen among the openings wide enough for the body.
CHANNEL_CHOICES = ("ahead", "widest")


def _positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise InputError(f"act: {name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class ActConfig:
    """How scene objects become actions and how the clearance channel is found.

    Parameters
    ----------
    reach_mm : float
        Reach distance (mm): an object farther than this (Euclidean, or depth without
        intrinsics) is never proposed for grasping.
    grasp_min_mm, grasp_max_mm : float
        Graspable size range (mm) when intrinsics are known. An object's size is the side of
        the square with its apparent area: ``sqrt(area) * depth / sqrt(fx * fy)``.
    grasp_min_px, grasp_max_px : float
        Graspable size range (px, side of the square of equal area) when no intrinsics are known.
    safety_mm : float
        Safety distance (mm): the clearance channel holds nothing nearer than this.
    lookahead_mm : float
        Obstacles in the path nearer than this (mm) are to be avoided; farther ones monitored.
    body_width_mm : float
        Width of the robot or person (mm) that must pass through the channel.
    body_width_px : float
        Width the channel needs (px) when no intrinsics are known.
    sensor_height_mm : float
        Height of the sensor above the floor (mm); with intrinsics, the band of rows the body
        sweeps is found from it (optical axis assumed horizontal).
    body_height_mm : float
        Height of the top of the body above the floor (mm).
    floor_margin_mm : float
        Points lower than this above the floor (mm) are floor, not obstruction.
    band_rows : tuple of float
        Without intrinsics, the band of rows (fractions of the image height, top to bottom) the
        body sweeps; rows below it are taken as floor.
    path_corridor : tuple of float
        Without intrinsics, the columns (fractions of the image width) that count as "in the
        path". With intrinsics the path is the strip of ``body_width_mm`` straight ahead.
    ttc_warning_s : float
        Time to collision (s, or frames when no frame period is known) below which a warning
        is raised and an object in the path is avoided whatever its depth.
    channel_choice : str
        ``"ahead"``: of the openings wide enough, the one nearest straight ahead (least turning);
        ``"widest"``: the widest.
    unknown_is_free : bool
        Whether a column without any valid reading in the band counts as free. False (default)
        is the cautious choice: no reading may be a black or shiny obstacle, not open space.
    """

    reach_mm: float = 800.0
    grasp_min_mm: float = 20.0
    grasp_max_mm: float = 200.0
    grasp_min_px: float = 3.0
    grasp_max_px: float = 60.0
    safety_mm: float = 1000.0
    lookahead_mm: float = 2000.0
    body_width_mm: float = 600.0
    body_width_px: float = 40.0
    sensor_height_mm: float = 1000.0
    body_height_mm: float = 1800.0
    floor_margin_mm: float = 100.0
    band_rows: tuple[float, float] = (0.15, 0.8)
    path_corridor: tuple[float, float] = (0.3, 0.7)
    ttc_warning_s: float = 2.0
    channel_choice: str = "ahead"
    unknown_is_free: bool = False

    def __post_init__(self) -> None:
        for name in (
            "reach_mm",
            "grasp_max_mm",
            "grasp_max_px",
            "safety_mm",
            "lookahead_mm",
            "body_width_mm",
            "body_width_px",
            "sensor_height_mm",
            "body_height_mm",
            "ttc_warning_s",
        ):
            _positive(name, getattr(self, name))
        for name in ("grasp_min_mm", "grasp_min_px", "floor_margin_mm"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise InputError(f"act: {name} must be a finite number >= 0, got {v!r}")
        if self.grasp_min_mm >= self.grasp_max_mm:
            raise InputError(
                f"act: grasp_min_mm ({self.grasp_min_mm}) must be below grasp_max_mm ({self.grasp_max_mm})"
            )
        if self.grasp_min_px >= self.grasp_max_px:
            raise InputError(
                f"act: grasp_min_px ({self.grasp_min_px}) must be below grasp_max_px ({self.grasp_max_px})"
            )
        if self.floor_margin_mm >= self.body_height_mm:
            raise InputError(
                f"act: floor_margin_mm ({self.floor_margin_mm}) must be below body_height_mm ({self.body_height_mm})"
            )
        for name in ("band_rows", "path_corridor"):
            lo_hi = getattr(self, name)
            if (
                len(lo_hi) != 2
                or not all(isinstance(x, (int, float)) for x in lo_hi)
                or not 0.0 <= lo_hi[0] < lo_hi[1] <= 1.0
            ):
                raise InputError(f"act: {name} must be two fractions 0 <= lo < hi <= 1, got {lo_hi!r}")
        if self.channel_choice not in CHANNEL_CHOICES:
            raise InputError(f"act: channel_choice must be one of {CHANNEL_CHOICES}, got {self.channel_choice!r}")
