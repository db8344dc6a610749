"""Ray casting against analytic depths of planes, spheres, boxes and cylinders."""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.sensor.geometry import (
    BackAndForth,
    Body,
    Box,
    Camera,
    Cylinder,
    Ellipsoid,
    Linear,
    Plane,
    cast,
)

# Odd sizes put a pixel centre exactly on the optical axis.
CAM = Camera(177, 133, position=(0.0, 1000.0, 0.0))
CY, CX = 66, 88


def test_intrinsics_follow_the_40_degree_field_of_view() -> None:
    k = Camera(176, 132).intrinsics
    assert k.fx == pytest.approx(88.0 / np.tan(np.radians(20.0)))  # 241.78 px
    assert k.fy == k.fx
    assert (k.cx, k.cy) == (87.5, 65.5)
    vertical = 2 * np.degrees(np.arctan(66.0 / k.fy))
    assert vertical == pytest.approx(30.5, abs=0.1)  # "about 40 x 30 degrees"


def test_fronto_parallel_plane_has_constant_depth_and_growing_ray_length() -> None:
    hits = cast(CAM, (Body(1, "wall", "wall", (Plane((0.0, 0.0, 2000.0), (0.0, 0.0, -1.0)),)),), 0.0)
    np.testing.assert_allclose(hits.depth, 2000.0)
    assert (hits.instances == 1).all()
    k = CAM.intrinsics
    x, y = (0 - k.cx) / k.fx, (0 - k.cy) / k.fy
    assert hits.distance[0, 0] == pytest.approx(2000.0 * np.sqrt(1 + x * x + y * y))
    assert hits.distance[CY, CX] == pytest.approx(2000.0)


def test_sphere_depth_matches_the_analytic_intersection() -> None:
    c, r = np.array([0.0, 1000.0, 1500.0]), 200.0
    hits = cast(CAM, (Body(1, "ball", "object", (Ellipsoid(tuple(c), (r, r, r)),)),), 0.0)
    assert hits.depth[CY, CX] == pytest.approx(1300.0)
    k = CAM.intrinsics
    for v, u in ((CY, CX + 20), (CY - 15, CX + 10), (CY + 5, CX - 25)):
        d = np.array([(u - k.cx) / k.fx, -(v - k.cy) / k.fy, 1.0])  # world Y is up
        oc = -(c - np.array(CAM.position))
        a, b, cc = d @ d, 2 * d @ oc, oc @ oc - r * r
        t = (-b - np.sqrt(b * b - 4 * a * cc)) / (2 * a)
        assert hits.depth[v, u] == pytest.approx(t, rel=1e-9)
    # outside the silhouette the ray misses: radius r at 1500 mm spans r/1500 * fx px
    rim = int(np.ceil(r / np.sqrt(1500.0**2 - r * r) * k.fx)) + 1
    assert hits.instances[CY, CX + rim] == 0
    assert hits.depth[CY, CX + rim] == 0.0


def test_box_cylinder_and_nearest_hit_wins() -> None:
    box = Body(1, "box", "object", (Box((-100.0, 900.0, 1000.0), (100.0, 1100.0, 1200.0)),))
    cyl = Body(2, "can", "object", (Cylinder((300.0, 800.0, 1600.0), 100.0, 400.0),))
    wall = Body(3, "wall", "wall", (Plane((0.0, 0.0, 2500.0), (0.0, 0.0, -1.0)),))
    hits = cast(CAM, (wall, cyl, box), 0.0)
    assert hits.depth[CY, CX] == pytest.approx(1000.0)  # front face of the box
    assert hits.instances[CY, CX] == 1
    k = CAM.intrinsics
    u = round(k.cx + 300.0 / 1500.0 * k.fx)  # column through the cylinder's axis
    assert hits.instances[CY, u] == 2
    x = (u - k.cx) / k.fx
    # ray (x, 0, 1) against the circle (X - 300)^2 + (Z - 1600)^2 = 100^2
    a, b, c = x * x + 1, -2 * (300 * x + 1600), 300**2 + 1600**2 - 100**2
    assert hits.depth[CY, u] == pytest.approx((-b - np.sqrt(b * b - 4 * a * c)) / (2 * a))
    assert hits.instances[0, 0] == 3 and hits.depth[0, 0] == pytest.approx(2500.0)


def test_pitched_camera_sees_the_floor_at_height_over_sine() -> None:
    cam = Camera(177, 133, position=(0.0, 1000.0, 0.0), pitch_deg=30.0)
    hits = cast(cam, (Body(1, "floor", "floor", (Plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)),)),), 0.0)
    # optical axis meets the floor after 1000 / sin 30° = 2000 mm
    assert hits.depth[CY, CX] == pytest.approx(2000.0)
    assert np.all(np.diff(hits.depth[:, CX]) < 0)  # nearer toward the bottom rows


def test_motions_move_the_body() -> None:
    ball = Ellipsoid((0.0, 1000.0, 2000.0), (100.0, 100.0, 100.0))
    lin = Body(1, "ball", "object", (ball,), motion=Linear(v=(0.0, 0.0, -500.0)))
    assert cast(CAM, (lin,), 1.0).depth[CY, CX] == pytest.approx(1400.0)
    tri = BackAndForth((0.0, 0.0, 0.0), (0.0, 0.0, -600.0), 2.0)
    np.testing.assert_allclose(tri.position(1.0), [0, 0, -600])
    np.testing.assert_allclose(tri.position(3.0), [0, 0, -600])
    np.testing.assert_allclose(tri.position(4.5), [0, 0, -300])
    np.testing.assert_allclose(tri.velocity(0.5), [0, 0, -600])
    np.testing.assert_allclose(tri.velocity(2.5), [0, 0, 600])


def test_camera_rejects_absurd_field_of_view() -> None:
    with pytest.raises(InputError, match="field of view"):
        Camera(10, 10, fov_x_deg=180.0)
