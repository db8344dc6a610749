"""The tracker on hand-built object sequences with known truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from depthgram.dynamics import Tracker, TrackerConfig
from depthgram.errors import InputError
from depthgram.scene.tree import Motion
from depthgram.segmentation.objects import SceneObject

#: The paper's queue slope (equation 13 and its least-squares extension): tests of its exact
#: values name it, since the default estimator is the Kalman filter.
QUEUE = TrackerConfig(estimator="queue")

W, H = 640, 480
FPS = 30.0


def box(oid: int, cx: float, cy: float, w: float, h: float, z: float, depth_label: int = 0) -> SceneObject:
    """A rectangular object clipped to the image, as segmentation would report it."""
    x0, x1 = max(0, round(cx - w / 2)), min(W, round(cx + w / 2))  # half-open
    y0, y1 = max(0, round(cy - h / 2)), min(H, round(cy + h / 2))
    area = (x1 - x0) * (y1 - y0)
    center = ((x0 + x1 - 1) / 2, (y0 + y1 - 1) / 2)
    return SceneObject(oid, "object", depth_label, z, 5.0, area, area / (W * H), center, (x0, y0, x1, y1))


def approaching(speed: float, z0: float, n: int, noise: float, seed: int = 0) -> list[SceneObject]:
    """A 100 mm x 100 mm square (fx = 500 px) coming straight at the sensor at ``speed`` mm/s."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        z = z0 + speed * k / FPS
        side = 500 * 100 / z
        out.append(box(3, 320, 240, side, side, z + rng.normal(0, noise)))
    return out


def test_approach_velocity_and_ttc_noise_free() -> None:
    tr = Tracker(QUEUE)
    objs = approaching(-600.0, 2000.0, 8, noise=0.0)
    for k, o in enumerate(objs):
        m = tr.update([o], k / FPS, (W, H)).motions[3]
        assert m.track_id == 1 and m.status == "visible" and m.fps_assumed is None
        if k == 0:
            assert m.v_radial is None and m.ttc is None
            continue
        assert m.v_radial == pytest.approx(-600.0, rel=1e-6)
        assert m.ttc == pytest.approx(o.depth / 600.0, rel=1e-6)  # depth over closing speed


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_approach_velocity_with_depth_noise(seed: int) -> None:
    # sigma 2 mm on the mean depth; the 4-frame least-squares slope then has a standard
    # error of 2 / sqrt(5) = 0.89 mm/frame, so 2 mm/frame is 2.2 standard errors: a few
    # frames in a hundred may exceed it, none by far.
    truth = -400.0
    tol = max(0.05 * abs(truth), 2.0 * FPS)  # 5 % or 2 mm/frame, whichever larger
    tr = Tracker(QUEUE)
    errors, ttc_rel = [], []
    for k, o in enumerate(approaching(truth, 2500.0, 60, noise=2.0, seed=seed)):
        m = tr.update([o], k / FPS, (W, H)).motions[3]
        if k >= 3:
            assert m.v_radial is not None and m.ttc is not None
            errors.append(m.v_radial - truth)
            z_true = 2500.0 + truth * k / FPS
            ttc_rel.append(m.ttc / (z_true / -truth) - 1)
    err = np.abs(errors)
    assert np.sqrt(np.mean(err**2)) < tol / 2
    assert np.mean(err <= tol) >= 0.9
    assert err.max() < 2 * tol
    assert np.median(np.abs(ttc_rel)) < 0.05


def test_receding_object_has_no_ttc() -> None:
    tr = Tracker(QUEUE)
    for k, o in enumerate(approaching(+500.0, 800.0, 5, noise=0.0)):
        m = tr.update([o], k / FPS, (W, H)).motions[3]
    assert m.v_radial == pytest.approx(500.0) and m.ttc is None


