"""The tracker on a real hand-held Kinect sequence (7-Scenes redkitchen, 30 Hz, mm PNGs).

The scene is static and the camera moves about 7 mm per frame (0.2 m/s, 36 mm at most), so
every radial velocity read comes from ego-motion, segmentation changes and sensor noise:
it must stay of the order of the camera's speed, never explode.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from depthgram.dynamics import Tracker
from depthgram.frame import Frame, Intrinsics, make_frame

FPS = 30.0
FRAMES = 30


def _frames(folder: Path, n: int) -> list[Frame]:
    try:
        from depthgram import read

        frames = list(itertools.islice(read(str(folder)), n))
    except ImportError:
        import cv2

        frames = [
            make_frame(cv2.imread(str(p), cv2.IMREAD_UNCHANGED), invalid_values=(65535,), index=k, name=str(p),
                       intrinsics=Intrinsics(585.0, 585.0, 320.0, 240.0))
            for k, p in enumerate(sorted(folder.glob("*.png"))[:n])
        ]  # fmt: skip
    return frames


def test_real_sequence_velocities_stay_physical(shared_data: Path) -> None:
    from depthgram.segmentation import segment

    folder = shared_data / "7scenes_redkitchen_seq" / "depth"
    if not folder.is_dir():
        pytest.skip(f"{folder} not found")
    frames = _frames(folder, FRAMES)
    assert len(frames) == FRAMES
    tracker = Tracker()
    speeds, n_objects, ids = [], 0, set()
    for k, fr in enumerate(frames):
        seg = segment(fr.depth, valid=fr.valid, intrinsics=fr.intrinsics)
        upd = tracker.update(seg.objects, k / FPS, fr.size)
        assert set(upd.motions) == {o.id for o in seg.objects}
        n_objects += len(seg.objects)
        ids.update(m.track_id for m in upd.motions.values())
        speeds += [abs(m.v_radial) for m in upd.motions.values() if m.v_radial is not None]
    v = np.array(speeds)
    assert len(v) > 0.5 * n_objects  # most objects are followed long enough to read a speed
    assert len(ids) < 0.25 * n_objects  # identities persist: far fewer tracks than detections
    assert np.median(v) < 100.0  # mm/s; the camera moves about 200 mm/s
    assert np.mean(v > 1000.0) < 0.02
    assert v.max() < 3000.0  # nothing explodes


def test_radial_velocity_from_poses_hand_computed() -> None:
    from depthgram.dynamics.evaluate import radial_velocity_from_poses

    depth = np.full((4, 6), 2000.0)
    labels = np.zeros((4, 6), np.int32)
    labels[1:3, 1:4] = 5
    eye = np.eye(4)
    # The camera steps 10 mm forward per frame: the object comes 10 mm nearer per frame.
    prev, nxt = eye.copy(), eye.copy()
    prev[2, 3], nxt[2, 3] = -10.0, 10.0
    v = radial_velocity_from_poses(depth, labels, [5, 7], (500.0, 500.0, 3.0, 2.0), prev, nxt, 2 / 30)
    assert v == {5: pytest.approx(-300.0)}  # mm/s; object 7 has no pixel
    # A turn about the optical axis changes no depth.
    c, s = np.cos(0.1), np.sin(0.1)
    rot = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    v = radial_velocity_from_poses(depth, labels, [5], (500.0, 500.0, 3.0, 2.0), rot.T, rot, 2 / 30)
    assert v[5] == pytest.approx(0.0, abs=1e-9)


def test_core_depth_change_follows_the_posed_truth_better_than_the_mean(shared_data: Path) -> None:
    # 7-Scenes' static scene against the true radial velocities from the camera poses (issue 13,
    # item 1): the mean depth of a wall or floor moves with what part of it is in view, the
    # core does not; and the core moved by the camera's motion (ICP, each pixel its own image
    # motion) lines up walls and floors that one shift per frame does not. Measured over 60
    # frames: within 25 % + 30 mm/s 0.77 of the readings with the camera's motion (walls 0.63,
    # floors 0.67), 0.69 with one shift (walls 0.47, floors 0.56), 0.50 from the mean. The 95th
    # percentile of the error with one shift is 0.73 of the mean's since the objects' feet came
    # back from the supports (0.67 before: the mean of an object with its foot moves less).
    from benchmarks.bench_tracking import truth_rows

    if not (shared_data / "7scenes_redkitchen_seq" / "pose").is_dir():
        pytest.skip("7scenes_redkitchen_seq with poses not found")
    rows = truth_rows(60, depth="core")
    plain_rows = truth_rows(60, depth="plain")
    assert rows is not None and plain_rows is not None
    shift, camera, plain = rows["core/shift"], rows["core/camera"], plain_rows["plain"]
    assert shift["within"] >= 0.6 and plain["within"] <= 0.55
    assert shift["err_p95"] < 0.8 * plain["err_p95"]
    assert camera["within"] >= 0.75 and camera["within"] >= shift["within"] + 0.06
    assert camera["err_p95"] < 0.9 * shift["err_p95"]
    kinds, kinds_shift = camera["by_kind"], shift["by_kind"]
    assert isinstance(kinds, dict) and isinstance(kinds_shift, dict)
    assert kinds["wall"][0] >= kinds_shift["wall"][0] + 0.1 and kinds["floor"][0] >= kinds_shift["floor"][0] + 0.05


def test_seven_scenes_meets_the_range_flow_target_and_raises_no_false_alarm(shared_data: Path) -> None:
    # Issue 13's target on the whole recording: 300 frames of a still kitchen seen by a hand-held
    # Kinect, objects of at least 1 % of the frame from the third frame of each track, within
    # 25 % + 30 mm/s of the poses' truth in at least 80 % of readings (measured 0.848; 0.723
    # before the camera's part of each velocity was read afresh each frame). The camera moves
    # at 0.5 m/s at most: one core read across two surfaces once gave -5.2 m/s and a collision
    # 0.4 s away; the largest reading is now 652 mm/s.
    from benchmarks.bench_tracking import real_rows, truth_rows

    if not (shared_data / "7scenes_redkitchen_seq" / "pose").is_dir():
        pytest.skip("7scenes_redkitchen_seq with poses not found")
    rows = truth_rows(300, image_motions=("camera",))
    speeds = real_rows(300)
    assert rows is not None and speeds is not None
    camera = rows["core/camera"]
    assert camera["within"] >= 0.8
    assert camera["err_p95"] < 120.0  # mm/s; measured 83
    assert camera["z_within_2sigma"] >= 0.95  # v_sigma holds the error; measured 0.987
    assert speeds["max"] < 1000.0 and speeds["over_1m_s"] == 0.0
