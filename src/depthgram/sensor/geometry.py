"""Scene geometry for the simulator: primitives, moving bodies, a pinhole camera, ray casting.

World frame: X right, Y up, Z forward (horizontal), millimetres, floor at Y = 0 in the
named scenes. The camera sits at a position and is pitched down by an angle; its own frame
is x right, y down, z along the optical axis. Rays are cast with direction vectors whose
camera-z component is 1, so the ray parameter *is* the depth along the optical axis (Z),
and the radial distance is that times the ray's length.

Every intersection is vectorized over all rays at once (no per-pixel Python loop); a body
is hit where the nearest of its parts is hit, and the nearest body wins the pixel.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError
from depthgram.frame import Intrinsics

__all__ = [
    "BackAndForth",
    "Body",
    "Box",
    "Camera",
    "Cylinder",
    "Ellipsoid",
    "Gait",
    "Linear",
    "Plane",
    "Primitive",
    "RayHits",
    "cast",
    "cast_times",
    "static_hits",
]

_EPS = 1e-6
Vec = tuple[float, float, float]
Arr = NDArray[np.float64]


def _nearest_positive(*ts: Arr) -> Arr:
    """Smallest candidate t > 0 per ray, inf where none."""
    stacked = np.stack(ts)
    stacked = np.where(np.isfinite(stacked) & (stacked > _EPS), stacked, np.inf)
    return np.asarray(stacked.min(axis=0))


@dataclass(frozen=True)
class Plane:
    """Infinite plane through ``point`` with normal ``normal`` (mm)."""

    point: Vec
    normal: Vec

    def intersect(self, origin: Arr, dirs: Arr) -> Arr:
        """Ray parameter of the hit for each ray (inf where none). ``dirs`` is (N, 3)."""
        n = np.asarray(self.normal, dtype=np.float64)
        denom = dirs @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = float((np.asarray(self.point) - origin) @ n) / denom
        return _nearest_positive(t)


@dataclass(frozen=True)
class Box:
    """Axis-aligned box from corner ``lo`` to corner ``hi`` (mm)."""

    lo: Vec
    hi: Vec

    def intersect(self, origin: Arr, dirs: Arr) -> Arr:
        """Ray parameter of the hit (slab method), inf where none."""
        lo = np.asarray(self.lo, dtype=np.float64)
        hi = np.asarray(self.hi, dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / dirs
            t1 = (lo - origin) * inv
            t2 = (hi - origin) * inv
        lo_t, hi_t = np.minimum(t1, t2), np.maximum(t1, t2)
        # fmax/fmin skip the NaN of a ray lying in a slab's face (0 * inf)
        tnear = np.fmax(np.fmax(lo_t[:, 0], lo_t[:, 1]), lo_t[:, 2])
        tfar = np.fmin(np.fmin(hi_t[:, 0], hi_t[:, 1]), hi_t[:, 2])
        hit = tfar >= np.maximum(tnear, _EPS)
        t = np.where(tnear > _EPS, tnear, tfar)
        return np.where(hit, t, np.inf)


@dataclass(frozen=True)
class Cylinder:
    """Upright cylinder (axis along world Y) with base centre ``base``, ``radius`` and ``height`` (mm)."""

    base: Vec
    radius: float
    height: float

    def intersect(self, origin: Arr, dirs: Arr) -> Arr:
        """Ray parameter of the nearest hit on the side or the caps, inf where none."""
        b = np.asarray(self.base, dtype=np.float64)
        o = origin - b
        dx, dy, dz = dirs[:, 0], dirs[:, 1], dirs[:, 2]
        a = dx * dx + dz * dz
        bq = 2.0 * (o[0] * dx + o[2] * dz)
        c = o[0] ** 2 + o[2] ** 2 - self.radius**2
        disc = bq * bq - 4.0 * a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            side = []
            for t in ((-bq - sq) / (2 * a), (-bq + sq) / (2 * a)):
                y = o[1] + t * dy
                side.append(np.where((y >= 0) & (y <= self.height), t, np.inf))
            caps = []
            for yc in (0.0, self.height):
                t = (yc - o[1]) / dy
                r2 = (o[0] + t * dx) ** 2 + (o[2] + t * dz) ** 2
                caps.append(np.where(r2 <= self.radius**2, t, np.inf))
        return _nearest_positive(*side, *caps)


@dataclass(frozen=True)
class Ellipsoid:
    """Axis-aligned ellipsoid with ``center`` and semi-axes ``radii`` (mm); a sphere when equal."""

    center: Vec
    radii: Vec

    def intersect(self, origin: Arr, dirs: Arr) -> Arr:
        """Ray parameter of the nearest hit, inf where none (solved on the unit sphere)."""
        r = np.asarray(self.radii, dtype=np.float64)
        o = (origin - np.asarray(self.center, dtype=np.float64)) / r
        d = dirs / r
        a = np.einsum("ij,ij->i", d, d)
        bq = 2.0 * (d @ o)
        c = float(o @ o) - 1.0
        disc = bq * bq - 4.0 * a * c
        with np.errstate(invalid="ignore"):
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        return _nearest_positive((-bq - sq) / (2 * a), (-bq + sq) / (2 * a))


Primitive = Plane | Box | Cylinder | Ellipsoid


@dataclass(frozen=True)
class Linear:
    """Offset p0 + v t (mm, mm/s) of a body; the zero motion by default."""

    p0: Vec = (0.0, 0.0, 0.0)
    v: Vec = (0.0, 0.0, 0.0)

    def position(self, t: float) -> Arr:
        """Offset (mm) at time ``t`` (s)."""
        return np.asarray(self.p0, dtype=np.float64) + t * np.asarray(self.v, dtype=np.float64)

    def velocity(self, t: float) -> Arr:
        """Velocity (mm/s) at time ``t`` (s)."""
        return np.asarray(self.v, dtype=np.float64)


@dataclass(frozen=True)
class BackAndForth:
    """Scripted back-and-forth: from p0 along v for ``half_period_s``, then back, repeating.

    The position is a triangle wave, so the speed is exactly |v| at every instant except
    the turning points (where the velocity reported is that of the leg that starts there).
    """

    p0: Vec
    v: Vec
    half_period_s: float

    def _phase(self, t: float) -> tuple[float, float]:
        cycle = np.mod(t, 2.0 * self.half_period_s)
        if cycle < self.half_period_s:
            return float(cycle), 1.0
        return float(2.0 * self.half_period_s - cycle), -1.0

    def position(self, t: float) -> Arr:
        """Offset (mm) at time ``t`` (s)."""
        s, _ = self._phase(t)
        return np.asarray(self.p0, dtype=np.float64) + s * np.asarray(self.v, dtype=np.float64)

    def velocity(self, t: float) -> Arr:
        """Velocity (mm/s) at time ``t`` (s)."""
        _, sign = self._phase(t)
        return sign * np.asarray(self.v, dtype=np.float64)


@dataclass(frozen=True)
class Gait:
    """The world as a walking, body-worn camera sees it: a steady approach with the gait's bob and sway.

    Offset ``v t + (sway sin(pi f t), bob sin(2 pi f t), 0)`` (mm): the body rises and falls once
    per step (``step_hz``) and sways sideways once per stride (two steps). Every body of a scene
    gets the same gait, so the camera moves and the world stands still; the sway is a translation
    (the camera's own pitch does not swing).

    Attributes
    ----------
    v : tuple of float
        Steady velocity of the world relative to the camera (mm/s): minus the walking velocity.
    bob_mm, sway_mm : float
        Vertical and sideways amplitudes (mm), world relative to the camera.
    step_hz : float
        Steps per second.
    """

    v: Vec = (0.0, 0.0, -1200.0)
    bob_mm: float = 20.0
    sway_mm: float = 15.0
    step_hz: float = 2.0

    def position(self, t: float) -> Arr:
        """Offset (mm) at time ``t`` (s)."""
        w = 2.0 * np.pi * self.step_hz
        gait = np.array([self.sway_mm * np.sin(0.5 * w * t), self.bob_mm * np.sin(w * t), 0.0])
        return np.asarray(np.asarray(self.v, dtype=np.float64) * t + gait, dtype=np.float64)

    def velocity(self, t: float) -> Arr:
        """Velocity (mm/s) at time ``t`` (s): the derivative of :meth:`position`."""
        w = 2.0 * np.pi * self.step_hz
        gait = np.array([0.5 * w * self.sway_mm * np.cos(0.5 * w * t), w * self.bob_mm * np.cos(w * t), 0.0])
        return np.asarray(np.asarray(self.v, dtype=np.float64) + gait, dtype=np.float64)


@dataclass(frozen=True)
class Body:
    """A rigid body of the scene: one ground-truth instance.

    Attributes
    ----------
    id : int
        Instance id (>= 1), the value of its pixels in the instance map.
    name : str
        "cup", "table", "floor", ...
    kind : str
        "object", "floor", "wall" or "ceiling".
    parts : tuple of Primitive
        Geometry in world coordinates at offset zero (mm).
    reflectivity : float
        Diffuse reflectivity at the sensor's wavelength, 0..1.
    motion : Linear, BackAndForth or Gait
        Offset of the parts over time.
    parent : int or None
        Id of the body it stands on.
    """

    id: int
    name: str
    kind: str
    parts: tuple[Primitive, ...]
    reflectivity: float = 0.5
    motion: Linear | BackAndForth | Gait = Linear()
    parent: int | None = None

    @property
    def moving(self) -> bool:
        """True when the body may move."""
        return isinstance(self.motion, (BackAndForth, Gait)) or any(self.motion.v)

    def intersect(self, origin: Arr, dirs: Arr, t: float) -> Arr:
        """Ray parameter of the nearest hit on any part at time ``t`` (s); inf where none."""
        o = origin - self.motion.position(t)
        return _nearest_positive(*(p.intersect(o, dirs) for p in self.parts))


@dataclass(frozen=True)
class Camera:
    """Pinhole camera with square pixels.

    Attributes
    ----------
    width, height : int
        Image size (px).
    fov_x_deg : float
        Horizontal field of view (degrees); 40° like the paper's Canesta sensor, giving
        about 30° vertically at 176 x 132.
    position : tuple of float
        Optical centre in the world (mm).
    pitch_deg : float
        Downward tilt of the optical axis from horizontal (degrees).
    """

    width: int
    height: int
    fov_x_deg: float = 40.0
    position: Vec = (0.0, 1000.0, 0.0)
    pitch_deg: float = 0.0

    def __post_init__(self) -> None:
        if not (0.0 < self.fov_x_deg < 170.0):
            raise InputError(f"camera field of view must be in (0, 170) degrees, got {self.fov_x_deg}")

    @property
    def intrinsics(self) -> Intrinsics:
        """Pinhole intrinsics (px), principal point at the image centre."""
        f = (self.width / 2.0) / np.tan(np.radians(self.fov_x_deg) / 2.0)
        return Intrinsics(float(f), float(f), (self.width - 1) / 2.0, (self.height - 1) / 2.0)

    @property
    def forward(self) -> Arr:
        """Unit optical axis in the world frame."""
        p = np.radians(self.pitch_deg)
        return np.array([0.0, -np.sin(p), np.cos(p)])

    def rays(self) -> tuple[Arr, Arr]:
        """World ray directions (H*W, 3), row-major, scaled so camera-z is 1; and their lengths.

        Computed once per camera and shared (read-only arrays): every frame and every
        exposure sub-step casts the same rays.
        """
        return self._rays

    @cached_property
    def _rays(self) -> tuple[Arr, Arr]:
        k = self.intrinsics
        u, v = np.meshgrid(np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64))
        xc = ((u - k.cx) / k.fx).ravel()
        yc = ((v - k.cy) / k.fy).ravel()
        p = np.radians(self.pitch_deg)
        right = np.array([1.0, 0.0, 0.0])
        down = np.array([0.0, -np.cos(p), -np.sin(p)])
        dirs = xc[:, None] * right + yc[:, None] * down + self.forward
        lengths = np.sqrt(1.0 + xc * xc + yc * yc)
        dirs.flags.writeable = False
        lengths.flags.writeable = False
        return dirs, lengths


@dataclass(frozen=True)
class RayHits:
    """Result of casting the camera's rays into the bodies at one instant.

    Attributes
    ----------
    depth : ndarray of float64, shape (H, W)
        Depth along the optical axis (mm), 0 where no surface.
    distance : ndarray of float64, shape (H, W)
        Radial distance from the optical centre (mm), 0 where no surface.
    instances : ndarray of int32, shape (H, W)
        Id of the body hit, 0 where none.
    """

    depth: Arr
    distance: Arr
    instances: NDArray[np.int32]


def cast(camera: Camera, bodies: tuple[Body, ...], t: float) -> RayHits:
    """Cast every pixel's ray into ``bodies`` at time ``t`` (s); the nearest hit wins."""
    return cast_times(camera, bodies, (t,))[0]


def static_hits(camera: Camera, bodies: tuple[Body, ...]) -> list[Arr]:
    """Ray parameters (one array per body that does not move, in ``bodies`` order).

    Pass the result to :func:`cast_times` as ``still`` to intersect static geometry once
    for a whole sequence instead of at every frame.
    """
    dirs, _ = camera.rays()
    origin = np.asarray(camera.position, dtype=np.float64)
    return [b.intersect(origin, dirs, 0.0) for b in bodies if not b.moving]


def cast_times(
    camera: Camera, bodies: tuple[Body, ...], times: tuple[float, ...], still: list[Arr] | None = None
) -> list[RayHits]:
    """:func:`cast` at several instants, intersecting the bodies that do not move only once.

    ``still`` is :func:`static_hits` of the same camera and bodies, when already computed.
    """
    dirs, lengths = camera.rays()
    origin = np.asarray(camera.position, dtype=np.float64)
    shape = (camera.height, camera.width)
    if not bodies:
        z = np.zeros(shape)
        return [RayHits(z, z.copy(), np.zeros(shape, np.int32)) for _ in times]
    order = [b for b in bodies if not b.moving] + [b for b in bodies if b.moving]
    ids = np.array([b.id for b in order], dtype=np.int32)
    if still is None:
        still = static_hits(camera, bodies)
    out = []
    for t in times:
        ts = np.stack(still + [b.intersect(origin, dirs, t) for b in order if b.moving])
        nearest = np.argmin(ts, axis=0)
        z = np.take_along_axis(ts, nearest[None], axis=0)[0]
        hit = np.isfinite(z)
        depth = np.where(hit, z, 0.0)
        out.append(
            RayHits(
                depth.reshape(shape),
                (depth * lengths).reshape(shape),
                np.where(hit, ids[nearest], 0).astype(np.int32).reshape(shape),
            )
        )
    return out
