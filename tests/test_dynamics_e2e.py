"""End to end on simulated ToF sequences: simulator -> segmentation -> tracker, against truth."""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.dynamics import evaluate_tracking
from depthgram.dynamics.evaluate import objects_from_labels, primary_segments
from depthgram.sensor import scenes
from depthgram.sensor.geometry import Body, Camera, Ellipsoid, Linear, Plane
from depthgram.sensor.scenes import FLOOR, SceneSpec
from depthgram.sensor.tof import ToFConfig


def test_approach_velocity_within_target_and_no_switch() -> None:
    # The hand comes at the sensor at 600 mm/s, turns at 1 s and recedes.
    score = evaluate_tracking("approach", 70, seed=1)
    (hand,) = score.bodies
    assert hand.visible_frames == hand.tracked_frames == 70
    assert hand.id_switches == 0
    assert len(hand.v_errors) >= 50
    assert any(t < 0 for t in hand.v_truth) and any(t > 0 for t in hand.v_truth)  # both directions scored
    # Target: within 5 % or 2 mm/frame (60 mm/s at 30 Hz), once the motion has lasted 3 frames.
    assert score.within(0.05, 60.0) == 1.0


def test_crossing_keeps_identity_behind_the_occluder_with_perfect_segmentation() -> None:
    # The tracker alone: objects straight from the truth instance map.
    score = evaluate_tracking("crossing", 75, seed=1, segmenter="truth")
    names = {b.name: b for b in score.bodies}
    cart, person = names["cart"], names["person"]
    # Every object that enters is tracked until it leaves, under one identity; the cart
    # passes behind the person for about four frames and comes back as itself.
    assert person.track_ids == (person.track_ids[0],) and cart.track_ids == (cart.track_ids[0],)
    frames = [f for f, _ in cart.id_by_frame]
    assert max(np.diff(frames)) >= 4  # the occlusion really happened
    assert score.lost_frames == 0
    assert score.within(0.05, 60.0) >= 0.9


def test_crossing_with_segmentation_keeps_the_cart_through_the_occlusion() -> None:
    # The surfaces default finds the cart again as a 362-px sliver at the person's far side;
    # the sliver's centre is 21 px off the cart's, as the one it went in as was 18 px off on
    # the other side. The track keeps its predicted centre while partly hidden (issue 13).
    score = evaluate_tracking("crossing", 48, seed=1)  # the cart is hidden around frames 34-37
    cart = {b.name: b for b in score.bodies}["cart"]
    frames = np.array([f for f, _ in cart.id_by_frame])
    ids = np.array([i for _, i in cart.id_by_frame])
    gap = int(np.argmax(np.diff(frames)))
    assert frames[gap + 1] - frames[gap] >= 4
    assert ids[gap] == ids[gap + 1]  # same track before and after passing behind the person


def test_objects_from_labels_hand_computed() -> None:
    labels = np.zeros((4, 6), np.int32)
    labels[1:3, 2:5] = 3
    depth = np.full((4, 6), 1000.0)
    depth[1, 2:5] = 1200.0
    (o,) = objects_from_labels(labels, depth)
    assert o.id == 3 and o.area == 6 and o.bbox_xy == (2, 1, 5, 3)
    assert o.center_xy == (3.0, 1.5) and o.depth == pytest.approx(1100.0) and o.depth_std == pytest.approx(100.0)
    inst = np.zeros_like(labels)
    inst[1:3, 2:4] = 7
    assert primary_segments(labels, inst) == {7: (3, 4)}


def test_person_keeps_one_id_from_entering_to_leaving_with_segmentation() -> None:
    # The person leaves the view around frames 44-60; the mean depth of its visible part drifts
    # as it crosses the border (a cylinder's flank is deeper than its middle), which once broke
    # the depth gate and gave it a new id for its last two frames.
    score = evaluate_tracking("crossing", 62, seed=1)
    person = next(b for b in score.bodies if b.name == "person")
    assert len(person.track_ids) == 1, person.track_ids
    assert person.id_switches == 0


def test_cart_keeps_one_id_from_entering_to_leaving_with_segmentation() -> None:
    # After the occlusion the cart comes out as a growing sliver whose centre lies off the
    # predicted centre of the whole cart by up to half its width; the track matches it by the
    # centre of the part it last saw, which once lost it to a new track one frame later.
    score = evaluate_tracking("crossing", 80, seed=1)
    cart = {b.name: b for b in score.bodies}["cart"]
    assert len(cart.track_ids) == 1, cart.track_ids
    assert score.id_switches == 0
    assert score.within(0.05, 60.0) >= 0.9


def _passing_balls(w: int, h: int) -> SceneSpec:
    """A near ball closing at 300 mm/s while a far ball passes behind it at 700 mm/s, sideways."""
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=0.0)
    near = Ellipsoid((0.0, 1000.0, 1600.0), (120.0,) * 3)
    far = Ellipsoid((-700.0, 1000.0, 1900.0), (120.0,) * 3)  # its front 180 mm behind the near one's at t = 0
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5),
        Body(2, "back_wall", "wall", (Plane((0.0, 0.0, 3000.0), (0.0, 0.0, -1.0)),), 0.7),
        Body(3, "near", "object", (near,), 0.7, Linear(v=(0.0, 0.0, -300.0)), parent=1),
        Body(4, "far", "object", (far,), 0.6, Linear(v=(700.0, 0.0, 0.0)), parent=1),
    )
    return SceneSpec("passing_balls", cam, bodies, ToFConfig())


def test_two_balls_touching_in_the_image_come_apart_with_their_ids(monkeypatch: pytest.MonkeyPatch) -> None:
    # Issue 13, item 4: the far ball slides behind the near one (they touch and overlap in the
    # image for about a second) and comes out on the other side. Both keep one id throughout;
    # the near ball's closing speed stays right while its neighbour drags on its outline.
    monkeypatch.setitem(scenes._BUILDERS, "passing_balls", _passing_balls)
    score = evaluate_tracking("passing_balls", 60, seed=1)
    balls = {b.name: b for b in score.bodies}
    near, far = balls["near"], balls["far"]
    assert near.tracked_frames == near.visible_frames == 60 and len(near.track_ids) == 1
    assert far.tracked_frames == far.visible_frames and len(far.track_ids) == 1
    assert score.id_switches == 0
    err, truth = np.abs(np.array(near.v_errors)), np.abs(np.array(near.v_truth))
    assert len(err) >= 50 and np.mean(err <= np.maximum(0.05 * truth, 60.0)) >= 0.95  # measured 1.00
