"""The default ``surfaces`` segmentation on scenes with exact truth, seen by a structured-light
camera (disparity quantised in 1/8 px with noise, as a Kinect v1 / Xtion): the failure modes
of issue 12 (a small object with no histogram peak, touching objects, a box showing two faces,
a person cut into depth slabs) and the sensor model estimated from the frames."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.frame import Intrinsics
from depthgram.segmentation import evaluate, segment
from depthgram.segmentation.config import SegmentConfig
from depthgram.segmentation.creases import crease_scale_px, crease_span_px
from depthgram.segmentation.noise_model import PROFILES, averaged_over_window, estimate_sensor
from depthgram.sensor.geometry import Body, Box, Camera, Cylinder, Ellipsoid, Plane, cast

W, H = 640, 480
F_SL, BASELINE = 580.0, 75.0  # Kinect v1 optics


def _structured_light(depth: np.ndarray, rng: np.random.Generator, noise_px: float = 0.065) -> np.ndarray:
    """Depth as a structured-light camera reports it: disparity f b / z, noisy, in 1/8 px steps."""
    out = np.zeros_like(depth, dtype=np.float32)
    ok = depth > 0
    disp = F_SL * BASELINE / depth[ok]
    disp = np.round((disp + noise_px * rng.standard_normal(disp.shape)) * 8.0) / 8.0
    out[ok] = (F_SL * BASELINE / np.maximum(disp, 1e-3)).astype(np.float32)
    return out


def _correlated(depth: np.ndarray, rng: np.random.Generator, window_px: int = 9) -> np.ndarray:
    """Structured light as the camera matches it: the disparity is the mean over its correlation window."""
    ok = depth > 0
    disp = np.where(ok, F_SL * BASELINE / np.where(ok, depth, 1.0), 0.0).astype(np.float32)
    size = (window_px, window_px)
    total = cv2.boxFilter(disp, -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
    count = cv2.boxFilter(ok.astype(np.float32), -1, size, normalize=False, borderType=cv2.BORDER_CONSTANT)
    mean = np.where(ok, total / np.maximum(count, 1.0), 0.0)
    return _structured_light(np.where(ok, F_SL * BASELINE / np.maximum(mean, 1e-3), 0.0), rng)


def _time_of_flight(depth: np.ndarray, rng: np.random.Generator, sigma_mm: float = 4.0) -> np.ndarray:
    """Depth as a time-of-flight camera reports it: per-pixel noise, millimetre steps."""
    noisy = np.round(depth + sigma_mm * rng.standard_normal(depth.shape))
    return np.where(depth > 0, noisy, 0.0).astype(np.float32)


def _render(bodies: tuple[Body, ...], camera: Camera, seed: int = 0) -> tuple[np.ndarray, np.ndarray, Intrinsics]:
    hits = cast(camera, bodies, 0.0)
    depth = _structured_light(hits.depth, np.random.default_rng(seed))
    return depth, hits.instances, camera.intrinsics


def _best(labels: np.ndarray, truth: np.ndarray, k: int) -> tuple[int, float]:
    """Segment of best IoU with truth instance ``k``, and that IoU."""
    scores = evaluate(labels, truth).objects
    s = next(o for o in scores if o.truth_id == k)
    return s.detected, s.iou


def _camera(pitch: float = 0.0, height: float = 1000.0) -> Camera:
    # Kinect v1's 57 degree horizontal field of view at 640 px: f = 589 px
    return Camera(W, H, fov_x_deg=57.0, position=(0.0, height, 0.0), pitch_deg=pitch)


def test_sensor_model_is_estimated_from_a_structured_light_frame() -> None:
    # a floor and a wall running from 0.8 to 4.5 m give every depth its own step
    floor = Body(1, "floor", "floor", (Plane((0, 0, 0), (0, 1, 0)),))
    wall = Body(2, "wall", "wall", (Plane((-900, 0, 0), (1, 0, 0)),))
    back = Body(3, "back", "wall", (Plane((0, 0, 4500), (0, 0, 1)),))
    depth, _, _ = _render((floor, wall, back), _camera(pitch=15.0))
    model = estimate_sensor(depth, depth > 0)
    for z in (1000.0, 2500.0):
        true_step = z * z / (F_SL * BASELINE) / 8.0
        assert model.step(z) == pytest.approx(true_step, rel=0.3), (z, model.describe())
    # and a ToF camera with millimetre output: constant steps, noise from the data
    rng = np.random.default_rng(1)
    tof = np.round(np.linspace(800, 3000, W)[None, :] + 4.0 * rng.standard_normal((H, W))).astype(np.float32)
    m = estimate_sensor(tof, tof > 0)
    assert m.step(3000.0) < 3.0 and m.sigma(1500.0) == pytest.approx(4.0, rel=0.35), m.describe()


def test_a_small_sphere_in_front_of_a_wall_is_its_own_object() -> None:
    # 0.5 % of the frame, 0.4 m in front of a wall at 2 m: no histogram peak of its own
    f = _camera().intrinsics.fx
    r_px = math.sqrt(0.005 * W * H / math.pi)
    z_front = 1600.0
    r_mm = r_px * z_front / f
    wall = Body(1, "wall", "wall", (Plane((0, 0, 2000), (0, 0, 1)),))
    ball = Body(2, "ball", "object", (Ellipsoid((150.0, 1050.0, z_front + r_mm), (r_mm, r_mm, r_mm)),))
    depth, truth, cam = _render((wall, ball), _camera())
    assert 0.004 < np.mean(truth == 2) < 0.006
    seg = segment(depth, valid=depth > 0, intrinsics=cam)
    sid, iou = _best(seg.labels, truth, 2)
    assert iou >= 0.85
    # no wall pixel in it: the ball's segment holds one surface only
    assert np.mean(truth[seg.labels == sid] == 1) < 0.01
    # the paper's histogram method hands it to the wall's band (the failure this fixes)
    _, iou_hist = _best(segment(depth, valid=depth > 0, intrinsics=cam, method="threshold").labels, truth, 2)
    assert iou_hist < 0.5


def test_a_cylinder_against_a_box_on_a_table_comes_out_as_two_objects() -> None:
    table = Body(1, "table", "floor", (Plane((0, 700, 0), (0, 1, 0)),))
    box = Body(2, "box", "object", (Box((-180.0, 700.0, 1200.0), (20.0, 950.0, 1350.0)),), parent=1)
    # touching the box's right side, its front 60 mm behind the box's front face
    can = Body(3, "can", "object", (Cylinder((70.0, 700.0, 1310.0), 50.0, 180.0),), parent=1)
    depth, truth, cam = _render((table, box, can), _camera(pitch=25.0, height=1300.0))
    seg = segment(depth, valid=depth > 0, intrinsics=cam)
    box_id, box_iou = _best(seg.labels, truth, 2)
    can_id, can_iou = _best(seg.labels, truth, 3)
    assert box_iou >= 0.8 and can_iou >= 0.7 and box_id != can_id, (box_iou, can_iou)


@pytest.mark.parametrize("sensor", ["structured-light", "tof"])
def test_a_box_lying_on_a_flat_block_comes_out_as_two_objects_with_a_wider_crease_span(sensor: str) -> None:
    # issue 28 (YCB-Video 0002's pudding box on the wood block): a box 35 mm thick lying on a
    # block 85 mm high, 25 mm back from its front edge, seen from 50 degrees above at 1 m. The
    # inside corner where the box's front meets the block's top is the only thing between them:
    # a structured-light camera spreads it over its correlation window, a time-of-flight
    # camera's noise at the default 2 px span on the sampling grid is above its bend
    table = Body(1, "table", "floor", (Plane((0, 700, 0), (0, 1, 0)),))
    block = Body(2, "block", "object", (Box((-100.0, 700.0, 630.0), (100.0, 785.0, 715.0)),), parent=1)
    box = Body(3, "box", "object", (Box((-50.0, 785.0, 655.0), (60.0, 820.0, 744.0)),), parent=2)
    cam = _camera(pitch=50.0, height=1500.0)
    hits = cast(cam, (table, block, box), 0.0)
    measure = _correlated if sensor == "structured-light" else _time_of_flight
    depth = measure(hits.depth, np.random.default_rng(0))
    seg = segment(depth, valid=depth > 0, intrinsics=cam.intrinsics, crease_span_fraction=1.0 / 64.0)
    block_id, block_iou = _best(seg.labels, hits.instances, 2)
    box_id, box_iou = _best(seg.labels, hits.instances, 3)
    assert block_id != box_id and block_iou >= 0.7 and box_iou >= 0.7, (block_iou, box_iou)


def _box_on_block(sensor: str) -> tuple[np.ndarray, np.ndarray, Intrinsics]:
    """The box lying on the block of issue 28 (see the test above), as ``sensor`` reads it."""
    table = Body(1, "table", "floor", (Plane((0, 700, 0), (0, 1, 0)),))
    block = Body(2, "block", "object", (Box((-100.0, 700.0, 630.0), (100.0, 785.0, 715.0)),), parent=1)
    box = Body(3, "box", "object", (Box((-50.0, 785.0, 655.0), (60.0, 820.0, 744.0)),), parent=2)
    cam = _camera(pitch=50.0, height=1500.0)
    hits = cast(cam, (table, block, box), 0.0)
    measure = _correlated if sensor == "structured-light" else _time_of_flight
    return measure(hits.depth, np.random.default_rng(0)), hits.instances, cam.intrinsics


def test_the_crease_span_follows_a_structured_light_cameras_correlation_window_by_default() -> None:
    # issue 28: the disparity averaged over a 9 x 9 window spreads the box's inside corner over
    # it; the frame reads as averaged (z**2 steps, noise below a step), so the default span is
    # one grid pixel past the window (5 on the 320 px grid) and parts the box from the block
    depth, truth, cam = _box_on_block("structured-light")
    model = estimate_sensor(depth, depth > 0)
    assert model.window_fraction > 0.0
    assert crease_span_px(320, model) == 5
    assert SegmentConfig().crease_span_fraction == 0.0
    seg = segment(depth, valid=depth > 0, intrinsics=cam)
    block_id, block_iou = _best(seg.labels, truth, 2)
    box_id, box_iou = _best(seg.labels, truth, 3)
    assert block_id != box_id and block_iou >= 0.7 and box_iou >= 0.7, (block_iou, box_iou)


def test_a_time_of_flight_frame_keeps_the_crease_span_of_1_128() -> None:
    # each ToF pixel is measured on its own (noise above its 1 mm unit): no window, so the
    # default gives the labels of the explicit 1/128 of before, and the named profiles follow
    # their family
    depth, _, cam = _box_on_block("tof")
    model = estimate_sensor(depth, depth > 0)
    assert model.window_fraction == 0.0
    assert crease_span_px(320, model) == crease_scale_px(320, 1.0 / 128.0) == 2
    default = segment(depth, valid=depth > 0, intrinsics=cam)
    before = segment(depth, valid=depth > 0, intrinsics=cam, crease_span_fraction=1.0 / 128.0)
    assert np.array_equal(default.labels, before.labels)
    assert crease_span_px(320, PROFILES["azure-kinect"]) == crease_span_px(320, PROFILES["tof"]) == 2
    assert crease_span_px(320, PROFILES["xtion"]) == crease_span_px(320, PROFILES["realsense-d400"]) == 5
    # an explicit share wins over the sensor
    assert crease_span_px(320, PROFILES["xtion"], 1.0 / 128.0) == 2


@pytest.mark.parametrize(
    ("model", "z_mm", "averaged"),
    [
        # the estimates of real frames (step_0, step_2, sigma_0, sigma_2; mm, 1/mm) at their median
        # depth: 7-Scenes' Kinect v1 (z**2 steps, no noise left between them), NVlabs' RealSense
        # (z**2 steps, noise 0.3 of a step), YCB-Video 0002's Xtion (1 mm steps, 0.05 mm of noise)
        ((0.0, 2.75e-6, 0.0, 0.0), 1878.0, True),
        ((0.33, 8.3e-7, 0.0, 3.5e-7), 876.0, True),
        ((1.0, 0.0, 0.0, 4.2e-8), 1087.0, True),
        # the Azure Kinect's ToF (flat 1.3 mm step, 0.4 of it in noise) and the simulator's ToF
        # (noise above its step: the step estimate is the noise's)
        ((1.33, 0.0, 0.07, 2.1e-7), 1491.0, False),
        ((1.46, 8.2e-7, 3.37, 2.1e-6), 1459.0, False),
    ],
)
def test_a_frame_reads_as_averaged_over_a_window_by_its_steps_and_noise(
    model: tuple[float, float, float, float], z_mm: float, averaged: bool
) -> None:
    assert averaged_over_window(*model, z_mm) is averaged


def test_the_crease_span_setting_takes_0_for_the_sensor_or_a_share() -> None:
    # as TOML's [segment] table gives them (``--config``)
    assert SegmentConfig.from_dict({"crease_span_fraction": 0.0}).surfaces.crease_span_fraction == 0.0
    assert SegmentConfig.from_dict({"crease_span_fraction": 0.015625}).surfaces.crease_span_fraction == 1.0 / 64.0
    for bad in (1e-4, -0.01, 0.2, float("nan")):
        with pytest.raises(InputError, match="crease_span_fraction"):
            SegmentConfig(crease_span_fraction=bad)


def test_a_box_showing_its_top_and_front_is_one_object() -> None:
    # seen from above at 35 degrees: two faces meeting at a convex edge
    floor = Body(1, "floor", "floor", (Plane((0, 0, 0), (0, 1, 0)),))
    box = Body(2, "box", "object", (Box((-200.0, 0.0, 1500.0), (200.0, 300.0, 1800.0)),), parent=1)
    depth, truth, cam = _render((floor, box), _camera(pitch=35.0, height=1400.0))
    seg = segment(depth, valid=depth > 0, intrinsics=cam)
    _, iou = _best(seg.labels, truth, 2)
    assert iou >= 0.9


def test_a_person_far_from_a_kinect_is_not_cut_into_depth_slabs() -> None:
    # at 3.5 m the depth step is 35 mm: 10 mm histogram bins would make a comb of peaks
    wall = Body(1, "wall", "wall", (Plane((0, 0, 5500), (0, 0, 1)),))
    person = Body(
        2,
        "person",
        "object",
        (Cylinder((0.0, 0.0, 3500.0), 220.0, 1500.0), Ellipsoid((0.0, 1650.0, 3500.0), (110.0, 130.0, 110.0))),
    )
    floor = Body(3, "floor", "floor", (Plane((0, 0, 0), (0, 1, 0)),))
    depth, truth, cam = _render((wall, person, floor), _camera(pitch=5.0, height=1200.0))
    seg = segment(depth, valid=depth > 0, intrinsics=cam)
    _, iou = _best(seg.labels, truth, 2)
    assert iou >= 0.85


def test_named_sensor_profiles_are_settings() -> None:
    depth = np.full((60, 80), 1500.0, np.float32)
    depth[20:40, 30:50] = 1200.0
    for name in ("kinect-v1", "xtion", "realsense-d400", "azure-kinect", "tof"):
        seg = segment(depth, sensor=name, min_area_px=50)
        assert sorted(o.area for o in seg.objects) == [400, 80 * 60 - 400], name
    assert PROFILES["kinect-v1"].step(1000.0) == pytest.approx(1000.0**2 / (580 * 75) / 8)
    from depthgram.errors import InputError

    with pytest.raises(InputError, match="sensor"):
        segment(depth, sensor="kinect-v9")


def test_a_table_top_with_the_room_seen_beneath_it_is_not_the_floor() -> None:
    # the same kind on every camera: the floor is the lowest horizontal support with nothing
    # seen beneath it. Here no floor is found (only a wall far behind, which runs below the
    # table's plane); the table top, the only horizontal support, was called floor before.
    wall = Body(1, "wall", "wall", (Plane((0, 0, 4200), (0, 0, 1)),))
    top = Body(2, "table", "object", (Box((-700.0, 716.0, 1100.0), (700.0, 720.0, 2600.0)),))
    cup = Body(3, "cup", "object", (Cylinder((0.0, 720.0, 1700.0), 45.0, 110.0),), parent=2)
    depth, truth, cam = _render((wall, top, cup), _camera(pitch=30.0, height=1500.0))
    seg = segment(depth, valid=depth > 0, intrinsics=cam)
    table = seg.objects[_best(seg.labels, truth, 2)[0] - 1]
    assert table.kind == "compound", table.kind


@pytest.mark.parametrize("depth_mm", [300.0, 3e4, 9e5])
def test_the_default_takes_any_positive_depth_without_an_internal_error(depth_mm: float) -> None:
    z = np.full((30, 40), depth_mm, np.float32)
    z[10:20, 10:20] = depth_mm * 0.5
    seg = segment(z, min_area_px=20, far_mm=1e6)  # past the default 20 m (issue 18.2)
    assert sorted(o.area for o in seg.objects) == [100, 1100]
    far = segment(z * 1e4, min_area_px=20, far_mm=1e6)
    assert far.objects == () and far.beyond_far_px == z.size


@pytest.mark.parametrize("pitch", [-13.0, 13.0])
def test_a_wall_nearly_facing_the_camera_is_no_floor_or_ceiling(pitch: float) -> None:
    # the Azure Kinect frame's window wall, 2 m away and 9 degrees off square, had become a
    # "floor" (camera looking 13 degrees up); looking down, it became a "ceiling"
    wall = Body(1, "wall", "wall", (Plane((0, 0, 2200), (0.16, 0, 1)),))
    desk = Body(2, "desk", "floor", (Box((-900.0, 600.0, 300.0), (900.0, 640.0, 1100.0)),))
    depth, truth, cam = _render((wall, desk), _camera(pitch=pitch, height=1000.0))
    seg = segment(depth, valid=depth > 0, intrinsics=cam)
    wall_seg = seg.objects[_best(seg.labels, truth, 1)[0] - 1]
    assert wall_seg.kind not in ("floor", "ceiling", "compound"), wall_seg.kind


@pytest.mark.parametrize(
    ("scene", "size", "wanted"),
    [
        ("ball_wall", (640, 480), {"ball": 0.95}),
        ("touching", (640, 480), {"box": 0.9, "cylinder": 0.9}),
        ("corridor", (176, 132), {"left_wall": 0.8, "right_wall": 0.8, "floor": 0.8, "ceiling": 0.8, "person": 0.9}),
    ],
)
def test_the_simulated_structured_light_sensor(scene: str, size: tuple[int, int], wanted: dict[str, float]) -> None:
    # the simulator's own structured-light model (disparity steps, projector shadows, holes)
    from depthgram.sensor import simulate

    sf = next(iter(simulate(scene, 1, size=size, seed=0, sensor="sl")))
    f = sf.frame
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics)
    scores = evaluate(seg.labels, np.where(f.valid, sf.instances, 0)).objects
    iou = {t.name: o.iou for o in scores for t in sf.truth if t.id == o.truth_id}
    assert all(iou[name] >= low for name, low in wanted.items()), iou


def test_table1_targets_hold_on_the_structured_light_simulator() -> None:
    from depthgram.sensor import simulate

    sf = next(iter(simulate("table", 1, size=(640, 480), seed=0, sensor="sl")))
    f = sf.frame
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics)
    ev = evaluate(seg.labels, np.where(f.valid, sf.instances, 0))
    assert ev.area_assigned >= 0.96 and ev.precision_assigned >= 0.95, (ev.area_assigned, ev.precision_assigned)