def test_frames_without_timestamps_take_the_configured_rate_or_warn() -> None:
    objs = approaching(-300.0, 1500.0, 6, noise=0.0)  # 10 mm per frame at 30 frames/s
    tr = Tracker(TrackerConfig(estimator="queue", fps=15.0))  # the same frames at 15 frames/s: 150 mm/s
    for o in objs:
        m = tr.update([o], None, (W, H)).motions[3]
    assert m.v_radial == pytest.approx(-150.0)
    assert m.ttc == pytest.approx(objs[-1].depth / 150.0)  # s
    tr = Tracker(QUEUE)
    with pytest.warns(UserWarning, match="--fps") as record:
        for o in objs:
            m = tr.update([o], None, (W, H)).motions[3]
    assert len(record) == 1  # once, not every frame
    assert m.v_radial == pytest.approx(-300.0)  # the nominal 30 frames/s
    assert m.fps_assumed == 30.0
    assert m.ttc == pytest.approx(objs[-1].depth / 300.0)


def test_a_single_still_without_a_rate_does_not_warn() -> None:
    # One frame has no time step: nothing rests on the assumed rate, so nothing is said.
    import warnings

    objs = approaching(-300.0, 1500.0, 2, noise=0.0)
    tr = Tracker(QUEUE)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tr.update([objs[0]], None, (W, H))
    with pytest.warns(UserWarning, match="--fps"):
        tr.update([objs[1]], None, (W, H))  # the second frame needs the rate
    tr.reset()
    with pytest.warns(UserWarning, match="--fps"):  # a new sequence is told again
        tr.update([objs[0]], None, (W, H))
        tr.update([objs[1]], None, (W, H))


def test_still_object_noise_does_not_explode() -> None:
    rng = np.random.default_rng(7)
    sigma = 4.0
    tr = Tracker()
    vs, ttcs = [], 0
    for k in range(200):
        o = box(1, 300, 200, 80, 60, 1800.0 + rng.normal(0, sigma))
        m = tr.update([o], k / FPS, (W, H)).motions[1]
        if k >= 3:
            assert m.v_radial is not None
            vs.append(m.v_radial / FPS)
            ttcs += m.ttc is not None
    v = np.abs(np.array(vs))
    # Slope of 4 equally spaced points: std sigma / sqrt(5) = 1.8 mm/frame.
    assert np.median(v) < sigma / np.sqrt(5)
    assert v.max() < 5 * sigma / np.sqrt(5)
    assert ttcs < 0.2 * len(vs)  # mostly "still": below min_speed


def test_two_objects_crossing_one_behind_the_other() -> None:
    # A (near, 1000 mm) moves right, B (far, 2500 mm) moves left; B is hidden while the
    # two overlap, then reappears on the far side.
    tr = Tracker()
    ids_a, ids_b, occluded_b = set(), set(), 0
    for k in range(50):
        xa, xb = 150 + 7 * k, 490 - 7 * k
        objs = [box(1, xa, 240, 90, 90, 1000.0 - 3 * k)]
        hidden = abs(xa - xb) < 60  # frames 21..28: 8 frames, within the budget of 10
        if not hidden:
            objs.append(box(2, xb, 250, 60, 60, 2500.0, depth_label=1))
        upd = tr.update(objs, k / FPS, (W, H))
        ids_a.add(upd.motions[1].track_id)
        if hidden:
            assert [t.status for t in upd.occluded] == ["occluded"]
            occluded_b += 1
        else:
            ids_b.add(upd.motions[2].track_id)
        assert not upd.ended
    assert occluded_b == 8
    assert ids_a == {1} and ids_b == {2}  # no identity switch
    m = upd.motions[1]
    assert m.v_radial == pytest.approx(-90.0, rel=1e-6)


def test_occluded_entries_are_skipped_in_the_fit() -> None:
    tr = Tracker(TrackerConfig(estimator="queue", queue_length=4))
    zs = {0: 2020.0, 1: 2010.0, 2: 2000.0, 3: 1990.0, 5: 1970.0}  # frame 4 missing
    for k in range(6):
        upd = tr.update([box(1, 320, 240, 50, 50, zs[k])] if k in zs else [], k / FPS, (W, H))
        if k == 4:
            assert upd.occluded[0].motion.v_radial == pytest.approx(-300.0)
    track = tr.tracks[0]
    assert [z for _, z in track.queue] == [2000.0, 1990.0, None, 1970.0]
    assert upd.motions[1].v_radial == pytest.approx(-300.0)


