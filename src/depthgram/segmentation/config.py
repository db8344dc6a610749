"""Configuration of the segmentation stage: one frozen dataclass, loadable from TOML.

:class:`SegmentConfig` keeps every setting as a flat field (the TOML ``[segment]`` keys, and
what the stages read); the settings of each method and step are also grouped in small frozen
classes, read as ``config.histogram``, ``.slices``, ``.planes``, ``.surfaces``, ``.region`` and
``.paper``, and may be given so in TOML (``[segment.paper] min_slices = 4`` for the flat
``paper_min_slices = 4``).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from typing import Any, ClassVar, TypeVar

from depthgram.errors import InputError
from depthgram.segmentation.noise_model import PROFILES

__all__ = [
    "METHODS",
    "RAISED_SUPPORTS",
    "HistogramConfig",
    "PaperConfig",
    "PlaneConfig",
    "RegionConfig",
    "SegmentConfig",
    "SliceConfig",
    "SurfaceConfig",
]

#: Segmentation methods: ``threshold`` (the paper's global histogram), ``slices`` (global
#: histogram for surfaces facing the sensor plus slicing for floor, ceiling, walls and supports),
#: ``region`` (region growing, the paper's reference), ``paper`` (the paper's slicing literally:
#: per-slice histograms joined by successive depth labels, no surface normals).
METHODS = ("surfaces", "slices", "threshold", "region", "paper")
#: Supports the raised pass cuts (``SegmentConfig.raised_supports``).
RAISED_SUPPORTS = ("facing", "all")

#: (field, smallest, largest) of the numeric options checked by :class:`SegmentConfig`; a
#: module constant so that validating a config (once per call with overrides) costs no dict.
_RANGES = (
    ("bin_mm", 0.01, 10_000.0),
    ("ref_depth_mm", 1.0, 1e6),
    ("min_area_fraction", 0.0, 1.0),
    ("slice_aperture_fraction", 1e-6, 1.0),
    ("paper_aperture_fraction", 1e-3, 1.0),
    ("region_tol_mm", 1e-6, 1e5),
    ("oblique_deg", 1.0, 60.0),
    ("jump_rel", 1e-4, 10.0),
    ("plane_min_area", 1e-4, 1.0),
    ("plane_min_spread", 0.0, 10.0),
    ("plane_tol_mm", 0.0, 1e4),
    ("plane_tol_rel", 0.0, 1.0),
    ("side_max_area", 0.0, 1.0),
    ("join_resolutions", 0.5, 100.0),
    ("max_slope_deg", 0.0, 89.0),
    ("crease_deg", 1.0, 89.0),
    ("raised_sigmas", 0.0, 1000.0),
    ("far_mm", 100.0, 1e6),
)

#: Most histogram bins ``far_mm / bin_mm`` may ask for (each costs 32 bytes of counts).
_MAX_BINS = 4e6


@dataclass(frozen=True)
class SegmentConfig:
    """Parameters of :func:`depthgram.segmentation.segment`.

    Attributes
    ----------
    method : str
        ``surfaces`` (default), ``slices``, ``threshold``, ``region`` or ``paper``; see
        :data:`METHODS`. ``surfaces`` finds supports as ``slices`` does and the objects on
        them as depth-continuous surfaces bounded by depth jumps and concave creases
        (:mod:`depthgram.segmentation.surfaces`); ``threshold`` is the paper's method.
    bin_mm : float
        Histogram bin width (mm). Follows the sensor's depth resolution: about 10 mm for the
        paper's 8-bit ToF over 3 m.
    depth_dependent_bins : bool
        When True the bins widen with depth: ``bin_mm`` at ``ref_depth_mm`` and proportional to
        depth elsewhere (log-spaced edges), because ToF noise grows with distance.
    ref_depth_mm : float
        Depth (mm) at which depth-dependent bins are ``bin_mm`` wide.
    fraction : float
        The paper's 10 % rule, in [0, 0.5]: the share of the peak-to-minimum depth difference
        used to place each cut (see ``cut_from``).
    cut_from : str
        ``minimum`` (default): the cut sits ``fraction`` of the peak-to-minimum distance before
        the following minimum, a safety margin against the next object. ``peak``: the cut sits
        ``fraction`` of that distance past the peak. The leading edge of each band is placed
        symmetrically from the preceding minimum. Pixels outside every band are background.
    gap_pixels : str
        What becomes of pixels between two bands (past one band's trailing cut, before the next
        band's leading cut): ``nearest`` (default) gives them to the band on their side of the
        histogram minimum; ``background`` leaves them out, as the paper does (the two are
        compared by ``benchmarks/table1.py --readings``; docs/design-notes.md).
    smooth_bins : float
        Gaussian smoothing of the histogram before peak search (bins, sigma); 0 disables.
    min_prominence : float
        Peak prominence needed, as a fraction of the valid pixel count (0..1), so that noise
        makes no peaks.
    min_area_fraction : float
        Smallest object kept, as a share of the frame's pixels (0..1). The default 0.003
        (920 px at 640 x 480) keeps a ball of 0.5 % of the frame in front of a wall (issue 12)
        without the noise objects of a lower limit on real frames (docs/design-notes.md).
    min_area_px : int
        Smallest object kept, in pixels; the larger of the two limits applies.
    min_area : float or None
        Deprecated (one release): pixels when >= 1, a fraction of the frame when < 1. When
        set it replaces both limits above.
    fill_holes_px : int
        Largest run of invalid pixels (px, along a row or column) bridged when labelling, so
        that an object seen through a sieve of dropouts stays one object. 0 disables.
    slice_aperture_fraction : float
        Slice height or width of a compound's ``part`` objects, as a share of the compound's
        extent across the slices (the paper's rule of thumb: about 10 % of the object
        dimension).
    slice_aperture_px : int
        The same in pixels; when > 0 it replaces the fraction.
    slice_aperture : float or None
        Deprecated (one release): pixels when >= 1, a fraction when < 1.
    slice_directions : str
        ``both``, ``horizontal`` (floor, ceiling, table tops) or ``vertical`` (walls).
    oblique_deg : float
        A surface whose normal is within this angle (degrees) of the vertical image axis is a
        horizontal support (floor, ceiling, table top); within it of the horizontal axis, a wall.
    min_spread : float
        An oblique surface spreads its depth over a plateau of the histogram (paper, section 3):
        a floor, ceiling or wall piece whose depth standard deviation is under this fraction of
        its mean depth is handled as facing the sensor (the flank of a mug near the camera).
    normal_window_px : int
        Side (px) of the box window over which surface orientation is estimated.
    jump_rel : float
        Relative depth step between neighbours (|dZ| / Z) that marks an occlusion edge; the
        orientation there is not estimated.
    region_tol_mm : float
        Region growing: largest depth difference (mm) between joined neighbours.
    region_relative : bool
        Region growing: when True the tolerance scales with depth (``region_tol_mm`` per metre).
    paper_min_slices : int
        ``paper`` method: fewest successive slices (>= 2) over which a run's depth must move the
        same way by more than one histogram bin to count as an oblique surface.
    paper_prominence : float
        ``paper`` method: ``min_prominence`` of each slice's histogram (fraction of the slice's
        valid pixels, 0..1). A slice holds a few hundred pixels, so the global floor would let
        sensor noise make peaks.
    paper_aperture_fraction : float
        ``paper`` method: slice thickness as a share of the image height (horizontal slices) or
        width (vertical slices). The paper asks for about 10 % of the
        expected object dimension; walls and floors span about 30 % of the frame, hence 0.03
        (``benchmarks/table1.py --paper`` compares apertures; docs/design-notes.md).
    paper_aperture_px : int
        The same in pixels; when > 0 it replaces the fraction.
    paper_aperture : float or None
        Deprecated (one release): pixels when >= 1, a fraction when < 1.
    support_planes : bool
        ``slices`` method: also find the dominant oblique planes with a robust fit of
        ``1/Z = a u + b v + c`` (:func:`depthgram.segmentation.ransac.find_planes`), so that a table
        top seen from above at a slant is a support whatever the camera's pitch; its pixels join
        the horizontal (or wall) supports of the orientation field. Planes are searched among
        the pixels the field left facing, so the two complement each other: planes alone lose
        the walls a level camera sees, the field alone misses a table top seen by a camera
        pitched down and merges the table with everything on it (``benchmarks/table1.py
        --tabletop``; docs/design-notes.md).
    plane_min_area : float
        Smallest support plane, as a fraction of the frame (0..1).
    plane_min_spread : float
        Smallest depth spread of a support plane, (95th - 5th percentile) / median depth: a
        flatter plane faces the sensor and is left to the histogram.
    plane_tol_mm : float
        A pixel lies on a support plane within ``max(plane_tol_mm, plane_tol_rel Z)`` (mm).
    plane_tol_rel : float
        Depth-proportional part of that tolerance (structured light noise grows with depth).
    raised_sigmas : float
        ``surfaces``: what stands above a support's plane by this many of the sensor's noise
        sigmas (over a window's mean, plus one quantisation step) is an object of its own,
        however flat (a dish, a book, a screwdriver on a table:
        :mod:`depthgram.segmentation.raised`); 0 leaves every support whole. Which supports are
        cut: ``raised_supports``.
    raised_supports : str
        ``facing`` (the default): a support facing the camera as large as a dominant plane
        (``plane_min_area``), a table seen from straight above (an arm camera), where its
        readings lie at nearly one depth and a thing's rise is read along the view; and a
        horizontal support holding a third of the frame, the scene itself (a table an arm
        camera looks at from 45 degrees, the floor before a chest camera). ``all``: every
        horizontal support (a kitchen's counters seen in passing), asked for (``--raised
        SIGMAS``): a real camera's floors and tables seen at an angle bend and streak by a few
        resolutions over their depths, which it cuts as it would a book, and it costs more
        (the figures are in docs/design-notes.md). A piece of a horizontal support with a third
        of its ring beyond the frame's edge (in a corner) is never cut.
    crease_deg : float
        ``surfaces``: smallest bend (degrees) between two surfaces that makes a concave crease
        (:func:`depthgram.segmentation.creases.concave_creases`), where it stands above the
        sensor's noise. Read through the focal length, so it is set with the margin of the
        scene's own focal estimate (about 10 %): 38 cuts a box lying on a block with the true
        intrinsics as with the estimate (40 cut it only with the estimate; the figures are in
        docs/design-notes.md).
    crease_span_fraction : float
        ``surfaces``: half-span of the concave creases' second difference, as a share of the
        width of the frame segmented (its sampling grid: 320 px for a 640 px frame), at least
        2 px (:func:`depthgram.segmentation.creases.crease_scale_px`). The default 0 follows the
        sensor (:func:`depthgram.segmentation.creases.crease_span_px`): 1/128 for time of
        flight, which finds the creases of objects standing side by side; one pixel past the
        correlation window of a structured-light or stereo camera (a named profile of that
        family, or a frame that reads as one: ``SensorModel.window_fraction``), which spreads
        each bend over that window, so that a box lying on a flat block is cut from it (issue
        28, YCB-Video 0002), and a small piece the wider band left under ``min_area`` is given
        the band's extra width back before it is judged. A share sets the span whatever the
        camera (``[segment] crease_span_fraction = 0.0078125``, the former default, keeps a
        wall's strip apart from a counter on 7-Scenes that the sensor's span joins to it; the
        figures are in docs/design-notes.md).
    work_width_px : int
        ``surfaces``: a frame wider than this is segmented on every ``step``-th pixel and row
        (``step = ceil(width / work_width_px)``: 2 at 640 px, 4 at 1280 px) and each pixel then
        takes the label of the grid sample next to it on its own surface
        (:mod:`depthgram.segmentation.coarse`). 0 segments every pixel.
    far_mm : float
        Far limit (mm): readings at or beyond it are left out as invalid and counted
        (:attr:`Segmentation.beyond_far_px`), which bounds the histogram. 20 m is past every
        indoor depth camera's range (the Azure Kinect's wide mode reaches 5.5 m, a RealSense
        D455 about 10 m).
    """

    method: str = "surfaces"
    bin_mm: float = 10.0
    depth_dependent_bins: bool = False
    ref_depth_mm: float = 1000.0
    fraction: float = 0.10
    cut_from: str = "minimum"
    gap_pixels: str = "nearest"
    smooth_bins: float = 1.0
    min_prominence: float = 0.002
    min_area_fraction: float = 0.003
    min_area_px: int = 1
    min_area: float | None = None
    fill_holes_px: int = 2
    slice_aperture_fraction: float = 0.10
    slice_aperture_px: int = 0
    slice_aperture: float | None = None
    slice_directions: str = "both"
    oblique_deg: float = 35.0
    min_spread: float = 0.05
    normal_window_px: int = 7
    jump_rel: float = 0.05
    region_tol_mm: float = 10.0
    region_relative: bool = True
    paper_min_slices: int = 3
    paper_prominence: float = 0.02
    paper_aperture_fraction: float = 0.03
    paper_aperture_px: int = 0
    paper_aperture: float | None = None
    support_planes: bool = True
    plane_min_area: float = 0.08
    plane_min_spread: float = 0.15
    plane_tol_mm: float = 8.0
    plane_tol_rel: float = 0.012
    max_planes: int = 3
    raised_sigmas: float = 4.0
    raised_supports: str = "facing"
    side_max_area: float = 0.08
    sensor: str = "auto"
    join_resolutions: float = 2.5
    max_slope_deg: float = 70.0
    crease_deg: float = 38.0
    crease_span_fraction: float = 0.0
    work_width_px: int = 320
    far_mm: float = 20_000.0

    def __post_init__(self) -> None:
        def bad(name: str, value: object, expected: str) -> InputError:
            return InputError(f"segment config: {name} = {value!r}, expected {expected}")

        if self.min_area is not None:
            v = self.min_area
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 1e-9 <= v <= 1e9):
                raise bad("min_area", self.min_area, "pixels (>= 1) or a fraction of the frame (< 1)")
            warnings.warn(
                "segment config: min_area is deprecated; use min_area_px (pixels) or min_area_fraction "
                "(share of the frame)",
                DeprecationWarning,
                stacklevel=4,
            )
        if not (isinstance(self.min_area_px, int) and 1 <= self.min_area_px <= 10**9):
            raise bad("min_area_px", self.min_area_px, "an integer number of pixels >= 1")
        if self.sensor != "auto" and self.sensor not in PROFILES:
            raise bad("sensor", self.sensor, f"'auto' or one of {sorted(PROFILES)}")
        if self.method not in METHODS:
            raise bad("method", self.method, f"one of {METHODS}")
        if self.cut_from not in ("minimum", "peak"):
            raise bad("cut_from", self.cut_from, "'minimum' or 'peak'")
        if self.gap_pixels not in ("nearest", "background"):
            raise bad("gap_pixels", self.gap_pixels, "'nearest' or 'background'")
        if self.raised_supports not in RAISED_SUPPORTS:
            raise bad("raised_supports", self.raised_supports, f"one of {RAISED_SUPPORTS}")
        if self.slice_directions not in ("both", "horizontal", "vertical"):
            raise bad("slice_directions", self.slice_directions, "'both', 'horizontal' or 'vertical'")
        for name, lo, hi in _RANGES:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
                raise bad(name, value, f"a number in [{lo}, {hi}]")
        v = self.crease_span_fraction
        if not (isinstance(v, (int, float)) and math.isfinite(v) and (v == 0.0 or 1e-3 <= v <= 0.1)):
            raise bad("crease_span_fraction", v, "0 (follow the sensor) or a share in [0.001, 0.1]")
        if not 0.0 <= self.fraction <= 0.5:
            raise bad("fraction", self.fraction, "a share in [0, 0.5] (the paper uses 0.10)")
        if not 0.0 <= self.min_prominence < 1.0:
            raise bad("min_prominence", self.min_prominence, "a fraction of the valid pixels in [0, 1)")
        if not 0.0 <= self.min_spread < 1.0:
            raise bad("min_spread", self.min_spread, "a fraction of the mean depth in [0, 1)")
        if not 0.0 <= self.smooth_bins <= 50.0:
            raise bad("smooth_bins", self.smooth_bins, "a sigma in bins in [0, 50]")
        if not (isinstance(self.fill_holes_px, int) and 0 <= self.fill_holes_px <= 64):
            raise bad("fill_holes_px", self.fill_holes_px, "an integer number of pixels in [0, 64]")
        if not (isinstance(self.normal_window_px, int) and 3 <= self.normal_window_px <= 101):
            raise bad("normal_window_px", self.normal_window_px, "an integer number of pixels in [3, 101]")
        if not (isinstance(self.paper_min_slices, int) and 2 <= self.paper_min_slices <= 1000):
            raise bad("paper_min_slices", self.paper_min_slices, "an integer number of slices in [2, 1000]")
        if not 0.0 <= self.paper_prominence < 1.0:
            raise bad("paper_prominence", self.paper_prominence, "a fraction of a slice's valid pixels in [0, 1)")
        for old, new in (("slice_aperture", "slice_aperture"), ("paper_aperture", "paper_aperture")):
            v = getattr(self, old)
            if v is None:
                continue
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 1e-3 <= v <= 1e5):
                raise bad(old, v, "pixels (>= 1) or a fraction in [0.001, 1)")
            warnings.warn(
                f"segment config: {old} is deprecated; use {new}_px (pixels) or {new}_fraction",
                DeprecationWarning,
                stacklevel=4,
            )
        for name in ("slice_aperture_px", "paper_aperture_px"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 0 <= v <= 100_000):
                raise bad(name, v, "an integer number of pixels >= 0 (0: use the fraction)")

        if self.far_mm / self.bin_mm > _MAX_BINS:
            raise bad("far_mm", self.far_mm, f"at most {_MAX_BINS:.0e} histogram bins of bin_mm = {self.bin_mm}")
        if not (isinstance(self.work_width_px, int) and 0 <= self.work_width_px <= 100_000):
            raise bad("work_width_px", self.work_width_px, "an integer number of pixels >= 0 (0: every pixel)")
        if not (isinstance(self.max_planes, int) and 0 <= self.max_planes <= 20):
            raise bad("max_planes", self.max_planes, "an integer number of planes in [0, 20]")

    def with_overrides(self, **overrides: Any) -> SegmentConfig:
        """Return a copy with some fields replaced; unknown names raise :class:`InputError`."""
        if not overrides:
            return self
        # the type is part of the key: 2 and 2.0 are equal, but only one may pass the checks
        items = tuple((name, type(value), value) for name, value in sorted(overrides.items()))
        try:
            return _replaced(self, items)
        except TypeError:  # an unhashable value: the checks name it
            return _replaced.__wrapped__(self, items)

    def slice_step(self, extent_px: int) -> int:
        """Thickness (px) of the slices of a compound ``extent_px`` pixels across them."""
        return _step(self.slice_aperture, self.slice_aperture_px, self.slice_aperture_fraction, extent_px, math.ceil)

    def paper_step(self, length_px: int) -> int:
        """Thickness (px) of the ``paper`` method's slices across an image side of ``length_px``."""
        step = _step(self.paper_aperture, self.paper_aperture_px, self.paper_aperture_fraction, length_px, round)
        return min(step, max(1, length_px))

    def min_pixels(self, n_pixels: int) -> int:
        """Smallest object kept (px) in a frame of ``n_pixels`` pixels (at least 1)."""
        if self.min_area is not None:
            if self.min_area >= 1:
                return math.ceil(self.min_area)
            return max(1, math.ceil(self.min_area * n_pixels))
        return max(1, self.min_area_px, math.ceil(self.min_area_fraction * n_pixels))

    @property
    def histogram(self) -> HistogramConfig:
        """The global histogram's settings (every method's depth labels; the ``threshold`` method)."""
        return _group(HistogramConfig, self)

    @property
    def slices(self) -> SliceConfig:
        """The orientation field's and the supports' slicing settings (``slices``, ``surfaces``)."""
        return _group(SliceConfig, self)

    @property
    def planes(self) -> PlaneConfig:
        """The support planes' settings (RANSAC; ``slices``, ``surfaces``)."""
        return _group(PlaneConfig, self)

    @property
    def surfaces(self) -> SurfaceConfig:
        """The ``surfaces`` method's settings: the sensor model and the join rule."""
        return _group(SurfaceConfig, self)

    @property
    def region(self) -> RegionConfig:
        """The ``region`` method's settings (region growing)."""
        return _group(RegionConfig, self)

    @property
    def paper(self) -> PaperConfig:
        """The ``paper`` method's settings (the paper's slicing)."""
        return _group(PaperConfig, self)

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> SegmentConfig:
        """Build from TOML's ``[segment]`` table: flat keys, or groups as tables (``paper = {min_slices = 4}``).

        A group's key is its class's field name; a group given as a table and the same flat
        key together are an error, as are unknown names.
        """
        flat: dict[str, Any] = {}
        for key, value in values.items():
            group = _GROUPS.get(key)
            if group is None:
                flat[key] = value
                continue
            items = dataclasses.asdict(value) if isinstance(value, group) else value
            if not isinstance(items, Mapping):
                raise InputError(f"segment config: {key} must be a table of settings")
            names = {f.name for f in fields(group)}
            unknown = sorted(set(items) - names)
            if unknown:
                raise InputError(f"segment config: unknown {key} setting(s) {unknown}; known: {sorted(names)}")
            for name, v in items.items():
                field_name = group.FLAT[name]
                if field_name in values:
                    raise InputError(f"segment config: {field_name} is given twice ({key}.{name})")
                _check_kind(f"{key}.{name}", v, getattr(_DEFAULT, field_name))
                flat[field_name] = v
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(flat) - known)
        if unknown:
            raise InputError(f"segment config: unknown setting(s) {unknown}; known: {sorted(known)}")
        return cls(**flat)


