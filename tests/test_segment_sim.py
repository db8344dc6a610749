"""Segmentation against the simulator's ground truth (seeded ToF frames) and on real recordings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthgram.segmentation import evaluate, segment

sensor = pytest.importorskip("depthgram.sensor")


def sim_frame(scene: str, index: int = 0, size: tuple[int, int] = (176, 132)):  # type: ignore[no-untyped-def]
    return list(sensor.simulate(scene, index + 1, size=size, seed=0))[index]


@pytest.fixture(scope="module")
def table():  # type: ignore[no-untyped-def]
    return sim_frame("table")


def test_table_scene_meets_the_area_and_precision_targets(table) -> None:  # type: ignore[no-untyped-def]
    f = table.frame
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics)
    ids = [t.id for t in table.truth]
    ev = evaluate(seg.labels, table.instances, valid=f.valid, truth_ids=ids)
    # beats the paper's 91 % at >= 95 % precision
    assert ev.area_assigned >= 0.96 and ev.precision_assigned >= 0.95
    for t in table.truth:
        if t.area >= 0.01 * f.valid.size:
            assert ev.score(t.id).iou >= 0.5, t.name
    # the cup, box, ball and bottle stand on the table but come out separate from it
    for t in table.truth:
        if t.parent == 3:
            s = ev.score(t.id)
            assert s.precision >= 0.9 and s.hoover == "correct", (t.name, s)
    # the table top is a compound of horizontal slices with successive depth labels
    top = seg.by_id()[ev.score(3).detected]
    assert top.kind == "compound" and len(top.parts) >= 5
    labels = [p.depth_label for p in top.parts]
    assert labels == sorted(labels) and labels[-1] > labels[0]


def test_global_thresholding_alone_merges_objects_with_the_table(table) -> None:  # type: ignore[no-untyped-def]
    f = table.frame
    ids = [t.id for t in table.truth]
    plain = evaluate(segment(f.depth, valid=f.valid, method="threshold").labels, table.instances, truth_ids=ids)
    region = evaluate(segment(f.depth, valid=f.valid, method="region").labels, table.instances, truth_ids=ids)
    cup = next(t.id for t in table.truth if t.name == "cup")
    assert plain.score(cup).precision < 0.5 and region.score(cup).precision < 0.5


def test_corridor_floor_walls_and_ceiling_are_compound_objects() -> None:
    sim = sim_frame("corridor")
    f = sim.frame
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics)
    ev = evaluate(seg.labels, sim.instances, valid=f.valid, truth_ids=[t.id for t in sim.truth])
    by_id = seg.by_id()
    for t in sim.truth:
        s = ev.score(t.id)
        if t.name in ("floor", "left_wall", "right_wall", "ceiling"):
            obj = by_id[s.detected]
            assert s.iou >= 0.8, (t.name, s)
            assert obj.kind == t.kind and len(obj.parts) >= 3, (t.name, obj.kind)
            # walls are cut in vertical slices, floor and ceiling in horizontal ones
            xs = [p.center_xy[0] for p in obj.parts]
            ys = [p.center_xy[1] for p in obj.parts]
            spread_x, spread_y = np.ptp(xs), np.ptp(ys)
            assert (spread_x > spread_y) == (t.kind == "wall")


def test_structured_light_sieve_and_random_dropouts(table) -> None:  # type: ignore[no-untyped-def]
    f = table.frame
    sieve = np.zeros(f.valid.shape, bool)
    sieve[::2, ::2] = True  # three quarters missing in a regular grid
    rng = np.random.default_rng(1)
    for valid in (f.valid & sieve, f.valid & (rng.random(f.valid.shape) > 0.3)):
        seg = segment(f.depth, valid=valid, intrinsics=f.intrinsics, fill_holes_px=1)
        assert not seg.labels[~valid].any()
        ev = evaluate(seg.labels, table.instances, valid=valid, truth_ids=[t.id for t in table.truth])
        assert ev.found_share == 1.0 and ev.area_assigned >= 0.95 and ev.precision_assigned >= 0.95


def test_crossing_scene_finds_both_movers() -> None:
    sim = sim_frame("crossing", 30)
    f = sim.frame
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics)
    ev = evaluate(seg.labels, sim.instances, valid=f.valid, truth_ids=[t.id for t in sim.truth])
    for t in sim.truth:
        if t.kind == "object" and t.area >= 0.01 * f.valid.size:
            assert ev.score(t.id).iou >= 0.5, t.name


def test_real_tof_mug_is_the_nearest_object(shared_data: Path) -> None:
    cv2 = pytest.importorskip("cv2")
    from depthgram.frame import Intrinsics, make_frame

    path = shared_data / "azure_kinect_tof_mug_single" / "depth.png"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    f = make_frame(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), intrinsics=Intrinsics(504.6, 504.7, 333.0, 349.0))
    seg = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics)
    assert seg.objects and not seg.labels[~f.valid].any()
    near = min((o for o in seg.objects if o.kind == "object"), key=lambda o: o.depth)
    # PROVENANCE.md: the mug is 0.25-0.30 m from the camera, the desk and wall much farther;
    # its curved flank is not taken for a wall, so the mug stays one object
    assert 250 <= near.depth <= 300 and near.area > 0.05 * f.valid.size
    assert near.centroid_mm is not None and near.area_mm2 is not None and near.area_mm2 > 0


def test_cart_side_face_joins_its_front_not_a_wall() -> None:
    """On `crossing` the cart shows its front and an oblique side: one compound, not a wall piece."""
    import numpy as np

    from depthgram.segmentation import segment
    from depthgram.sensor import simulate

    sim = list(simulate("crossing", 13, seed=1))[-1]  # cart entering from the side
    cart = next(t for t in sim.truth if t.name == "cart")
    seg = segment(sim.frame.depth, valid=sim.frame.valid, intrinsics=sim.frame.intrinsics)
    mask = sim.instances == cart.id
    ids, counts = np.unique(seg.labels[mask], return_counts=True)
    objects = seg.by_id()
    kinds = {objects[int(i)].kind for i, c in zip(ids, counts, strict=True) if i and c >= 0.1 * mask.sum()}
    assert "wall" not in kinds, kinds
    best = int(ids[np.argmax(counts)])
    assert best and counts.max() >= 0.85 * mask.sum()
