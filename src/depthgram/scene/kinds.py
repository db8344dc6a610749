"""The kinds of the supports by gravity: floor, table top, wall and ceiling as gravity says.

The segmentation names its supports by the image's axes (:mod:`depthgram.segmentation.orientation`):
a horizontal support is a surface whose depth changes from row to row, a wall one whose depth
changes from column to column. That holds for a level camera only. A camera on an arm looking
down at 45 degrees sees a table top as facing it; one looking straight down sees it as a flat
object; a hand-held camera rolled by 20 degrees sees a table's edge run across the image as a
wall's would. The pixel classes stay as they are (they choose which pixels are fitted as
planes, which is right whatever the mounting); only the kinds are named here, after the
segmentation, from each support's fitted plane and the direction of gravity:

- a plane facing up (its normal within :data:`LEVEL_DEG` of up) is a support: the ``floor`` when
  it is the lowest one with nothing seen beneath it, a table top (``compound``) otherwise;
- a plane facing down above the camera is the ``ceiling``;
- a plane whose normal is within :data:`LEVEL_DEG` of horizontal is a ``wall`` when it is large;
- a support whose plane is oblique to gravity keeps no guessed kind: it is a ``compound``.

A facing segment (kind ``object``) becomes a support only when it is large and planar: a table
top seen from straight above, the back wall of a room, the carpet beyond a desk. A box's top is
small beside the table it stands on and stays an object.

Gravity comes from the frame (``--gravity``, ``--tilt``, an IMU, the simulator's truth). Without
it, it is estimated from the largest support seen from above (what the image's axes call a
horizontal support, or a large flat facing segment, with its normal toward the image's top),
kept over the recent frames of a stream. Where no support is seen from above, a large flat
facing segment that things rest on (held in by it, standing a little nearer) is one seen from
straight above: its normal is up (:func:`resting_gravity`; an arm camera over a table, no IMU).
Without any of these, no ``floor`` or ``ceiling`` is guessed: a horizontal support is a
``compound``.

A reading lies on a plane within 1.5 % of its depth plus 4 mm, or the camera's step and two
sigmas there when the sensor model is known.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.noise_model import SensorModel
from depthgram.segmentation.objects import SceneObject, Segmentation

__all__ = ["GravityKinds", "name_kinds", "resting_gravity"]

#: The most a support's normal leans off vertical (degrees) to be horizontal, or off horizontal
#: to be a wall.
LEVEL_DEG = 30.0
#: Support kinds the segmentation names from the image's axes: renamed here.
_SUPPORT_KINDS = ("floor", "wall", "ceiling", "compound")
#: Least share of the frame a facing segment covers to be taken for a support (a table top seen
#: from above, a wall facing the camera), or, lying lower than every other support by
#: :data:`_LOWER_MM`, to be taken for one (the carpet beyond a desk).
BIG_SHARE = 0.08
LOW_SHARE = 0.02
_LOWER_MM = 150.0
#: Least seen area (m²) of a facing segment taken for a wall, and of a vertical support of the
#: segmentation kept one (a box's side is smaller: a 20 x 20 cm face is 0.04 m²)
WALL_M2 = 0.25
WALL_SUPPORT_M2 = 0.05
#: Least share of a segment's samples within the tolerance of its plane (:func:`_tolerance`): a facing segment
#: taken for a support, and a support the segmentation found (what lies on a table merged with
#: it by a noisy camera is off its plane).
_PLANAR_SHARE = 0.7
_SUPPORT_PLANAR_SHARE = 0.5
_TOL_REL = 0.015
_TOL_MM = 4.0
#: Least height (mm) of the floor below the camera: a support nearer below is a table top (an
#: arm's camera 0.4-0.7 m over a table sees nothing else), not the floor a person or a robot
#: stands on (a chest-worn camera is 1.1-1.5 m over it, a hand-held one as much).
FLOOR_MIN_MM = 800.0
#: Readings more than this (mm) beyond a support's plane, over this share of the frame's,
#: make it raised (a table top), not the floor.
_BENEATH_MM = 150.0
_BENEATH_SHARE = 0.01
#: Most share of the readings around a large upright facing segment's outline lying beyond its plane
#: (by more than :data:`_BENEATH_MM`) for it to be a wall: a wall's outline meets the floor, the
#: ceiling, the next wall or what stands before it; a person's is seen against the wall behind.
_BEYOND_OUTLINE_SHARE = 0.5
#: Least share of the frame of a facing segment tested as a piece of a wall (:func:`_wall_pieces`).
_MIN_PIECE_SHARE = 0.002
_PIECE_SAMPLES = 300
#: Samples of the frame the planes are fitted on.
_SAMPLES = 3000
#: Fewest segments resting on a large flat facing segment, and the tallest (mm) counted, for its
#: normal to be taken for up (:func:`resting_gravity`): a table top seen from straight above
#: holds a few things a few centimetres to a few decimetres high
_RESTING_LEAST = 2
_RESTING_MAX_MM = 400.0
#: Frames an estimated gravity is remembered in a stream.
_MEMORY = 30


@dataclass(frozen=True)
class _Planes:
    """Planes fitted to some segments: unit normals toward the camera, offsets, centroids, fit quality."""

    ids: NDArray[np.int64]
    normal: NDArray[np.float64]  # (k, 3), toward the camera: n . P = -offset on the plane
    offset: NDArray[np.float64]  # (k,) distance (mm) of the plane from the camera
    centroid: NDArray[np.float64]  # (k, 3) mean point (mm) of the inliers
    planar: NDArray[np.bool_]  # (k,) enough samples lie on the plane


def _tolerance(z_mm: NDArray[np.float64] | float, sensor: SensorModel | None) -> NDArray[np.float64] | float:
    """How far (mm) a reading at depth ``z_mm`` may lie off a plane and still be on it.

    :data:`_TOL_REL` of the depth plus :data:`_TOL_MM`, and at least one quantisation step and
    two noise sigmas of the camera (``sensor``, when known): a structured-light camera's step at
    6 m (about 100 mm) is more than 1.5 % of it, and a wall there read in steps is still flat.
    """
    tol = _TOL_REL * z_mm + _TOL_MM
    if sensor is None:
        return tol
    return np.maximum(tol, sensor.step(z_mm) + 2.0 * sensor.sigma(z_mm))


def _fit_planes(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    cam: Intrinsics,
    ids: list[int],
    supports: set[int],
    sensor: SensorModel | None = None,
) -> _Planes:
    """Fit a plane to each of ``ids`` on a grid of samples (about :data:`_SAMPLES` of the frame).

    ``supports``: the ids the segmentation named supports, held to a looser planarity;
    ``sensor``: the camera's model, when known (:func:`_tolerance`).

    The plane is linear in inverse depth over the normalised pixel coordinates, ``1000/Z = a u' +
    b v' + c`` (u' = (x - cx) / fx), with its normal along (a, b, c) and its distance 1000 /
    |(a, b, c)|: a least-squares fit of all segments at once (sums by label), then again on the
    samples within the tolerance of the first fit.
    """
    h, w = depth.shape
    s = max(1, round(math.sqrt(h * w / _SAMPLES)))
    lab = labels[::s, ::s]
    zf = depth[::s, ::s]
    lut = np.full(max(int(lab.max(initial=0)), max(ids)) + 1, -1, np.int64)
    lut[np.asarray(ids, np.int64)] = np.arange(len(ids))
    rows_img = lut[lab]
    ys, xs = np.nonzero((rows_img >= 0) & (zf > 0))
    row = rows_img[ys, xs]
    zs = zf[ys, xs].astype(np.float64)
    u = np.asarray((xs * float(s) - cam.cx) / cam.fx, np.float64)
    v = np.asarray((ys * float(s) - cam.cy) / cam.fy, np.float64)
    q = 1000.0 / zs
    k = len(ids)
    keep = np.ones(row.size, bool)
    coef = np.zeros((k, 3))
    for _ in range(2):
        coef = _solve(row[keep], u[keep], v[keep], q[keep], k)
        pred = coef[row, 0] * u + coef[row, 1] * v + coef[row, 2]
        zp = 1000.0 / np.maximum(pred, 1e-9)
        keep = np.abs(zp - zs) <= _tolerance(zs, sensor)
    rk = row[keep]
    n_in = np.bincount(rk, minlength=k)
    n_all = np.maximum(np.bincount(row, minlength=k), 1)
    norm = np.maximum(np.linalg.norm(coef, axis=1), 1e-12)
    normal = -coef / norm[:, None]
    offset = 1000.0 / norm
    zk = zs[keep]
    cen = (
        np.stack(
            [
                np.bincount(rk, weights=u[keep] * zk, minlength=k),
                np.bincount(rk, weights=v[keep] * zk, minlength=k),
                np.bincount(rk, weights=zk, minlength=k),
            ],
            axis=1,
        )
        / np.maximum(n_in, 1)[:, None]
    )
    least = np.array([_SUPPORT_PLANAR_SHARE if i in supports else _PLANAR_SHARE for i in ids])
    planar = (n_in >= 10) & (n_in >= least * n_all)
    return _Planes(np.asarray(ids, np.int64), normal, offset, cen, planar)


def _frame_points(depth: NDArray[np.float32], cam: Intrinsics) -> NDArray[np.float64]:
    """Return the 3-D points (mm) of a grid of the frame's readings (about :data:`_SAMPLES`)."""
    h, w = depth.shape
    s = max(1, round(math.sqrt(h * w / _SAMPLES)))
    zf = depth[::s, ::s]
    ys, xs = np.nonzero(zf > 0)
    z = zf[ys, xs].astype(np.float64)
    return _points(xs * float(s), ys * float(s), z, cam)


