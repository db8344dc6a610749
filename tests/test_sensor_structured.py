"""Structured-light sensor model (Kinect v1 / Xtion): quantisation, shadows, holes, exact ground truth."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from depthgram.cli import main
from depthgram.errors import InputError
from depthgram.sensor import StructuredLightConfig, simulate, structured
from depthgram.sensor.scenes import BALL_DEPTH_MM, BALL_RADIUS_MM, BALL_WALL_GAP_MM
from depthgram.sources import read

CFG = StructuredLightConfig()


def _one(scene: str, **kw: object):  # type: ignore[no-untyped-def]
    return next(iter(simulate(scene, **kw)))  # type: ignore[arg-type]


@pytest.mark.parametrize(("z", "hand_mm"), [(1000.0, 2.8736), (2000.0, 11.494), (3000.0, 25.862)])
def test_depth_step_formula(z: float, hand_mm: float) -> None:
    # z^2 / (f b) * step with f = 580 px, b = 75 mm, step = 1/8 px, by hand
    assert structured.depth_step_mm(z, CFG) == pytest.approx(hand_mm, rel=1e-4)


@pytest.mark.parametrize("z", [800.0, 1500.0, 2500.0, 4000.0])
def test_measured_levels_are_spaced_by_the_step(z: float) -> None:
    true = np.linspace(0.97 * z, 1.03 * z, 20001)
    levels = np.unique(structured.measure(true, CFG))
    gaps = np.diff(levels.astype(np.float64))
    near = np.argmin(np.abs(levels[:-1] - z))
    assert gaps[near] == pytest.approx(z * z / (580.0 * 75.0) / 8.0, rel=0.02)


def test_levels_in_a_simulated_frame_follow_the_formula() -> None:
    # the corridor's floor, walls and ceiling run from 2.5 m to 6 m: every reading is f b / (k / 8) for a
    # whole k, and the closest readings near z are one step apart
    sim = _one("corridor", size=(320, 240), sensor="sl", noise=False)
    levels = np.unique(sim.frame.depth[sim.frame.valid].astype(np.float64))
    k = 580.0 * 75.0 / levels * 8.0
    np.testing.assert_allclose(k, np.rint(k), atol=2e-3)
    for z in (2600.0, 3200.0, 4000.0):
        near = levels[(levels > 0.97 * z) & (levels < 1.03 * z)]
        assert near.size >= 3
        gaps, step = np.diff(near), near[:-1] ** 2 / (580.0 * 75.0) / 8.0
        adjacent = gaps < 1.5 * step  # a level no pixel happened to read leaves a double gap
        assert adjacent.any()
        np.testing.assert_allclose(gaps[adjacent], step[adjacent], rtol=0.02)


def test_noise_grows_with_the_square_of_depth() -> None:
    rng = np.random.default_rng(1)
    cfg = StructuredLightConfig(disparity_step_px=1e-4)  # quantisation out of the way
    for z in (1000.0, 3000.0):
        m = structured.measure(np.full(20000, z), cfg, rng).astype(np.float64)
        assert m.std() == pytest.approx(z * z / (580.0 * 75.0) * 0.07, rel=0.05)


def _ball_rows(sim) -> list[int]:  # type: ignore[no-untyped-def]
    ball = np.flatnonzero(np.any(sim.instances == 3, axis=1) | np.any(sim.shadow, axis=1))
    return [int(r) for r in ball]


@pytest.mark.parametrize("side", [1, -1])
def test_shadow_lies_beside_the_ball_away_from_the_projector(side: int) -> None:
    cfg = StructuredLightConfig(projector_side=side, registration_scale=None)
    sim = _one("ball_wall", size=(640, 480), sensor="sl", noise=False, structured_light=cfg)
    assert sim.shadow is not None and sim.shadow.any()
    ball = sim.true_depth > 0
    ball &= _one("ball_wall", size=(640, 480), noise=False).instances == 3
    for r in np.flatnonzero(sim.shadow.any(axis=1)):
        cols = np.flatnonzero(sim.shadow[r])
        bcols = np.flatnonzero(ball[r])
        assert bcols.size, f"row {r}: shadow without the ball"
        wall = cols[~ball[r, cols]]
        # projector on the right: the band on the wall touches the ball's left edge (the ball's
        # own limb on that side may be unlit too)
        if side == 1:
            assert wall.max() < bcols.min() and cols.max() >= bcols.min() - 1
        else:
            assert wall.min() > bcols.max() and cols.min() <= bcols.max() + 1
    # widest band: the disparity difference between the ball's rim and the wall, f b (1/z1 - 1/z2)
    fx = 320.0 / math.tan(math.radians(20.0))
    rim = BALL_DEPTH_MM  # the silhouette of a sphere lies at about its centre's depth
    width = fx * 75.0 * (1.0 / rim - 1.0 / (BALL_DEPTH_MM + BALL_WALL_GAP_MM))
    wall_shadow = sim.shadow & ~ball
    assert wall_shadow.sum(axis=1).max() == pytest.approx(width, abs=1.5)
    # the shadow is on the wall, nothing else (the ball lights itself on the projector side)
    tof = _one("ball_wall", size=(640, 480), noise=False)
    assert set(np.unique(tof.instances[sim.shadow])) <= {2, 3}


def test_shadow_on_the_left_of_every_table_object() -> None:
    sim = _one("table", size=(320, 240), sensor="sl", noise=False)
    tof = _one("table", size=(320, 240), noise=False)
    # cup, ball, bottle (the ball's own shadow reaches the box's right side, so the box is left out)
    for oid in (4, 6, 7):
        mask = tof.instances == oid
        rows = np.flatnonzero(mask.any(axis=1))
        left = right = 0
        for r in rows:
            cols = np.flatnonzero(mask[r])
            c0, c1 = cols.min(), cols.max()
            left += int(c0 > 0 and sim.shadow[r, c0 - 1])
            right += int(c1 < mask.shape[1] - 1 and sim.shadow[r, c1 + 1])
        assert left > 0.3 * len(rows) and right == 0, (oid, left, right, len(rows))


def test_ground_truth_stays_exact() -> None:
    sl = _one("touching", size=(320, 240), sensor="sl", noise=False)
    tof = _one("touching", size=(320, 240), noise=False)
    np.testing.assert_array_equal(sl.true_depth, tof.true_depth)
    ok = sl.frame.valid
    np.testing.assert_array_equal(sl.instances[ok], tof.instances[ok])
    assert not sl.instances[~ok].any()
    for o in sl.truth:
        assert o.area == int(np.count_nonzero(sl.instances == o.id))
    # each reading is the quantisation level nearest the true depth: within half a step in disparity
    d_true = structured.disparity_px(sl.true_depth[ok], CFG)
    d_meas = structured.disparity_px(sl.frame.depth[ok], CFG)
    assert np.abs(d_meas - d_true).max() <= CFG.disparity_step_px / 2 + 1e-6
    # invalid = shadow or registration hole, and nothing else within range
    holes = structured.registration_holes(ok.shape, CFG.registration_scale)
    np.testing.assert_array_equal(~ok & (sl.true_depth > 0), sl.shadow | (holes & (sl.true_depth > 0)))


def test_registration_holes_form_a_dashed_lattice() -> None:
    holes = structured.registration_holes((480, 640), 1.06)
    rows = np.flatnonzero(holes.mean(axis=1) > 0.3)
    # 480 source rows spread over 480 * 1.06 target rows: a share 1 - 1 / 1.06 of the rows is missed
    assert len(rows) == pytest.approx(480 * (1 - 1 / 1.06), abs=1.5)
    assert np.diff(rows).min() >= 16
    r = rows[len(rows) // 2]
    assert holes[r].mean() == pytest.approx(0.5, abs=0.06)  # every other pixel along the row
    assert not structured.registration_holes((48, 64), None).any()


def test_small_ball_and_touching_scenes() -> None:
    for size in ((176, 132), (640, 480)):
        sim = _one("ball_wall", size=size, noise=False)
        ball = sim.truth[[o.name for o in sim.truth].index("ball")]
        assert ball.area / (size[0] * size[1]) == pytest.approx(0.005, abs=0.0004)
        wall = sim.truth[[o.name for o in sim.truth].index("back_wall")]
        assert wall.depth - (BALL_DEPTH_MM - BALL_RADIUS_MM) == pytest.approx(BALL_WALL_GAP_MM + BALL_RADIUS_MM, abs=25)
    sim = _one("touching", size=(320, 240), noise=False)
    box, cyl = (sim.instances == 4), (sim.instances == 5)
    # they touch in the image (4-neighbours) and stand at similar depths
    assert (box[:, :-1] & cyl[:, 1:]).any() or (cyl[:, :-1] & box[:, 1:]).any()
    depths = {o.name: o.depth for o in sim.truth}
    assert abs(depths["box"] - depths["cylinder"]) < 30.0


def test_sources_and_cli_spell_the_sensor(tmp_path: Path) -> None:
    frames = list(read("sim:ball_wall?frames=2&sensor=sl"))
    assert len(frames) == 2 and not frames[0].valid.all()
    assert frames[0].meta.get("sensor") == "structured-light"
    tof = next(iter(read("sim:ball_wall?frames=1")))
    assert tof.valid.all() and tof.meta.get("sensor") is None
    with pytest.raises(InputError, match="unknown sensor"):
        read("sim:table?sensor=lidar")
    with pytest.raises(InputError, match="unknown sensor"):
        simulate("table", sensor="lidar")
    assert main(["simulate", "touching", "--sensor", "structured-light", "--out", str(tmp_path)]) == 0
    camera = json.loads((tmp_path / "depth" / "camera.json").read_text())
    assert camera["sensor"] == "structured-light"
