"""Read frames ahead in a background thread, as a live sensor delivers them while we work.

Decoding a recorded frame (a PNG, a ROS message) is work a live camera does not ask of its
consumer. Reading it on the consumer's thread makes a recording look slower than the sensor
it came from; reading it in a thread beside the pipeline overlaps the two (the decoders of
OpenCV and numpy release the GIL). At most ``ahead`` frames wait in the queue, so memory stays
flat however long the recording.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")

_END = object()


def prefetch(items: Iterable[T], ahead: int = 2) -> Iterator[T]:
    """Yield ``items`` in order, read up to ``ahead`` items in advance in a background thread.

    Parameters
    ----------
    items : iterable
        Frames (or anything else) to read; iterated in the background thread only.
    ahead : int
        How many items may wait read but not yet taken. 0 reads on the caller's thread, as
        does a live source (``items.live`` true, e.g. a RealSense camera).

    Yields
    ------
    The items of ``items``, in order. An error raised while reading is raised here, after
    the items read before it. Closing the generator early (``break``) stops the reader and
    closes ``items``.
    """
    if ahead < 0:
        raise ValueError(f"ahead must be >= 0, got {ahead}")
    if ahead == 0 or getattr(items, "live", False):
        # a live camera is read when asked: a queued frame would be stale when processed
        yield from items
        return
    box: queue.Queue[tuple[object, BaseException | None]] = queue.Queue(maxsize=ahead)
    stop = threading.Event()

    def put(entry: tuple[object, BaseException | None]) -> bool:
        # a bounded wait, so that the reader notices a consumer that has gone
        while not stop.is_set():
            try:
                box.put(entry, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def read() -> None:
        it = iter(items)
        try:
            for item in it:
                if not put((item, None)):
                    return
            put((_END, None))
        except BaseException as exc:  # handed to the consumer, who raises it in order
            put((_END, exc))
        finally:
            close = getattr(it, "close", None)
            if close is not None:
                close()

    reader = threading.Thread(target=read, name="depthgram-prefetch", daemon=True)
    reader.start()
    try:
        while True:
            item, exc = box.get()
            if exc is not None:
                raise exc
            if item is _END:
                return
            yield item  # type: ignore[misc]
    finally:
        stop.set()
        reader.join()
