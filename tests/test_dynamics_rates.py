"""Frame-rate independence: fast approaches get a velocity and a time to collision at any rate.

Issue 13, item 0: a clean object closing at walking speed used to get no velocity at all,
because a per-frame relative depth-jump gate restarted its queue on every frame before the
track had a velocity (so its prediction was "standing still"). These sequences are noise
free, so the truth is exact: z(t) = z0 + v t, and the time to collision is z / -v.
"""

from __future__ import annotations

import itertools

import pytest

from depthgram.dynamics import Tracker, TrackerConfig
from depthgram.segmentation.objects import SceneObject

W, H = 640, 480
FX = 500.0  # px, a 200 mm wide object


def square(z: float) -> SceneObject:
    """A 200 mm square straight ahead at depth ``z`` (mm), as segmentation reports it."""
    side = min(FX * 200.0 / z, 0.9 * H)
    x0, x1 = round(320 - side / 2), round(320 + side / 2)
    y0, y1 = round(240 - side / 2), round(240 + side / 2)
    area = (x1 - x0) * (y1 - y0)
    center = ((x0 + x1 - 1) / 2, (y0 + y1 - 1) / 2)
    return SceneObject(1, "object", 0, z, 5.0, area, area / (W * H), center, (x0, y0, x1, y1))


CASES = list(itertools.product((10.0, 15.0, 30.0, 60.0), (500.0, 1000.0, 1500.0, 2000.0), (1500.0, 3000.0)))


@pytest.mark.parametrize("estimator", ["queue", "kalman"])
@pytest.mark.parametrize(("fps", "speed", "z0"), CASES)
def test_fast_approach_gets_velocity_and_ttc_within_three_frames(
    fps: float, speed: float, z0: float, estimator: str
) -> None:
    tr = Tracker(TrackerConfig(estimator=estimator))
    checked = 0
    for k in itertools.count():
        z = z0 - speed * k / fps
        if z < 400.0:  # the sensor's near limit; the object would fill the view
            break
        m = tr.update([square(z)], k / fps, (W, H)).motions[1]
        assert m.track_id == 1
        if k < 3:  # three frames of first sight to settle
            continue
        assert m.v_radial is not None, f"frame {k}: no velocity"
        assert m.v_radial == pytest.approx(-speed, rel=0.10), f"frame {k}"
        assert m.ttc is not None, f"frame {k}: no time to collision"
        assert m.ttc == pytest.approx(z / speed, rel=0.10), f"frame {k}"
        checked += 1
    assert checked >= 1  # every case leaves at least one frame to check


def test_queue_v_sigma_is_the_slope_standard_error_of_the_noise_model() -> None:
    cfg = TrackerConfig(estimator="queue", depth_sigma_mm=4.0, depth_sigma_floor_mm=1.0)
    tr = Tracker(cfg)
    for k in range(2):
        m = tr.update([square(2000.0)], k / 30, (W, H)).motions[1]
    # two entries 1/30 s apart, each with sigma 1 + 4 * 2^2 = 17 mm: slope sigma 17 * sqrt(2) * 30
    assert m.v_sigma == pytest.approx(17.0 * 2**0.5 * 30.0)


def test_kalman_rejects_a_one_frame_outlier_and_keeps_a_steady_reading() -> None:
    """A steady approach at 1 m/s with one reading 150 mm off (a segment that grabbed the wall
    behind for a frame): the filter's innovation gate drops it, so the velocity does not swing
    by more than 3 v_sigma between neighbouring frames, and stays within 10 %."""
    tr = Tracker(TrackerConfig(estimator="kalman"))
    prev = None
    for k in range(40):
        z = 3000.0 - 1000.0 * k / 30
        m = tr.update([square(z + (150.0 if k == 20 else 0.0))], k / 30, (W, H)).motions[1]
        if k >= 3:
            assert m.v_radial is not None and m.v_sigma is not None
            assert m.v_radial == pytest.approx(-1000.0, rel=0.10), k
            if prev is not None:
                assert abs(m.v_radial - prev.v_radial) <= 3 * m.v_sigma, k
            prev = m


