"""The scene's parse tree: the background start node, objects derived from it, supports.

Node attributes follow the paper's equations 12 and 17: area A, center (x, y), the depth
label and mean depth, and for sequences v_radial and time to collision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Motion", "Node", "Relation", "SceneTree"]


@dataclass(frozen=True)
class Motion:
    """Dynamic attributes of one object across frames (paper, equation 17).

    Attributes
    ----------
    track_id : int
        Stable identity across frames.
    v_radial : float or None
        Radial velocity (mm/s), positive means receding. None until it is known.
    ttc : float or None
        Time to collision (s) for approaching objects; None for receding or still ones, and
        while the velocity is not known well enough.
    status : str
        ``visible``, ``entering``, ``leaving`` or ``occluded``.
    v_sigma : float or None
        Standard deviation of ``v_radial`` (mm/s), None when not estimated.
    fps_assumed : float or None
        The frame rate (frames/s) assumed because the frames had no timestamps and no rate
        was given; None when the times were known. Velocities and times to collision scale
        with it.
    """

    track_id: int
    v_radial: float | None = None
    ttc: float | None = None
    status: str = "visible"
    v_sigma: float | None = None
    fps_assumed: float | None = None


@dataclass(frozen=True)
class Node:
    """One node of the parse tree.

    The root has kind ``Bkg`` and id 0. Every other node is a terminal ``o_<label>``
    carrying its object's attributes; objects standing on a support are its children.

    Conventions of :func:`depthgram.scene.build_tree`: the root's label is -1 (no depth
    band), its area is the frame's pixel count and its center the image center, so the
    frame size is recoverable; ``parts`` holds the sorted distinct depth labels of a
    compound object's parts (written ``o_2..5`` when successive).
    """

    id: int
    kind: str
    depth_label: int
    depth: float
    area: int
    center_xy: tuple[float, float]
    v_radial: float | None = None
    ttc: float | None = None
    status: str | None = None
    parts: tuple[int, ...] = ()
    children: tuple[Node, ...] = ()


@dataclass(frozen=True)
class Relation:
    """A horizontal link between two siblings: ``a <relation> b``.

    ``relation`` is one of ``left_of``, ``right_of``, ``above``, ``below``,
    ``in_front_of``, ``occludes``.
    """

    a: int
    relation: str
    b: int


@dataclass(frozen=True)
class SceneTree:
    """A parsed scene: its root node and the horizontal relations between siblings."""

    root: Node
    relations: tuple[Relation, ...] = ()

    @property
    def frame_size(self) -> tuple[int, int] | None:
        """(width, height) in px of the frame the tree describes, read back from the root.

        :func:`depthgram.scene.build_tree` gives the root the frame's pixel count as area and
        the middle pixel ``((W - 1) / 2, (H - 1) / 2)`` as center, and the sentence keeps both,
        so the size survives a round trip through text. None when the root does not follow
        that convention (a hand-made tree).
        """
        cx, cy = self.root.center_xy
        if not (math.isfinite(cx) and math.isfinite(cy)):
            return None
        w, h = round(2 * cx + 1), round(2 * cy + 1)
        if w <= 0 or h <= 0 or w * h != self.root.area or abs(2 * cx + 1 - w) > 1e-6 or abs(2 * cy + 1 - h) > 1e-6:
            return None
        return (w, h)

    def nodes(self) -> list[Node]:
        """All nodes but the root, depth-first in child order."""
        out: list[Node] = []
        stack = list(reversed(self.root.children))
        while stack:
            n = stack.pop()
            out.append(n)
            stack.extend(reversed(n.children))
        return out

    def parent_of(self) -> dict[int, int]:
        """Map node id to its parent's id (0 for the root's children)."""
        out: dict[int, int] = {}
        stack = [self.root]
        while stack:
            n = stack.pop()
            for c in n.children:
                out[c.id] = n.id
                stack.append(c)
        return out