def _points(
    x: NDArray[np.number], y: NDArray[np.number], z: NDArray[np.float64], cam: Intrinsics
) -> NDArray[np.float64]:
    """Return the 3-D points (mm) seen at pixels ``(x, y)`` of the frame at depths ``z`` (mm)."""
    return np.stack([(x - cam.cx) / cam.fx * z, (y - cam.cy) / cam.fy * z, z], axis=1)


def _solve(
    row: NDArray[np.int64], u: NDArray[np.float64], v: NDArray[np.float64], q: NDArray[np.float64], k: int
) -> NDArray[np.float64]:
    """Least squares ``q = a u + b v + c`` per row, all rows at once (normal equations by bincount)."""
    cols = (u, v, np.ones_like(u))
    ata = np.zeros((k, 3, 3))
    atb = np.zeros((k, 3))
    for i in range(3):
        atb[:, i] = np.bincount(row, weights=cols[i] * q, minlength=k)
        for j in range(i, 3):
            ata[:, i, j] = ata[:, j, i] = np.bincount(row, weights=cols[i] * cols[j], minlength=k)
    ata += np.eye(3) * 1e-9
    out = np.asarray(np.linalg.solve(ata, atb[:, :, None])[:, :, 0], np.float64)
    return out


def _beneath_shares(points: NDArray[np.float64], planes: _Planes, rows: NDArray[np.int64]) -> NDArray[np.float64]:
    """Share of the samples lying beyond each of ``rows``' planes (seen through it) by more than :data:`_BENEATH_MM`."""
    if not points.shape[0] or not rows.size:
        return np.zeros(rows.size)
    signed = points @ planes.normal[rows].T + planes.offset[rows][None, :]  # < 0: beyond the plane
    return np.asarray(np.count_nonzero(signed < -_BENEATH_MM, axis=0) / points.shape[0], np.float64)


