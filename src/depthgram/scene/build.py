"""Build the scene's parse tree from segmented objects: who stands on what, and sibling relations.

The paper derives every object directly from the start node ``Bkg`` and outlines a
multi-level tree "for scenes with clusters of objects supported by a basic object like a
table" (section 5). Here an object is a child of the object it rests on: its bottom edge
lies on the support's image extent, and its mean depth matches the support's depth at the
contact row. Floors, walls and ceilings are children of ``Bkg``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.errors import InputError
from depthgram.scene.sentence import ROOT_KIND, ROOT_LABEL
from depthgram.scene.tree import Motion, Node, Relation, SceneTree

if TYPE_CHECKING:  # only the type: the scene stage must import even while segment changes
    from depthgram.segmentation.objects import SceneObject

__all__ = ["TreeConfig", "build_tree", "support_depth_at"]

#: Kinds that never rest on another object: they are the room's own surfaces.
_SURFACES = ("floor", "wall", "ceiling")
_SQRT12 = math.sqrt(12.0)


@dataclass(frozen=True)
class TreeConfig:
    """How supports and relations are decided.

    Parameters
    ----------
    depth_tolerance_mm : float
        Largest difference (mm) between an object's mean depth and its support's estimated
        depth at the object's bottom row, for support depths where the relative term is smaller.
    depth_tolerance_rel : float
        The same tolerance as a fraction of the support's depth at that row (ToF and stereo
        errors grow with depth).
    contact_px : int
        Margin (px) around the support's bounding box within which the object's bottom edge
        may lie, and how many rows below the bottom edge are looked at in the label map.
    min_contact : float
        With a label map: smallest fraction (0..1) of the object's bottom-edge columns whose
        pixels just below belong to the support.
    relation_gap_mm : float
        Depth difference (mm) above which one sibling is ``in_front_of`` / ``occludes`` another.
    floor_reach : float
        An object that rests on nothing found but reaches down to within this fraction of
        the frame height above the floor's top row becomes a child of the floor: the floor
        around a table's or a box's foot is hidden by the object itself, so its depth at the
        contact cannot be checked. Objects ending higher (a hand in the air) stay under Bkg.
    relations : bool
        Derive horizontal relations between siblings.
    """

    depth_tolerance_mm: float = 250.0
    depth_tolerance_rel: float = 0.15
    contact_px: int = 4
    min_contact: float = 0.2
    relation_gap_mm: float = 100.0
    floor_reach: float = 0.1
    relations: bool = True

    def __post_init__(self) -> None:
        checks = [
            ("depth_tolerance_mm", 0.0 <= self.depth_tolerance_mm <= 10_000.0, "0..10000 mm"),
            ("depth_tolerance_rel", 0.0 <= self.depth_tolerance_rel <= 1.0, "0..1"),
            ("contact_px", 0 <= self.contact_px <= 200, "0..200 px"),
            ("min_contact", 0.0 <= self.min_contact <= 1.0, "0..1"),
            ("relation_gap_mm", 0.0 <= self.relation_gap_mm <= 10_000.0, "0..10000 mm"),
            ("floor_reach", 0.0 <= self.floor_reach <= 1.0, "0..1 of the frame height"),
        ]
        for name, ok, want in checks:
            value = getattr(self, name)
            if not ok or (isinstance(value, float) and not math.isfinite(value)):
                raise InputError(f"TreeConfig.{name} must be in {want}, got {value!r}")


_DEFAULT = TreeConfig()


def support_depth_at(obj: SceneObject, row: float) -> float:
    """Estimated depth (mm) of a support's surface at an image row.

    A floor or table top seen obliquely recedes upward in the image. With only the mean and
    standard deviation of its depth, model the depth as a linear ramp over the object's rows:
    a uniform ramp of range R has standard deviation R / sqrt(12), centered on the mean row.
    Frontal objects have a small spread and so an almost flat ramp.

    Parameters
    ----------
    obj : SceneObject
        The support.
    row : float
        Image row (px).
    """
    height = obj.bbox_xy[3] - obj.bbox_xy[1]
    span = _SQRT12 * obj.depth_std
    frac = float(np.clip((obj.center_xy[1] - row) / height, -0.5, 0.5))
    return obj.depth + span * frac


def _contact_fractions(
    labels: NDArray[np.integer],
    objects: Sequence[SceneObject],
    index: Mapping[int, int],
    rows: int,
    need: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """Share of each object's bottom-edge columns whose pixels just below belong to each other object.

    Returns an (n, n) array: ``[i, j]`` for object i resting on object j. Only pixels inside
    each object's bounding box are read, so the cost follows the objects' size, not the frame's;
    objects with ``need[i]`` False (no support passed the geometric test) are not read at all.
    """
    n = len(objects)
    if n == 0:
        return np.zeros((0, 0))
    ids = np.array([o.id for o in objects], np.int64)
    boxes = np.array([o.bbox_xy for o in objects], np.int64).reshape(n, 4)
    todo = np.array([o.kind not in _SURFACES for o in objects], np.bool_)
    if need is not None:
        todo &= np.asarray(need, np.bool_)
    # object id -> its row and column in the result; ids beyond the table (labels of objects
    # not passed) are looked up as -1 in the kernel, so the label map needs no max() pass
    column_of = np.full(max(max(index, default=0), int(ids.max())) + 1, -1, np.int64)
    for oid, j in index.items():
        if oid >= 0:
            column_of[oid] = j
    return _contacts_below(np.ascontiguousarray(labels), ids, boxes, todo, column_of, int(rows), n)


@njit(cache=True, nogil=True)
def _contacts_below(
    labels: NDArray[np.integer],
    ids: NDArray[np.int64],
    boxes: NDArray[np.int64],
    todo: NDArray[np.bool_],
    column_of: NDArray[np.int64],
    rows: int,
    n: int,
) -> NDArray[np.float64]:
    # Per column of each object: its lowest pixel, then the first other label within `rows`
    # below it, reading each box once instead of building box-sized temporaries per object
    # (docs/design-notes.md, compiled kernels).
    out = np.zeros((n, n))
    h = labels.shape[0]
    for i in range(ids.size):
        if not todo[i]:
            continue
        oid = ids[i]
        x0, y0, x1, y1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        cols = 0
        for x in range(x0, x1):
            bottom = -1
            for y in range(y1 - 1, y0 - 1, -1):
                if labels[y, x] == oid:
                    bottom = y
                    break
            if bottom < 0:
                continue
            cols += 1
            for k in range(1, rows + 1):
                r = bottom + k
                if r >= h:
                    break
                lab = labels[r, x]
                if lab != 0 and lab != oid:
                    j = column_of[lab] if 0 < lab < column_of.size else -1
                    if j >= 0:
                        out[i, j] += 1.0
                    break
        if cols:
            for j in range(n):
                out[i, j] = out[i, j] / cols
    return out


def build_tree(
    objects: Sequence[SceneObject],
    frame_size: tuple[int, int],
    *,
    motion: Mapping[int, Motion] | None = None,
    config: TreeConfig | None = None,
    labels: NDArray[np.integer] | None = None,
) -> SceneTree:
    """Return the scene's parse tree: ``Bkg`` at the root, every object below what supports it.

    Parameters
    ----------
    objects : sequence of SceneObject
        The frame's objects (ids >= 1, unique).
    frame_size : (int, int)
        Frame (width, height) in pixels. The root's area is ``width * height`` and its center
        the image center, so the sentence carries the frame size.
    motion : mapping of int to Motion, optional
        Dynamic attributes per object id (v_radial, ttc, status) for sequences.
    config : TreeConfig, optional
        Tolerances; defaults to ``TreeConfig()``.
    labels : ndarray of int, shape (H, W), optional
        The segmentation's label map. When given, an object rests on a support only if the
        pixels just below its bottom edge belong to that support (``config.min_contact``).

    Returns
    -------
    SceneTree
        Children are ordered left to right by center x. Relations (one per sibling pair at
        most): ``a occludes b`` for every pair of siblings whose bounding boxes overlap with
        ``a`` nearer by more than ``relation_gap_mm``; then, between neighbours in left-to-right
        order only, the first of ``left_of`` (boxes disjoint in x), ``above`` / ``below``
        (disjoint in y) or ``in_front_of`` (depth gap). Neighbours only keep the list to
        about one relation per object; the rest follows from the attributes.

    Raises
    ------
    InputError
        For ids < 1, repeated ids, a non-positive frame size or a label map of another size.
    """
    cfg = config or _DEFAULT
    width, height = (int(v) for v in frame_size)
    if width <= 0 or height <= 0:
        raise InputError(f"build_tree: frame size must be positive (width, height), got {frame_size}")
    objs = list(objects)
    ids = [o.id for o in objs]
    if any(i < 1 for i in ids) or len(set(ids)) != len(ids):
        raise InputError(f"build_tree: object ids must be unique and >= 1 (0 is Bkg), got {ids}")
    if labels is not None and labels.shape != (height, width):
        raise InputError(
            f"build_tree: label map shape {labels.shape} does not match the frame size "
            f"{width}x{height} (expected shape ({height}, {width}))"
        )
    n = len(objs)
    parent = np.zeros(n, dtype=np.int64)  # object id of the support, 0 for Bkg
    if n:
        parent = _supports(objs, cfg, labels)
        _fall_to_floor(objs, parent, cfg.floor_reach * height)

    motion = motion or {}
    kids: dict[int, list[int]] = {}
    for i, p in enumerate(parent.tolist()):
        kids.setdefault(int(p), []).append(i)
    for v in kids.values():
        v.sort(key=lambda i: (objs[i].center_xy[0], objs[i].id))

    def node(i: int) -> Node:
        o = objs[i]
        m = motion.get(o.id)
        return Node(
            id=o.id,
            kind=o.kind,
            depth_label=o.depth_label,
            depth=float(o.depth),
            area=int(o.area),
            center_xy=(float(o.center_xy[0]), float(o.center_xy[1])),
            v_radial=None if m is None else m.v_radial,
            ttc=None if m is None else m.ttc,
            status=None if m is None else m.status,
            parts=tuple(sorted({p.depth_label for p in o.parts})),
            children=tuple(node(c) for c in kids.get(o.id, [])),
        )

    root = Node(
        id=0,
        kind=ROOT_KIND,
        depth_label=ROOT_LABEL,
        depth=0.0,
        area=width * height,
        center_xy=((width - 1) / 2.0, (height - 1) / 2.0),
        children=tuple(node(c) for c in kids.get(0, [])),
    )
    rels = _relations(objs, parent, kids, cfg) if cfg.relations and n > 1 else ()
    return SceneTree(root=root, relations=rels)


def _supports(objs: Sequence[SceneObject], cfg: TreeConfig, labels: NDArray[np.integer] | None) -> NDArray[np.int64]:
    """Support (object id, 0 for Bkg) of each object, decided for all pairs at once."""
    n = len(objs)
    bbox = np.array([o.bbox_xy for o in objs], dtype=np.float64)
    x0, y0, x_end, y_end = bbox.T
    last_x, last_y = x_end - 1, y_end - 1  # the box's last column and row
    cx = np.array([o.center_xy[0] for o in objs])
    depth = np.array([o.depth for o in objs])
    std = np.array([o.depth_std for o in objs])
    area = np.array([o.area for o in objs], dtype=np.float64)
    cy = np.array([o.center_xy[1] for o in objs])
    idv = np.array([o.id for o in objs], dtype=np.float64)
    kind = [o.kind for o in objs]
    is_floor = np.array([k == "floor" for k in kind])
    rests = np.array([k not in _SURFACES for k in kind])  # may rest on something
    holds = np.array([k not in ("wall", "ceiling") for k in kind])  # may hold something
    m = float(cfg.contact_px)

    # Rows i: the object; columns j: the candidate support.
    foot = last_y[:, None]
    ok = rests[:, None] & holds[None, :] & ~np.eye(n, dtype=bool)
    ok &= (cx[:, None] >= x0[None, :] - m) & (cx[:, None] <= last_x[None, :] + m)
    ok &= (foot >= y0[None, :] - m) & (foot <= last_y[None, :] + m)
    # A strict order on (floor, bottom row, area, -id) keeps the support relation a tree:
    # a support reaches at least as low in the image as what it holds, and is larger.
    rank = np.empty(n, dtype=np.int64)
    rank[np.lexsort((-idv, area, y_end, is_floor))] = np.arange(n)
    greater = rank[None, :] > rank[:, None]
    ok &= greater
    # Support depth at the object's bottom row (linear ramp, see support_depth_at).
    height = (y_end - y0)[None, :]
    frac = np.clip((cy[None, :] - foot) / height, -0.5, 0.5)
    z_at = depth[None, :] + _SQRT12 * std[None, :] * frac
    err = np.abs(depth[:, None] - z_at)
    tol = np.maximum(cfg.depth_tolerance_mm, cfg.depth_tolerance_rel * z_at)
    ok &= err <= tol
    score = err / np.maximum(tol, 1e-9) + 1e-12 * area[None, :]
    if labels is not None:
        index = {o.id: i for i, o in enumerate(objs)}
        # Only objects with a geometric candidate need their pixels read: a large background
        # object (a wall behind everything) has none and would cost a full-frame scan.
        contact = _contact_fractions(labels, objs, index, max(cfg.contact_px, 1), need=ok.any(axis=1))
        ok &= contact >= cfg.min_contact
        # Contact with the pixels below is the stronger evidence; depth breaks ties.
        score = score - 10.0 * contact
    score = np.where(ok, score, np.inf)
    best = np.argmin(score, axis=1)
    has = np.isfinite(score[np.arange(n), best])
    return np.where(has, idv[best], 0).astype(np.int64)


def _fall_to_floor(objs: Sequence[SceneObject], parent: NDArray[np.int64], reach_px: float) -> None:
    """Give unsupported objects that reach down to the floor's rows to the (largest) floor."""
    floors = [o for o in objs if o.kind == "floor"]
    if not floors:
        return
    floor = max(floors, key=lambda o: (o.area, -o.id))
    fx0, fy0, fx1, _ = floor.bbox_xy
    for i, o in enumerate(objs):
        if parent[i] != 0 or o.kind in _SURFACES:
            continue
        x0, _, x1, y1 = o.bbox_xy
        if y1 - 1 >= fy0 - reach_px and x0 < fx1 and x1 > fx0:
            parent[i] = floor.id


