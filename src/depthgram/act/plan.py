"""From the scene tree to an action plan: grasp or avoid each object, the channel, ttc warnings.

Paper, section 4: "The object center indicates the action vector while the depth label
outlines the cost of the action." Each object node becomes one :class:`Action` whose
direction points from the sensor to the object's image center and whose ranking follows
its depth label.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from depthgram.act.channel import Channel, clearance_channel
from depthgram.act.config import ActConfig
from depthgram.errors import InputError
from depthgram.frame import Frame, Intrinsics
from depthgram.scene.tree import Node, SceneTree

__all__ = ["ACTIONS", "Action", "Plan", "TtcWarning", "plan", "plan_to_dict", "plan_to_text"]

#: Proposed actions, most urgent first (the order of the ranking).
ACTIONS = ("avoid", "grasp", "monitor", "none")

_GRASPABLE = ("object", "compound")  # a compound is one solid unit (paper, section 3)
_SUPPORTS = ("floor", "ceiling")  # what the body moves over or under: never an obstacle


@dataclass(frozen=True)
class Action:
    """The action proposed for one object.

    Attributes
    ----------
    object_id : int
        Node id in the scene tree.
    action : str
        One of :data:`ACTIONS`.
    direction : tuple of float
        Unit vector from the sensor toward the object's center: (X, Y, Z) in the camera frame
        (x right, y down, z forward) when intrinsics are known, else (x, y) in the image from
        its center (x right, y down).
    distance_mm : float
        Euclidean distance to the object's center (mm) with intrinsics; its mean depth without.
    cost_mm : float
        Effort of the action: the travel along the action vector (mm, the same unit as
        ``distance_mm``). Ranking uses the depth label first (the paper's cost) and this to
        break ties.
    depth_label : int
        Depth label of the object (0 nearest).
    kind : str
        Node kind (``object``, ``wall``, ...).
    reason : str
        Why this action, for people.
    """

    object_id: int
    action: str
    direction: tuple[float, ...]
    distance_mm: float
    cost_mm: float
    depth_label: int
    kind: str
    reason: str


@dataclass(frozen=True)
class TtcWarning:
    """An object approaching with time to collision below the threshold.

    Attributes
    ----------
    object_id : int
    ttc : float
        Time to collision (s, or frames when the frame period is unknown).
    depth_mm : float
    v_radial : float or None
        Radial velocity (mm/s or mm/frame; negative approaching).
    """

    object_id: int
    ttc: float
    depth_mm: float
    v_radial: float | None = None


@dataclass(frozen=True)
class Plan:
    """The action plan of one frame.

    Attributes
    ----------
    actions : tuple of Action
        Ranked: avoid, grasp, monitor, none; within each by depth label, then cost.
    channel : Channel or None
        The clearance channel; None when blocked or when no depth frame was given.
    warnings : tuple of TtcWarning
        Time-to-collision warnings, soonest first.
    channel_checked : bool
        Whether a depth frame was there to look for the channel (False: ``channel`` is None
        because it is unknown, not because the way is blocked).
    """

    actions: tuple[Action, ...] = ()
    channel: Channel | None = None
    warnings: tuple[TtcWarning, ...] = ()
    channel_checked: bool = False


def _direction(node: Node, size: tuple[int, int], k: Intrinsics | None) -> tuple[tuple[float, ...], float]:
    x, y = node.center_xy
    if k is not None:
        ray = ((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0)
        norm = math.sqrt(sum(c * c for c in ray))
        return tuple(c / norm for c in ray), float(node.depth) * norm
    w, h = size
    dx, dy = x - (w - 1) / 2.0, y - (h - 1) / 2.0
    norm = math.hypot(dx, dy)
    vec = (dx / norm, dy / norm) if norm > 1e-9 else (0.0, 0.0)
    return vec, float(node.depth)


def _in_path(node: Node, size: tuple[int, int], k: Intrinsics | None, cfg: ActConfig) -> bool:
    x = node.center_xy[0]
    if k is not None:
        # Lateral offset of the center (mm) against the strip the body sweeps, widened by the
        # object's own half width so that an object overlapping the strip counts.
        lateral = abs((x - k.cx) * node.depth / k.fx)
        half = 0.5 * math.sqrt(max(node.area, 0)) * node.depth / math.sqrt(k.fx * k.fy)
        return lateral <= cfg.body_width_mm / 2.0 + half
    w = size[0]
    return cfg.path_corridor[0] * w <= x <= cfg.path_corridor[1] * w


def _size(node: Node, k: Intrinsics | None) -> float:
    side_px = math.sqrt(max(node.area, 0))
    return side_px * node.depth / math.sqrt(k.fx * k.fy) if k is not None else side_px


def _decide(node: Node, size: tuple[int, int], k: Intrinsics | None, cfg: ActConfig, dist: float) -> tuple[str, str]:
    unit = "mm" if k is not None else "px"
    lo, hi = (cfg.grasp_min_mm, cfg.grasp_max_mm) if k is not None else (cfg.grasp_min_px, cfg.grasp_max_px)
    s = _size(node, k)
    approaching = node.ttc is not None and node.ttc < cfg.ttc_warning_s
    if node.kind in _GRASPABLE and dist <= cfg.reach_mm and lo <= s <= hi and not approaching:
        return "grasp", f"within reach ({dist:.0f} <= {cfg.reach_mm:.0f} mm), size {s:.0f} {unit} graspable"
    if node.kind in _SUPPORTS:
        return "none", f"{node.kind}: support, not an obstacle"
    if _in_path(node, size, k, cfg):
        if node.ttc is not None and approaching:
            return "avoid", f"in path, time to collision {node.ttc:.2f} < {cfg.ttc_warning_s:g}"
        if node.depth <= cfg.lookahead_mm:
            return "avoid", f"in path at {node.depth:.0f} mm (<= {cfg.lookahead_mm:.0f} mm look-ahead)"
        return "monitor", f"in path beyond look-ahead ({node.depth:.0f} mm)"
    if approaching:
        return "monitor", "approaching beside the path"
    if node.kind in _GRASPABLE and dist <= cfg.reach_mm:
        return "none", f"within reach but size {s:.0f} {unit} outside {lo:g}..{hi:g} {unit}"
    return "none", "out of the path" if node.kind in _GRASPABLE or node.kind == "wall" else "not actionable"


def plan(
    tree: SceneTree,
    frame: Frame | None = None,
    *,
    frame_size: tuple[int, int] | None = None,
    config: ActConfig | None = None,
) -> Plan:
    """Propose an action per object node, the clearance channel and ttc warnings.

    Parameters
    ----------
    tree : SceneTree
        The parsed scene; every node but the root is considered.
    frame : Frame, optional
        The depth frame the tree came from: gives the size, the intrinsics (metric directions
        and sizes) and the depth image for the clearance channel.
    frame_size : tuple of int, optional
        (width, height) in pixels, needed when no frame is given.
    config : ActConfig, optional

    Returns
    -------
    Plan

    Raises
    ------
    InputError
        When neither a frame nor a frame size is given, or they disagree.
    """
    cfg = config or ActConfig()
    if frame is not None:
        if frame_size is not None and tuple(frame_size) != frame.size:
            raise InputError(
                f"{frame.name or f'frame {frame.index}'}: frame_size {frame_size} differs from "
                f"the frame's size {frame.size}"
            )
        size = frame.size
        k = frame.intrinsics
    elif frame_size is not None:
        size = (int(frame_size[0]), int(frame_size[1]))
        if size[0] <= 0 or size[1] <= 0:
            raise InputError(f"plan: frame_size must be positive (width, height), got {frame_size}")
        k = None
    else:
        raise InputError("plan: give the depth frame or frame_size=(width, height)")

    actions: list[Action] = []
    warnings: list[TtcWarning] = []
    for node in tree.nodes():
        if node.kind == "part":
            continue
        direction, dist = _direction(node, size, k)
        action, reason = _decide(node, size, k, cfg, dist)
        actions.append(Action(node.id, action, direction, dist, dist, node.depth_label, node.kind, reason))
        if node.ttc is not None and 0 <= node.ttc < cfg.ttc_warning_s:
            warnings.append(TtcWarning(node.id, float(node.ttc), float(node.depth), node.v_radial))
    actions.sort(key=lambda a: (ACTIONS.index(a.action), a.depth_label, a.cost_mm, a.object_id))
    warnings.sort(key=lambda w: w.ttc)
    channel = clearance_channel(frame, cfg) if frame is not None else None
    return Plan(tuple(actions), channel, tuple(warnings), frame is not None)


def _r(v: float | None, nd: int = 3) -> float | None:
    return None if v is None else round(float(v), nd)


def plan_to_dict(p: Plan) -> dict[str, Any]:
    """Return the plan as plain JSON-ready data (lists, floats rounded, None for unknown)."""
    ch = p.channel
    return {
        "actions": [
            {
                "object": a.object_id,
                "action": a.action,
                "kind": a.kind,
                "depth_label": a.depth_label,
                "direction": [round(c, 4) for c in a.direction],
                "distance_mm": _r(a.distance_mm, 1),
                "cost_mm": _r(a.cost_mm, 1),
                "reason": a.reason,
            }
            for a in p.actions
        ],
        "channel_checked": p.channel_checked,
        "channel": None
        if ch is None
        else {
            "columns": [ch.col_start, ch.col_stop],
            "center_col": ch.center_col,
            "width_px": ch.width_px,
            "angle_deg": _r(ch.angle_deg, 2),
            "width_mm": _r(ch.width_mm, 1),
            "free_mm": _r(ch.free_mm, 1),
        },
        "warnings": [
            {"object": w.object_id, "ttc": _r(w.ttc, 3), "depth_mm": _r(w.depth_mm, 1), "v_radial": _r(w.v_radial, 2)}
            for w in p.warnings
        ],
    }


def plan_to_text(p: Plan) -> str:
    """Return the plan as a few lines for people: warnings first, then actions, then the channel."""
    lines = [f"WARNING object {w.object_id}: time to collision {w.ttc:.2f} at {w.depth_mm:.0f} mm" for w in p.warnings]
    for a in p.actions:
        d = ", ".join(f"{c:+.2f}" for c in a.direction)
        lines.append(
            f"{a.action:<7} object {a.object_id} ({a.kind}, label {a.depth_label}) "
            f"at {a.distance_mm:.0f} mm toward ({d}): {a.reason}"
        )
    ch = p.channel
    if ch is None:
        lines.append(
            "channel: blocked (no opening wide enough)" if p.channel_checked else "channel: unknown (no depth image)"
        )
    else:
        where = f"columns {ch.col_start}-{ch.col_stop}"
        if ch.angle_deg is not None and ch.width_mm is not None:
            side = "right" if ch.angle_deg > 0 else "left" if ch.angle_deg < 0 else "ahead"
            lines.append(f"channel: {abs(ch.angle_deg):.1f} deg {side}, {ch.width_mm:.0f} mm wide ({where})")
        else:
            lines.append(f"channel: {where}, {ch.width_px} px wide")
    return "\n".join(lines)
