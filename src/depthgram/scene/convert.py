"""Scene trees as JSON-ready dictionaries, and back."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from depthgram.errors import InputError
from depthgram.scene.tree import Node, Relation, SceneTree

__all__ = ["tree_from_dict", "tree_to_dict"]


def _node_dict(n: Node, parent: int | None) -> dict[str, Any]:
    return {
        "id": n.id,
        "kind": n.kind,
        "depth_label": n.depth_label,
        "depth": n.depth,
        "area": n.area,
        "center_xy": [n.center_xy[0], n.center_xy[1]],
        "parent": parent,
        "children": [c.id for c in n.children],
        "parts": list(n.parts),
        "v_radial": n.v_radial,
        "ttc": n.ttc,
        "status": n.status,
    }


def tree_to_dict(tree: SceneTree) -> dict[str, Any]:
    """Return a JSON-ready dictionary of the tree.

    Returns
    -------
    dict
        ``nodes``: the root then every node depth-first, each with ``id``, ``kind``,
        ``depth_label``, ``depth`` (mm), ``area`` (px), ``center_xy`` ([x, y] px), ``parent`` (None
        for the root), ``children`` (ids, in order), ``parts`` (depth labels), ``v_radial``,
        ``ttc`` and ``status`` (None when unknown); ``relations``: ``[a, relation, b]`` lists.
    """
    nodes = [_node_dict(tree.root, None)]
    stack = [(c, tree.root.id) for c in reversed(tree.root.children)]
    while stack:
        n, p = stack.pop()
        nodes.append(_node_dict(n, p))
        stack.extend((c, n.id) for c in reversed(n.children))
    return {"nodes": nodes, "relations": [[r.a, r.relation, r.b] for r in tree.relations]}


def tree_from_dict(data: Mapping[str, Any]) -> SceneTree:
    """Rebuild a tree written by :func:`tree_to_dict`.

    Raises
    ------
    InputError
        When a node lacks a field, an id repeats, a child id is unknown or no root is given.
    """
    try:
        raw = {int(d["id"]): d for d in data["nodes"]}
        if len(raw) != len(data["nodes"]):
            raise InputError("tree dictionary: node ids repeat")
        roots = [d for d in data["nodes"] if d.get("parent") is None]
        if len(roots) != 1:
            raise InputError(f"tree dictionary: expected one root (parent null), found {len(roots)}")

        def opt(v: Any) -> float | None:
            return None if v is None else float(v)

        def build(d: Mapping[str, Any], seen: frozenset[int]) -> Node:
            nid = int(d["id"])
            if nid in seen:
                raise InputError(f"tree dictionary: node {nid} is its own ancestor")
            kids = []
            for c in d["children"]:
                if int(c) not in raw:
                    raise InputError(f"tree dictionary: node {nid} names unknown child {c}")
                kids.append(build(raw[int(c)], seen | {nid}))
            return Node(
                id=nid,
                kind=str(d["kind"]),
                depth_label=int(d["depth_label"]),
                depth=float(d["depth"]),
                area=int(d["area"]),
                center_xy=(float(d["center_xy"][0]), float(d["center_xy"][1])),
                v_radial=opt(d.get("v_radial")),
                ttc=opt(d.get("ttc")),
                status=None if d.get("status") is None else str(d["status"]),
                parts=tuple(int(p) for p in d.get("parts", ())),
                children=tuple(kids),
            )

        root = build(roots[0], frozenset())
        rels = tuple(Relation(int(a), str(r), int(b)) for a, r, b in data.get("relations", ()))
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"tree dictionary: malformed ({type(exc).__name__}: {exc})") from None
    return SceneTree(root=root, relations=rels)