def _relations(
    objs: Sequence[SceneObject], parent: NDArray[np.int64], kids: Mapping[int, list[int]], cfg: TreeConfig
) -> tuple[Relation, ...]:
    gap = cfg.relation_gap_mm
    bbox = np.array([o.bbox_xy for o in objs], dtype=np.float64)
    depth = np.array([o.depth for o in objs])
    x0, y0, x1, y1 = bbox.T
    overlap = (x0[:, None] < x1[None, :]) & (x0[None, :] < x1[:, None])
    overlap &= (y0[:, None] < y1[None, :]) & (y0[None, :] < y1[:, None])
    siblings = parent[:, None] == parent[None, :]
    occ = overlap & siblings & (depth[:, None] + gap < depth[None, :])
    out = [Relation(objs[i].id, "occludes", objs[j].id) for i, j in zip(*np.nonzero(occ), strict=True)]
    # Plain lists: indexing numpy scalars one by one costs more than the whole loop.
    occl = occ.tolist()
    bx0, by0, bx1, by1 = x0.tolist(), y0.tolist(), x1.tolist(), y1.tolist()
    z = depth.tolist()
    for group in kids.values():
        for i, j in itertools.pairwise(group):
            if occl[i][j] or occl[j][i]:
                continue
            a, b = objs[i].id, objs[j].id
            if bx1[i] <= bx0[j]:
                out.append(Relation(a, "left_of", b))
            elif by1[i] <= by0[j]:
                out.append(Relation(a, "above", b))
            elif by1[j] <= by0[i]:
                out.append(Relation(a, "below", b))
            elif z[i] + gap < z[j]:
                out.append(Relation(a, "in_front_of", b))
            elif z[j] + gap < z[i]:
                out.append(Relation(b, "in_front_of", a))
    return tuple(out)