@dataclass(frozen=True)
class HistogramConfig:
    """The global histogram's settings; see :class:`SegmentConfig` (the same names)."""

    bin_mm: float
    depth_dependent_bins: bool
    ref_depth_mm: float
    fraction: float
    cut_from: str
    gap_pixels: str
    smooth_bins: float
    min_prominence: float

    #: Each field's flat :class:`SegmentConfig` name.
    FLAT: ClassVar[dict[str, str]] = {
        n: n
        for n in (
            "bin_mm", "depth_dependent_bins", "ref_depth_mm", "fraction", "cut_from", "gap_pixels", "smooth_bins",
            "min_prominence",
        )
    }  # fmt: skip


@dataclass(frozen=True)
class SliceConfig:
    """Orientation and slicing settings: ``SegmentConfig.slice_aperture_fraction`` is ``aperture_fraction`` here."""

    aperture_fraction: float
    aperture_px: int
    directions: str
    oblique_deg: float
    min_spread: float
    normal_window_px: int
    jump_rel: float
    side_max_area: float

    FLAT: ClassVar[dict[str, str]] = {
        "aperture_fraction": "slice_aperture_fraction",
        "aperture_px": "slice_aperture_px",
        "directions": "slice_directions",
        "oblique_deg": "oblique_deg",
        "min_spread": "min_spread",
        "normal_window_px": "normal_window_px",
        "jump_rel": "jump_rel",
        "side_max_area": "side_max_area",
    }


