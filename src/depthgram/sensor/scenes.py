"""The named scenes of the simulator, built from :mod:`depthgram.sensor.geometry` primitives.

World frame: X right, Y up (floor at Y = 0), Z forward, millimetres. Every scene keeps its
surfaces within the 50 MHz ambiguity range (radial distance below about 2998 mm) except
``corridor``, whose floor, walls and ceiling run to an end wall at 6 m: its default sensor
therefore adds a 40 MHz second frequency for unwrapping (unambiguous to about 15 m), as the
paper's "multiple beams of different frequencies to extend the sensor range".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from depthgram.errors import InputError
from depthgram.frame import Gravity
from depthgram.sensor.geometry import (
    BackAndForth,
    Body,
    Box,
    Camera,
    Cylinder,
    Ellipsoid,
    Gait,
    Linear,
    Plane,
)
from depthgram.sensor.tof import ToFConfig

__all__ = [
    "APPROACH_SPEED_MM_S",
    "RUSH_SPEED_MM_S",
    "SCENES",
    "STEADY_SPEED_MM_S",
    "WALK_SPEED_MM_S",
    "SceneSpec",
    "build_scene",
]

#: Speed (mm/s) of the hand in ``approach``: toward the sensor for 2 s, then away for 2 s.
APPROACH_SPEED_MM_S = 600.0

FLOOR = Plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))


@dataclass(frozen=True)
class SceneSpec:
    """A scene ready to render: camera, bodies and the sensor model it is meant for."""

    name: str
    camera: Camera
    bodies: tuple[Body, ...]
    tof: ToFConfig

    @property
    def gravity(self) -> Gravity:
        """Which way is down in the camera's frame: exact, from the camera's pitch (source ``simulator``)."""
        g = Gravity.from_tilt(self.camera.pitch_deg)
        return Gravity(g.vector, "simulator")


def _back_wall(z: float) -> Plane:
    return Plane((0.0, 0.0, z), (0.0, 0.0, -1.0))


def _table(w: int, h: int) -> SceneSpec:
    # Camera above the table looking down 25°, so the top is a horizontal plane seen
    # obliquely (as in the paper's Fig. 1) and objects stand out against the wall behind.
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=14.0)
    top_y = 750.0
    legs = tuple(
        Box((x - 25.0, 0.0, z - 25.0), (x + 25.0, top_y - 40.0, z + 25.0))
        for x in (-600.0, 600.0)
        for z in (750.0, 1450.0)
    )
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.4),
        Body(2, "back_wall", "wall", (_back_wall(2300.0),), 0.7),
        Body(3, "table", "object", (Box((-650.0, top_y - 40.0, 700.0), (650.0, top_y, 1500.0)), *legs), 0.5, parent=1),
        Body(4, "cup", "object", (Cylinder((-280.0, top_y, 1000.0), 45.0, 110.0),), 0.8, parent=3),
        Body(5, "box", "object", (Box((-180.0, top_y, 1050.0), (-20.0, top_y + 150.0, 1170.0)),), 0.6, parent=3),
        Body(6, "ball", "object", (Ellipsoid((80.0, top_y + 70.0, 1000.0), (70.0, 70.0, 70.0)),), 0.7, parent=3),
        Body(7, "bottle", "object", (Cylinder((260.0, top_y, 1150.0), 40.0, 260.0),), 0.6, parent=3),
    )
    return SceneSpec("table", cam, bodies, ToFConfig())


def _corridor(w: int, h: int) -> SceneSpec:
    half_w, ceiling, end = 900.0, 2000.0, 6000.0
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=0.0)
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5),
        Body(2, "left_wall", "wall", (Plane((-half_w, 0.0, 0.0), (1.0, 0.0, 0.0)),), 0.8),
        Body(3, "right_wall", "wall", (Plane((half_w, 0.0, 0.0), (-1.0, 0.0, 0.0)),), 0.8),
        Body(4, "ceiling", "ceiling", (Plane((0.0, ceiling, 0.0), (0.0, -1.0, 0.0)),), 0.8),
        Body(5, "end_wall", "wall", (_back_wall(end),), 0.8),
        Body(6, "box", "object", (Box((-450.0, 0.0, 2600.0), (-100.0, 600.0, 2900.0)),), 0.7, parent=1),
        Body(7, "person", "object", (Cylinder((350.0, 0.0, 3800.0), 200.0, 1750.0),), 0.6, parent=1),
    )
    return SceneSpec("corridor", cam, bodies, ToFConfig(f_mod2_hz=40e6))


def _approach(w: int, h: int) -> SceneSpec:
    cam = Camera(w, h, position=(0.0, 1200.0, 0.0), pitch_deg=0.0)
    hand = Ellipsoid((0.0, 1200.0, 1800.0), (85.0, 100.0, 35.0))
    motion = BackAndForth((0.0, 0.0, 0.0), (0.0, 0.0, -APPROACH_SPEED_MM_S), 2.0)
    bodies = (
        Body(1, "back_wall", "wall", (_back_wall(2500.0),), 0.7),
        Body(2, "hand", "object", (hand,), 0.6, motion),
    )
    return SceneSpec("approach", cam, bodies, ToFConfig())


def _crossing(w: int, h: int) -> SceneSpec:
    # A person walks in from the left close by while a cart rolls in from the right behind:
    # the person hides the cart for about four frames at 30 fps around t = 1.2 s; both
    # leave on the far side (the person by t = 2 s, the cart by t = 2.5 s).
    cam = Camera(w, h, position=(0.0, 900.0, 0.0), pitch_deg=8.0)
    person = Cylinder((-720.0, 0.0, 1300.0), 200.0, 1800.0)
    cart = Box((1250.0 - 200.0, 0.0, 2100.0), (1250.0 + 200.0, 1000.0, 2350.0))
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5),
        Body(2, "back_wall", "wall", (_back_wall(2500.0),), 0.7),
        Body(3, "person", "object", (person,), 0.6, Linear(v=(700.0, 0.0, 0.0)), parent=1),
        Body(4, "cart", "object", (cart,), 0.7, Linear(v=(-900.0, 0.0, 0.0)), parent=1),
    )
    return SceneSpec("crossing", cam, bodies, ToFConfig())


#: Sphere of ``ball_wall``: centre depth (mm) and radius (mm). Its image covers 0.5 % of the
#: frame at any size of aspect 4:3 (the 40 degree camera's focal length scales with the width):
#: pi * (f r / z)**2 = 0.005 * w * h with f = (w / 2) / tan(20 deg) gives r = 40.4 mm at 1600 mm.
BALL_DEPTH_MM = 1600.0
BALL_RADIUS_MM = 40.4
#: Distance (mm) from the ball's centre to the wall behind it, along the optical axis.
BALL_WALL_GAP_MM = 400.0


def _ball_wall(w: int, h: int) -> SceneSpec:
    # A small ball hanging 0.4 m in front of a wall (issue 12): its pixels make no histogram
    # peak of their own, so a band-per-peak segmentation hands them to the wall.
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=0.0)
    centre = (150.0, 1080.0, BALL_DEPTH_MM)
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5),
        Body(2, "back_wall", "wall", (_back_wall(BALL_DEPTH_MM + BALL_WALL_GAP_MM),), 0.7),
        Body(3, "ball", "object", (Ellipsoid(centre, (BALL_RADIUS_MM,) * 3),), 0.7),
    )
    return SceneSpec("ball_wall", cam, bodies, ToFConfig())


def _touching(w: int, h: int) -> SceneSpec:
    # A cylinder standing against the side of a box on a table, their fronts 15 mm apart in
    # depth (issue 12): only the surface orientation and a thin depth crease separate them.
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=14.0)
    top_y = 750.0
    legs = tuple(
        Box((x - 25.0, 0.0, z - 25.0), (x + 25.0, top_y - 40.0, z + 25.0))
        for x in (-600.0, 600.0)
        for z in (750.0, 1450.0)
    )
    box = Box((-140.0, top_y, 1050.0), (40.0, top_y + 160.0, 1170.0))
    radius = 45.0
    cylinder = Cylinder((40.0 + radius, top_y, 1110.0), radius, 200.0)  # touches the box's +x face
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.4),
        Body(2, "back_wall", "wall", (_back_wall(2300.0),), 0.7),
        Body(3, "table", "object", (Box((-650.0, top_y - 40.0, 700.0), (650.0, top_y, 1500.0)), *legs), 0.5, parent=1),
        Body(4, "box", "object", (box,), 0.6, parent=3),
        Body(5, "cylinder", "object", (cylinder,), 0.6, parent=3),
    )
    return SceneSpec("touching", cam, bodies, ToFConfig())


#: Height (mm) of the table top in the arm scenes, and the clutter's centre on it (x, z).
ARM_TABLE_Y = 750.0
ARM_CLUTTER_XZ = (0.0, 1100.0)
#: Distance (mm) from the arm camera to the clutter's centre on the table, along its optical axis.
ARM_DOWN_MM = 650.0
ARM_45_MM = 600.0


def _clutter(top_y: float) -> tuple[Body, ...]:
    """Return a table top with clutter around :data:`ARM_CLUTTER_XZ`: flat things lying down, a mug, a box.

    Flat objects stand 18-25 mm above the table (a dish, a book, a screwdriver, a banana): a few
    sensor resolutions at arm's length, the case issue 28 names. The table fills the arm camera's
    view; the box shows its top and two sides at 45 degrees.
    """
    cx, cz = ARM_CLUTTER_XZ
    legs = tuple(
        Box((x - 25.0, 0.0, z - 25.0), (x + 25.0, top_y - 40.0, z + 25.0))
        for x in (-600.0, 600.0)
        for z in (750.0, 1450.0)
    )
    table = Box((-650.0, top_y - 40.0, 700.0), (650.0, top_y, 1500.0))
    return (
        Body(1, "floor", "floor", (FLOOR,), 0.4),
        Body(2, "back_wall", "wall", (_back_wall(2300.0),), 0.7),
        Body(3, "table", "object", (table, *legs), 0.5, parent=1),
        Body(4, "dish", "object", (Cylinder((cx - 130.0, top_y, cz + 80.0), 75.0, 18.0),), 0.8, parent=3),
        Body(
            5,
            "book",
            "object",
            (Box((cx + 20.0, top_y, cz + 40.0), (cx + 170.0, top_y + 25.0, cz + 150.0)),),
            0.6,
            parent=3,
        ),
        Body(
            6,
            "screwdriver",
            "object",
            (Box((cx - 60.0, top_y, cz - 140.0), (cx + 120.0, top_y + 18.0, cz - 115.0)),),
            0.6,
            parent=3,
        ),
        Body(
            7,
            "banana",
            "object",
            (Ellipsoid((cx - 150.0, top_y + 20.0, cz - 90.0), (70.0, 20.0, 22.0)),),
            0.7,
            parent=3,
        ),
        Body(8, "mug", "object", (Cylinder((cx + 60.0, top_y, cz - 30.0), 40.0, 100.0),), 0.8, parent=3),
        Body(
            9,
            "box",
            "object",
            (Box((cx + 140.0, top_y, cz - 140.0), (cx + 210.0, top_y + 140.0, cz - 60.0)),),
            0.6,
            parent=3,
        ),
    )


def _arm_down(w: int, h: int) -> SceneSpec:
    # An arm camera straight above the clutter: the table is a plane facing the sensor, and only
    # the objects' heights tell them from it.
    cx, cz = ARM_CLUTTER_XZ
    cam = Camera(w, h, position=(cx, ARM_TABLE_Y + ARM_DOWN_MM, cz), pitch_deg=90.0)
    return SceneSpec("arm_down", cam, _clutter(ARM_TABLE_Y), ToFConfig())


def _arm_45(w: int, h: int) -> SceneSpec:
    # The same clutter from an arm camera looking 45 degrees down at its centre.
    cx, cz = ARM_CLUTTER_XZ
    d = ARM_45_MM / math.sqrt(2.0)
    cam = Camera(w, h, position=(cx, ARM_TABLE_Y + d, cz - d), pitch_deg=45.0)
    return SceneSpec("arm_45", cam, _clutter(ARM_TABLE_Y), ToFConfig())


#: Walking speed (mm/s) of the chest-worn camera in ``chest_walk``.
WALK_SPEED_MM_S = 1200.0
#: Height (mm) and downward tilt (degrees) of the chest-worn camera.
CHEST_HEIGHT_MM = 1300.0
CHEST_TILT_DEG = 30.0


def _chest_walk(w: int, h: int) -> SceneSpec:
    # A blind user's chest camera, tilted down 30 degrees, walking down a hallway at 1.2 m/s with
    # the gait's bob and sway: a box, a bag lying on the floor and a pole ahead. The floor runs
    # to about 5 m in the view: a second modulation frequency unwraps it, as in ``corridor``.
    gait = Gait(v=(0.0, 0.0, -WALK_SPEED_MM_S))
    cam = Camera(w, h, position=(0.0, CHEST_HEIGHT_MM, 0.0), pitch_deg=CHEST_TILT_DEG)
    half_w = 1200.0
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5, gait),
        Body(2, "left_wall", "wall", (Plane((-half_w, 0.0, 0.0), (1.0, 0.0, 0.0)),), 0.8, gait),
        Body(3, "right_wall", "wall", (Plane((half_w, 0.0, 0.0), (-1.0, 0.0, 0.0)),), 0.8, gait),
        Body(4, "box", "object", (Box((-500.0, 0.0, 2600.0), (-100.0, 450.0, 2900.0)),), 0.7, gait, parent=1),
        Body(5, "bag", "object", (Ellipsoid((300.0, 60.0, 2300.0), (180.0, 60.0, 120.0)),), 0.6, gait, parent=1),
        Body(6, "pole", "object", (Cylinder((500.0, 0.0, 3600.0), 50.0, 2200.0),), 0.6, gait, parent=1),
    )
    return SceneSpec("chest_walk", cam, bodies, ToFConfig(f_mod2_hz=40e6))


#: Speeds (mm/s) of the balls of ``ball_approach`` and ``ball_rush``, straight at the sensor at a
#: constant speed (issue 30: 600 mm/s is judged at 30 frames/s, 1.5 m/s at 15 frames/s).
STEADY_SPEED_MM_S = 600.0
RUSH_SPEED_MM_S = 1500.0


def _straight_at(w: int, h: int, name: str, speed: float) -> SceneSpec:
    # A ball coming straight at the camera from 2.5 m at a constant speed, before a wall at 2.7 m
    # (radial distance at the corners under the 50 MHz ambiguity range).
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=0.0)
    ball = Ellipsoid((60.0, 1040.0, 2500.0), (100.0, 100.0, 100.0))
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5),
        Body(2, "back_wall", "wall", (_back_wall(2700.0),), 0.7),
        Body(3, "ball", "object", (ball,), 0.7, Linear(v=(0.0, 0.0, -speed))),
    )
    return SceneSpec(name, cam, bodies, ToFConfig())


def _ball_approach(w: int, h: int) -> SceneSpec:
    return _straight_at(w, h, "ball_approach", STEADY_SPEED_MM_S)


def _ball_rush(w: int, h: int) -> SceneSpec:
    return _straight_at(w, h, "ball_rush", RUSH_SPEED_MM_S)


def _pass_behind(w: int, h: int) -> SceneSpec:
    # A far ball rolls from right to left behind a nearer ball (hidden around t = 1.1 s) and then
    # behind a box (around t = 2.0 s) while the nearer ball closes slowly; it enters the view at
    # about t = 0.2 s and leaves at about t = 2.9 s (issue 30: identity through occlusion).
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=0.0)
    box = Box((-420.0, 860.0, 1400.0), (-160.0, 1140.0, 1550.0))
    near = Ellipsoid((300.0, 1000.0, 1750.0), (120.0, 120.0, 120.0))
    far = Ellipsoid((1100.0, 1000.0, 2300.0), (110.0, 110.0, 110.0))
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5),
        Body(2, "back_wall", "wall", (_back_wall(2600.0),), 0.7),
        Body(3, "box", "object", (box,), 0.6),
        Body(4, "near_ball", "object", (near,), 0.7, Linear(v=(0.0, 0.0, -150.0))),
        Body(5, "far_ball", "object", (far,), 0.6, Linear(v=(-700.0, 0.0, 0.0))),
    )
    return SceneSpec("pass_behind", cam, bodies, ToFConfig())


def _cross_front(w: int, h: int) -> SceneSpec:
    # A near ball crosses from left to right in front of a still box and a receding ball while
    # it closes on the camera: the occluder moves, the hidden ones do not (or slowly).
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=0.0)
    mover = Ellipsoid((-700.0, 1000.0, 1500.0), (110.0, 110.0, 110.0))
    box = Box((-330.0, 870.0, 2000.0), (-90.0, 1130.0, 2150.0))
    ball = Ellipsoid((260.0, 1020.0, 2000.0), (120.0, 120.0, 120.0))
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5),
        Body(2, "back_wall", "wall", (_back_wall(2600.0),), 0.7),
        Body(3, "box", "object", (box,), 0.6),
        Body(4, "far_ball", "object", (ball,), 0.7, Linear(v=(0.0, 0.0, 150.0))),
        Body(5, "mover", "object", (mover,), 0.6, Linear(v=(600.0, 0.0, -200.0))),
    )
    return SceneSpec("cross_front", cam, bodies, ToFConfig())


_BUILDERS = {
    "table": _table,
    "corridor": _corridor,
    "approach": _approach,
    "crossing": _crossing,
    "ball_wall": _ball_wall,
    "touching": _touching,
    "arm_down": _arm_down,
    "arm_45": _arm_45,
    "chest_walk": _chest_walk,
    "ball_approach": _ball_approach,
    "ball_rush": _ball_rush,
    "pass_behind": _pass_behind,
    "cross_front": _cross_front,
}

#: Names of the scenes :func:`depthgram.sensor.simulate` knows.
SCENES: tuple[str, ...] = tuple(_BUILDERS)


def build_scene(name: str, size: tuple[int, int]) -> SceneSpec:
    """Return the scene ``name`` for a camera of ``size`` (width, height) px.

    Raises
    ------
    InputError
        For an unknown name; the message lists the known ones.
    """
    try:
        builder = _BUILDERS[name]
    except KeyError:
        raise InputError(f"unknown scene {name!r}; known scenes: {', '.join(SCENES)}") from None
    return builder(int(size[0]), int(size[1]))
