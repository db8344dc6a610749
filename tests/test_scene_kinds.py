"""The supports' kinds follow gravity (issue 28, item 3), scored against the simulator's truth.

Each segment covering a truth body over more than a share of the frame is looked up by the body
it covers most; its kind must be what gravity makes of that body: the table seen from above is
a support (``compound``, a table top), never a ``ceiling`` or an ``object``; the floor under a
chest camera tilted 30 degrees down is the ``floor``; its walls are ``wall``; what lies on the
table stays an ``object``.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from depthgram import Pipeline, read
from depthgram.frame import Frame, Gravity, Intrinsics
from depthgram.scene.kinds import GravityKinds, name_kinds
from depthgram.segmentation import segment
from depthgram.sensor import simulate

#: segments smaller than this share of the frame are not looked at
_SHARE = 0.02


def _kinds(
    scene: str, sensor: str, with_gravity: bool, size: tuple[int, int] = (320, 240), share: float = _SHARE
) -> dict[str, set[str]]:
    """Return, per truth body, the kinds of the segments covering it most (segments over ``share`` of the frame)."""
    (sim,) = simulate(scene, 1, size=size, sensor=sensor, seed=1)
    pipe = Pipeline(track=False, gravity=sim.gravity if with_gravity else None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = pipe.process(sim.frame)
    labels = result.segmentation.labels
    names = {o.id: o.name for o in sim.truth}
    out: dict[str, set[str]] = {}
    for o in result.segmentation.objects:
        pixels = sim.instances[labels == o.id]
        if pixels.size < share * labels.size:
            continue
        ids, counts = np.unique(pixels, return_counts=True)
        out.setdefault(names.get(int(ids[counts.argmax()]), "?"), set()).add(o.kind)
    return out


@pytest.mark.parametrize("sensor", ["tof", "sl"])
@pytest.mark.parametrize("scene", ["arm_down", "arm_45"])
def test_a_table_seen_from_an_arm_is_a_table_top_given_gravity(scene: str, sensor: str) -> None:
    kinds = _kinds(scene, sensor, with_gravity=True)
    # straight down the table faces the camera (a flat object to the image's axes); at 45
    # degrees it is a horizontal support: either way gravity makes it a table top, 0.4-0.65 m
    # below the camera (not the floor: nothing a person stands on is that near)
    assert kinds["table"] == {"compound"}
    for name in ("dish", "book", "screwdriver", "banana", "mug"):
        assert kinds.get(name, {"object"}) == {"object"}, name  # lying on the table: objects
    assert "ceiling" not in set().union(*kinds.values())


@pytest.mark.parametrize("sensor", ["tof", "sl"])
def test_the_floor_under_a_tilted_chest_camera_is_the_floor(sensor: str) -> None:
    for with_gravity in (True, False):  # without it, gravity is estimated from the floor itself
        kinds = _kinds("chest_walk", sensor, with_gravity)
        assert kinds["floor"] == {"floor"}
        assert kinds.get("left_wall", {"wall"}) == {"wall"}
        assert kinds.get("right_wall", {"wall"}) == {"wall"}
        assert kinds.get("box", {"object"}) == {"object"}


@pytest.mark.parametrize("sensor", ["tof", "sl"])
def test_the_table_scene_names_its_back_wall_a_wall(sensor: str) -> None:
    # the back wall faces the camera (an object to the image's axes); gravity, given or
    # estimated from the floor and the table, makes it a wall
    for with_gravity in (True, False):
        kinds = _kinds("table", sensor, with_gravity)
        assert kinds["back_wall"] == {"wall"}
        assert kinds["floor"] == {"floor"}
        assert kinds["table"] == {"compound"}


@pytest.mark.parametrize("size", [(640, 360), (848, 480)])
def test_a_16_9_frame_estimates_gravity_from_the_far_strip_of_floor(size: tuple[int, int]) -> None:
    # the simulator's camera at 16:9 sees less of the floor below (its vertical view is
    # narrower): a strip 2.4 m away whose depth spreads too little for the segmentation to keep
    # it a support (a facing object); its plane is still a floor seen from above, and gravity
    # estimated from it names the back wall a wall and the strip the floor
    kinds = _kinds("table", "tof", False, size=size)
    assert kinds["back_wall"] == {"wall"}, kinds
    assert kinds["floor"] == {"floor"}, kinds
    assert kinds["table"] == {"compound"}, kinds


@pytest.mark.parametrize("sensor", ["tof", "sl"])
def test_a_piece_of_the_back_wall_under_the_table_is_the_wall(sensor: str) -> None:
    # the table cuts the back wall: the strip seen under it (1.7 % of the frame) is too small to
    # be named a support on its own, but its readings lie in the wall's plane
    for with_gravity in (True, False):
        kinds = _kinds("table", sensor, with_gravity, share=0.005)
        assert kinds["back_wall"] == {"wall"}, kinds
        assert all(kinds[n] == {"object"} for n in ("bottle", "box", "ball", "cup")), kinds


@pytest.mark.parametrize("sensor", ["tof", "sl"])
def test_a_person_before_the_end_of_a_corridor_is_not_a_wall(sensor: str) -> None:
    # large, flat and upright, but seen against the end wall behind it: a wall has nothing
    # behind it (a blind user must not hear a person as a wall)
    kinds = _kinds("corridor", sensor, with_gravity=True)
    assert kinds["person"] == {"object"}, kinds
    assert kinds["left_wall"] == {"wall"} and kinds["right_wall"] == {"wall"}, kinds
    # structured light reads the end wall, 6 m away, in steps of about 100 mm, more than the
    # 1.5 % + 4 mm a plane's readings are held to: the camera's step and noise widen it
    assert kinds["end_wall"] == {"wall"}, kinds


@pytest.mark.parametrize("sensor", ["tof", "sl"])
def test_a_table_seen_straight_down_without_gravity_is_a_support_by_what_rests_on_it(sensor: str) -> None:
    # no IMU and no support seen from above: the things lying on the plane facing the camera,
    # held in by it a few centimetres nearer, say it is a table top and its normal is up
    kinds = _kinds("arm_down", sensor, with_gravity=False)
    assert kinds["table"] == {"compound"}, kinds
    for name in ("dish", "book", "screwdriver", "banana", "mug"):
        assert kinds.get(name, {"object"}) == {"object"}, name
    assert not {"ceiling", "floor", "wall"} & set().union(*kinds.values()), kinds


@pytest.mark.parametrize("what", ["bare", "one", "far"])
def test_a_plane_facing_the_camera_is_no_support_without_things_resting_on_it(what: str) -> None:
    # a plane 1.5 m ahead, square to the camera: bare, with one block 60 mm before it (one
    # thing may hang on a wall), or with two blocks 0.8 m before it (people before a wall):
    # nothing says which way is up, so nothing is named by a guessed gravity
    depth, cam = _plane_frame((0.0, 0.0, -1.0), 1500.0)
    blocks = {"bare": [], "one": [(20, 40, 60.0)], "far": [(20, 40, 800.0), (95, 40, 800.0)]}[what]
    for x, y, rise in blocks:
        depth[y : y + 35, x : x + 40] -= rise
    depth += np.random.default_rng(0).normal(0.0, 2.0, depth.shape).astype(np.float32)  # a camera's noise
    seg = segment(depth, intrinsics=cam)
    assert len(seg.objects) == 1 + len(blocks)
    named, used = name_kinds(seg, depth, cam, None)
    assert used is None
    assert all(o.kind == "object" for o in named.objects), [(o.id, o.kind) for o in named.objects]


def test_two_things_resting_on_a_plane_facing_the_camera_make_it_the_floor_under_them() -> None:
    # the same plane with two blocks 40 and 60 mm nearer, held in by it: its normal is up, and
    # 1.5 m below the camera with nothing seen beyond it, it is the floor
    depth, cam = _plane_frame((0.0, 0.0, -1.0), 1500.0)
    for x, y, rise in ((20, 40, 40.0), (95, 40, 60.0)):
        depth[y : y + 35, x : x + 40] -= rise
    depth += np.random.default_rng(0).normal(0.0, 2.0, depth.shape).astype(np.float32)
    seg = segment(depth, intrinsics=cam)
    assert len(seg.objects) == 3
    named, used = name_kinds(seg, depth, cam, None)
    assert used is not None
    np.testing.assert_allclose(used, (0.0, 0.0, 1.0), atol=0.02)
    big = max(named.objects, key=lambda o: o.area)
    assert big.kind == "floor"
    assert sorted(o.kind for o in named.objects if o.id != big.id) == ["object", "object"]


def _plane_frame(normal: tuple[float, float, float], offset_mm: float) -> tuple[np.ndarray, Intrinsics]:
    """Depth (mm) of the plane ``normal . P = -offset`` (normal toward the camera) over a 160 x 120 frame."""
    cam = Intrinsics(150.0, 150.0, 79.5, 59.5)
    v, u = np.mgrid[0:120, 0:160]
    ray = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones(u.shape)], axis=-1)
    dot = ray @ np.asarray(normal)
    depth = np.where(dot < -1e-6, offset_mm / np.maximum(-dot, 1e-6), 0.0)
    return depth.astype(np.float32), cam


@pytest.mark.parametrize("tilt", [0.0, 40.0])
def test_a_horizontal_support_is_named_by_gravity_not_by_the_image(tilt: float) -> None:
    # one plane 1.3 m below the camera, seen by a camera tilted down: the floor with gravity;
    # with gravity upside down (a camera mounted on its head, the plane above it) the ceiling
    g = Gravity.from_tilt(tilt)
    up = -np.asarray(g.vector)
    depth, cam = _plane_frame(tuple(up), 1300.0)
    seg = segment(depth, intrinsics=cam)
    assert len(seg.objects) >= 1
    named, used = name_kinds(seg, depth, cam, g.vector)
    big = max(named.objects, key=lambda o: o.area)
    assert big.kind == "floor"
    assert used is not None
    flipped, _ = name_kinds(seg, depth, cam, tuple(-np.asarray(g.vector)))
    assert max(flipped.objects, key=lambda o: o.area).kind == "ceiling"


def test_without_any_gravity_no_floor_or_ceiling_is_guessed() -> None:
    # a plane facing down (seen from below) gives no estimate of gravity: a support, not a ceiling
    depth, cam = _plane_frame((0.0, 0.8, -0.6), 1300.0)
    seg = segment(depth, intrinsics=cam)
    named = GravityKinds()(seg, depth, cam, None)
    assert all(o.kind not in ("floor", "ceiling") for o in named.objects)


def test_gravity_estimated_from_a_floor_is_kept_for_the_next_frames_of_a_stream() -> None:
    # frame 1: a floor 1.3 m below a camera tilted 40 degrees down (gravity estimated from it);
    # frame 2: only a wall 2 m ahead, whose depth grows toward the image's top: a ceiling to the
    # image's axes, a wall by the remembered gravity, and no guessed ceiling when the frame does
    # not continue the stream (nothing says which way is up)
    g = np.asarray(Gravity.from_tilt(40.0).vector)
    floor, cam = _plane_frame(tuple(-g), 1300.0)
    t = np.radians(40.0)
    wall_normal = (0.0, float(np.sin(t)), float(-np.cos(t)))  # the horizontal ahead, turned to the camera
    wall, _ = _plane_frame(wall_normal, 2000.0)
    kinds = GravityKinds()
    first = kinds(segment(floor, intrinsics=cam), floor, cam, None)
    assert max(first.objects, key=lambda o: o.area).kind == "floor"
    seg = segment(wall, intrinsics=cam)
    assert max(seg.objects, key=lambda o: o.area).kind == "ceiling"  # the image's axes
    assert max(kinds(seg, wall, cam, None).objects, key=lambda o: o.area).kind == "wall"
    assert max(kinds(seg, wall, cam, None, related=False).objects, key=lambda o: o.area).kind == "compound"


def test_gravity_estimated_on_a_hand_held_real_recording(shared_data: Path) -> None:
    # 7-Scenes red kitchen, hand-held Kinect: gravity-direction.txt is gravity in the world frame
    # of the poses (camera to world), so R_t^T g is the truth in each frame's camera. The
    # estimate from the frame's supports seen from above (no IMU, no --gravity), every 30th frame
    # as the camera turns and tilts: within 8 degrees each (measured: median 2.5, largest 6.0)
    root = shared_data / "7scenes_redkitchen_seq"
    if not (root / "gravity-direction.txt").exists():
        pytest.skip(f"{root} not found")
    g_world = np.loadtxt(root / "gravity-direction.txt")
    g_world /= np.linalg.norm(g_world)
    errors = []
    for i, frame in enumerate(read(root)):
        if i % 30:
            continue
        rot = np.loadtxt(root / "pose" / f"frame-{i:06d}.pose.txt")[:3, :3]
        assert frame.intrinsics is not None
        _, g = name_kinds(segment(frame), frame.depth, frame.intrinsics, None)
        assert g is not None, f"frame {i}: no gravity estimated"
        errors.append(math.degrees(math.acos(float(np.clip(g @ (rot.T @ g_world), -1.0, 1.0)))))
    assert len(errors) == 10
    assert max(errors) <= 8.0, errors
    assert float(np.median(errors)) <= 4.0, errors


def _rolled(scene: str, quarter_turns: int) -> tuple[Frame, np.ndarray, tuple[float, float, float], dict[int, str]]:
    """A simulated frame as a camera rolled by ``quarter_turns`` x 90 degrees sees it: depth, truth, gravity, names."""
    (sim,) = simulate(scene, 1, size=(320, 240), seed=0)
    f = sim.frame
    assert f.intrinsics is not None and sim.gravity is not None
    k, g = f.intrinsics, np.array(sim.gravity.vector)
    depth, valid, truth = f.depth, f.valid, sim.instances
    for _ in range(quarter_turns):
        # np.rot90: pixel (u, v) -> (v, W - 1 - u), so camera x' = y and y' = -x
        w = depth.shape[1]
        depth, valid, truth = (np.ascontiguousarray(np.rot90(a)) for a in (depth, valid, truth))
        k = Intrinsics(k.fy, k.fx, k.cy, w - 1 - k.cx)
        g = np.array([g[1], -g[0], g[2]])
    frame = Frame(depth, valid, intrinsics=k, index=0, name=f"{scene} rolled {90 * quarter_turns}")
    return frame, truth, (float(g[0]), float(g[1]), float(g[2])), {o.id: o.name for o in sim.truth}


@pytest.mark.parametrize("turns", [1, 2, 3])
@pytest.mark.parametrize("scene", ["table", "chest_walk"])
def test_a_rolled_camera_finds_the_same_objects_and_kinds_given_gravity(scene: str, turns: int) -> None:
    # a robot's camera may be mounted on its side or upside down: the segmentation does not
    # read the image's axes for what it finds, and the kinds follow the gravity it is given
    upright, truth0, g0, names = _rolled(scene, 0)
    frame, truth, g, _ = _rolled(scene, turns)
    for f, t, down in ((upright, truth0, g0), (frame, truth, g)):
        r = Pipeline(track=False, gravity=down).process(f)
        kinds: dict[str, set[str]] = {}
        for o in r.segmentation.objects:
            if o.area >= _SHARE * f.depth.size:
                ids, counts = np.unique(t[r.segmentation.labels == o.id], return_counts=True)
                kinds.setdefault(names.get(int(ids[counts.argmax()]), "?"), set()).add(o.kind)
        assert "floor" in kinds["floor"], (f.name, kinds)
        walls = ("back_wall", "left_wall", "right_wall")
        assert all(kinds.get(n, {"wall"}) <= {"wall"} for n in walls), (f.name, kinds)
        assert all(kinds.get(n, {"object"}) == {"object"} for n in ("box", "bottle", "ball", "cup")), (f.name, kinds)


def test_an_estimated_gravity_is_reported_and_warned_of_once() -> None:
    # an arm camera over a table, no gravity given: the JSON line carries the estimate (source
    # "estimated", within a few degrees of straight down) and one GravityWarning names the options;
    # with the tilt given, no warning and the line carries the user's
    from depthgram.frame import GravityWarning

    sims = list(simulate("arm_down", 2, size=(320, 240), sensor="tof", seed=1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pipe = Pipeline(track=False)
        records = [pipe.process(s.frame).to_record() for s in sims]
    said = [w for w in caught if issubclass(w.category, GravityWarning)]
    assert len(said) == 1 and "--gravity" in str(said[0].message) and "--tilt" in str(said[0].message)
    for rec in records:
        assert rec["gravity"]["source"] == "estimated"
        np.testing.assert_allclose(rec["gravity"]["vector"], sims[0].gravity.vector, atol=0.05)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = Pipeline(track=False, tilt_deg=90.0).process(sims[0].frame).to_record()
    assert not [w for w in caught if issubclass(w.category, GravityWarning)]
    assert rec["gravity"]["source"] == "tilt"