@dataclass(frozen=True)
class PlaneConfig:
    """Support-plane settings: ``SegmentConfig.plane_min_area`` is ``min_area`` here, ``support_planes`` ``enabled``."""

    enabled: bool
    min_area: float
    min_spread: float
    tol_mm: float
    tol_rel: float
    max_planes: int

    FLAT: ClassVar[dict[str, str]] = {
        "enabled": "support_planes",
        "min_area": "plane_min_area",
        "min_spread": "plane_min_spread",
        "tol_mm": "plane_tol_mm",
        "tol_rel": "plane_tol_rel",
        "max_planes": "max_planes",
    }


@dataclass(frozen=True)
class SurfaceConfig:
    """The ``surfaces`` method's settings; see :class:`SegmentConfig` (the same names)."""

    sensor: str
    join_resolutions: float
    max_slope_deg: float
    crease_deg: float
    crease_span_fraction: float
    raised_sigmas: float
    raised_supports: str
    work_width_px: int

    FLAT: ClassVar[dict[str, str]] = {
        n: n
        for n in (
            "sensor",
            "join_resolutions",
            "max_slope_deg",
            "crease_deg",
            "crease_span_fraction",
            "raised_sigmas",
            "raised_supports",
            "work_width_px",
        )
    }


@dataclass(frozen=True)
class RegionConfig:
    """Region growing's settings: ``SegmentConfig.region_tol_mm`` is ``tol_mm`` here."""

    tol_mm: float
    relative: bool

    FLAT: ClassVar[dict[str, str]] = {"tol_mm": "region_tol_mm", "relative": "region_relative"}


