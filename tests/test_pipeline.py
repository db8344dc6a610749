"""The pipeline end to end on simulated scenes with ground truth, and its TOML configuration."""

from __future__ import annotations

import json

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.pipeline import Config, Pipeline, describe
from depthgram.sensor import simulate


def test_config_round_trips_through_toml(tmp_path) -> None:
    cfg = Config().replace(segment={"min_area_px": 123}, tracker={"max_missed": 7})
    path = tmp_path / "cfg.toml"
    cfg.save(path)
    back = Config.load(path)
    assert back == cfg
    assert back.segment.min_area_px == 123 and back.tracker.max_missed == 7


def test_config_refuses_unknown_keys_and_sections(tmp_path) -> None:
    with pytest.raises(InputError, match="unknown setting"):
        Config.from_dict({"segment": {"no_such_setting": 1}})
    with pytest.raises(InputError, match="unknown section"):
        Config.from_dict({"segmentation": {}})
    bad = tmp_path / "bad.toml"
    bad.write_text("[segment\nmin_area = 3", encoding="utf-8")
    with pytest.raises(InputError, match="not valid TOML"):
        Config.load(bad)


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.count_nonzero(a & b)) / max(1, int(np.count_nonzero(a | b)))


def test_table_scene_objects_match_ground_truth_and_record_is_complete() -> None:
    sim = next(iter(simulate("table", 1, seed=3)))
    result = Pipeline(track=False).process(sim.frame)
    rec = json.loads(json.dumps(result.to_record()))
    for key in ("frame", "time_s", "size", "unit", "objects", "sentence", "relations"):
        assert key in rec
    assert rec["size"] == [sim.frame.size[0], sim.frame.size[1]] and rec["unit"] == "mm"
    ids = {o["id"] for o in rec["objects"]}
    assert ids == set(np.unique(result.segmentation.labels)) - {0}
    for o in rec["objects"]:
        for key in ("id", "kind", "depth_label", "depth", "area", "center_xy", "bbox_xy", "parent", "parts"):
            assert key in o
        assert o["area"] == int(np.count_nonzero(result.segmentation.labels == o["id"]))
    # every compact ground-truth object of at least 1% of the frame is found (IoU >= 0.5)
    total = sim.instances.size
    for t in sim.truth:
        if t.kind != "object" or t.area < 0.01 * total:
            continue
        best = max(
            (_iou(result.segmentation.labels == o.id, sim.instances == t.id) for o in result.segmentation.objects),
            default=0.0,
        )
        assert best >= 0.5, f"{t.name} not found (best IoU {best:.2f})"


def test_approaching_hand_keeps_its_id_and_reads_the_true_speed() -> None:
    sims = list(simulate("approach", 12, seed=1))
    pipe = Pipeline()
    results = [pipe.process(s.frame) for s in sims]
    hand_truth = [next(t for t in s.truth if t.name == "hand") for s in sims]
    track_ids = []
    for s, r, ht in zip(sims, results, hand_truth, strict=True):
        mask = s.instances == ht.id
        best = max(r.segmentation.objects, key=lambda o: _iou(r.segmentation.labels == o.id, mask))
        track_ids.append(best.id)
    assert len(set(track_ids)) == 1, f"hand changed identity: {track_ids}"
    last = results[-1].motions[track_ids[-1]]
    assert last.v_radial is not None and last.fps_assumed is None
    truth_v = hand_truth[-1].v_radial
    assert abs(last.v_radial - truth_v) <= max(0.05 * abs(truth_v), 2 * 30.0), (last.v_radial, truth_v)


def test_describe_one_array_without_tracking() -> None:
    depth = np.full((60, 80), 2000.0, np.float32)
    depth[20:40, 30:50] = 800.0
    result = describe(depth)
    near = [o for o in result.segmentation.objects if abs(o.depth - 800) < 5]
    assert len(near) == 1 and near[0].area == 400
    assert result.sentence.startswith("Bkg")
