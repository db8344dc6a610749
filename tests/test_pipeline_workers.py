"""Segmenting in worker processes (``Pipeline.run(workers=N)``, ``--workers``): same results, in order."""

from __future__ import annotations

import json

import numpy as np
import pytest

from depthgram.cli import main
from depthgram.pipeline import Config, Pipeline
from depthgram.sensor.simulate import simulate


def _frames(scene: str, n: int) -> list:
    return [s.frame for s in simulate(scene, n)]


def test_workers_give_the_same_results_in_frame_order() -> None:
    frames = _frames("crossing", 24)
    one = list(Pipeline(Config()).run(frames, workers=1))
    two = list(Pipeline(Config()).run(frames, workers=2))
    assert [r.frame.index for r in two] == [f.index for f in frames]
    for a, b in zip(one, two, strict=True):
        assert a.sentence == b.sentence
        assert np.array_equal(a.segmentation.labels, b.segmentation.labels)
        assert a.motions == b.motions
    # the tracks were read: the comparison covers velocities, not only still scenes
    assert sum(m.v_radial is not None for r in two for m in r.motions.values()) > 20


def test_stopping_early_leaves_no_worker_behind() -> None:
    import multiprocessing

    run = Pipeline(Config()).run(_frames("approach", 12), workers=2)
    first = next(run)
    run.close()
    assert first.frame.index == 0
    assert not [p for p in multiprocessing.active_children() if "Process" in type(p).__name__ and p.is_alive()]


def test_workers_must_be_at_least_one() -> None:
    with pytest.raises(Exception, match="workers must be >= 1"):
        next(Pipeline(Config()).run(_frames("approach", 2), workers=0))


def test_describe_with_workers_prints_the_same_lines(capsys: pytest.CaptureFixture[str]) -> None:
    lines = {}
    for n in ("1", "2"):
        assert main(["describe", "sim:approach?frames=8", "--quiet", "--workers", n]) == 0
        lines[n] = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.startswith("{")]
    assert lines["1"] == lines["2"] and len(lines["1"]) == 8
    with pytest.raises(SystemExit):
        main(["describe", "sim:approach?frames=2", "--workers", "0"])
    assert "at least 1" in capsys.readouterr().err