@dataclass(frozen=True)
class PaperConfig:
    """The ``paper`` method's settings: ``SegmentConfig.paper_min_slices`` is ``min_slices`` here."""

    min_slices: int
    prominence: float
    aperture_fraction: float
    aperture_px: int

    FLAT: ClassVar[dict[str, str]] = {
        "min_slices": "paper_min_slices",
        "prominence": "paper_prominence",
        "aperture_fraction": "paper_aperture_fraction",
        "aperture_px": "paper_aperture_px",
    }


#: The groups of :class:`SegmentConfig`, by the name of the property that reads each.
_GROUPS: dict[str, Any] = {
    "histogram": HistogramConfig,
    "slices": SliceConfig,
    "planes": PlaneConfig,
    "surfaces": SurfaceConfig,
    "region": RegionConfig,
    "paper": PaperConfig,
}


_G = TypeVar("_G")

#: The defaults, whose kinds a grouped setting must have (true/false, a number, text).
_DEFAULT = SegmentConfig()


def _check_kind(name: str, value: object, default: object) -> None:
    """Refuse a grouped setting whose kind differs from its default's, as the flat keys are refused."""
    if isinstance(default, bool):
        ok, expected = isinstance(value, bool), "true or false"
    elif isinstance(default, (int, float)):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        ok = ok and (isinstance(value, int) or not isinstance(default, int))
        expected = "an integer" if isinstance(default, int) else "a number"
    else:
        ok, expected = isinstance(value, str), "text"
    if not ok:
        raise InputError(f"segment config: {name} = {value!r}, expected {expected}")


def _group(group: type[_G], config: SegmentConfig) -> _G:
    """One group of a config's flat fields as its small class."""
    flat: dict[str, str] = group.FLAT  # type: ignore[attr-defined]
    return group(**{name: getattr(config, f) for name, f in flat.items()})


def _step(old: float | None, px: int, fraction: float, length: int, rounding: Any) -> int:
    if old is not None:  # the deprecated two-meaning spelling
        px, fraction = (round(old), 0.0) if old >= 1 else (0, old)
    if px > 0:
        return px
    return max(1, int(rounding(fraction * length)))


@lru_cache(maxsize=64)
def _replaced(config: SegmentConfig, items: tuple[tuple[str, type, Any], ...]) -> SegmentConfig:
    # cached: a real-time caller passing ``method="threshold"`` on every frame would otherwise
    # validate a new config each time, a noticeable share of a small frame's time
    overrides = {name: value for name, _, value in items}
    known = {f.name for f in fields(config)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise InputError(f"segment config: unknown option(s) {unknown}; known: {sorted(known)}")
    return replace(config, **overrides)
