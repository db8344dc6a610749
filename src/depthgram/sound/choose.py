"""Which objects of a stream sound, and how they stay apart: voices that belong to tracked objects.

On a moving camera the segmentation finds a dozen objects a frame and the tracker's ids come
and go; voicing every frame's nearest few makes a churn of short-lived voices. A
:class:`Chooser` instead gives a voice to a tracked object (its id) once the object has been
seen for ``confirm_frames`` frames in a row, keeps it while the object stays, and fills a free
place by priority: an object with a time to collision under ``ttc_alert`` first (soonest
first), then the nearest, then the largest. An approaching object may take the place of a
voice without one. An object covering ``facing_area`` of the view or more is a surface facing
the camera (a wall ahead): it hums, steady, among the surfaces instead of beeping.

Concurrent voices are kept apart for the ear: any two differ by at least ``min_semitones`` in
pitch, or ``min_pan`` in pan position, or a factor ``min_rate_ratio`` in beep rate. Pitch
(the height cue) moves to the nearest free step of a ``min_semitones`` ladder when a voice
would otherwise be confused with a more important one.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from depthgram.scene.tree import Node, SceneTree
from depthgram.segmentation.objects import SceneObject
from depthgram.sound.mapping import SoundMapping
from depthgram.sound.voice import BEEP_KINDS, OBLIQUE_KINDS, Voice, beep_voice, glide_voice

__all__ = ["MATCH_DEPTH", "MATCH_VIEW", "Chooser", "distinguishable", "pan_position"]

#: A lost object's voice goes on with a new track within this share of the view's width and
#: height of where it was ...
MATCH_VIEW = 0.15
#: ... and this share of its depth.
MATCH_DEPTH = 0.35
#: How many of the tracks voiced last are remembered, so that one coming back is not counted
#: as a new thing (:attr:`Chooser.distinct`).
VOICED_MEMORY = 256


def pan_position(v: Voice) -> float:
    """Pan position of a voice in 0 (hard left) .. 1 (hard right), from its equal-power gains."""
    left, right = v.pan_a
    return math.atan2(right, left) / (math.pi / 2)


def distinguishable(a: Voice, b: Voice, mapping: SoundMapping) -> bool:
    """Whether two voices sounding together differ enough for the ear (the mapping's three rules).

    A beep and a hum always differ (one pulses, one does not); two voices differ when their
    pitches are ``min_semitones`` apart, or their pan positions ``min_pan`` apart, or their
    beep rates a factor ``min_rate_ratio`` apart.
    """
    if (a.rate > 0) != (b.rate > 0):
        return True
    fa, fb = math.sqrt(a.freq_a * a.freq_b), math.sqrt(b.freq_a * b.freq_b)
    if abs(12 * math.log2(fa / fb)) >= mapping.min_semitones - 1e-6:
        return True
    if abs(pan_position(a) - pan_position(b)) >= mapping.min_pan - 1e-9:
        return True
    if a.rate > 0 and b.rate > 0 and max(a.rate, b.rate) / min(a.rate, b.rate) >= mapping.min_rate_ratio - 1e-9:
        return True
    return False


@dataclass
class _Slot:
    track: int  # the tracked object it voices now
    node: Node  # the object as last seen
    missing: int = 0  # frames in a row its object has been missing
    prev_depth: float | None = None  # the object's depth (mm) the frame before
    step: int | None = None  # pitch step last given (index on the ladder)


class Chooser:
    """Chooses a stream's voices frame after frame (see the module's notes).

    A voice has an id of its own (its key is ``("o", voice id)``): when the tracker loses an
    object and finds a new one where it was (within :data:`MATCH_VIEW` of the view and
    :data:`MATCH_DEPTH` of its depth) during the ``hold_frames`` after, the voice goes on with
    the new track instead
    of one voice ending and another starting. Meanwhile it keeps its last parameters.

    Parameters
    ----------
    mapping : SoundMapping
        Its ``max_voices``, ``max_glides``, ``confirm_frames``, ``hold_frames`` and separation
        settings apply.
    """

    def __init__(self, mapping: SoundMapping) -> None:
        self.mapping = mapping
        self._seen: dict[int, int] = {}  # track id -> frames in a row it has been in the scene
        self._slots: dict[int, _Slot] = {}  # voice id -> its slot, in the order the voices entered
        self._next_voice = 1
        self._entered: list[int] = []  # voices that entered with the last frame
        self._frames = 0  # frames chosen so far
        self.distinct = 0  # objects voiced so far, each counted once however often it comes back
        # the tracks voiced most recently (track id -> None, oldest first): a track whose voice
        # ended and comes back is the same thing to the listener, so it is counted once;
        # bounded, so that a live stream's memory stays flat
        self._voiced: OrderedDict[int, None] = OrderedDict()

    def _remember(self, track: int) -> None:
        self._voiced[track] = None
        self._voiced.move_to_end(track)
        if len(self._voiced) > VOICED_MEMORY:
            self._voiced.popitem(last=False)

    def _urgent(self, n: Node) -> bool:
        return n.ttc is not None and 0 < n.ttc < self.mapping.ttc_alert

    def _priority(self, n: Node) -> tuple[float, float, float, int]:
        """Sort key: time to collision when it warns, then depth (mm), then larger area, then id."""
        return (n.ttc if self._urgent(n) and n.ttc is not None else math.inf, n.depth, -n.area, n.id)

    def choose(self, tree: SceneTree, frame_size: tuple[int, int]) -> tuple[list[tuple[int, Node]], list[Node]]:
        """Return the beeping objects as (voice id, node), most important first, and the humming surfaces."""
        m = self.mapping
        w, h = frame_size
        nodes = list(tree.nodes())
        facing = [n for n in nodes if n.kind in BEEP_KINDS and n.area >= m.facing_area * w * h]
        objs = {n.id: n for n in nodes if n.kind in BEEP_KINDS and n.area < m.facing_area * w * h}
        self._seen = {i: self._seen.get(i, 0) + 1 for i in objs}
        taken = {s.track for s in self._slots.values() if s.track in objs}
        for vid, slot in list(self._slots.items()):
            if slot.track in objs:
                slot.prev_depth = slot.node.depth if slot.missing == 0 else None
                slot.node, slot.missing = objs[slot.track], 0
                continue
            # Lost: take up a new track where the object was, else wait, then end.
            near = [
                n
                for i, n in objs.items()
                if i not in taken
                and abs(n.center_xy[0] - slot.node.center_xy[0]) <= MATCH_VIEW * w
                and abs(n.center_xy[1] - slot.node.center_xy[1]) <= MATCH_VIEW * h
                and abs(n.depth - slot.node.depth) <= MATCH_DEPTH * slot.node.depth
            ]
            if near:
                n = min(near, key=lambda n: abs(n.depth - slot.node.depth))
                slot.track, slot.node, slot.missing, slot.prev_depth = n.id, n, 0, None
                taken.add(n.id)
                self._remember(n.id)
                continue
            slot.missing += 1
            if slot.missing > m.hold_frames:
                del self._slots[vid]
        self._entered = []  # voices that enter this frame
        self._frames += 1
        # The first frame of a stream has no history to confirm against: its objects enter at once.
        need = 1 if self._frames == 1 else m.confirm_frames
        ready = sorted(
            (n for i, n in objs.items() if i not in taken and (self._seen[i] >= need or self._urgent(n))),
            key=self._priority,
        )
        for n in ready:
            if len(self._slots) >= m.max_voices:
                if not self._urgent(n):
                    break
                # An approaching object takes the place of the least important voice without a warning.
                calm = [v for v, s in self._slots.items() if not self._urgent(s.node)]
                if not calm:
                    break
                del self._slots[max(calm, key=lambda v: self._priority(self._slots[v].node))]
            self._slots[self._next_voice] = _Slot(n.id, n)
            self._entered.append(self._next_voice)
            self._next_voice += 1
            if n.id not in self._voiced:
                self.distinct += 1
            self._remember(n.id)
        order = list(self._slots)  # the order the voices entered
        beeps = sorted(
            ((v, s.node) for v, s in self._slots.items()), key=lambda t: (not self._urgent(t[1]), order.index(t[0]))
        )
        surfs = sorted((n for n in nodes if n.kind in OBLIQUE_KINDS or n in facing), key=lambda n: (n.depth, n.id))
        return beeps, surfs[: m.max_glides]

    def voices(
        self,
        tree: SceneTree,
        frame_size: tuple[int, int],
        objects: Sequence[SceneObject] = (),
        intrinsics: Any = None,
        gravity: Any = None,
    ) -> dict[tuple[str, int], Voice]:
        """Return this frame's voices by key, chosen and kept apart (see the module's notes).

        Parameters
        ----------
        tree : SceneTree
        frame_size : tuple of int
            (width, height) of the frame (px).
        objects : sequence of SceneObject, optional
            The segmentation's objects, for the extent of surfaces.
        intrinsics : Intrinsics, optional
            For the azimuth of each voice (pan); image columns without them.
        gravity : Gravity, optional
            The frame's: with the intrinsics, pitch follows elevation above the horizon
            rather than the image row, so a tilted camera does not move it.

        Returns
        -------
        dict
            Voice key -> Voice; beeps in order of importance, then glides.
        """
        m = self.mapping
        beeps, glides = self.choose(tree, frame_size)
        by_id: Mapping[int, SceneObject] = {o.id: o for o in objects}
        placed: list[tuple[int, float, float]] = []
        out: dict[tuple[str, int], Voice] = {}
        # Voices entering together first sound in scan order over scan_s (left to right by default).
        new = [(vid, n) for vid, n in beeps if vid in self._entered]
        if m.scan == "left_to_right":
            new.sort(key=lambda t: (t[1].center_xy[0], t[1].id))
        order = {vid: i / max(len(new) - 1, 1) if m.scan != "none" else 0.0 for i, (vid, _) in enumerate(new)}
        for vid, n in beeps:
            slot = self._slots[vid]
            if n.ttc is not None and slot.prev_depth is not None and n.depth > slot.prev_depth + 0.01 * n.depth + 5:
                # It has turned away: the tracker's speed still reads the approach for a frame or
                # two (a slope over several frames), the sound stops warning at once.
                n = replace(n, ttc=None)
            v = beep_voice(n, frame_size, m, intrinsics, order=order.get(vid, 0.0), key=("o", vid), gravity=gravity)
            v = self._apart(slot, v, placed)
            out[v.key] = v
        for n in glides:
            g = glide_voice(n, frame_size, m, by_id, intrinsics, facing=n.kind in BEEP_KINDS, gravity=gravity)
            out[g.key] = g
        return out

    def _apart(self, st: _Slot, v: Voice, placed: list[tuple[int, float, float]]) -> Voice:
        """Return ``v`` on the pitch ladder, at the nearest step no placed voice is confused with.

        ``placed`` holds the (step, pan position, rate) of the voices already placed, and gets
        this one's. Two voices on different steps are at least ``min_semitones`` apart, so a
        step is taken only by a placed voice that is also near in pan and in rate.
        """
        m = self.mapping
        top = max(0, math.floor(12 * math.log2(m.pitch_high_hz / m.pitch_low_hz) / m.min_semitones + 1e-9))
        want = 12 * math.log2(v.freq_a / m.pitch_low_hz) / m.min_semitones
        step = round(want)
        # Hysteresis: a voice keeps its step until its height is a whole step away, so an object
        # near a boundary does not warble between two pitches.
        if st.step is not None and abs(want - st.step) < 1.0:
            step = st.step
        step = min(max(step, 0), top)
        pan = pan_position(v)
        taken = {
            k
            for k, p, r in placed
            if abs(p - pan) < m.min_pan - 1e-9 and max(r, v.rate) < m.min_rate_ratio * min(r, v.rate) - 1e-9
        }
        best = step  # more voices than the ladder can hold apart: keep its own height
        for dist in range(0, top + 1):
            free = [k for k in ((step - dist, step + dist) if dist else (step,)) if 0 <= k <= top and k not in taken]
            if free:
                best = free[0]
                break
        st.step = best
        placed.append((best, pan, v.rate))
        f = m.pitch_low_hz * 2.0 ** (best * m.min_semitones / 12)
        return replace(v, freq_a=f, freq_b=f)
