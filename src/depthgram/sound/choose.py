"""Which objects of a stream sound, and how they stay apart: voices that belong to tracked objects.

On a moving camera the segmentation finds a dozen objects a frame and the tracker's ids come
and go; voicing every frame's nearest few makes a churn of short-lived voices. A
:class:`Chooser` instead gives a voice to a tracked object (its id) once the object has been
seen for ``confirm_frames`` frames in a row, keeps it while the object stays, and fills a free
place by priority: an object with a time to collision under ``ttc_alert`` first (soonest
first), then the nearest, then the largest. An approaching object may take the place of a
voice without one.

Concurrent voices are kept apart for the ear: any two differ by at least ``min_semitones`` in
pitch, or ``min_pan`` in pan position, or a factor ``min_rate_ratio`` in beep rate. Pitch
(the height cue) moves to the nearest free step of a ``min_semitones`` ladder when a voice
would otherwise be confused with a more important one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from depthgram.scene.tree import Node, SceneTree
from depthgram.segmentation.objects import SceneObject
from depthgram.sound.mapping import SoundMapping
from depthgram.sound.synth import BEEP_KINDS, OBLIQUE_KINDS, Voice, glide_voice

__all__ = ["Chooser", "distinguishable", "pan_position"]


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
class _Track:
    seen: int = 0  # frames in a row the object has been in the scene
    step: int | None = None  # pitch step last given (index on the ladder)


class Chooser:
    """Chooses a stream's voices frame after frame (see the module's notes).

    Parameters
    ----------
    mapping : SoundMapping
        Its ``max_voices``, ``max_glides``, ``confirm_frames`` and separation settings apply.
    """

    def __init__(self, mapping: SoundMapping) -> None:
        self.mapping = mapping
        self._tracks: dict[int, _Track] = {}
        self._held: list[int] = []  # ids with a beeping voice, in the order they entered
        self.distinct: set[int] = set()  # every id that has had a beeping voice

    def choose(self, tree: SceneTree) -> tuple[list[Node], list[Node]]:
        """Return the beeping objects (held ones first, then newcomers by priority) and humming surfaces."""
        m = self.mapping
        nodes = list(tree.nodes())
        objs = {n.id: n for n in nodes if n.kind in BEEP_KINDS}
        for i in list(self._tracks):
            if i not in objs:
                del self._tracks[i]
        for i in objs:
            self._tracks.setdefault(i, _Track()).seen += 1
        held = [i for i in self._held if i in objs]

        def urgent(n: Node) -> bool:
            return n.ttc is not None and 0 < n.ttc < m.ttc_alert

        def priority(n: Node) -> tuple[float, float, float, int]:
            return (n.ttc if urgent(n) and n.ttc is not None else math.inf, n.depth, -n.area, n.id)

        ready = sorted(
            (n for i, n in objs.items() if i not in held and (self._tracks[i].seen >= m.confirm_frames or urgent(n))),
            key=priority,
        )
        for n in ready:
            if len(held) < m.max_voices:
                held.append(n.id)
                continue
            if not urgent(n):
                break
            # An approaching object takes the place of the least important voice without a warning.
            calm = [i for i in held if not urgent(objs[i])]
            if not calm:
                break
            worst = max(calm, key=lambda i: priority(objs[i]))
            held[held.index(worst)] = n.id
        self._held = held
        self.distinct.update(held)
        surfs = sorted((n for n in nodes if n.kind in OBLIQUE_KINDS), key=lambda n: (n.depth, n.id))
        return [objs[i] for i in held], surfs[: m.max_glides]

    def voices(
        self,
        tree: SceneTree,
        frame_size: tuple[int, int],
        objects: Sequence[SceneObject] = (),
        intrinsics: Any = None,
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

        Returns
        -------
        dict
            Voice key -> Voice; beeps in order of importance, then glides.
        """
        from depthgram.sound.synth import beep_voice

        m = self.mapping
        beeps, glides = self.choose(tree)
        by_id: Mapping[int, SceneObject] = {o.id: o for o in objects}
        placed: list[Voice] = []
        out: dict[tuple[str, int], Voice] = {}
        urgent_first = sorted(
            beeps, key=lambda n: (not (n.ttc is not None and 0 < n.ttc < m.ttc_alert), self._held.index(n.id))
        )
        for n in urgent_first:
            v = beep_voice(n, frame_size, m, intrinsics)
            v = self._apart(n.id, v, placed)
            placed.append(v)
            out[v.key] = v
        for n in glides:
            g = glide_voice(n, frame_size, m, by_id, intrinsics)
            out[g.key] = g
        return out

    def _apart(self, track: int, v: Voice, placed: Sequence[Voice]) -> Voice:
        """``v`` on the pitch ladder, moved to the nearest step no placed voice is confused with."""
        m = self.mapping
        st = self._tracks.setdefault(track, _Track())
        ladder = 12 * math.log2(m.pitch_high_hz / m.pitch_low_hz) / m.min_semitones
        top = max(0, math.floor(ladder + 1e-9))
        want = 12 * math.log2(v.freq_a / m.pitch_low_hz) / m.min_semitones
        step = round(want)
        # Hysteresis: a voice keeps its step until its height is half a step beyond it, so an
        # object near a boundary does not warble between two pitches.
        if st.step is not None and abs(want - st.step) < 1.0:
            step = st.step
        step = min(max(step, 0), top)

        def at(k: int) -> Voice:
            f = m.pitch_low_hz * 2.0 ** (k * m.min_semitones / 12)
            return replace(v, freq_a=f, freq_b=f)

        for dist in range(0, 2 * top + 2):
            for k in (step - dist, step + dist) if dist else (step,):
                if 0 <= k <= top and all(distinguishable(at(k), p, m) for p in placed):
                    st.step = k
                    return at(k)
        st.step = step  # more voices than the ladder can hold apart: keep its own height
        return at(step)
