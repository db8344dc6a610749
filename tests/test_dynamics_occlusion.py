"""Identity through occlusion (issue 30, item 2) and the field's tracking metrics (item 4)."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from depthgram.dynamics import Tracker, TrackerConfig
from depthgram.dynamics.evaluate import mot_sequence
from depthgram.segmentation.objects import SceneObject

W, H = 320, 240


def box(oid: int, cx: float, z: float, side: float = 40.0) -> SceneObject:
    """A square of ``side`` px centred at (``cx``, 120) px at depth ``z`` (mm), as segmentation gives it."""
    x0, y0 = round(cx - side / 2), round(120 - side / 2)
    x1, y1 = x0 + round(side), y0 + round(side)
    area = (x1 - x0) * (y1 - y0)
    return SceneObject(
        oid, "object", 0, z, 5.0, area, area / (W * H), ((x0 + x1 - 1) / 2, (y0 + y1 - 1) / 2), (x0, y0, x1, y1)
    )


def _pass_behind(fps: float, hidden_s: float, occluder: bool = True) -> list[dict[int, int]]:
    """A far square slides right at 60 px/s behind a near wide one (or into empty space) for ``hidden_s``.

    Returns each frame's track id per object id (1: the far square, 2: the near one).
    """
    tr = Tracker(TrackerConfig(fps=fps))
    out = []
    n = round(fps * (1.0 + hidden_s + 0.5))
    for k in range(n):
        t = k / fps
        seen = not (1.0 <= t < 1.0 + hidden_s)
        objs = [box(1, 60.0 + 60.0 * t, 2400.0)] if seen else []
        if occluder:
            # wide enough to hide the far square all along its hidden stretch
            objs.append(box(2, 60.0 + 60.0 * (1.0 + hidden_s / 2), 1200.0, side=60.0 * hidden_s + 60.0))
        out.append({oid: m.track_id for oid, m in tr.update(objs, None, (W, H)).motions.items()})
    return out


@pytest.mark.parametrize("fps", [15.0, 30.0])
def test_a_track_hidden_behind_a_nearer_object_gets_its_id_back_within_a_second(fps: float) -> None:
    # 0.8 s hidden: 24 frames at 30 frames/s, beyond the frame budget (max_missed = 10)
    frames = _pass_behind(fps, 0.8)
    far = [f[1] for f in frames if 1 in f]
    near = {f[2] for f in frames}
    assert set(far) == {far[0]}  # the same id before and after
    assert near == {frames[0][2]} and far[0] not in near  # the occluder's id is never handed over


def test_a_sliver_of_the_occluder_does_not_take_the_hidden_tracks_id() -> None:
    # Structured light, pass_behind at 640 x 480: a ball 2.24 m away hidden behind a box for
    # ten frames took a sliver of the box's side, split off by segmentation for one frame,
    # 745 mm nearer than its prediction: the depth gate had widened by 20 % of the depth per
    # frame missed. It widens now as far as the track's filter says its depth may stray.
    fps = 30.0
    tr = Tracker(TrackerConfig(fps=fps))
    wall = box(3, 160.0, 1200.0, side=90.0)  # the occluder: x 115..205
    ids: dict[int, set[int]] = {1: set(), 4: set()}
    for k in range(45):
        cx = 60.0 + 150.0 * k / fps  # the far square slides right at 150 px/s behind the box
        objs = [wall]
        if not 95.0 <= cx <= 225.0:
            objs.append(box(1, cx, 2240.0))
        if k == 17:  # ten frames hidden, the sliver: 33 % nearer than the far square, on its path
            area = 8 * 100
            objs.append(
                SceneObject(4, "object", 0, 1490.0, 5.0, area, area / (W * H), (189.5, 119.5), (186, 70, 194, 170))
            )
        for oid, m in tr.update(objs, None, (W, H)).motions.items():
            ids.setdefault(oid, set()).add(m.track_id)
    assert len(ids[1]) == 1  # the far square keeps its id
    assert not ids[4] & ids[1]  # the sliver got an id of its own


def test_a_track_gone_in_the_open_or_hidden_too_long_ends() -> None:
    # Nothing nearer where it vanished: the frame budget applies, and it comes back as new.
    frames = _pass_behind(30.0, 0.8, occluder=False)
    far = [f[1] for f in frames if 1 in f]
    assert len(set(far)) == 2
    # Hidden longer than max_occluded_s (1 s): a new id too.
    frames = _pass_behind(30.0, 1.3)
    far = [f[1] for f in frames if 1 in f]
    assert len(set(far)) == 2


def test_occluded_track_past_the_frame_budget_keeps_its_velocity() -> None:
    tr = Tracker(TrackerConfig(fps=30.0))
    for k in range(12):  # receding at 300 mm/s, then hidden behind a nearer object
        z = 2000.0 + 300.0 * k / 30.0
        upd = tr.update([box(1, 100.0, z), box(2, 200.0, 1000.0, side=80.0)], None, (W, H))
    for _ in range(12, 27):
        upd = tr.update([box(2, 110.0, 1000.0, side=80.0)], None, (W, H))
    (hidden,) = upd.occluded
    assert hidden.missed == 15 and hidden.status == "occluded"
    assert hidden.motion.v_radial is not None
    assert_allclose(hidden.motion.v_radial, 300.0, rtol=0.05)
    # its predicted depth: where it would be at 300 mm/s, within the uncertainty it reports,
    # which has grown over the 15 frames it coasted
    truth = 2000.0 + 300.0 * 26 / 30.0
    assert hidden.depth_mm is not None and hidden.depth_sigma_mm is not None
    assert abs(hidden.depth_mm - truth) <= 2 * hidden.depth_sigma_mm
    assert_allclose(hidden.depth_mm, truth, rtol=0.01)
    assert hidden.center_xy is not None
    assert_allclose(hidden.center_xy, (99.5, 119.5), atol=0.5)  # it stood still in the image


@pytest.mark.parametrize("sensor", ["tof", "structured-light"])
def test_ball_behind_a_ball_and_a_box_keeps_its_id_by_the_fields_metrics(sensor: str) -> None:
    # Issue 30's target on the passing-behind sequence: the far ball is hidden behind the near
    # ball for about 7 frames and behind the box for about 13 (0.43 s, past max_missed).
    pytest.importorskip("motmetrics")
    pytest.importorskip("norfair")
    ours, plain = mot_sequence("pass_behind", 100, sensor=sensor, seed=1)
    assert ours.tracker == "depthgram" and plain.tracker == "norfair"
    assert ours.id_switches == 0 and ours.idf1 >= 0.95  # measured 0.990 (tof), 0.992
    assert ours.merged == 0
    # norfair over the same segments, matched on image centres only: the hidden ball comes
    # out under a new id
    assert plain.id_switches >= 1 and plain.idf1 < ours.idf1
    assert ours.v_covered >= 0.95  # v_sigma holds the error of the near ball's closing speed