@pytest.mark.parametrize("gap", [10, 11])
def test_occlusion_budget(gap: int) -> None:
    cfg = TrackerConfig(max_missed=10)
    tr = Tracker(cfg)
    ended = []
    for k in range(5):
        tr.update([box(1, 320, 240, 50, 50, 1500.0)], k / FPS, (W, H))
    for k in range(5, 5 + gap):
        upd = tr.update([], k / FPS, (W, H))
        ended.extend(upd.ended)
    m = tr.update([box(1, 320, 240, 50, 50, 1500.0)], (5 + gap) / FPS, (W, H)).motions[1]
    if gap <= cfg.max_missed:
        assert m.track_id == 1 and not ended
    else:
        assert m.track_id == 2
        assert [t.id for t in ended] == [1] and ended[0].confirmed


def test_enter_at_left_and_leave_at_right() -> None:
    # A 60 px wide object at constant depth crossing the whole field of view; its mean
    # depth reads 40 mm deeper while partly visible (the visible part is its rim).
    tr = Tracker()
    tr.update([], 0.0, (W, H))  # at the very first frame nothing is "entering" yet
    statuses, ids, vs = [], set(), []
    k = 1
    for cx in range(-25, W + 30, 8):
        clipped = cx - 30 < 0 or cx + 30 > W
        o = box(4, cx, 240, 60, 60, 1500.0 + (40.0 if clipped else 0.0))
        upd = tr.update([o], k / FPS, (W, H))
        k += 1
        m = upd.motions[4]
        statuses.append((cx, m.status))
        ids.add(m.track_id)
        if m.v_radial is not None:
            vs.append(m.v_radial)
    assert ids == {1}
    left = [s for cx, s in statuses if cx - 30 < 0]
    right = [s for cx, s in statuses if cx + 30 > W]
    middle = [s for cx, s in statuses if cx - 30 > 2 and cx + 30 < W - 3]
    assert set(left) == {"entering"}
    assert set(right) == {"leaving"}
    assert set(middle) == {"visible"}
    assert np.abs(vs).max() < 1e-6  # area change and rim bias are not read as motion
    # It leaves: the track survives the budget as occluded, then ends.
    ended = []
    for j in range(TrackerConfig().max_missed + 1):
        ended.extend(tr.update([], (k + j) / FPS, (W, H)).ended)
    assert [t.id for t in ended] == [1]


def test_one_frame_split_keeps_identity_of_the_bigger_part() -> None:
    tr = Tracker()
    for k in range(6):
        if k == 3:  # segmentation cut the object in two, 70 / 30
            objs = [box(7, 300, 240, 28, 100, 1200.0), box(8, 334, 240, 70, 100, 1200.0)]
        else:
            objs = [box(7, 320, 240, 100, 100, 1200.0)]
        upd = tr.update(objs, k / FPS, (W, H))
        if k == 3:
            assert upd.motions[8].track_id == 1
            assert upd.motions[7].track_id == 2
        else:
            assert upd.motions[7].track_id == 1
        assert not upd.ended  # the splinter never was a confirmed track
    assert [t.id for t in tr.tracks] == [1]


def test_one_frame_merge_keeps_both_identities_and_velocity() -> None:
    tr = Tracker(QUEUE)
    for k in range(8):
        za = 1500.0 - 10 * k  # big object approaching 300 mm/s
        if k == 4:  # merged with its small neighbour at 1600 mm for one frame
            merged = box(1, 340, 240, 140, 100, (100 * 100 * za + 40 * 100 * 1600.0) / 14000)
            objs = [merged]
        else:
            objs = [box(1, 320, 240, 100, 100, za), box(2, 390, 240, 40, 100, 1600.0)]
        upd = tr.update(objs, k / FPS, (W, H))
        if k == 4:
            assert upd.motions[1].track_id == 1
            assert [t.id for t in upd.occluded] == [2]
        else:
            assert upd.motions[1].track_id == 1 and upd.motions[2].track_id == 2
        if k >= 2:
            # the merged frame's biased depth is not fitted
            assert upd.motions[1].v_radial == pytest.approx(-300.0, rel=1e-6)


