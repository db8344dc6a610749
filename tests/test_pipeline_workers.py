"""Segmenting in worker processes (``Pipeline.run(workers=N)``, ``--workers``): same results, in order."""

from __future__ import annotations

import dataclasses
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


def test_image_motion_prepared_beside_the_segmentation_reads_the_same_motions() -> None:
    """Tracker.prepare (run by the pipeline in a thread) changes where the work is done, not its result."""
    import dataclasses

    from depthgram.dynamics import FramePixels, Tracker, TrackerConfig
    from depthgram.segmentation import segment

    frames = _frames("approach", 10)
    segs = [segment(f.depth, valid=f.valid, intrinsics=f.intrinsics) for f in frames]
    readings = []
    for prepare in (False, True):
        tracker = Tracker(TrackerConfig(fps=30.0))
        out = []
        for f, seg in zip(frames, segs, strict=True):
            if prepare:
                tracker.prepare(f.depth, f.intrinsics)
            upd = tracker.update(seg.objects, None, f.size, FramePixels(f.depth, seg.labels, f.intrinsics))
            out.append({k: dataclasses.astuple(m) for k, m in upd.motions.items()})
        readings.append(out)
    assert readings[0] == readings[1]
    assert any(m[1] is not None for frame in readings[1] for m in frame.values())  # velocities were read
    # a prepared motion for another depth array is not used for this one
    tracker = Tracker(TrackerConfig(fps=30.0))
    tracker.prepare(frames[1].depth, frames[1].intrinsics)
    upd = tracker.update(segs[0].objects, None, frames[0].size, FramePixels(frames[0].depth, segs[0].labels))
    assert upd.motions  # ran on its own


def test_the_pipeline_reads_the_same_motions_with_and_without_the_motion_thread() -> None:
    frames = _frames("approach", 10)
    threaded = list(Pipeline(Config()).run(frames))
    pipe = Pipeline(Config())
    pipe._prepare_motion = lambda frame: None  # type: ignore[method-assign]
    inline = list(pipe.run(frames))
    assert [r.motions for r in threaded] == [r.motions for r in inline]
    assert [r.sentence for r in threaded] == [r.sentence for r in inline]


def test_a_recording_described_beside_the_next_segmentation_gives_the_results_of_process() -> None:
    # run() of frames read ahead describes frame t on the thread beside while frame t + 1 is
    # segmented; process() does one frame after the other
    frames = _frames("crossing", 24)
    pipe = Pipeline(Config())
    stepped = [pipe.process(f) for f in frames]
    overlapped = list(Pipeline(Config()).run(frames))
    assert [r.frame.index for r in overlapped] == [f.index for f in frames]
    for a, b in zip(stepped, overlapped, strict=True):
        assert a.sentence == b.sentence
        assert a.motions == b.motions
        assert a.plan == b.plan
        assert np.array_equal(a.segmentation.labels, b.segmentation.labels)
    assert sum(m.v_radial is not None for r in overlapped for m in r.motions.values()) > 20


def test_stopping_a_described_recording_early_leaves_the_tracker_usable() -> None:
    frames = _frames("approach", 12)
    pipe = Pipeline(Config())
    run = pipe.run(frames)
    first = [next(run) for _ in range(5)]
    run.close()  # the description of frame 5, in flight, finishes before close returns
    later = [pipe.process(f) for f in frames[6:]]
    again = list(Pipeline(Config()).run(frames))
    assert [r.sentence for r in first] == [r.sentence for r in again[:5]]
    assert later and all(r.motions for r in later)


def test_a_live_source_gets_each_result_before_its_next_frame_is_read() -> None:
    frames = _frames("approach", 6)
    taken: list[int] = []

    class Live:
        live = True

        def __iter__(self):  # type: ignore[no-untyped-def]
            for f in frames:
                taken.append(f.index)
                yield f

    for r in Pipeline(Config()).run(Live()):
        assert taken[-1] == r.frame.index  # no frame was taken before this result came


def test_a_recording_that_fails_midway_still_gives_every_frame_before_the_failure() -> None:
    frames = _frames("approach", 8)

    def broken():  # type: ignore[no-untyped-def]
        yield from frames[:5]
        raise OSError("frame 5: truncated file")

    got = []
    with pytest.raises(OSError, match="frame 5"):
        for r in Pipeline(Config()).run(broken()):
            got.append(r.frame.index)
    assert got == [0, 1, 2, 3, 4]
    # a frame the segmentation refuses: the frames before it come first, then its error
    bad = [*frames[:3], dataclasses.replace(frames[3], depth=np.zeros((2, 2, 2), np.float32))]
    got = []
    with pytest.raises(Exception, match="2-D"):
        for r in Pipeline(Config()).run(bad):
            got.append(r.frame.index)
    assert got == [0, 1, 2]
