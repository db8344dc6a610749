"""Reading frames ahead in a thread: order, errors, bounded memory, early stop; the pipeline on top."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

from depthgram.errors import InputError
from depthgram.pipeline import Pipeline
from depthgram.sources import open_source
from depthgram.sources.prefetch import prefetch


def _readers() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "depthgram-prefetch"]


@pytest.mark.parametrize("ahead", [0, 1, 3])
def test_every_item_comes_once_in_order(ahead: int) -> None:
    assert list(prefetch(iter(range(200)), ahead=ahead)) == list(range(200))
    assert list(prefetch([], ahead=ahead)) == []


def test_an_error_while_reading_comes_after_the_items_read_before_it() -> None:
    def broken() -> Iterator[int]:
        yield from range(3)
        raise InputError("rec/frame-3.png: truncated PNG, expected 640 x 480 uint16")

    got = []
    with pytest.raises(InputError, match=r"frame-3\.png: truncated PNG"):
        for item in prefetch(broken(), ahead=2):
            got.append(item)
    assert got == [0, 1, 2]


def test_at_most_ahead_items_wait_so_memory_stays_flat() -> None:
    produced = 0

    def counting() -> Iterator[int]:
        nonlocal produced
        for i in range(1000):
            produced += 1
            yield i

    items = prefetch(counting(), ahead=2)
    assert next(items) == 0
    time.sleep(0.3)  # time for an unbounded reader to run far ahead
    # taken 1, 2 waiting in the queue, 1 in the reader's hand blocked on the full queue
    assert produced <= 1 + 2 + 1
    items.close()


def test_stopping_early_stops_the_reader_and_closes_the_source() -> None:
    closed = threading.Event()

    def source() -> Iterator[int]:
        try:
            yield from range(10_000)
        finally:
            closed.set()

    for i in prefetch(source(), ahead=2):
        if i == 1:
            break
    assert closed.wait(5), "the source was not closed"
    assert not _readers()


def test_ahead_must_not_be_negative() -> None:
    with pytest.raises(ValueError, match="ahead must be >= 0"):
        list(prefetch([1], ahead=-1))


def test_pipeline_run_reading_ahead_gives_the_same_scenes() -> None:
    spec = "sim:approach?frames=6"
    ahead = [r.sentence for r in Pipeline().run(open_source(spec), read_ahead=2)]
    inline = [r.sentence for r in Pipeline().run(open_source(spec), read_ahead=0)]
    assert ahead == inline and len(ahead) == 6
    assert any("v=" in s for s in ahead)  # tracks carried across frames either way


def test_warm_up_leaves_the_pipeline_as_it_was() -> None:
    frames = list(open_source("sim:approach?frames=3"))
    warmed = Pipeline()
    assert warmed.warm_up(frames[0]) > 0
    fresh = Pipeline()
    assert [warmed.process(f).sentence for f in frames] == [fresh.process(f).sentence for f in frames]


def test_a_live_camera_is_never_read_ahead() -> None:
    class Live:
        live = True

        def __init__(self) -> None:
            self.threads: set[str] = set()

        def __iter__(self) -> Iterator[int]:
            for i in range(5):
                self.threads.add(threading.current_thread().name)
                yield i

    cam = Live()
    assert list(prefetch(cam, ahead=2)) == list(range(5))
    assert cam.threads == {threading.current_thread().name}