def test_min_hits_confirms_and_tentative_tracks_die_silently() -> None:
    tr = Tracker(TrackerConfig(min_hits=3))
    for k in range(3):
        tr.update([box(1, 100, 100, 30, 30, 900.0)], k / FPS, (W, H))
        assert tr.tracks[0].confirmed == (k >= 2)
    tr.update([box(1, 100, 100, 30, 30, 900.0), box(2, 500, 300, 30, 30, 900.0)], 3 / FPS, (W, H))
    upd = tr.update([box(1, 100, 100, 30, 30, 900.0)], 4 / FPS, (W, H))
    assert not upd.ended and not upd.occluded and [t.id for t in tr.tracks] == [1]


def test_reset_restarts_ids() -> None:
    tr = Tracker()
    tr.update([box(1, 100, 100, 30, 30, 900.0), box(2, 300, 100, 30, 30, 900.0)], 0.0, (W, H))
    tr.reset()
    assert tr.tracks == ()
    upd = tr.update([box(5, 100, 100, 30, 30, 900.0)], 0.0, (W, H))
    assert upd.motions[5].track_id == 1


def test_bad_input_is_reported() -> None:
    tr = Tracker()
    o = box(1, 100, 100, 30, 30, 900.0)
    with pytest.raises(InputError, match="duplicate"):
        tr.update([o, o], 0.0, (W, H))
    with pytest.raises(InputError, match="frame_size"):
        tr.update([o], 0.0, (0, H))
    tr.update([o], 1.0, (W, H))
    with pytest.raises(InputError, match="not after"):
        tr.update([o], 1.0, (W, H))
    with pytest.raises(InputError, match="timestamps"):
        tr.update([o], None, (W, H))


def test_motions_are_ordinary_motion_objects() -> None:
    tr = Tracker()
    for k, o in enumerate(approaching(-600.0, 2000.0, 3, noise=0.0)):
        m = tr.update([o], k / FPS, (W, H)).motions[3]
    expected = Motion(track_id=1, v_radial=m.v_radial, ttc=m.ttc, status="visible", v_sigma=m.v_sigma)
    assert m == expected and repr(m) == repr(expected) and hash(m) == hash(expected)
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.ttc = 0.0  # type: ignore[misc]


def test_depth_jump_restarts_the_queue_instead_of_reading_speed() -> None:
    # A still object whose segment suddenly covers a surface 300 mm behind (15 %, inside
    # the matching gate): without the restart the fit would read metres per second.
    tr = Tracker(QUEUE)
    vs = []
    for k in range(10):
        z = 2000.0 if k < 5 else 2300.0
        m = tr.update([box(1, 320, 240, 80, 80, z)], k / FPS, (W, H)).motions[1]
        vs.append(m.v_radial)
    assert m.track_id == 1
    assert vs[5] is None  # one valid entry after the restart
    assert all(v == pytest.approx(0.0, abs=1e-9) for v in vs[6:])
    off = Tracker(TrackerConfig(estimator="queue", max_depth_jump_rate=float("inf")))
    for k in range(7):
        z = 2000.0 if k < 5 else 2300.0
        m = off.update([box(1, 320, 240, 80, 80, z)], k / FPS, (W, H)).motions[1]
    assert m.v_radial is not None and m.v_radial > 2000.0  # what the restart prevents


