"""Action plans on rendered scenes whose right answer is known (sensor simulator -> pipeline -> plan)."""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.pipeline import Pipeline
from depthgram.sensor.geometry import Body, Box, Camera, Plane
from depthgram.sensor.scenes import SceneSpec
from depthgram.sensor.simulate import render
from depthgram.sensor.tof import ToFConfig


def _scene(box_x: tuple[float, float], box_z: float) -> SceneSpec:
    """A level wide-angle camera 1 m above the floor, a back wall at 2.5 m, one tall box on the floor.

    90 degrees across, so that at 0.7 m the view is 1.4 m wide and a 600 mm body can fit beside
    the box; two modulation frequencies keep the wall's far corners unambiguous.
    """
    cam = Camera(176, 132, fov_x_deg=90.0, position=(0.0, 1000.0, 0.0), pitch_deg=0.0)
    bodies = (
        Body(1, "floor", "floor", (Plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)),), 0.5),
        Body(2, "back_wall", "wall", (Plane((0.0, 0.0, 2500.0), (0.0, 0.0, -1.0)),), 0.7),
        Body(3, "box", "object", (Box((box_x[0], 0.0, box_z), (box_x[1], 1900.0, box_z + 300.0)),), 0.6, parent=1),
    )
    return SceneSpec("plan-test", cam, bodies, ToFConfig(f_mod2_hz=40e6))


def _plan(spec: SceneSpec):
    sim = render(spec, spec.tof, 0, 30.0, np.random.default_rng(0))
    result = Pipeline(track=False).process(sim.frame)
    box = sim.instances == 3
    best = max(result.segmentation.objects, key=lambda o: np.count_nonzero((result.segmentation.labels == o.id) & box))
    return result.plan, best.id


def test_obstacle_ahead_on_the_left_is_avoided_and_the_channel_opens_to_the_right() -> None:
    plan, box_id = _plan(_scene((-900.0, -150.0), 700.0))
    action = next(a for a in plan.actions if a.object_id == box_id)
    assert action.action == "avoid"
    assert plan.channel is not None
    assert plan.channel.angle_deg is not None and plan.channel.angle_deg > 0  # to the right, where the space is
    assert plan.channel.width_mm is not None and plan.channel.width_mm >= 600


def test_obstacle_on_the_right_opens_the_channel_to_the_left() -> None:
    plan, _ = _plan(_scene((150.0, 900.0), 700.0))
    assert plan.channel is not None and plan.channel.angle_deg is not None
    assert plan.channel.angle_deg < 0


def test_obstacle_beyond_the_safety_distance_leaves_the_way_open() -> None:
    plan, _ = _plan(_scene((-900.0, -150.0), 1500.0))
    assert plan.channel is not None and abs(plan.channel.angle_deg or 0.0) < 5.0  # straight ahead


def test_wall_to_wall_obstacle_blocks_the_channel() -> None:
    plan, box_id = _plan(_scene((-2500.0, 2500.0), 700.0))
    assert plan.channel is None
    assert next(a for a in plan.actions if a.object_id == box_id).action == "avoid"


@pytest.mark.parametrize("z", [400.0])
def test_small_near_object_is_grasped(z: float) -> None:
    cam = Camera(176, 132, position=(0.0, 1000.0, 0.0), pitch_deg=30.0)
    bodies = (
        Body(1, "floor", "floor", (Plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)),), 0.5),
        Body(2, "table", "object", (Box((-500.0, 0.0, 300.0), (500.0, 700.0, 1200.0)),), 0.5, parent=1),
        Body(3, "cup", "object", (Box((-40.0, 700.0, z + 100.0), (40.0, 800.0, z + 180.0)),), 0.8, parent=2),
    )
    plan, cup_id = _plan(SceneSpec("grasp-test", cam, bodies, ToFConfig()))
    assert next(a for a in plan.actions if a.object_id == cup_id).action == "grasp"


@pytest.mark.parametrize(
    ("sensor", "margin", "body"), [(1000.0, 100.0, 1800.0), (300.0, 100.0, 1800.0), (1500.0, 50.0, 1200.0)]
)
def test_body_band_equals_the_height_formula(sensor: float, margin: float, body: float) -> None:
    from depthgram.act import ActConfig
    from depthgram.act.channel import column_clearance

    sim = render(_scene((-900.0, -150.0), 700.0), ToFConfig(f_mod2_hz=40e6), 0, 30.0, np.random.default_rng(1))
    f = sim.frame
    cfg = ActConfig(sensor_height_mm=sensor, floor_margin_mm=margin, body_height_mm=body)
    k = f.intrinsics
    assert k is not None
    d = f.depth.astype(np.float64)
    height = sensor - (np.arange(d.shape[0])[:, None] - k.cy) * d / k.fy
    ok = f.valid & (d > 0) & (height > margin) & (height < body)
    np.testing.assert_allclose(column_clearance(f, cfg), np.where(ok, d, np.inf).min(axis=0), rtol=1e-6)
