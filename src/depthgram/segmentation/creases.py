"""Concave creases: the inside corners where an object stands against another.

A plane is affine in inverse depth, so the second difference of inverse depth is zero on any
plane and positive across an inside corner; a crease separates two surfaces in
:func:`depthgram.segmentation.surfaces.label_surfaces` (the labeller state of
:func:`crease_state`). A convex edge does not separate, as in the convexity rule of LCCP (Stein
et al., CVPR 2014).
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.segmentation._kernels import creases as kernels_creases
from depthgram.segmentation._kernels.creases import inverse_depth
from depthgram.segmentation.label import ACTIVE, BLOCK, HOLE
from depthgram.segmentation.noise_model import SensorModel

__all__ = [
    "concave_creases",
    "crease_scale_px",
    "crease_span_px",
    "crease_state",
    "inverse_depth",
    "surface_state",
    "warm_up",
]


def crease_scale_px(width_px: int, fraction: float = 1.0 / 128.0) -> int:
    """Distance (px) over which creases are looked for: ``fraction`` of the frame width, at least 2.

    A crease is a change of slope; it must be judged over a span wider than the sensor's
    smoothing (structured light correlates over 7-9 px windows) yet narrower than the objects.
    1/128 is 2 px on the 320 px sampling grid of a 640 px frame, inside that window: what a
    camera without one takes (:func:`crease_span_px`).
    """
    return max(2, round(width_px * fraction))


def crease_span_px(width_px: int, sensor: SensorModel, fraction: float = 0.0) -> int:
    """Half-span (px) of the concave creases' second difference on a frame of this sensor.

    Parameters
    ----------
    width_px : int
        Width (px) of the frame segmented (its sampling grid: 320 px for a 640 px frame).
    sensor : SensorModel
        Its ``window_fraction`` (share of the frame width) is the window each reading is a mean
        over: 0 for time of flight.
    fraction : float
        Half-span as a share of ``width_px`` when given (``SegmentConfig.crease_span_fraction``,
        :func:`crease_scale_px`); 0 follows the sensor.

    Returns
    -------
    int
        Half-span (px on the segmented frame), at least 2.

    Notes
    -----
    A structured-light or stereo camera reads each pixel as a mean over its correlation window
    (7-9 px at 640 px), so a bend of the surface comes out as a curve spread over the window,
    and a second difference whose half-span lies inside it sees only part of the turn (issue 28:
    YCB-Video 0002's box lying on a block, 2 px on the 320 px grid of its 640 px frames, 4 frame
    px, merges with it). The half-span is set one pixel past the window (5 px on that grid, 10
    frame px for a 9 px window): the two points it compares each lie on a face beyond the
    window's reach of the crease. A time-of-flight pixel is measured on its own: the span stays
    ``round(width / 128)``, which finds the creases of objects standing side by side.
    """
    if fraction > 0.0:
        return crease_scale_px(width_px, fraction)
    r = crease_scale_px(width_px)
    if sensor.window_fraction > 0.0:
        # one pixel past the window, so that neither end of the span reads the bend
        r = max(r, math.floor(sensor.window_fraction * width_px) + 1)
    return r


def concave_creases(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    sensor: SensorModel,
    *,
    scale_px: int,
    min_angle_deg: float,
    focal_px: float,
    inverse: NDArray[np.float32] | None = None,
) -> NDArray[np.bool_]:
    """Pixels on a concave crease (an inside corner seen from the camera).

    Parameters
    ----------
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm), 0 where invalid.
    valid : ndarray of bool
        Pixels with a reading.
    sensor : SensorModel
        Sets the noise floor of the test.
    scale_px : int
        Half-span (px) of the second difference.
    min_angle_deg : float
        Smallest bend (degrees) between the two surfaces that counts as a crease, for a surface
        facing the sensor.
    focal_px : float
        Focal length (px).
    inverse : ndarray of float32, shape (2, H, W), optional
        ``1000 / depth_mm`` and the readings (1 / 0) of this frame as :func:`inverse_depth` gives
        them, when the caller has them (the orientation field takes the same): read where the
        creases are taken on every pixel.

    Returns
    -------
    ndarray of bool, shape (H, W)

    Notes
    -----
    A plane is affine in inverse depth ``w = 1/z`` (see :mod:`depthgram.segmentation.orientation`),
    so the second difference ``w(p - r e) + w(p + r e) - 2 w(p)`` is zero on any plane whatever
    its slant, positive where the surface bends away from the camera on both sides (concave,
    an inside corner: depth has a ridge) and negative where it bends toward it (convex). Divided
    by ``w``, a bend between two surfaces with slopes ``tan a`` and ``tan b`` toward the camera
    gives about ``r (tan a + tan b) / f`` whatever the depth. It is taken along rows, columns
    and both diagonals of a valid-weighted box mean; a span across a depth jump is skipped (it
    is an occlusion edge, not a crease). The threshold is the larger of the bend of
    ``min_angle_deg`` and four times the noise of the smoothed second difference.
    """
    if depth_mm.shape[1] > 320 and scale_px >= 4:
        # a crease is a band about 2 r wide: on every 2nd pixel of a wide frame it is found at
        # a quarter of the cost, with half the span and focal length
        sub = concave_creases(
            np.ascontiguousarray(depth_mm[::2, ::2]),
            np.ascontiguousarray(valid[::2, ::2]),
            sensor,
            scale_px=scale_px // 2,
            min_angle_deg=min_angle_deg,
            focal_px=focal_px / 2.0,
        )
        h, w = depth_mm.shape
        wide: NDArray[np.bool_] = sub.repeat(2, axis=0).repeat(2, axis=1)[:h, :w] & valid
        return wide
    k, geom, noise_scale = _crease_factors(scale_px, min_angle_deg, focal_px)
    if not _compiled_model(sensor):
        return _creases_numpy(depth_mm, valid, sensor, scale_px, k, geom, noise_scale)
    im, ok, c32, min_den, r = _crease_inputs(depth_mm, valid, sensor, scale_px, k, inverse)
    # the labeller state with every reading facing blocks exactly at the creases (one kernel
    # per route for the state and the crease map)
    state, exact = kernels_creases.crease_state_window(im, ok, ok, c32, min_den, k, r, geom, noise_scale)
    if not exact:
        state = kernels_creases.crease_state_from_sums(_window_sums(im, k), ok, ok, c32, min_den, r, geom, noise_scale)
    out: NDArray[np.bool_] = state == BLOCK
    return out


def _crease_factors(scale_px: int, min_angle_deg: float, focal_px: float) -> tuple[int, np.float32, np.float32]:
    """Return the creases' window width (px), bend of ``min_angle_deg`` over the span, and noise factor."""
    k = 2 * (scale_px // 2) + 1
    geom = np.float32(scale_px * math.tan(math.radians(min_angle_deg)) / focal_px)
    noise_scale = np.float32(math.sqrt(6.0) / (0.7 * k))
    return k, geom, noise_scale


def _compiled_model(sensor: SensorModel) -> bool:
    """Whether the compiled creases repeat this model's arithmetic (else the numpy route).

    A model's coefficients are float values: numpy float scalars are taken as the floats they
    hold, whose float32 arithmetic the compiled route repeats (the numpy route would compute in
    float64 with them: strong scalars). Only another model's arithmetic, or coefficients of
    another kind, go the numpy way.
    """
    coefs = (sensor.step_0, sensor.step_2, sensor.sigma_0, sensor.sigma_2)
    plain = all(type(c) in (int, float, np.float64, np.float32) for c in coefs)
    return plain and type(sensor).resolution is SensorModel.resolution


def _crease_inputs(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    sensor: SensorModel,
    scale_px: int,
    k: int,
    inverse: NDArray[np.float32] | None,
) -> tuple[Any, ...]:
    # the compiled route's arguments: 1000 / z and the readings (2, H, W), the readings,
    # coefficients, the least count of readings, span
    z = np.ascontiguousarray(depth_mm, np.float32)
    ok = np.ascontiguousarray(valid, np.bool_)
    im = inverse if inverse is not None else inverse_depth(z, ok)
    # the sensor's coefficients as float32, as numpy's scalar rules make Python floats in
    # _creases_numpy
    coefs = (sensor.step_0, sensor.step_2, sensor.sigma_0, sensor.sigma_2)
    c32 = np.array([float(c) for c in coefs], np.float32)
    return im, ok, c32, np.float32(0.5 * k * k), int(scale_px)


def _window_sums(im: NDArray[np.float32], k: int) -> NDArray[np.float32]:
    # OpenCV's k x k window sums of 1000 / z and the readings, for a frame whose values
    # window.exact_rows refused: both from one two-channel filter (the same sums as one
    # filter each, a test)
    img = cv2.merge([im[0], im[1]])
    return np.asarray(cv2.boxFilter(img, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT), np.float32)


def crease_state(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    facing: NDArray[np.bool_],
    sensor: SensorModel,
    *,
    scale_px: int,
    min_angle_deg: float,
    focal_px: float,
    inverse: NDArray[np.float32] | None = None,
) -> NDArray[np.int8]:
    """Labeller state of :func:`label_surfaces` with the frame's concave creases blocking.

    ``surface_state(valid, facing, concave_creases(...))`` (the same arguments), in one
    compiled call where :func:`concave_creases` takes its compiled route: the creases go to
    the state row by row, without a crease map.
    """
    wide = depth_mm.shape[1] > 320 and scale_px >= 4
    if wide or not _compiled_model(sensor):
        creases = concave_creases(
            depth_mm, valid, sensor, scale_px=scale_px, min_angle_deg=min_angle_deg, focal_px=focal_px, inverse=inverse
        )
        return surface_state(np.ascontiguousarray(valid, np.bool_), np.ascontiguousarray(facing, np.bool_), creases)
    k, geom, noise_scale = _crease_factors(scale_px, min_angle_deg, focal_px)
    im, ok, c32, min_den, r = _crease_inputs(depth_mm, valid, sensor, scale_px, k, inverse)
    face = np.ascontiguousarray(facing, np.bool_)
    # the window sums taken row by row in the same call, OpenCV's to the last bit where
    # window.exact_rows holds (always on real frames so far), else OpenCV's
    # kept (issue 31): with the orientation field's, OpenCV's route alone was 8-10 % slower end to end
    state, exact = kernels_creases.crease_state_window(im, ok, face, c32, min_den, k, r, geom, noise_scale)
    if exact:
        return state
    return kernels_creases.crease_state_from_sums(_window_sums(im, k), ok, face, c32, min_den, r, geom, noise_scale)


def _creases_numpy(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    sensor: SensorModel,
    scale_px: int,
    k: int,
    geom: np.float32,
    noise_scale: np.float32,
) -> NDArray[np.bool_]:
    """:func:`concave_creases` at full resolution in numpy.

    The reference of the compiled crease kernels (``_kernels.creases``), and the route for a
    sensor model whose arithmetic it does not know.
    """
    h, w = depth_mm.shape
    inv = np.zeros((h, w), np.float32)
    np.divide(np.float32(1000.0), depth_mm, out=inv, where=valid)
    m = valid.astype(np.float32)
    den = np.asarray(cv2.boxFilter(m, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT), np.float32)
    ws = np.asarray(cv2.boxFilter(inv, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT), np.float32)
    has = den >= 0.5 * k * k
    np.divide(ws, den, out=ws, where=has)
    ws[~has] = 0.0
    z = np.zeros_like(ws)
    np.divide(np.float32(1000.0), ws, out=z, where=has)
    # relative noise of w equals that of z; a mean over ~k*k/2 readings and a second difference
    # of three such means (variance 6x)
    rel_noise = np.asarray(sensor.resolution(z), np.float32) / 2.0 / np.maximum(z, 1.0)
    noise = rel_noise * noise_scale
    thr = np.maximum(geom, 4.0 * noise)
    out = np.zeros((h, w), np.bool_)
    r = scale_px
    jump = np.float32(0.06)
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a, ha = _shifted(ws, has, dy * r, dx * r)
        b, hb = _shifted(ws, has, -dy * r, -dx * r)
        sec = (a + b) - 2.0 * ws
        ok = has & ha & hb
        ok &= np.abs(a - ws) <= jump * ws
        ok &= np.abs(b - ws) <= jump * ws
        out |= ok & (sec > thr * ws)
    return out & valid


def _shifted(
    img: NDArray[np.float32], has: NDArray[np.bool_], dy: int, dx: int
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """``img[y + dy, x + dx]`` at every pixel, with ``False`` validity outside the frame."""
    h, w = img.shape
    out = np.zeros_like(img)
    ok = np.zeros_like(has)
    ys, yd = (slice(dy, h), slice(0, h - dy)) if dy >= 0 else (slice(0, h + dy), slice(-dy, h))
    xs, xd = (slice(dx, w), slice(0, w - dx)) if dx >= 0 else (slice(0, w + dx), slice(-dx, w))
    out[yd, xd] = img[ys, xs]
    ok[yd, xd] = has[ys, xs]
    return out, ok


def surface_state(valid: NDArray[np.bool_], facing: NDArray[np.bool_], creases: NDArray[np.bool_]) -> NDArray[np.int8]:
    """Labeller state of :func:`depthgram.segmentation.surfaces.label_surfaces`.

    Facing pixels off a crease are active, other readings block, pixels without a reading are
    holes.
    """
    state = np.where(facing & ~creases, np.int8(ACTIVE), np.int8(BLOCK))
    out: NDArray[np.int8] = np.where(valid, state, np.int8(HOLE)).astype(np.int8)
    return out


def warm_up() -> None:
    """Load (on a fresh install: compile) the crease kernels that read OpenCV's window sums.

    The creases sum their windows themselves where float64 adds them exactly
    (:mod:`depthgram.segmentation.window`); a frame whose values span too many octaves takes
    OpenCV's sums and these kernels. No frame of the recordings at hand does, so a stream
    would load them in its middle.
    """
    f = np.float32(1.0)
    ok = np.ones((2, 2), np.bool_)
    sums = np.ones((2, 2, 2), np.float32)
    c = np.ones(4, np.float32)
    kernels_creases.crease_state_from_sums(sums, ok, ok, c, f, 1, f, f)
