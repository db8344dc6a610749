"""Action plans and the clearance channel on hand-built scenes whose right answer is known."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from depthgram.act import ActConfig, clearance_channel, column_clearance, openings, plan, plan_to_dict, plan_to_text
from depthgram.errors import InputError
from depthgram.frame import Intrinsics, make_frame
from depthgram.scene.tree import Node, SceneTree

W, H = 176, 132
K = Intrinsics(fx=100.0, fy=100.0, cx=87.5, cy=65.5)
SENSOR_H = 1000.0  # ActConfig default sensor height (mm)


def _floor(depth: np.ndarray) -> np.ndarray:
    """Paint a flat floor 1 m below a level sensor where it is nearer than what is there."""
    v = np.arange(H, dtype=np.float64)[:, None] - K.cy
    with np.errstate(divide="ignore"):
        z = np.where(v > 0, SENSOR_H * K.fy / v, np.inf)
    return np.where(z < depth, z, depth)


def box_scene() -> np.ndarray:
    """A wall close on the left, a box ahead, a back wall far away on the right; a floor."""
    d = np.full((H, W), 3500.0)
    d[:, :40] = 900.0  # left wall, inside the safety distance
    d[30:101, 40:91] = 800.0  # box ahead of the sensor
    return _floor(d)


def tree_of(*nodes: Node) -> SceneTree:
    return SceneTree(Node(0, "Bkg", -1, 0.0, W * H, (W / 2, H / 2), children=nodes))


BOX = Node(1, "object", 0, 800.0, 51 * 71, (65.0, 65.0))


def test_box_ahead_is_avoided_and_channel_opens_right() -> None:
    frame = make_frame(box_scene(), intrinsics=K)
    p = plan(tree_of(BOX), frame)
    (a,) = p.actions
    assert a.action == "avoid"
    ch = p.channel
    assert ch is not None
    assert (ch.col_start, ch.col_stop) == (91, 175)
    # Hand-computed: pinch at the box (800 mm), 85 columns at fx = 100 -> 680 mm.
    assert ch.width_mm == pytest.approx(85 / 100 * 800, rel=1e-4)
    assert ch.angle_deg == pytest.approx(math.degrees(math.atan((133 - 87.5) / 100)), abs=1e-6)
    assert ch.angle_deg > 0  # to the right, where the space is
    assert ch.free_mm == pytest.approx(3500.0)
    assert "right" in plan_to_text(p)


def test_floor_is_ignored_by_the_channel() -> None:
    d = _floor(np.full((H, W), 5000.0))
    near = column_clearance(make_frame(d, intrinsics=K))
    # Only the far wall is in the band: the floor (as near as 1.5 m at the bottom row) is not.
    assert np.allclose(near, 5000.0)
    ch = clearance_channel(make_frame(d, intrinsics=K))
    assert ch is not None and (ch.col_start, ch.col_stop) == (0, W - 1)
    assert ch.angle_deg == pytest.approx(0.0, abs=1e-9)


def test_wall_fully_in_front_blocks_the_channel() -> None:
    frame = make_frame(np.full((H, W), 700.0), intrinsics=K)
    wall = Node(1, "wall", 0, 700.0, W * H, (87.5, 65.5))
    p = plan(tree_of(wall), frame)
    assert p.channel is None and p.channel_checked
    assert p.actions[0].action == "avoid"
    assert "blocked" in plan_to_text(p)


def test_opening_narrower_than_the_body_is_not_a_channel() -> None:
    d = np.full((H, W), 700.0)
    d[:, 80:96] = 4000.0  # 16 columns at the 700 mm pinch: 112 mm, far below 600 mm
    assert clearance_channel(make_frame(d, intrinsics=K)) is None
    # Without intrinsics the body width is in pixels: 16 px passes a 10 px body.
    ch = clearance_channel(make_frame(d), ActConfig(body_width_px=10))
    assert ch is not None and (ch.col_start, ch.col_stop) == (80, 95)
    assert ch.width_mm is None and ch.angle_deg is None


def test_channel_choice_ahead_or_widest() -> None:
    d = np.full((H, W), 700.0)
    d[:, 0:70] = 3000.0  # wide opening on the left, 70 px
    d[:, 80:130] = 3000.0  # narrower one nearer the middle, 50 px
    ahead = clearance_channel(make_frame(d), ActConfig(body_width_px=40))
    widest = clearance_channel(make_frame(d), ActConfig(body_width_px=40, channel_choice="widest"))
    assert ahead is not None and ahead.col_start == 80
    assert widest is not None and widest.col_start == 0


def test_unknown_columns_are_blocked_unless_configured() -> None:
    d = np.full((H, W), 700.0)
    d[:, 100:] = 0.0  # no reading
    assert clearance_channel(make_frame(d), ActConfig(body_width_px=40)) is None
    ch = clearance_channel(make_frame(d), ActConfig(body_width_px=40, unknown_is_free=True))
    assert ch is not None and (ch.col_start, ch.col_stop) == (100, W - 1) and ch.free_mm is None


def test_openings_runs() -> None:
    assert openings(np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], bool)) == [(0, 1), (4, 4), (6, 8)]
    assert openings(np.zeros(5, bool)) == []


def test_small_near_object_is_grasped_far_one_is_not() -> None:
    frame = make_frame(np.full((H, W), 3000.0), intrinsics=K)
    cup = Node(1, "object", 0, 500.0, 100, (88.0, 80.0))  # 10x10 px at 0.5 m: 50 mm
    far_cup = Node(2, "object", 1, 1500.0, 11, (88.0, 80.0))  # ~50 mm at 1.5 m: beyond reach
    p = plan(tree_of(cup, far_cup), frame)
    by_id = {a.object_id: a for a in p.actions}
    assert by_id[1].action == "grasp"
    assert by_id[2].action != "grasp"
    # Action vector: unit ray through the center, distance = depth * |ray| (hand-computed).
    ray = np.array([(88.0 - 87.5) / 100, (80.0 - 65.5) / 100, 1.0])
    assert by_id[1].direction == pytest.approx(tuple(ray / np.linalg.norm(ray)))
    assert by_id[1].distance_mm == pytest.approx(500.0 * np.linalg.norm(ray))
    assert by_id[1].cost_mm == pytest.approx(by_id[1].distance_mm)


def test_walls_and_floor_are_never_grasped() -> None:
    frame = make_frame(np.full((H, W), 3000.0), intrinsics=K)
    small_wall = Node(1, "wall", 0, 400.0, 100, (88.0, 65.0))
    floor = Node(2, "floor", 1, 600.0, 100, (88.0, 120.0))
    acts = {a.object_id: a.action for a in plan(tree_of(small_wall, floor), frame).actions}
    assert acts == {1: "avoid", 2: "none"}


def test_ranking_avoid_then_grasp_then_by_label() -> None:
    frame = make_frame(np.full((H, W), 3000.0), intrinsics=K)
    nodes = (
        Node(1, "object", 2, 1800.0, 400, (90.0, 60.0)),  # in path, label 2 -> avoid
        Node(2, "object", 0, 500.0, 100, (100.0, 70.0)),  # grasp
        Node(3, "object", 1, 1200.0, 900, (85.0, 65.0)),  # in path, label 1 -> avoid
        Node(4, "object", 3, 3000.0, 400, (5.0, 65.0)),  # far aside -> none
    )
    order = [(a.object_id, a.action) for a in plan(tree_of(*nodes), frame).actions]
    assert order == [(3, "avoid"), (1, "avoid"), (2, "grasp"), (4, "none")]


def test_ttc_below_threshold_warns() -> None:
    frame = make_frame(np.full((H, W), 3000.0), intrinsics=K)
    coming = Node(1, "object", 1, 2600.0, 900, (88.0, 65.0), v_radial=-2000.0, ttc=1.3)
    slow = Node(2, "object", 2, 2800.0, 900, (20.0, 65.0), v_radial=-500.0, ttc=5.6)
    p = plan(tree_of(coming, slow), frame, config=ActConfig(ttc_warning_s=2.0))
    assert [w.object_id for w in p.warnings] == [1]
    assert p.warnings[0].ttc == pytest.approx(1.3)
    # Beyond the look-ahead, yet avoided because it arrives within the threshold.
    assert {a.object_id: a.action for a in p.actions}[1] == "avoid"
    assert plan_to_text(p).startswith("WARNING object 1")


def test_pixel_mode_without_intrinsics() -> None:
    ahead = Node(1, "object", 0, 900.0, 2000, (88.0, 66.0))
    aside = Node(2, "object", 1, 1200.0, 2000, (10.0, 66.0))
    p = plan(tree_of(ahead, aside), frame_size=(W, H))
    acts = {a.object_id: a for a in p.actions}
    assert acts[1].action == "avoid" and acts[2].action == "none"
    # Image direction from the image center (87.5, 65.5).
    assert acts[2].direction == pytest.approx((-1.0, 0.0), abs=0.01)
    assert len(acts[2].direction) == 2
    assert p.channel is None and not p.channel_checked
    assert "unknown" in plan_to_text(p)


def test_plan_to_dict_is_json_ready() -> None:
    frame = make_frame(box_scene(), intrinsics=K)
    d = plan_to_dict(plan(tree_of(BOX), frame))
    back = json.loads(json.dumps(d))
    assert back["actions"][0]["action"] == "avoid"
    # cost in the unit its key names, beside the distance (mm both)
    assert back["actions"][0]["cost_mm"] == pytest.approx(back["actions"][0]["distance_mm"], abs=0.1)
    assert back["channel"]["columns"] == [91, 175]
    assert back["channel"]["width_mm"] == pytest.approx(680.0)


def test_bad_inputs_are_clear_errors() -> None:
    with pytest.raises(InputError, match="frame_size"):
        plan(tree_of(BOX))
    with pytest.raises(InputError, match="reach_mm"):
        ActConfig(reach_mm=-1)
    with pytest.raises(InputError, match="channel_choice"):
        ActConfig(channel_choice="left")
    with pytest.raises(InputError, match="path_corridor"):
        ActConfig(path_corridor=(0.8, 0.2))
