"""Issue 30, item 3 "steady velocity": a ball closing at a steady speed reads it, under a moving camera too.

At 640 x 480 the ICP of a still ToF camera reads a motion of a millimetre or two on some frames
(a large approaching ball drags it), and an object's core was then read under the camera's motion
alone: at a fixed pixel the depth of an approaching convex surface changes faster than its
centre's, so the ball closing at 600 mm/s read about 640 mm/s on those frames (within 5 % 0.73 of
`ball_approach`'s frames). The core now also scales the object by its own radial motion.
Ray-cast frames, so the truth is exact.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from depthgram.dynamics import FramePixels, Tracker
from depthgram.dynamics.camera_motion import CameraMotion
from depthgram.dynamics.core_depth import core_depth_change
from depthgram.dynamics.evaluate import objects_from_labels
from depthgram.sensor.geometry import Body, Camera, Ellipsoid, Linear, cast
from depthgram.sensor.scenes import build_scene

BALL = (60.0, 1040.0, 2500.0)  # the ball's centre at t = 0 (mm), 100 mm radius, as `ball_approach`'s
# the camera's axes in the world at pitch 0: x right, y down, z forward
AXES = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])


def _bodies(size: tuple[int, int], start: tuple[float, float, float], speed: float) -> tuple[Body, ...]:
    """`ball_approach`'s floor and wall, with the ball at ``start`` closing at ``speed`` (mm/s)."""
    ball = Body(3, "ball", "object", (Ellipsoid(start, (100.0, 100.0, 100.0)),), 0.7, Linear(v=(0.0, 0.0, -speed)))
    return (*[b for b in build_scene("ball_approach", size).bodies if b.id != 3], ball)


@pytest.mark.parametrize("size", [(320, 240), (640, 480)])
def test_the_core_under_the_cameras_motion_reads_an_approaching_balls_depth_change(size: tuple[int, int]) -> None:
    # The camera steps 3 mm right, 1 up and 2 forward while the ball closes by 20 mm (600 mm/s
    # at 30 frames/s): every point of the ball comes 22 mm nearer. Read under the exact camera
    # motion alone its core said 23.3 mm (+5.8 %); with its own scale, within 0.3 %.
    w, h = size
    bodies = _bodies(size, (60.0, 1040.0, 1500.0), 600.0)
    pa, pb = np.array([0.0, 1000.0, 0.0]), np.array([3.0, 1001.0, 2.0])
    before = cast(Camera(w, h, position=tuple(pa)), bodies, 0.0)
    now = cast(Camera(w, h, position=tuple(pb)), bodies, 1 / 30)
    k = Camera(w, h).intrinsics
    camera = CameraMotion(np.eye(3), AXES @ (pb - pa), k)
    ys, xs = np.nonzero(now.instances == 3)
    box = (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1)
    z = float(before.depth[before.instances == 3].mean())
    truth = -600.0 / 30 - (pb[2] - pa[2])
    change = core_depth_change(
        FramePixels(before.depth.astype(np.float32), before.instances.astype(np.int64), k),
        FramePixels(now.depth.astype(np.float32), now.instances.astype(np.int64), k),
        {3: (3, box, [], 1.0)},
        (0.0, 0.0),
        camera=camera,
        own_scales={3: (z - 600.0 / 30) / z},  # its own change over its depth then
    )
    assert_allclose(change[3], truth, rtol=0.01)


def test_a_ball_closing_before_a_hand_held_camera_reads_its_speed_from_the_third_frame() -> None:
    # 640 x 480 at 30 frames/s, the ball closing at 600 mm/s from 2.5 m to 0.7 m while the
    # camera sways by a few centimetres (as a hand holds it), 15 mm of depth noise a pixel.
    # Truth: the change of the ball's depth in the camera over each frame. Within 5 % in 0.85
    # of the frames from the third before the core's own scale, 0.97 with it.
    w, h, fps, speed = 640, 480, 30.0, 600.0
    bodies = _bodies((w, h), BALL, speed)
    k_int = Camera(w, h).intrinsics
    rng = np.random.default_rng(0)
    tracker = Tracker()

    def position(t: float) -> tuple[float, float, float]:
        s = np.sin(2 * np.pi * np.array([t / 1.1, t / 0.7, t / 0.9]))
        return (40.0 * s[0], 1000.0 + 20.0 * s[1], 24.0 * s[2])

    def ball_depth(t: float) -> float:  # the ball's centre in the camera (mm)
        return BALL[2] - speed * t - position(t)[2]

    err, sigma, truth = [], [], []
    ids = set()
    n = round((BALL[2] - 700.0) / speed * fps)
    for k in range(n):
        t = k / fps
        hit = cast(Camera(w, h, position=position(t)), bodies, t)
        depth = (hit.depth + rng.normal(0.0, 15.0, hit.depth.shape) * (hit.depth > 0)).astype(np.float32)
        labels = hit.instances.astype(np.int64)
        m = tracker.update(objects_from_labels(labels, depth), t, (w, h), FramePixels(depth, labels, k_int)).motions[3]
        ids.add(m.track_id)
        if k < 2:  # scored from the track's third frame
            continue
        assert m.v_radial is not None and m.v_sigma is not None, k
        v_true = (ball_depth(t) - ball_depth(t - 1 / fps)) * fps
        err.append(m.v_radial - v_true)
        sigma.append(m.v_sigma)
        truth.append(v_true)
    assert len(ids) == 1
    e, s, v = np.array(err), np.array(sigma), np.array(truth)
    assert np.mean(np.abs(e) <= 0.05 * np.abs(v)) >= 0.9
    assert np.mean(np.abs(e) <= 2 * s) >= 0.9  # v_sigma covers the error it makes
    # no bias: the median relative error measured +1.1 % (the sway's accelerations lag a little)
    assert_allclose(np.median(e / np.abs(v)), 0.0, atol=0.025)
