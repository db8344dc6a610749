"""The sound of a scene in words: what a listener hears, voice by voice."""

from __future__ import annotations

import math
from collections.abc import Sequence

from depthgram.scene.tree import Node, SceneTree
from depthgram.segmentation.objects import SceneObject
from depthgram.sound.mapping import SoundMapping
from depthgram.sound.synth import select, voices

__all__ = ["hearing", "where"]


def where(pan: tuple[float, float]) -> str:
    """Return the side a listener hears an equal-power pan on: far left .. centre .. far right."""
    p = math.atan2(pan[1], pan[0]) / (math.pi / 2)  # 0 hard left, 0.5 centre, 1 hard right
    for limit, word in ((0.15, "far left"), (0.4, "left"), (0.6, "centre"), (0.85, "right")):
        if p < limit:
            return word
    return "far right"


def hearing(
    tree: SceneTree, frame_size: tuple[int, int], mapping: SoundMapping, objects: Sequence[SceneObject] = ()
) -> list[str]:
    """One line per node of the tree: what it sounds like under the mapping, or why it is silent.

    Beeping objects first (nearest first), then humming surfaces, then the silent ones.

    Parameters
    ----------
    tree : SceneTree
    frame_size : tuple of int
        (width, height) of the frame (px).
    mapping : SoundMapping
    objects : sequence of SceneObject, optional
        The segmented objects, for the extent of surfaces.

    Returns
    -------
    list of str
    """
    by_id: dict[int, Node] = {n.id: n for n in tree.nodes()}
    out: list[str] = []
    for v in voices(tree, frame_size, mapping, objects):
        n = by_id[v.key[1]]
        head = f"o_{n.id} {n.kind} at {n.depth / 1000:.2f} m"
        loud = 20 * math.log10(max(v.gain_a, 1e-9))
        if v.rate > 0:
            fast = ""
            if v.rate > mapping.rate(n.depth) + 1e-9:
                fast = f", sped up from {mapping.rate(n.depth):.1f}/s: approaching, {n.ttc:.1f} s to collision"
            out.append(
                f"{head}: beeps {v.rate:.1f}/s{fast}, {v.freq_a:.0f} Hz, {where(v.pan_a)}, "
                f"{1000 * v.beep_s:.0f} ms, {v.harmonics} harmonic(s), {loud:.0f} dB"
            )
        else:
            side = where(v.pan_a) if where(v.pan_a) == where(v.pan_b) else f"{where(v.pan_a)} to {where(v.pan_b)}"
            out.append(
                f"{head}: hums, gliding {v.freq_a:.0f} -> {v.freq_b:.0f} Hz and back every "
                f"{mapping.glide_period_s:g} s, {side}, {loud:.0f} dB at its near end"
            )
    out.extend(
        f"o_{n.id} {n.kind} at {n.depth / 1000:.2f} m: silent, {why}" for n, why in select(tree, mapping).left_out
    )
    return out
