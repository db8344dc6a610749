"""Objects whose outlines touch in the image, against the simulator's truth (issue 30 item 1).

Where two objects' outlines touch in the image at different depths, no segment may hold both;
a small ball 0.4-1.5 m before a wall is an object of its own in every frame. Each case at
176 x 132, 320 x 240 and 640 x 480, through the ToF and the structured-light sensor models.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy import ndimage

from depthgram.segmentation import segment
from depthgram.sensor import StructuredLightConfig
from depthgram.sensor.geometry import Body, Camera, Ellipsoid, Linear
from depthgram.sensor.scenes import BALL_RADIUS_MM, FLOOR, SceneSpec, _back_wall, build_scene
from depthgram.sensor.simulate import SimFrame, render, render_structured

SIZES = ((176, 132), (320, 240), (640, 480))
SENSORS = ("tof", "structured-light")
#: Share of a truth object's pixels in another object's segment that counts as a merge, as
#: ``depthgram bench tracking`` counts them (``dynamics.evaluate.mot_sequence``).
MERGE_SHARE = 0.25
#: Truth objects smaller than this share of the frame are not judged (the tracking metrics' floor).
MIN_AREA_SHARE = 0.002


def _frame(spec: SceneSpec, sensor: str, k: int, fps: float = 30.0) -> SimFrame:
    """Frame ``k`` of ``spec`` through ``sensor``, with noise (seeded by the frame)."""
    rng = np.random.default_rng([1, k])
    if sensor == "tof":
        return render(spec, spec.tof, k, fps, rng)
    return render_structured(spec, StructuredLightConfig(), k, fps, rng)


def _touching(instances: NDArray[np.integer], a: int, b: int) -> bool:
    """Whether the image regions of truth bodies ``a`` and ``b`` are 4-neighbours somewhere."""
    return bool((ndimage.binary_dilation(instances == a) & (instances == b)).any())


def _merges(sf: SimFrame, labels: NDArray[np.integer]) -> list[tuple[int, int]]:
    """Pairs (a, b) of truth objects whose segment (the one holding most of a) holds a quarter of b."""
    inst = sf.instances
    objects = [b for b in sf.truth if b.kind == "object" and b.area >= MIN_AREA_SHARE * inst.size]
    out = []
    for a in objects:
        ids, counts = np.unique(labels[(inst == a.id) & (labels > 0)], return_counts=True)
        if not ids.size:
            continue
        seg = labels == ids[np.argmax(counts)]
        out += [(a.id, b.id) for b in objects if b.id != a.id and (seg & (inst == b.id)).sum() >= MERGE_SHARE * b.area]
    return out


@pytest.mark.parametrize("sensor", SENSORS)
@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("scene", ["pass_behind", "cross_front"])
def test_no_merge_where_silhouettes_touch(scene: str, size: tuple[int, int], sensor: str) -> None:
    # pass_behind: a ball at 2.3 m rolls behind a ball at 1.75-1.6 m and a box at 1.4 m;
    # cross_front: a ball at 1.5-1.2 m crosses before a box and a ball at 2.0-2.3 m. The frames
    # judged are those in which two objects' outlines touch (from the truth), of every 3rd from
    # 15 to 84
    spec = build_scene(scene, size)
    judged = 0
    for k in range(15, 85, 3):
        sf = _frame(spec, sensor, k)
        ids = [b.id for b in sf.truth if b.kind == "object" and b.area >= MIN_AREA_SHARE * sf.instances.size]
        if not any(_touching(sf.instances, a, b) for a in ids for b in ids if a < b):
            continue
        judged += 1
        seg = segment(sf.frame)
        assert not _merges(sf, seg.labels), (
            f"{scene} {sensor} {size[0]}x{size[1]} frame {k}: objects {_merges(sf, seg.labels)} in one segment "
            "where their outlines touch; expected each in its own"
        )
    assert judged >= 3, f"{scene} {size}: only {judged} frames with touching outlines; the scene changed?"


#: Speed (mm/s) of the ball toward the wall: issue 30's steady approach.
BALL_SPEED_MM_S = 600.0


def _ball_before_wall(w: int, h: int, wall_mm: float) -> SceneSpec:
    # ball_wall's small ball (0.5 % of the frame at 1.6 m), from 1.5 m before the wall toward it
    cam = Camera(w, h, position=(0.0, 1000.0, 0.0), pitch_deg=0.0)
    ball = Ellipsoid((150.0, 1080.0, wall_mm - 1500.0), (BALL_RADIUS_MM,) * 3)
    speed = BALL_SPEED_MM_S
    bodies = (
        Body(1, "floor", "floor", (FLOOR,), 0.5),
        Body(2, "back_wall", "wall", (_back_wall(wall_mm),), 0.7),
        Body(3, "ball", "object", (ball,), 0.7, Linear(v=(0.0, 0.0, speed))),
    )
    return SceneSpec("ball_before_wall", cam, bodies, build_scene("ball_wall", (w, h)).tof)


@pytest.mark.parametrize("sensor", SENSORS)
@pytest.mark.parametrize("size", SIZES)
def test_small_ball_before_a_wall_is_its_own_object_in_every_frame(size: tuple[int, int], sensor: str) -> None:
    # 20 frames (8 at 640 x 480) spread over its way from 1.5 m to 0.4 m before a wall at 2 m
    # at 600 mm/s and 30 frames/s: in each, the segment holding most of the ball matches it
    # (IoU >= 0.5) and is at most 10 % wall
    n = 8 if size[0] >= 640 else 20
    spec = _ball_before_wall(*size, wall_mm=2000.0)
    last = round(1100.0 / BALL_SPEED_MM_S * 30.0)
    for k in (round(i * last / (n - 1)) for i in range(n)):
        sf = _frame(spec, sensor, k)
        labels = segment(sf.frame).labels
        ball = sf.instances == 3
        ids, counts = np.unique(labels[ball & (labels > 0)], return_counts=True)
        assert ids.size, f"ball before a wall, {sensor} {size}, frame {k}: no segment on the ball"
        seg = labels == ids[np.argmax(counts)]
        iou = (ball & seg).sum() / (ball | seg).sum()
        wall = (seg & (sf.instances == 2)).sum() / seg.sum()
        gap = 1500.0 - BALL_SPEED_MM_S * k / 30.0
        assert iou >= 0.5 and wall <= 0.1, (
            f"ball before a wall, {sensor} {size[0]}x{size[1]}, frame {k} ({gap:.0f} mm before it): "
            f"IoU {iou:.2f} with its segment, which is {wall:.0%} wall; expected IoU >= 0.5 and <= 10 % wall"
        )
