"""Structured-light depth (Kinect v1, Asus Xtion, PrimeSense Carmine) as plain functions over arrays.

Such a camera projects a fixed speckle pattern from a projector beside its infrared camera and
measures, per pixel, the pattern's shift (disparity, px) against a reference; depth follows by
triangulation, ``z = f * b / d``. What a segmentation meets on these cameras, and this module
reproduces:

- **Disparity quantisation.** The disparity is matched to 1/8 px, so depth comes in steps that
  grow with the square of the distance: ``dz = z**2 / (f * b) * step`` (about 2.9 mm at 1 m,
  11.5 mm at 2 m and 26 mm at 3 m for f = 580 px, b = 75 mm, step 1/8 px). The depth histogram
  is a comb whose teeth spread apart with distance.
- **Noise in disparity**, so depth noise also grows with z**2 (Khoshelham & Elberink 2012,
  "Accuracy and resolution of Kinect depth data": about 1.5 mm at 1 m to 4 cm at 5 m, a
  disparity noise of about 0.07 px).
- **Projector shadow.** A surface point that the projector cannot light (another surface lies
  between them) carries no pattern and reads invalid. The projector sits ``baseline_mm`` to the
  camera's right (+x in the image), so each occluding edge casts an invalid band on its left
  whose width is ``f * b * (1 / z_front - 1 / z_back)`` px: the disparity difference.
- **Registration holes.** Depth registered to the colour camera is forward-mapped onto a grid
  of a slightly different scale, and target pixels that no source pixel lands on stay empty: a
  lattice of dashed invalid rows and columns every ``scale / (scale - 1)`` px (about 18 px).

The values of valid pixels come from each pixel's own true depth (the sub-pixel misplacement of
registration is not modelled), so the simulator's ground truth stays exact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from depthgram.errors import InputError

__all__ = [
    "StructuredLightConfig",
    "depth_from_disparity",
    "depth_step_mm",
    "disparity_px",
    "measure",
    "registration_holes",
]


@dataclass(frozen=True)
class StructuredLightConfig:
    """Sensor model of a structured-light depth camera (defaults: Kinect v1 / Xtion / PrimeSense).

    Attributes
    ----------
    focal_px : float
        Focal length (px) of the infrared camera that matches the pattern, at its native
        640 x 480: about 580 px on Kinect v1 and Xtion. It sets the depth step; the output
        image keeps the simulated camera's own intrinsics (registered depth).
    baseline_mm : float
        Projector to infrared camera distance (mm), about 75 mm.
    disparity_step_px : float
        Disparity resolution (px): 1/8 px sub-pixel matching.
    disparity_noise_px : float
        Standard deviation of the disparity noise (px) before quantisation.
    min_mm, max_mm : float
        Depth range (mm) read; nearer or farther is invalid.
    shadow : bool
        Pixels the projector cannot light read invalid.
    projector_side : int
        +1: projector on the camera's right (+x, Kinect v1 and Xtion; shadows on the left of
        near objects), -1: on its left.
    registration_scale : float or None
        Ratio of the colour camera's scale to the infrared camera's when the depth is
        registered to colour; > 1 leaves a lattice of empty rows and columns, a share
        ``1 - 1 / scale`` of them (5.7 % at 1.06), half their pixels each. None: depth in
        the infrared camera's own frame, no holes.
    """

    focal_px: float = 580.0
    baseline_mm: float = 75.0
    disparity_step_px: float = 0.125
    disparity_noise_px: float = 0.07
    min_mm: float = 400.0
    max_mm: float = 8000.0
    shadow: bool = True
    projector_side: int = 1
    registration_scale: float | None = 1.06

    def __post_init__(self) -> None:
        def bad(what: str) -> InputError:
            return InputError(f"StructuredLightConfig: {what}")

        for name, v in (
            ("focal_px", self.focal_px),
            ("baseline_mm", self.baseline_mm),
            ("disparity_step_px", self.disparity_step_px),
        ):
            if not (np.isfinite(v) and v > 0):
                raise bad(f"{name} must be a positive number, got {v}")
        if not (np.isfinite(self.disparity_noise_px) and self.disparity_noise_px >= 0):
            raise bad(f"disparity_noise_px must be >= 0 px, got {self.disparity_noise_px}")
        if not (0 <= self.min_mm < self.max_mm and np.isfinite(self.max_mm)):
            raise bad(f"depth range must have 0 <= min_mm < max_mm, got {self.min_mm}..{self.max_mm}")
        if self.projector_side not in (-1, 1):
            raise bad(f"projector_side must be +1 (right) or -1 (left), got {self.projector_side}")
        if self.registration_scale is not None and not (1.0 <= self.registration_scale <= 2.0):
            raise bad(f"registration_scale must be in [1, 2] or None, got {self.registration_scale}")


def disparity_px(depth_mm: ArrayLike, cfg: StructuredLightConfig) -> NDArray[np.float64]:
    """Disparity ``f * b / z`` (px) of depths (mm); 0 where the depth is not positive."""
    z = np.asarray(depth_mm, dtype=np.float64)
    out = np.zeros(z.shape)
    np.divide(cfg.focal_px * cfg.baseline_mm, z, out=out, where=z > 0)
    return out


def depth_from_disparity(disp_px: ArrayLike, cfg: StructuredLightConfig) -> NDArray[np.float64]:
    """Depth ``f * b / d`` (mm) of disparities (px); 0 where the disparity is not positive."""
    d = np.asarray(disp_px, dtype=np.float64)
    out = np.zeros(d.shape)
    np.divide(cfg.focal_px * cfg.baseline_mm, d, out=out, where=d > 0)
    return out


def depth_step_mm(depth_mm: ArrayLike, cfg: StructuredLightConfig) -> NDArray[np.float64]:
    """Spacing (mm) of the depths the camera can report near ``depth_mm``: ``z**2 / (f b) * step``.

    To first order in the step; the exact spacing between the two levels around z differs
    by a fraction ``step / d`` of it (0.2 % at 1 m).
    """
    z = np.asarray(depth_mm, dtype=np.float64)
    return z * z / (cfg.focal_px * cfg.baseline_mm) * cfg.disparity_step_px


def measure(
    true_depth_mm: ArrayLike, cfg: StructuredLightConfig, rng: np.random.Generator | None = None
) -> NDArray[np.float32]:
    """Measured depth (mm, 0 invalid) of true depths: disparity noise, 1/8 px quantisation, range.

    Parameters
    ----------
    true_depth_mm : array_like
        True depth along the optical axis (mm), 0 where no surface.
    cfg : StructuredLightConfig
        The sensor.
    rng : numpy.random.Generator, optional
        Noise source; None: no noise (quantisation and range remain).
    """
    z = np.asarray(true_depth_mm, dtype=np.float64)
    d = disparity_px(z, cfg)
    if rng is not None and cfg.disparity_noise_px > 0:
        d = d + rng.normal(0.0, cfg.disparity_noise_px, d.shape) * (d > 0)
    d = np.rint(d / cfg.disparity_step_px) * cfg.disparity_step_px
    depth = depth_from_disparity(d, cfg)
    depth[(z <= 0) | (depth < cfg.min_mm) | (depth > cfg.max_mm)] = 0.0
    return depth.astype(np.float32)


def registration_holes(shape: tuple[int, int], scale: float | None) -> NDArray[np.bool_]:
    """Pixels left empty when an image of ``shape`` is forward-mapped at ``scale`` about its centre.

    Each source pixel (u, v) lands on the target pixel nearest to
    ``c + scale * ((u, v) - c)``; with scale > 1 some target rows and columns receive none.
    The missed rows and columns form a lattice; the holes are every other pixel along them
    (dashed lines), as the rounding of the real mapping, which also shifts with depth, leaves
    them: a 4-connected labelling is cut there, an 8-connected one is not.
    """
    h, w = shape
    holes = np.zeros(shape, bool)
    if scale is None or scale == 1.0:
        return holes
    for axis, n in ((0, h), (1, w)):
        c = (n - 1) / 2.0
        hit = np.zeros(n, bool)
        target = np.rint(c + scale * (np.arange(n) - c)).astype(np.int64)
        hit[target[(target >= 0) & (target < n)]] = True
        if axis == 0:
            holes[~hit, :] = True
        else:
            holes[:, ~hit] = True
    rows, cols = np.indices(shape)
    dashed: NDArray[np.bool_] = holes & ((rows + cols) % 2 == 0)
    return dashed