def test_ttc_only_when_the_velocity_is_known_well_enough() -> None:
    # A slow approach read through a noisy sensor model: the closing speed is within its
    # v_sigma, so no time to collision is claimed; a precise sensor gives one.
    for sigma, has_ttc in ((200.0, False), (0.5, True)):
        tr = Tracker(TrackerConfig(estimator="kalman", depth_sigma_mm=sigma))
        for k in range(4):
            m = tr.update([square(2000.0 - 600.0 * k / 30)], k / 30, (W, H)).motions[1]
        assert m.v_radial is not None and m.v_sigma is not None
        assert (m.ttc is not None) == has_ttc, (sigma, m)


@pytest.mark.parametrize("estimator", ["queue", "kalman"])
@pytest.mark.parametrize("fps", [10.0, 30.0, 60.0])
def test_moving_object_hidden_for_max_missed_frames_gets_its_id_back(fps: float, estimator: str) -> None:
    """An object crossing the view at 0.6 m/s (2 m away) and approaching at 0.3 m/s is hidden
    for ``max_missed`` frames and comes back where its motion takes it: same id, and its
    velocity is read again at once, at any frame rate."""
    cfg = TrackerConfig(estimator=estimator)
    tr = Tracker(cfg)
    px_per_s = FX * 600.0 / 2000.0  # 150 px/s across the image
    ids = set()
    for k in range(40):
        t = k / fps
        z = 2000.0 - 300.0 * t
        o = square(z)
        shift = px_per_s * t - 100.0
        x0, y0, x1, y1 = o.bbox_xy
        o = SceneObject(1, "object", 0, z, 5.0, o.area, o.area_fraction, (o.center_xy[0] + shift, o.center_xy[1]),
                        (round(x0 + shift), y0, round(x1 + shift), y1))  # fmt: skip
        hidden = 15 <= k < 15 + cfg.max_missed
        upd = tr.update([] if hidden else [o], t, (W, H))
        assert not upd.ended
        if not hidden:
            ids.add(upd.motions[1].track_id)
            if k == 15 + cfg.max_missed:  # back from behind
                assert upd.motions[1].v_radial == pytest.approx(-300.0, rel=0.10)
    assert ids == {1}


@pytest.mark.parametrize("sensor", ["tof", "structured-light"])
@pytest.mark.parametrize(("scene", "fps", "frames", "rel", "share"), [("ball_rush", 15.0, 20, 0.10, 0.8)])
def test_a_ball_closing_at_a_steady_speed_reads_it_from_its_third_frame(
    scene: str, fps: float, frames: int, rel: float, share: float, sensor: str
) -> None:
    # Issue 30, item 3, through the simulator, segmentation and tracker: a ball closes at
    # 1.5 m/s from 2.5 m to 0.5 m at 15 frames/s. Where it grows by 12-35 % a frame in the
    # image, its core once read -1.06 m/s; its mean depth reads the truth.
    from depthgram.dynamics.evaluate import mot_sequence

    pytest.importorskip("motmetrics")
    for size in ((176, 132), (320, 240)):
        (s,) = mot_sequence(scene, frames, size=size, fps=fps, sensor=sensor, trackers=("depthgram",), v_rel=rel)
        assert s.id_switches == 0 and s.idf1 == 1.0
        assert s.v_readings >= frames - 3
        assert s.v_within >= share, (size, s.v_within)
        assert s.v_covered >= 0.9, (size, s.v_covered)


def test_a_ball_closing_at_600_mm_s_at_30_fps_stays_within_5_percent() -> None:
    from depthgram.dynamics.evaluate import mot_sequence

    pytest.importorskip("motmetrics")
    (s,) = mot_sequence("ball_approach", 90, size=(320, 240), trackers=("depthgram",))
    assert s.v_readings >= 85
    assert s.v_within >= 0.9, s.v_within