def estimate_gravity(seg: Segmentation, planes: _Planes) -> NDArray[np.float64] | None:
    """Return gravity (unit, down, camera coordinates) from the largest support seen from above, or None.

    The segmentation's horizontal supports (``floor``, ``compound``), and its large flat facing
    segments, whose plane's normal points to the image's top by more than 35 degrees off the
    optical axis are floors and table tops seen from above; the largest one's normal is up, and
    those agreeing with it within 15 degrees are averaged in, weighted by their area. A facing
    segment counts when it covers :data:`BIG_SHARE` of the frame: a floor seen as a far strip
    (a 16:9 frame's narrower view, or a camera looking ahead) spreads its depth too little for
    the segmentation to keep it a support, while its plane says what it is.
    """
    area = {o.id: o.area for o in seg.objects}
    kind = {o.id: o.kind for o in seg.objects}
    big = BIG_SHARE * seg.labels.size
    lean = math.sin(math.radians(35.0))
    pick = [
        j
        for j, i in enumerate(planes.ids.tolist())
        if (kind[i] in ("floor", "compound") or (kind[i] == "object" and area[i] >= big))
        and planes.planar[j]
        and -planes.normal[j, 1] >= lean
    ]
    if not pick:
        return None
    best = max(pick, key=lambda j: area[int(planes.ids[j])])
    up = planes.normal[best]
    agree = [j for j in pick if float(planes.normal[j] @ up) >= math.cos(math.radians(15.0))]
    weights = np.array([area[int(planes.ids[j])] for j in agree], np.float64)
    mean = (planes.normal[agree] * weights[:, None]).sum(axis=0)
    return np.asarray(-mean / np.linalg.norm(mean), np.float64)


