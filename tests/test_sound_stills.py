"""Stills: no motion (velocity, time to collision, approach alarm) between unrelated frames."""

from __future__ import annotations

import dataclasses
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from depthgram.cli import main
from depthgram.errors import InputError
from depthgram.frame import Frame
from depthgram.pipeline import Config, Pipeline
from depthgram.sensor.simulate import simulate
from depthgram.sound import SoundMapping, voices
from depthgram.sources import open_source
from depthgram.stills import kinship


def untimed(frames: list[Frame]) -> list[Frame]:
    """The frames as a folder of images without a rate would give them (no timestamps)."""
    return [dataclasses.replace(f, time_s=None, index=i) for i, f in enumerate(frames)]


def sim(scene: str, n: int = 1, start: int = 0) -> list[Frame]:
    return [s.frame for s in simulate(scene, start + n)][start:]


def test_kinship_tells_a_recording_from_unrelated_scenes() -> None:
    a, b = sim("approach", 2)
    assert kinship(a, b).related and kinship(a, b).agree > 0.9
    (table,), (corridor,) = sim("table"), sim("corridor")
    k = kinship(table, corridor)
    assert not k.related and "agree" in k.reason
    small = dataclasses.replace(table, depth=table.depth[:64, :64], valid=table.valid[:64, :64])
    assert not kinship(table, small).related and "sizes differ" in kinship(table, small).reason


def motion_read(results: list) -> list[tuple[int, int]]:
    return [
        (r.frame.index, oid)
        for r in results
        for oid, m in r.motions.items()
        if m.v_radial is not None or m.ttc is not None
    ]


def test_no_motion_between_unrelated_untimed_frames_but_a_recording_is_tracked() -> None:
    mixed = untimed(sim("approach", 3) + sim("table") + sim("corridor") + sim("approach", 2, start=10))
    results = list(Pipeline(Config()).run(mixed))
    assert [bool(r.still) for r in results] == [False, False, False, True, True, True, True]
    assert "nothing in common" in results[3].still and "folder of stills" in results[5].still
    assert all(i < 3 for i, _ in motion_read(results))  # only inside the first run
    assert motion_read(results)  # which was tracked
    # A timed recording with a cut: tracks restart after the cut, not across it.
    timed = sim("approach", 4)
    cut = [*timed[:2], dataclasses.replace(sim("corridor")[0], time_s=timed[2].time_s), *timed[3:]]
    res = list(Pipeline(Config()).run(cut))
    assert [bool(r.still) for r in res] == [False, False, True, True]


def test_stills_setting_turns_tracking_off_and_round_trips(tmp_path: Path) -> None:
    frames = sim("approach", 4)
    assert motion_read(list(Pipeline(Config()).run(frames)))
    assert not motion_read(list(Pipeline(Config().with_stills(True)).run(frames)))
    p = tmp_path / "c.toml"
    Config().with_stills(True).save(p)
    assert Config.load(p).stills is True
    with pytest.raises(InputError, match="stills"):
        Config.from_dict({"stills": "sometimes"})


def test_stills_flag_on_describe(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for flag, moving in (([], True), (["--stills"], False)):
        assert main(["describe", "sim:approach?frames=6", "--quiet", *flag]) == 0
        recs = [json.loads(line) for line in capsys.readouterr().out.splitlines() if line.startswith("{")]
        assert any(o.get("ttc") is not None for r in recs for o in r["objects"]) is moving


@pytest.mark.parametrize("folder", ["nvlabs_ucn_demo_tabletop", "osd_samples_uoais/disparity"])
def test_no_motion_and_no_approach_cue_on_a_folder_of_stills(shared_data: Path, folder: str) -> None:
    results = list(Pipeline(Config()).run(open_source(str(shared_data / folder))))
    assert len(results) >= 5 and all(r.still for r in results[1:])
    assert not motion_read(results)
    m = SoundMapping()
    for r in results:  # every beep at the rate of its depth alone: no approach speed-up
        by_id = {n.id: n for n in r.tree.nodes()}
        for v in voices(r.tree, r.frame.size, m):
            if v.rate:
                assert v.rate == pytest.approx(m.rate(by_id[v.key[1]].depth))


def test_recordings_keep_their_motion(shared_data: Path) -> None:
    src = open_source(str(shared_data / "7scenes_redkitchen_seq" / "depth"), fps=30.0)
    results = [r for _, r in zip(range(20), Pipeline(Config()).run(src), strict=False)]
    assert not any(r.still for r in results) and motion_read(results)
    assert np.isfinite([m.v_radial for r in results for m in r.motions.values() if m.v_radial is not None]).all()


def test_a_fast_turn_of_a_hand_held_camera_is_not_a_cut(shared_data: Path) -> None:
    """7-Scenes read without timestamps: every successive pair is one recording (6 were not)."""
    frames = list(open_source(str(shared_data / "7scenes_redkitchen_seq" / "depth")))
    assert all(f.time_s is None for f in frames)
    kin = [kinship(a, b) for a, b in itertools.pairwise(frames)]
    assert all(k.related for k in kin), [(i, round(k.agree, 2)) for i, k in enumerate(kin) if not k.related]
    assert min(k.agree for k in kin) > 0.8
    turned = [k for k in kin if k.shift != (0.0, 0.0)]  # the pairs that needed the shift
    assert turned and all(abs(k.shift[0]) + abs(k.shift[1]) > 1 for k in turned)


def test_one_unrelated_pair_in_an_untimed_recording_restarts_tracks_but_does_not_end_tracking() -> None:
    frames = sim("approach", 12)
    glitch = untimed([*frames[:5], sim("corridor")[0], *frames[6:]])
    results = list(Pipeline(Config()).run(glitch))
    assert [bool(r.still) for r in results] == [False] * 5 + [True, True] + [False] * 5
    assert "nothing in common" in results[5].still and "folder of stills" not in results[6].still
    assert any(i >= 9 for i, _ in motion_read(results))  # tracked again after the glitch