def test_partly_hidden_object_is_not_read_as_moving() -> None:
    """A still object (a box at 2000 mm) is covered step by step by a nearer one passing in front.

    Its visible part shrinks and, as on a real surface seen at a slant, the visible mean depth
    drifts (here +15 mm per frame); none of that is radial motion (paper, case b)."""
    tr = Tracker()
    v_far: list[float | None] = []
    for k in range(14):
        covered = 0 if k < 4 else min(k - 3, 8) * 5  # px of the far box's 60 px width hidden
        far = box(1, 100 + covered / 2, 60, 60 - covered, 40, 2000.0 + 15.0 * (covered / 5))
        near = box(2, 40 + 5 * k, 60, 30, 50, 900.0)
        upd = tr.update([far, near], k / 30.0, (176, 132))
        v_far.append(upd.motions[1].v_radial)
    # while it is being covered, no velocity reading strays beyond noise: the biased entries are skipped
    assert all(v is None or abs(v) < 60.0 for v in v_far[4:]), v_far


def test_object_turning_compound_restarts_the_queue() -> None:
    """A box still in depth shows its oblique side from frame 5 on: segmentation then reports a
    compound whose depth is read from its nearest part, 20 mm nearer than the front face's mean
    (a reading another way, not motion). The tracker must not read it as 600 mm/s."""
    tr = Tracker()
    vs: list[float | None] = []
    for k in range(10):
        o = box(1, 320, 240, 80, 80, 2000.0)
        if k >= 5:
            front = dataclasses.replace(o, kind="part", id=2, depth=1980.0)
            side = dataclasses.replace(o, kind="part", id=3, depth=2010.0)
            o = dataclasses.replace(o, kind="compound", parts=(front, side))
        m = tr.update([o], k / FPS, (W, H)).motions[1]
        assert m.track_id == 1
        vs.append(m.v_radial)
    # a speed once two depth differences agree: none on the first two frames, nor on the two
    # after the restart
    assert vs[:2] == [None, None] and vs[5:7] == [None, None], vs
    assert all(v == pytest.approx(0.0, abs=1e-9) for v in vs[2:5] + vs[7:]), vs


def test_compound_depth_ignores_one_nearer_sliver_at_its_edge() -> None:
    from depthgram.dynamics.tracker import track_depth

    o = box(1, 320, 240, 80, 80, 2150.0)

    def compound(*depths: float) -> SceneObject:
        parts = tuple(dataclasses.replace(o, kind="part", id=10 + i, depth=d) for i, d in enumerate(depths))
        return dataclasses.replace(o, kind="compound", parts=parts)

    # a front face in four slices at 2131-2132 mm, a mixed-pixel sliver at 2124 mm, a side behind
    assert track_depth(compound(2124.0, 2131.2, 2131.5, 2132.0, 2190.0, 2240.0)) == 2131.2
    # a surface running away in depth (slices 2 % apart): its nearest slice
    assert track_depth(compound(2000.0, 2040.0, 2080.0)) == 2000.0
    assert track_depth(compound(2131.0, 2190.0)) == 2131.0
    assert track_depth(o) == 2150.0  # a plain object: its mean depth


def test_kernel_settings_carry_each_config_field_under_its_name() -> None:
    import math

    from depthgram.dynamics.match import cost_params
    from depthgram.dynamics.tracker import estimate_params, step_params

    cfg = TrackerConfig(
        estimator="queue", max_depth_jump_rate=0.7, border_px=3, center_tau_s=0.05, min_hits=2,
        max_area_ratio=4.0, w_label=0.3, own_accel_sigma=1234.0, fit_border_entries=True,
    )  # fmt: skip
    sp, ep, cp = step_params(cfg), estimate_params(cfg), cost_params(cfg)
    assert (sp.max_depth_jump_rate, sp.border_px, sp.center_tau_s, sp.min_hits) == (0.7, 3.0, 0.05, 2)
    assert sp.fit_border_entries and sp.max_missed == cfg.max_missed and sp.area_tau_s == cfg.area_tau_s
    assert not ep.kalman and ep.min_speed == cfg.min_speed and ep.own_accel_sigma == 1234.0
    assert (ep.depth_sigma_mm, ep.innovation_gate) == (cfg.depth_sigma_mm, cfg.innovation_gate)
    assert cp.log_max_area_ratio == math.log(4.0) and cp.w_label == 0.3 and cp.max_center_rate == cfg.max_center_rate
    # the filter judges jumps by its own innovation gate: the queue's jump test is off
    kalman = TrackerConfig(estimator="kalman", max_depth_jump_rate=0.7)
    assert math.isinf(step_params(kalman).max_depth_jump_rate) and estimate_params(kalman).kalman
    # one compiled signature whatever numeric types the config was given
    assert all(isinstance(x, float) for x in cost_params(TrackerConfig(max_center_rate=3, w_area=1)))