def resting_gravity(
    seg: Segmentation, planes: _Planes, depth: NDArray[np.float32], cam: Intrinsics, sensor: SensorModel | None = None
) -> NDArray[np.float64] | None:
    """Return gravity (unit, down, camera coordinates) from a large flat segment things rest on, or None.

    When no support is seen from above (:func:`estimate_gravity`), a camera may still look
    straight down at one: an arm camera over a table, whose top faces it. Things lie on a
    support, not beside it: a large flat facing segment (:data:`BIG_SHARE` of the frame) holding
    at least :data:`_RESTING_LEAST` other segments that stand on its near side by more than the
    noise and less than :data:`_RESTING_MAX_MM`, and that it surrounds (most of their outline's
    neighbours on the sampling grid are its readings), is a support seen from above: its normal
    is up. The largest such segment wins.
    """
    area = {o.id: o.area for o in seg.objects}
    kind = {o.id: o.kind for o in seg.objects}
    big = BIG_SHARE * seg.labels.size
    cands = [
        j for j, i in enumerate(planes.ids.tolist()) if kind[i] == "object" and area[i] >= big and planes.planar[j]
    ]
    if not cands:
        return None
    h, w = depth.shape
    s = max(1, round(math.sqrt(h * w / _SAMPLES)))
    lab = np.where(depth[::s, ::s] > 0, seg.labels[::s, ::s], 0)
    # the segments' neighbours on the grid: (segment, neighbour) pairs of differing readings
    pairs = []
    for a, b in ((lab[:, :-1], lab[:, 1:]), (lab[:-1, :], lab[1:, :])):
        differ = (a != b) & (a > 0) & (b > 0)
        pairs.append(np.stack([a[differ], b[differ]], axis=1))
        pairs.append(np.stack([b[differ], a[differ]], axis=1))
    edges = np.concatenate(pairs)
    ys, xs = np.nonzero(lab)
    z = depth[::s, ::s][ys, xs].astype(np.float64)
    points = _points(xs * float(s), ys * float(s), z, cam)
    of = lab[ys, xs]
    for j in sorted(cands, key=lambda j: -area[int(planes.ids[j])]):
        sid = int(planes.ids[j])
        touching = edges[:, 0][edges[:, 1] == sid]
        resting = 0
        for i in np.unique(touching).tolist():
            mine = of == i
            if np.count_nonzero(mine) < 5:
                continue
            held = np.count_nonzero(touching == i) / max(int(np.count_nonzero(edges[:, 0] == i)), 1)
            if held < 0.5:
                continue
            near = points[mine] @ planes.normal[j] + planes.offset[j]  # > 0: toward the camera
            rise = float(np.median(near))
            if float(np.median(_tolerance(z[mine], sensor))) < rise <= _RESTING_MAX_MM:
                resting += 1
        if resting >= _RESTING_LEAST:
            return np.asarray(-planes.normal[j], np.float64)
    return None


