"""The simulator's scenes for new mountings (issue 28, item 6): arm cameras over clutter, a chest camera walking."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from depthgram import Pipeline
from depthgram.sensor import SCENES, simulate
from depthgram.sensor.geometry import Gait
from depthgram.sensor.scenes import (
    ARM_45_MM,
    ARM_DOWN_MM,
    CHEST_TILT_DEG,
    WALK_SPEED_MM_S,
    build_scene,
)

FLAT = {"dish": 18.0, "book": 25.0, "screwdriver": 18.0}


def test_the_new_scenes_are_known() -> None:
    assert {"arm_down", "arm_45", "chest_walk"} <= set(SCENES)


@pytest.mark.parametrize("sensor", ["tof", "sl"])
def test_arm_down_sees_the_table_and_flat_objects_at_their_exact_heights(sensor: str) -> None:
    (sim,) = simulate("arm_down", 1, size=(160, 120), sensor=sensor, noise=False)
    by_name = {o.name: o for o in sim.truth}
    assert set(by_name) == {"table", "dish", "book", "screwdriver", "banana", "mug", "box"}
    assert all(by_name[n].parent == by_name["table"].id for n in by_name if n != "table")
    # looking straight down, depth along the optical axis is the height below the camera
    for name, height in FLAT.items():
        pixels = sim.true_depth[sim.instances == by_name[name].id]
        assert_allclose(np.median(pixels), ARM_DOWN_MM - height, atol=1e-3)  # the top face
        assert pixels.min() >= ARM_DOWN_MM - height - 1e-3 and pixels.max() <= ARM_DOWN_MM  # and its sides
    table = sim.true_depth[sim.instances == by_name["table"].id]
    assert_allclose(table, ARM_DOWN_MM, atol=1e-3)
    assert sim.gravity is not None and sim.gravity.source == "simulator"
    assert_allclose(sim.gravity.vector, (0.0, 0.0, 1.0), atol=1e-12)
    assert sim.frame.gravity is None  # truth, not input: the camera has no IMU


def test_arm_45_looks_at_the_clutter_centre_from_45_degrees() -> None:
    (sim,) = simulate("arm_45", 1, size=(160, 120), noise=False)
    # the principal point lies between the four central pixels, all on the bare table: their
    # depths straddle the distance to the clutter's centre
    centre = sim.true_depth[59:61, 79:81]
    assert_allclose(centre.mean(), ARM_45_MM, atol=2.0)
    assert_allclose(sim.gravity.tilt_deg if sim.gravity else None, 45.0)
    box = next(o for o in sim.truth if o.name == "box")
    spec = build_scene("arm_45", (160, 120))
    assert spec.camera.pitch_deg == 45.0 and box.area > 50  # its top and a side face the camera


def test_gait_velocity_is_the_derivative_of_its_position() -> None:
    g = Gait()
    for t in (0.0, 0.13, 0.4, 0.77):
        dt = 1e-6
        assert_allclose(g.velocity(t), (g.position(t + dt) - g.position(t - dt)) / (2 * dt), rtol=1e-6, atol=1e-3)


@pytest.mark.parametrize("sensor", ["tof", "sl"])
def test_chest_walk_approaches_at_walking_speed_with_the_gait(sensor: str) -> None:
    sims = list(simulate("chest_walk", 3, size=(160, 120), sensor=sensor, fps=30.0, noise=False))
    t = math.radians(CHEST_TILT_DEG)
    gait = Gait(v=(0.0, 0.0, -WALK_SPEED_MM_S))
    for k, sim in enumerate(sims):
        v = gait.velocity(k / 30.0)
        expected = v[1] * -math.sin(t) + v[2] * math.cos(t)  # onto the optical axis (0, -sin t, cos t)
        box = next(o for o in sim.truth if o.name == "box")
        assert_allclose(box.v_radial, expected, rtol=1e-9)
        assert box.v_radial < -900.0
    # the box comes nearer by about a walking step's worth in two frames
    first, last = (next(o for o in s.truth if o.name == "box").depth for s in (sims[0], sims[-1]))
    assert first - last > 0.5 * WALK_SPEED_MM_S * math.cos(t) * 2 / 30.0
    assert sims[0].gravity is not None
    assert_allclose(sims[0].gravity.tilt_deg, CHEST_TILT_DEG)


@pytest.mark.parametrize("scene", ["arm_down", "arm_45", "chest_walk"])
def test_the_pipeline_describes_the_new_scenes_with_their_gravity(scene: str) -> None:
    sims = list(simulate(scene, 2, size=(160, 120), seed=4))
    gravity = sims[0].gravity
    assert gravity is not None
    results = list(Pipeline(gravity=gravity).run(s.frame for s in sims))
    record = results[0].to_record()
    assert record["camera"]["intrinsics_source"] == "given"  # a bare frame with intrinsics
    assert_allclose(record["gravity"]["vector"], gravity.vector, atol=1e-6)
    assert record["objects"]  # something is found; how well is the segmentation's to improve (issue 28)
    np.testing.assert_array_equal(results[1].frame.depth, sims[1].frame.depth)