def test_status_codes_and_names_agree() -> None:
    from depthgram.dynamics import STATUSES
    from depthgram.dynamics import kernels as K

    assert STATUSES == ("visible", "entering", "leaving", "occluded")
    assert [STATUSES[int(s)] for s in K.Status] == [s.name.lower() for s in K.Status]
    assert (K.VISIBLE, K.ENTERING, K.LEAVING, K.OCCLUDED) == tuple(int(s) for s in K.Status)


def test_keep_tracks_moves_the_kept_records_and_their_queues_to_the_front_in_order() -> None:
    from depthgram.dynamics.kernels import keep_tracks, new_tracks

    tracks = new_tracks(8)
    tracks["id"] = np.arange(1, 9)
    tracks["kf_z"][:6] = 1000.0 + np.arange(6)
    qt = np.arange(32.0).reshape(8, 4)
    qz = -qt
    keep = np.array([True, False, True, True, False, True])
    want_t, want_qt, want_qz = tracks[:6][keep].copy(), qt[:6][keep].copy(), qz[:6][keep].copy()
    assert keep_tracks(tracks, qt, qz, 6, keep) == 4
    for name in want_t.dtype.names:  # field by field: padding bytes are not state
        np.testing.assert_array_equal(tracks[name][:4], want_t[name])
    assert tracks["id"][:4].tolist() == [1, 3, 4, 6]
    np.testing.assert_array_equal(qt[:4], want_qt)
    np.testing.assert_array_equal(qz[:4], want_qz)
    assert tracks["id"][6:].tolist() == [7, 8]  # beyond the live tracks: untouched


@pytest.mark.parametrize("estimator", ["queue", "kalman"])
def test_track_records_hold_what_their_fields_say(estimator: str) -> None:
    from depthgram.dynamics.kernels import TRACK_DTYPE, TRACK_FIELDS, Status

    assert TRACK_DTYPE.names == tuple(name for name, _, _ in TRACK_FIELDS)
    # a box sliding right at 3 px per frame (90 px/s) and closing at 300 mm/s, noise-free
    tr = Tracker(TrackerConfig(estimator=estimator))
    frames = 10
    objs = [box(7, 200 + 3 * k, 240, 60, 60, 2000.0 - 300.0 * k / FPS, depth_label=2) for k in range(frames)]
    for k, o in enumerate(objs):
        tr.update([o], k / FPS, (W, H))
    last = objs[-1]
    t = tr._tracks[0]
    assert (t["id"], t["hits"], t["missed"], t["status"], t["label"]) == (1, frames, 0, Status.VISIBLE, 2)
    assert (t["cx"], t["cy"]) == last.center_xy == (t["ox"], t["oy"])
    assert (t["x0"], t["y0"], t["x1"], t["y1"]) == last.bbox_xy
    assert t["vx"] == pytest.approx(90.0, rel=1e-6) and t["vy"] == 0.0
    assert t["depth"] == last.depth and t["area"] == last.area and t["t_seen"] == (frames - 1) / FPS
    assert t["z_fit"] == pytest.approx(last.depth, abs=1e-6) and t["v"] == pytest.approx(-300.0, rel=1e-6)
    assert not t["read_nearest"]
    if estimator == "kalman":
        assert t["kf_v"] == pytest.approx(-300.0, rel=0.02) and t["kf_z"] == pytest.approx(last.depth, abs=1.0)
        assert t["kf_n"] == frames and t["kf_rej"] == 0 and t["kf_pvv"] > 0
    np.testing.assert_allclose(tr._qt[0], [k / FPS for k in range(frames - 4, frames)])
    np.testing.assert_allclose(tr._qz[0], [o.depth for o in objs[-4:]])