def name_kinds(
    seg: Segmentation,
    depth: NDArray[np.float32],
    cam: Intrinsics,
    gravity: tuple[float, float, float] | NDArray[np.float64] | None,
    *,
    estimate: bool = True,
    sensor: SensorModel | None = None,
) -> tuple[Segmentation, NDArray[np.float64] | None]:
    """Return ``seg`` with its supports named by gravity, and the gravity used (None: none known).

    ``gravity``: unit vector down in camera coordinates, or None: estimated from this frame
    (:func:`estimate_gravity`) when ``estimate``; ``sensor``: the camera's model the frame was
    segmented with, when known (how far off its plane a reading may lie, :func:`_tolerance`).
    See the module's text for the rules.
    """
    size = depth.size
    ids = [o.id for o in seg.objects if o.kind in _SUPPORT_KINDS or (o.kind == "object" and o.area >= LOW_SHARE * size)]
    if not ids:
        return seg, None if gravity is None else np.asarray(gravity, np.float64)
    supports = {o.id for o in seg.objects if o.kind in _SUPPORT_KINDS}
    planes = _fit_planes(seg.labels, depth, cam, ids, supports, sensor)
    g = None if gravity is None else np.asarray(gravity, np.float64)
    if g is None and estimate:
        g = estimate_gravity(seg, planes)
        if g is None:
            g = resting_gravity(seg, planes, depth, cam, sensor)
    by_id = {o.id: o for o in seg.objects}
    kinds = {i: by_id[i].kind for i in ids}
    if g is None:
        # no guessed floor or ceiling: a horizontal support is a support
        new = {i: ("compound" if k in ("floor", "ceiling") else k) for i, k in kinds.items()}
        return _renamed(seg, new), None
    up = -g
    c = planes.normal @ up
    height = planes.centroid @ g  # mm below the camera
    cos_level = math.cos(math.radians(LEVEL_DEG))
    sin_level = math.sin(math.radians(LEVEL_DEG))
    new = dict(kinds)
    ups: list[int] = []
    upright: list[int] = []  # large flat facing segments upright to gravity: walls unless seen against more
    for j, i in enumerate(ids):
        o = by_id[i]
        facing = o.kind == "object"
        if not planes.planar[j]:
            continue
        big = o.area >= BIG_SHARE * size
        if c[j] >= cos_level and height[j] > 0:
            ups.append(j)
            new[i] = "compound"
        elif c[j] <= -cos_level and height[j] < 0:
            if big or not facing:
                new[i] = "ceiling"
        elif abs(c[j]) <= sin_level:
            # a wall is large: a box's side is a compound (a support of the segmentation) or
            # stays an object
            least = WALL_SUPPORT_M2 if not facing else WALL_M2
            large = o.area_mm2 is None or o.area_mm2 >= least * 1e6
            if not facing:
                new[i] = "wall" if large and o.kind != "compound" else "compound"
            elif big and large:
                upright.append(j)
        elif not facing:
            new[i] = "compound"  # oblique to gravity: no floor, wall or ceiling
    for j in upright:
        # a wall meets what is around it (floor, ceiling, the next wall) or is hidden by what
        # stands before it; a large flat thing standing before a wall (a person, a door ajar) is
        # seen against what lies behind it along most of its outline
        if _outline_beyond(seg.labels, depth, cam, by_id[ids[j]], planes, j) < _BEYOND_OUTLINE_SHARE:
            new[ids[j]] = "wall"
    if ups:
        _name_floors(ups, ids, by_id, new, height, planes, depth, cam, size)
    walls = [j for j, i in enumerate(ids) if new[i] == "wall"]
    if walls:
        # the pieces not named on their own: small ones, and those too small for a wall yet too
        # large for a piece of one by share alone (a strip of the back wall beside a bottle)
        named = {i for i in ids if new[i] != "object"}
        new.update(_wall_pieces(seg, depth, cam, planes, walls, named, sensor))
    return _renamed(seg, new), g


