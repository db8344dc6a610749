"""Real-time pacing of a recording: when the next frame is due, and whether the one in hand is lost.

:class:`Pacer` is the real-time rule of ``depthgram run``, ``depthgram listen`` and the live
viewer: each frame is due one period (or its timestamp's gap) after the one before; a frame whose
slot has passed by more than a period while the consumer was busy is lost, as a live sensor loses
it; an early frame waits for its slot. All therefore drop frames by the same rule, and their drop
counts can be compared.
"""

from __future__ import annotations

import time
from collections.abc import Callable

__all__ = ["Pacer"]


class Pacer:
    """When the next frame is due and whether the frame in hand is already lost.

    Parameters
    ----------
    period_s : float
        Time between frames (s) at the rate being played.
    clock : callable
        Monotonic clock (s).

    Notes
    -----
    The rule: frame ``k`` is due ``k`` periods after the clock started (or at its timestamp's
    offset, with :meth:`advance` given the gap); it is lost when the consumer is ready for it
    more than one period after it was due. A consumer reading from a source slower than real
    time (:meth:`note_read` measures it) never drops: skipping frames cannot catch up when
    reading one costs a period, so playback slows down instead.
    """

    def __init__(self, period_s: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.period = period_s
        self.clock = clock
        self.due = clock()
        self.read_s = 0.0  # running mean time to read one frame (s)
        self._last_s: float | None = None  # the time of the last frame admitted (s)

    def start(self, now: float | None = None) -> None:
        """Start the clock: the next frame is due ``now``."""
        self.due = self.clock() if now is None else now

    def note_read(self, seconds: float) -> None:
        """Record how long reading a frame took (s)."""
        self.read_s = seconds if self.read_s == 0 else 0.9 * self.read_s + 0.1 * seconds

    @property
    def slow_source(self) -> bool:
        """Reading a frame takes at least a period: dropping frames cannot catch up."""
        return self.read_s >= self.period

    def late(self, now: float | None = None) -> bool:
        """Whether the frame due now is lost: its slot passed more than a period ago."""
        now = self.clock() if now is None else now
        return now - self.due > self.period and not self.slow_source

    def wait_s(self, now: float | None = None) -> float:
        """Seconds until the next frame is due (0 when it is due or late)."""
        now = self.clock() if now is None else now
        return max(0.0, self.due - now)

    def advance(self, gap_s: float | None = None, now: float | None = None) -> None:
        """Make the next frame due ``gap_s`` (default: one period) after the last one.

        From a slow source the backlog is forgotten instead: the next frame is due at most
        one period ago, so it is never late.
        """
        self.due += self.period if gap_s is None else gap_s
        if self.slow_source:
            now = self.clock() if now is None else now
            self.due = max(self.due, now - self.period)

    def admit(self, time_s: float, sleep: Callable[[float], None] = time.sleep) -> bool:
        """Take the frame stamped ``time_s`` (s): False when its slot is already lost, else wait for it.

        The frame is due its time's gap after the last one's (:meth:`advance`); a late one is
        lost as a live sensor loses it, an early one waits (``sleep``) until its slot.
        """
        if self._last_s is not None:
            self.advance(time_s - self._last_s)
        self._last_s = time_s
        if self.late():
            return False
        wait = self.wait_s()
        if wait > 0:
            sleep(wait)
        return True
