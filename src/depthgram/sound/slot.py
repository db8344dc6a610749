"""The newest voice targets handed from the pipeline's process to the audio process.

One slot in shared memory, no queue and no lock: a frame the audio side has not taken yet is
simply replaced by the next one, so a slow pipeline can never make the sound late.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError
from depthgram.sound.synth import Voice

#: Voice key kinds, by their index in a :class:`TargetSlot`.
_KINDS = ("o", "g")
#: Numbers per voice in a :class:`TargetSlot`: kind, id, then the Voice's fields in order.
_PER_VOICE = 16
#: Numbers before the voices: sequence, frame, arrival (s), sent (s), voice count, checksum.
_HEAD = 6

__all__ = ["TargetSlot", "Update"]


@dataclass(frozen=True)
class Update:
    """New voice targets for a frame, as the audio side receives them."""

    targets: dict[tuple[str, int], Voice]
    frame: int
    arrival_s: float | None
    sent_s: float | None = None  # when the targets left the pipeline (s, perf_counter)


class TargetSlot:
    """The newest voice targets in memory shared by two processes: one slot, no queue, no lock.

    The pipeline's process writes each frame's voices with :meth:`put`; the audio callback reads
    the newest with :meth:`take` at the start of every block. A write replaces the slot whatever
    the reader did (a frame not yet heard is superseded, never queued), and the reader never
    waits for the writer (a sequence lock: the reader keeps the old targets when it catches a
    write half done and looks again at the next block). Nothing crosses a pipe and no thread of
    the audio process has to wake up to relay the targets.

    Parameters
    ----------
    shared : ctypes array of c_double
        The slot's memory, from :meth:`create` (``multiprocessing`` ``RawArray``): handed to the
        audio process as an argument of its ``Process``.

    Notes
    -----
    Layout (float64): sequence (odd while a write is under way), frame, arrival (s), sent (s),
    voice count, checksum, then :data:`_PER_VOICE` numbers per voice, then the sequence again.
    The reader accepts a copy whose two sequence numbers match, are even, still match the slot
    after the copy, and whose checksum holds.
    """

    def __init__(self, shared: Any) -> None:
        self._shared = shared  # kept alive with the view
        self._a = np.frombuffer(shared, dtype=np.float64)
        self.capacity = (len(self._a) - _HEAD - 1) // _PER_VOICE
        if self.capacity < 1 or len(self._a) != _HEAD + self.capacity * _PER_VOICE + 1:
            raise InputError(f"TargetSlot: the shared array has {len(self._a)} numbers, not a slot's layout")
        self._seen = float(self._a[0])  # the sequence number last taken
        self.taken = 0  # writes read by take()
        self.superseded = 0  # writes replaced by a newer one before take() saw them
        self.retries = 0  # reads that caught a write half done

    @classmethod
    def create(cls, ctx: Any, capacity: int) -> TargetSlot:
        """Return a new empty slot for ``capacity`` voices in memory made by ``ctx`` (a multiprocessing context)."""
        if capacity < 1:
            raise InputError(f"TargetSlot capacity must be >= 1 voice, got {capacity}")
        return cls(ctx.RawArray("d", _HEAD + capacity * _PER_VOICE + 1))

    @property
    def shared(self) -> Any:
        """The shared memory, for the other process."""
        return self._shared

    def put(self, targets: dict[tuple[str, int], Voice], frame: int, arrival_s: float | None, sent_s: float) -> None:
        """Write the voices of one frame (replacing what is there), with its index and times (s)."""
        if len(targets) > self.capacity:
            raise InputError(f"TargetSlot: {len(targets)} voices, the slot holds at most {self.capacity}")
        rows = np.empty((len(targets), _PER_VOICE))
        for row, (key, v) in zip(rows, targets.items(), strict=True):
            if key[0] not in _KINDS:
                raise InputError(f"TargetSlot: voice key kind must be one of {_KINDS}, got {key!r}")
            row[:] = (
                _KINDS.index(key[0]),
                key[1],
                v.freq_a,
                v.freq_b,
                v.gain_a,
                v.gain_b,
                v.pan_a[0],
                v.pan_a[1],
                v.pan_b[0],
                v.pan_b[1],
                v.rate,
                v.beep_s,
                v.harmonics,
                v.order,
                math.nan if v.azimuth is None else v.azimuth,
                math.nan if v.elevation is None else v.elevation,
            )
        a = self._a
        seq = a[0] + 1.0  # odd: a write is under way
        a[0] = seq
        end = _HEAD + rows.size
        a[_HEAD:end] = rows.ravel()
        a[1:5] = (frame, math.nan if arrival_s is None else arrival_s, sent_s, len(targets))
        a[5] = _checksum(a[1:5], a[_HEAD:end])
        a[-1] = seq + 1.0
        a[0] = seq + 1.0

    def take(self) -> Update | None:
        """Return the newest write not yet taken (None when there is none, or it is being written)."""
        a = self._a
        seq = float(a[0])
        if seq == self._seen or seq % 2:
            return None
        snap = a.copy()
        if snap[0] != seq or snap[-1] != seq or a[0] != seq:
            self.retries += 1
            return None
        n = int(snap[4])
        body = snap[_HEAD : _HEAD + n * _PER_VOICE]
        if not 0 <= n <= self.capacity or _checksum(snap[1:5], body) != snap[5]:
            self.retries += 1
            return None
        self.superseded += max(0, int((seq - self._seen) // 2) - 1)
        self._seen = seq
        self.taken += 1
        targets = {}
        for r in body.reshape(n, _PER_VOICE).tolist():
            key = (_KINDS[int(r[0])], int(r[1]))
            az, el = (None if math.isnan(x) else x for x in (r[14], r[15]))
            targets[key] = Voice(
                key, r[2], r[3], r[4], r[5], (r[6], r[7]), (r[8], r[9]), r[10], r[11], int(r[12]), r[13], az, el
            )
        arrival = None if math.isnan(snap[2]) else float(snap[2])
        return Update(targets, int(snap[1]), arrival, float(snap[3]))


def _checksum(head: NDArray[np.float64], body: NDArray[np.float64]) -> float:
    # NaN-safe (a missing arrival is NaN) and the same bits for the same numbers in both processes.
    return float(np.nansum(head) + np.nansum(body))