def _outline_beyond(
    labels: NDArray[np.int32], depth: NDArray[np.float32], cam: Intrinsics, o: SceneObject, planes: _Planes, j: int
) -> float:
    """Share of the readings just outside ``o``'s outline lying beyond its plane (row ``j``) by :data:`_BENEATH_MM`."""
    h, w = labels.shape
    x0, y0, x1, y1 = o.bbox_xy
    x0, y0, x1, y1 = max(x0 - 1, 0), max(y0 - 1, 0), min(x1 + 1, w), min(y1 + 1, h)
    mask = (labels[y0:y1, x0:x1] == o.id).astype(np.uint8)
    ring = (cv2.dilate(mask, np.ones((3, 3), np.uint8)) > mask) & (depth[y0:y1, x0:x1] > 0)
    ys, xs = np.nonzero(ring)
    if ys.size == 0:
        return 0.0
    z = depth[y0:y1, x0:x1][ys, xs].astype(np.float64)
    pts = _points(xs + x0, ys + y0, z, cam)
    beyond = pts @ planes.normal[j] + planes.offset[j] < -_BENEATH_MM
    return float(np.count_nonzero(beyond)) / ys.size


def _wall_pieces(
    seg: Segmentation,
    depth: NDArray[np.float32],
    cam: Intrinsics,
    planes: _Planes,
    walls: list[int],
    seen: set[int],
    sensor: SensorModel | None,
) -> dict[int, str]:
    """Return ``{id: "wall"}`` for the small facing segments lying in a wall's plane.

    A nearer object cuts a wall into pieces (the back wall under a table, beside a cupboard);
    the pieces not named a support on their own (``seen`` holds those that were) are the same
    wall where their readings lie in its plane, within the fit's tolerance (a piece's own fit is
    too loose: a strip under a table turns its normal 20 degrees). Only walls: a flat thing lying
    on a floor or a table stands above its plane by less than that tolerance at a few metres,
    and it must stay an object (something to step over).
    """
    least = max(_MIN_PIECE_SHARE * depth.size, 1.0)
    small = [o for o in seg.objects if o.kind == "object" and o.id not in seen and o.area >= least]
    out: dict[int, str] = {}
    for o in small:
        # a piece of a wall has its centroid in the wall's plane: most pieces are not read further
        c = o.centroid_mm
        if c is None or not any(
            abs(float(planes.normal[j] @ np.asarray(c)) + float(planes.offset[j])) <= _tolerance(float(c[2]), sensor)
            for j in walls
        ):
            continue
        # inside the piece's box, on a grid fine enough for about _PIECE_SAMPLES of its pixels
        # (the frame's grid leaves a strip a few rows high with a handful)
        x0, y0, x1, y1 = o.bbox_xy
        st = max(1, math.isqrt(max(1, o.area // _PIECE_SAMPLES)))
        lab = seg.labels[y0:y1:st, x0:x1:st]
        zf = depth[y0:y1:st, x0:x1:st]
        ys, xs = np.nonzero((lab == o.id) & (zf > 0))
        if ys.size < 10:
            continue
        z = zf[ys, xs].astype(np.float64)
        pts = _points(xs * st + x0, ys * st + y0, z, cam)
        tol = _tolerance(z, sensor)
        for j in walls:
            if np.count_nonzero(np.abs(pts @ planes.normal[j] + planes.offset[j]) <= tol) >= _PLANAR_SHARE * z.size:
                out[o.id] = "wall"
                break
    return out


def _name_floors(
    ups: list[int],
    ids: list[int],
    by_id: dict[int, SceneObject],
    new: dict[int, str],
    height: NDArray[np.float64],
    planes: _Planes,
    depth: NDArray[np.float32],
    cam: Intrinsics,
    size: int,
) -> None:
    """Name the supports facing up (``ups``, rows of ``ids``; ``new`` updated): floor, table top or an object on one.

    A facing segment lying on a larger support (a dish, a book) or standing over it (a box's
    top) is an object on that support; one smaller than :data:`BIG_SHARE` is a support only
    below all the others (the floor beyond a desk). The floor is the lowest, at least
    :data:`FLOOR_MIN_MM` below the camera, with nothing seen beyond its plane.
    """
    area = np.array([by_id[i].area for i in ids], np.float64)
    for j in list(ups):
        i = ids[j]
        if by_id[i].kind != "object":
            continue
        others = [k for k in ups if k != j]
        on_other = any(area[k] > area[j] and height[k] >= height[j] - max(50.0, 0.03 * height[j]) for k in others)
        lowest = bool(others) and all(height[j] > height[k] + _LOWER_MM for k in others)
        if on_other or not (area[j] >= BIG_SHARE * size or lowest):
            new[i] = "object"
            ups.remove(j)
    if not ups:
        return
    rows = np.array(ups, np.int64)
    deepest = float(height[rows].max())
    near = rows[(height[rows] >= deepest - 100.0) & (height[rows] >= FLOOR_MIN_MM)]
    shares = _beneath_shares(_frame_points(depth, cam), planes, near) if near.size else np.zeros(0)
    for j, share in zip(near.tolist(), shares.tolist(), strict=True):
        if share < _BENEATH_SHARE:
            new[int(planes.ids[j])] = "floor"


def _renamed(seg: Segmentation, kinds: dict[int, str]) -> Segmentation:
    """``seg`` with the objects of ``kinds`` given those kinds (the same object where unchanged)."""
    if all(o.kind == kinds.get(o.id, o.kind) for o in seg.objects):
        return seg
    objects = tuple(replace(o, kind=kinds[o.id]) if kinds.get(o.id, o.kind) != o.kind else o for o in seg.objects)
    return replace(seg, objects=objects)


class GravityKinds:
    """Names each frame's supports by gravity (:func:`name_kinds`), remembering an estimated gravity.

    A frame's own gravity (``--gravity``, ``--tilt``, an IMU) is used as given. Without it,
    gravity is estimated from the frame's supports seen from above, else the last estimate of
    the recent frames (:data:`_MEMORY`) of the same stream is used.
    """

    def __init__(self) -> None:
        self._last: NDArray[np.float64] | None = None
        self._age = 0
        #: the gravity the last frame was named by when it was estimated (this frame's or a
        #: recent one's), else None (given, or none known)
        self.estimated: NDArray[np.float64] | None = None

    def __call__(
        self,
        seg: Segmentation,
        depth: NDArray[np.float32],
        cam: Intrinsics,
        gravity: tuple[float, float, float] | None,
        *,
        related: bool = True,
        sensor: SensorModel | None = None,
    ) -> Segmentation:
        """Return ``seg`` named by gravity.

        ``related``: the frame continues the previous one; ``sensor``: as :func:`name_kinds`.
        """
        self.estimated = None
        if gravity is not None:
            out, _ = name_kinds(seg, depth, cam, gravity, sensor=sensor)
            return out
        if not related:
            self._last = None
        out, g = name_kinds(seg, depth, cam, None, sensor=sensor)
        if g is not None:
            self._last, self._age = g, 0
            self.estimated = g
            return out
        self._age += 1
        if self._last is not None and self._age <= _MEMORY:
            out, _ = name_kinds(seg, depth, cam, self._last, estimate=False, sensor=sensor)
            self.estimated = self._last
        return out
