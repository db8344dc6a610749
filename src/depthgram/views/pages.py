"""What each open page of the viewer holds: its newest frame, what it missed, its sound.

The :class:`~depthgram.views.player.Player` offers every frame to every page; a page that has not
drawn the last one yet keeps only the newest (the older is counted as dropped for that page).
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from typing import Any

__all__ = ["Delivery", "Page"]


@dataclass(frozen=True)
class Delivery:
    """One frame as the pages get it.

    ``header`` is the JSON header (a dict, for tests and tools) and ``head`` the same serialised
    without its closing brace, so that each page's own counts are appended without serialising
    the record, tree and plan once per page; ``body`` is :func:`~depthgram.views.wire.pack_body`'s.
    """

    header: dict[str, Any]
    head: str
    body: bytes


class Page:
    """One open page: its newest undelivered frame, what it missed, whether it wants sound.

    Used on the event loop's thread only. A page with sound on has a live renderer of its own
    (:class:`~depthgram.sound.live.LiveSonifier`): each frame swaps its voices' targets, and the
    page pulls blocks from it as its audio clock consumes them (:attr:`audio_need`).
    """

    def __init__(self) -> None:
        self.slot: Delivery | None = None
        self.ready = asyncio.Event()  # set when the page may receive the next frame
        self.ready.set()
        self.wake = asyncio.Event()  # set when the slot is filled, the ack or an audio request arrives
        self.dropped = 0
        self.sound = False
        self.live: Any = None  # the page's LiveSonifier, made when it first turns sound on
        self.audio_need = 0  # samples the page asked for and has not been sent yet
        self.audio_sent = 0  # samples sent so far
        self.heard = -1  # the newest frame whose voices a sent block carries
        self.notices: list[dict[str, Any]] = []  # sent after the newest frame, never dropped

    def offer(self, delivery: Delivery, targets: dict[Any, Any] | None) -> None:
        """Put the newest frame in the page's slot (dropping one not taken yet) and swap its voices.

        ``targets``: the frame's voices (``{}`` silences them), or None to leave them as they are.
        The voices change now, not when the page draws the frame: the sound never waits for
        the picture.
        """
        if self.slot is not None:
            self.dropped += 1  # the page is behind: the older frame is never sent
        self.slot = delivery
        if targets is not None and self.live is not None and self.sound:
            self.live.set_targets(targets, frame=delivery.header["index"])
        self.wake.set()

    def silence(self) -> None:
        """Fade the page's voices out (a pause, the end): its blocks go on, silent."""
        if self.live is not None:
            self.live.clear()

    def notify(self, message: dict[str, Any]) -> None:
        """Queue a notice for the page; notices are never dropped."""
        self.notices.append(message)
        self.wake.set()
