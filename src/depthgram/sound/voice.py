"""One voice's parameters, and how one node of a scene tree becomes one.

A beeping object: pan from its direction (the azimuth, with the camera's intrinsics) or its
column, pitch from its row, loudness and beep rate from its nearness (faster with a short time to
collision), timbre and beep length from its area. A surface: a hum gliding between its near and
far ends (steady, for one facing the camera).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from depthgram.scene.tree import Node
from depthgram.segmentation.objects import SceneObject
from depthgram.sound.mapping import SoundMapping

__all__ = ["BEEP_KINDS", "OBLIQUE_KINDS", "Voice", "beep_voice", "direction", "glide_voice"]

#: Node kinds heard as a gliding tone rather than beeps.
OBLIQUE_KINDS = ("floor", "wall", "ceiling", "compound")


@dataclass(frozen=True)
class Voice:
    """Target parameters of one voice for one frame (what the mapping made of one node).

    For a beeping object, the ``*_b`` fields equal the ``*_a`` ones; for a glide, ``a`` is the
    surface's near end and ``b`` its far end.
    """

    key: tuple[str, int]
    freq_a: float
    freq_b: float
    gain_a: float
    gain_b: float
    pan_a: tuple[float, float]
    pan_b: tuple[float, float]
    rate: float  # beeps per second; 0 for a glide
    beep_s: float
    harmonics: int
    order: float  # scan position in 0..1 (when the voice first sounds)
    # Direction of the voice from the camera (degrees): azimuth positive to the right, elevation
    # positive up. None without the intrinsics (binaural rendering then reads the pan). Used by
    # the binaural mode only; a glide's is its surface's centre.
    azimuth: float | None = None
    elevation: float | None = None


#: Node kinds heard as beeps.
BEEP_KINDS = ("object",)


def _extent(n: Node, objects: Mapping[int, SceneObject]) -> tuple[float, float, float, float]:
    """(near depth mm, far depth mm, near column px, far column px) of an oblique surface."""
    o = objects.get(n.id)
    parts = o.parts if o is not None else ()
    if len(parts) >= 2:
        near_p = min(parts, key=lambda p: p.depth)
        far_p = max(parts, key=lambda p: p.depth)
        return near_p.depth, far_p.depth, near_p.center_xy[0], far_p.center_xy[0]
    # Without its parts (a tree read back from text) the extent is unknown: assume the
    # surface runs from half to one and a half times its mean depth, at its center column.
    return 0.5 * n.depth, 1.5 * n.depth, n.center_xy[0], n.center_xy[0]


def direction(x: float, y: float, intrinsics: Any, gravity: Any = None) -> tuple[float | None, float | None]:
    """(azimuth, elevation) in degrees of pixel (x, y): right and up positive; (None, None) without intrinsics.

    Without ``gravity`` the elevation is the ray's angle above the plane of the camera's optical
    axis and its rows, so a tilted camera tilts it too. With it (a
    :class:`~depthgram.frame.Gravity`, down in camera coordinates) the elevation is above the
    horizon and the azimuth is measured in the horizontal plane from where the camera points:
    what stays put keeps its direction when the camera pitches or rolls.
    """
    if intrinsics is None:
        return None, None
    if gravity is not None:
        g = gravity.vector
        ray = ((x - intrinsics.cx) / intrinsics.fx, (y - intrinsics.cy) / intrinsics.fy, 1.0)
        norm = math.sqrt(sum(c * c for c in ray))
        down = sum(r * q for r, q in zip(ray, g, strict=True)) / norm
        el = math.degrees(math.asin(max(-1.0, min(1.0, -down))))
        # The optical axis (0, 0, 1) less its vertical part: the heading; right = down x heading.
        fwd = (-g[2] * g[0], -g[2] * g[1], 1.0 - g[2] * g[2])
        f_norm = math.sqrt(sum(c * c for c in fwd))
        if f_norm < 1e-6:  # looking straight up or down: no heading, the image's own azimuth
            return math.degrees(math.atan2(x - intrinsics.cx, intrinsics.fx)), el
        right = (g[1] * fwd[2] - g[2] * fwd[1], g[2] * fwd[0] - g[0] * fwd[2], g[0] * fwd[1] - g[1] * fwd[0])
        along = sum(r * q for r, q in zip(ray, fwd, strict=True))
        across = sum(r * q for r, q in zip(ray, right, strict=True))
        return math.degrees(math.atan2(across, along)), el
    az = math.degrees(math.atan2(x - intrinsics.cx, intrinsics.fx))
    el = math.degrees(
        math.atan2(intrinsics.cy - y, math.hypot(intrinsics.fy, (x - intrinsics.cx) * intrinsics.fy / intrinsics.fx))
    )
    return az, el


def _pitch(y: float, height: int, mapping: SoundMapping, elevation: float | None) -> float:
    """Pitch (Hz): from the elevation above the horizon when known, else from the image row."""
    if elevation is not None:
        return mapping.pitch_elevation(elevation)
    return mapping.pitch(y, height)


def _pan(x: float, frame_size: tuple[int, int], mapping: SoundMapping, intrinsics: Any) -> tuple[float, float]:
    """Equal-power gains of an image column: from its azimuth when the intrinsics are known."""
    if intrinsics is None:
        return mapping.pan(x, frame_size[0])
    return mapping.pan_azimuth(math.atan2(x - intrinsics.cx, intrinsics.fx))


def beep_voice(
    n: Node,
    frame_size: tuple[int, int],
    mapping: SoundMapping,
    intrinsics: Any = None,
    *,
    order: float = 0.0,
    key: tuple[str, int] | None = None,
    gravity: Any = None,
) -> Voice:
    """Return the beeping voice of one object node.

    Parameters
    ----------
    n : Node
    frame_size : tuple of int
        (width, height) of the frame (px).
    mapping : SoundMapping
    intrinsics : Intrinsics, optional
        The camera's: the pan then follows the object's azimuth (``pan_azimuth_deg``).
    order : float
        Scan position in 0..1 (when it first sounds).
    key : tuple of (str, int), optional
        The voice's key; ``("o", n.id)`` by default.
    gravity : Gravity, optional
        The camera's (the frame's ``gravity``): with the intrinsics, pitch then follows the
        object's elevation above the horizon, which a tilted camera does not change.

    Returns
    -------
    Voice
    """
    w, h = frame_size
    az, el = direction(n.center_xy[0], n.center_xy[1], intrinsics, gravity)
    f = _pitch(n.center_xy[1], h, mapping, el if gravity is not None else None)
    g = mapping.gain(n.depth)
    pan = _pan(n.center_xy[0], frame_size, mapping, intrinsics)
    harm, beep = mapping.weight(n.area / float(w * h))
    return Voice(key or ("o", n.id), f, f, g, g, pan, pan, mapping.rate(n.depth, n.ttc), beep, harm, order, az, el)


def glide_voice(
    n: Node,
    frame_size: tuple[int, int],
    mapping: SoundMapping,
    objects: Mapping[int, SceneObject] | None = None,
    intrinsics: Any = None,
    *,
    facing: bool = False,
    gravity: Any = None,
) -> Voice:
    """Return the gliding hum of one surface node, between its near and far ends.

    Parameters
    ----------
    n : Node
    frame_size : tuple of int
        (width, height) of the frame (px).
    mapping : SoundMapping
    objects : mapping of int to SceneObject, optional
        The segmentation's objects by id: the glide spans the surface's real nearest and
        farthest slices when given, else an assumed extent.
    intrinsics : Intrinsics, optional
        The camera's, for the azimuth of the ends.
    facing : bool
        A surface facing the camera (all at one depth): a steady hum at its centre, no glide.
    gravity : Gravity, optional
        The camera's: the hum's pitch then follows its centre's elevation above the horizon.

    Returns
    -------
    Voice
    """
    if facing:
        d_near = d_far = n.depth
        x_near = x_far = n.center_xy[0]
    else:
        d_near, d_far, x_near, x_far = _extent(n, objects or {})
    az, el = direction(n.center_xy[0], n.center_xy[1], intrinsics, gravity)
    fc = _pitch(n.center_xy[1], frame_size[1], mapping, el if gravity is not None else None)
    span = mapping.glide_octaves * (mapping.nearness(d_near) - mapping.nearness(d_far))
    k = 10.0 ** (mapping.glide_gain_db / 20.0)
    return Voice(
        ("g", n.id),
        fc * 2.0 ** (span / 2),
        fc * 2.0 ** (-span / 2),
        k * mapping.gain(d_near),
        k * mapping.gain(d_far),
        _pan(x_near, frame_size, mapping, intrinsics),
        _pan(x_far, frame_size, mapping, intrinsics),
        0.0,
        0.0,
        1,
        0.0,
        az,
        el,
    )
