"""Stereo synthesis of a scene tree: one voice per salient object, gliding tones for surfaces.

Each object is a train of short raised-cosine beeps: pan from its column (equal power), pitch
from its row, loudness and beep rate from its nearness (faster still when its time to
collision is short), timbre and beep length from its area. Oblique surfaces (walls, floor,
ceiling, compound objects) are a continuous tone gliding between their near and far ends
(paper, section 4: "a continuously variable sound to represent the angle of its surface").

A :class:`Sonifier` keeps every voice's oscillator and pulse phase between frames, and moves
its parameters to a new frame's values over a short ramp, so that a stream has no clicks and
lasts exactly as long as the frames it was pushed.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError
from depthgram.scene.tree import Node, SceneTree
from depthgram.segmentation.objects import SceneObject
from depthgram.sound.binaural import HRIRSet
from depthgram.sound.choose import Chooser
from depthgram.sound.mapping import SoundMapping
from depthgram.sound.voice import BEEP_KINDS, OBLIQUE_KINDS, Voice, beep_voice, glide_voice

__all__ = [
    "BEEP_KINDS",
    "OBLIQUE_KINDS",
    "Selection",
    "Sonifier",
    "Voice",
    "beep_voice",
    "glide_voice",
    "render_scene",
    "select",
    "still_seconds",
    "voices",
]


_TABLE = 4096  # wavetable length (power of two: the index wraps with a mask)
_HANN = 1024  # beep envelope table length
_KNEE = 0.8  # the soft limiter is the identity below this level


@dataclass(frozen=True)
class Selection:
    """Which nodes of a tree sound under a mapping, and why the others do not.

    Attributes
    ----------
    beeps : tuple of Node
        Objects heard as beeps, nearest first (at most ``max_voices``).
    glides : tuple of Node
        Oblique surfaces heard as a gliding tone, nearest first (at most ``max_glides``).
    left_out : tuple of (Node, str)
        Every other node with the reason it is silent, nearest first.
    """

    beeps: tuple[Node, ...]
    glides: tuple[Node, ...]
    left_out: tuple[tuple[Node, str], ...]

    def describe_left_out(self) -> list[str]:
        """One line per silent node: ``o_3 (object, 2.10 m): ...``."""
        return [f"o_{n.id} ({n.kind}, {n.depth / 1000:.2f} m): {why}" for n, why in self.left_out]


def select(tree: SceneTree, mapping: SoundMapping, frame_size: tuple[int, int] | None = None) -> Selection:
    """Return the nodes a scene voices: the nearest ``max_voices`` objects and ``max_glides`` surfaces.

    Every node of the tree counts on its own, whatever its parent: an object standing on a
    table or inside a compound support is voiced like one standing on the floor. (A compound's
    ``parts`` are depth labels of its slices, not node ids, so they never name other nodes.)

    An object covering ``facing_area`` of the view or more (a wall ahead) hums among the
    surfaces.

    Parameters
    ----------
    tree : SceneTree
    mapping : SoundMapping
    frame_size : tuple of int, optional
        (width, height) of the frame (px); the tree's own when omitted.

    Returns
    -------
    Selection
    """
    nodes = sorted(tree.nodes(), key=lambda n: (n.depth, n.id))
    size = frame_size or tree.frame_size
    big = mapping.facing_area * size[0] * size[1] if size else math.inf
    objs = [n for n in nodes if n.kind in BEEP_KINDS and n.area < big]
    surfs = [n for n in nodes if n.kind in OBLIQUE_KINDS or (n.kind in BEEP_KINDS and n.area >= big)]
    left: list[tuple[Node, str]] = []
    for n in nodes:
        if n.kind not in BEEP_KINDS and n.kind not in OBLIQUE_KINDS:
            left.append((n, f"no voice rule for kind {n.kind!r}"))
    for group, cap, what, setting in (
        (objs, mapping.max_voices, "objects", "max_voices"),
        (surfs, mapping.max_glides, "surfaces", "max_glides"),
    ):
        for n in group[cap:]:
            left.append((n, f"{cap} nearer {what} already sound ({setting} = {cap})"))
    left.sort(key=lambda t: (t[0].depth, t[0].id))
    return Selection(tuple(objs[: mapping.max_voices]), tuple(surfs[: mapping.max_glides]), tuple(left))


def voices(
    tree: SceneTree,
    frame_size: tuple[int, int],
    mapping: SoundMapping,
    objects: Sequence[SceneObject] = (),
) -> list[Voice]:
    """Return the voices a scene makes under a mapping: the nearest objects and surfaces only.

    Parameters
    ----------
    tree : SceneTree
    frame_size : tuple of int
        (width, height) of the frame (px).
    mapping : SoundMapping
    objects : sequence of SceneObject, optional
        The segmentation's objects (ids as in the tree). A surface's glide runs between its
        nearest and farthest slice (``parts``) when they are given, else over an assumed extent.

    Returns
    -------
    list of Voice
        Beeping objects first (nearest first), then glides; :func:`select` says which nodes
        were left out and why.
    """
    sel = select(tree, mapping, frame_size)
    by_id = {o.id: o for o in objects}
    if mapping.scan == "left_to_right":
        ranked = sorted(sel.beeps, key=lambda n: (n.center_xy[0], n.id))
    else:
        ranked = list(sel.beeps)  # already nearest first; "none" ignores the order
    rank = {n.id: i / max(len(ranked) - 1, 1) for i, n in enumerate(ranked)}
    out = [beep_voice(n, frame_size, mapping, order=rank[n.id] if mapping.scan != "none" else 0.0) for n in sel.beeps]
    out += [glide_voice(n, frame_size, mapping, by_id, facing=n.kind in BEEP_KINDS) for n in sel.glides]
    return out


def still_seconds(voices_: Sequence[Voice], mapping: SoundMapping, *, beeps: int = 2) -> float:
    """Length (s) of a still's sound in which every voice is heard at least ``beeps`` times.

    A beeping voice first sounds at ``order * scan_s`` and then every ``1 / rate`` s; a glide
    needs one ``glide_period_s`` to run near -> far -> near. The result adds one beep period
    of the slowest voice as a margin (so the last beep is whole, before the final fade),
    is at least 1 s and is rounded up to 0.1 s.

    Parameters
    ----------
    voices_ : sequence of Voice
    mapping : SoundMapping
    beeps : int
        Times each object is heard.

    Returns
    -------
    float
    """
    need = 1.0
    for v in voices_:
        if v.rate > 0:
            need = max(need, v.order * mapping.scan_s + beeps / v.rate + v.beep_s + mapping.ramp_s)
        else:
            need = max(need, beeps * mapping.glide_period_s)
    return math.ceil(need * 10 - 1e-9) / 10


@dataclass
class _State:
    voice: Voice  # the parameters at the start of the current ramp
    target: Voice  # the parameters the ramp moves to
    done: int = 0  # samples of the ramp already played (a ramp may span several audio blocks)
    osc: float = 0.0  # oscillator phase (cycles)
    pulse: float = 0.0  # pulse or glide phase (cycles); negative: waiting for its first beep
    fading: bool = False
    hrir: int = -1  # binaural: the direction (index in the HRIR set) the voice is heard from; -1 none yet


def _lerp_voice(a: Voice, b: Voice, t: float) -> Voice:
    """Return the voice a share ``t`` (0..1) of the way from ``a`` to ``b`` (where a cut ramp stands)."""

    def mix(x: float, y: float) -> float:
        return x + (y - x) * t

    return replace(
        b,
        freq_a=mix(a.freq_a, b.freq_a),
        freq_b=mix(a.freq_b, b.freq_b),
        gain_a=mix(a.gain_a, b.gain_a),
        gain_b=mix(a.gain_b, b.gain_b),
        pan_a=(mix(a.pan_a[0], b.pan_a[0]), mix(a.pan_a[1], b.pan_a[1])),
        pan_b=(mix(a.pan_b[0], b.pan_b[0]), mix(a.pan_b[1], b.pan_b[1])),
        rate=mix(a.rate, b.rate),
        beep_s=mix(a.beep_s, b.beep_s),
        harmonics=b.harmonics if t >= 0.5 else a.harmonics,
    )


@functools.lru_cache(maxsize=16)
def _wavetables(harmonics_max: int) -> tuple[NDArray[np.float64], ...]:
    """One period with 1..k harmonics of amplitude 1/k, each normalised to peak 1 (index 0: silence)."""
    t = np.arange(_TABLE) / _TABLE
    tables = [np.zeros(_TABLE)]
    acc = np.zeros(_TABLE)
    for k in range(1, harmonics_max + 1):
        acc = acc + np.sin(2 * np.pi * k * t) / k
        tables.append(acc / np.abs(acc).max())
    for tab in tables:
        tab.flags.writeable = False  # shared between sonifiers: constants
    return tuple(tables)


@functools.lru_cache(maxsize=1)
def _hann_table() -> NDArray[np.float64]:
    """Raised-cosine beep envelope over one beep; the extra last entry (0) means "after the beep"."""
    x = np.arange(_HANN + 1) / _HANN
    h = 0.5 - 0.5 * np.cos(2 * np.pi * x)
    h[-1] = 0.0
    h.flags.writeable = False
    return h


def _soft_limit(x: NDArray[np.float64]) -> NDArray[np.float64]:
    # Identity below the knee so that quiet scenes keep their exact levels; above it a tanh
    # curve with matching slope: never clips, never jumps.
    a = np.abs(x)
    if a.size == 0 or a.max() <= _KNEE:
        return x
    over = _KNEE + (1 - _KNEE) * np.tanh((a - _KNEE) / (1 - _KNEE))
    return np.where(a <= _KNEE, x, np.sign(x) * over)


class VoiceBank:
    """The voices sounding now, each with its phases and its ramp toward the latest targets.

    Shared by :class:`Sonifier` (one call per frame) and :class:`depthgram.sound.live.LiveSonifier`
    (one call per audio block, many per frame): a ramp longer than a call goes on in the next.
    """

    def __init__(self, mapping: SoundMapping, samplerate: int, hrirs: HRIRSet | None = None) -> None:
        if hrirs is not None and hrirs.samplerate != samplerate:
            raise InputError(
                f"VoiceBank: the HRIRs are at {hrirs.samplerate} Hz, the sound at {samplerate} Hz; "
                "resample them with HRIRSet.at_rate"
            )
        self.mapping = mapping
        self.samplerate = samplerate
        self.hrirs = hrirs
        self._spectra: dict[tuple[int, int], NDArray[np.complex128]] = {}  # (direction, fft size) -> (2, bins)
        self._tail: NDArray[np.float64] | None = None  # binaural: the filters' overlap into the next call
        self.states: dict[tuple[str, int], _State] = {}
        self._tables = _wavetables(mapping.harmonics_max)
        self._hann = _hann_table()
        from depthgram.sound._kernels import glide_voice, pulse_voice  # numba: loaded only when sound is made

        self._pulse_voice = pulse_voice
        self._glide_voice = glide_voice

    def warm_up(self) -> None:
        """Compile the kernels now (a beep and a glide, rendered and thrown away), not in a live callback."""
        probe = VoiceBank(self.mapping, self.samplerate, self.hrirs)
        beep = Voice(("o", 0), 440.0, 440.0, 0.5, 0.5, (0.7, 0.7), (0.7, 0.7), 4.0, 0.05, 2, 0.0)
        glide = replace(beep, key=("g", 0), freq_b=330.0, rate=0.0, beep_s=0.0, harmonics=1)
        probe.render({beep.key: beep, glide.key: glide}, 64)

    def render(self, targets: Mapping[tuple[str, int], Voice], n: int) -> NDArray[np.float64]:
        """Return ``n`` stereo samples (float64, limited to -1..1) moving every voice toward ``targets``.

        A voice missing from ``targets`` fades out over the ramp and is then dropped; a new one
        starts from silence.
        """
        sr = self.samplerate
        m = self.mapping
        r = max(1, round(m.ramp_s * sr))
        out_l = np.zeros(n)
        out_r = np.zeros(n)
        scratch = np.zeros(n)  # the unused second channel of a mono voice (binaural)
        spatial: list[tuple[NDArray[np.float64], int]] = []  # binaural: (mono input, direction) to filter
        goal = dict(targets)
        for key, st in self.states.items():
            if key not in goal:  # gone from the scene: fade out over the ramp, then drop
                if not st.fading:
                    st.fading = True
                    goal[key] = replace(st.target, gain_a=0.0, gain_b=0.0)
                else:
                    goal[key] = st.target
            else:
                st.fading = False
        for key, new in goal.items():
            if key not in self.states:
                # A beep starts from silence by its envelope; a glide fades in from gain 0.
                first = new if key[0] == "o" else replace(new, gain_a=0.0, gain_b=0.0)
                pulse = -m.scan_s * new.order * new.rate if key[0] == "o" else 0.0
                self.states[key] = _State(first, new, 0, 0.0, pulse)
            st = self.states[key]
            if new != st.target:
                # A new target mid-ramp starts from where the ramp stands, never from a jump.
                st.voice = _lerp_voice(st.voice, st.target, min(st.done / r, 1.0))
                st.target, st.done = new, 0
            elif st.done >= r:
                st.voice = new
            old = st.voice
            done = st.done
            # Binaural: the voice is made mono (pan 1, 0 into a scratch pair), then filtered by
            # the responses of its direction into both ears.
            dest_l, dest_r = (np.zeros(n), scratch) if self.hrirs is not None else (out_l, out_r)
            pan_old_a, pan_new_a = (_MONO, _MONO) if self.hrirs is not None else (old.pan_a, new.pan_a)
            if key[0] == "o":
                st.osc, st.pulse = self._pulse_voice(
                    dest_l,
                    dest_r,
                    self._tables[new.harmonics],
                    self._tables[old.harmonics],
                    self._hann,
                    old.harmonics != new.harmonics,
                    st.osc,
                    st.pulse,
                    float(sr),
                    float(r),
                    float(min(done, r)),
                    m.duty_max,
                    m.master_gain,
                    old.freq_a,
                    new.freq_a,
                    old.rate,
                    new.rate,
                    old.beep_s,
                    new.beep_s,
                    old.gain_a,
                    new.gain_a,
                    pan_old_a[0],
                    pan_new_a[0],
                    pan_old_a[1],
                    pan_new_a[1],
                )
            else:
                # A glide: continuous tone, parameters following the triangle near -> far -> near.
                cyc, gp = self._glide_voice(
                    dest_l,
                    dest_r,
                    self._tables[new.harmonics],
                    self.hrirs is not None,
                    st.osc,
                    st.pulse,
                    float(sr),
                    sr * m.glide_period_s,
                    float(r),
                    float(done),
                    m.master_gain,
                    old.freq_a,
                    new.freq_a,
                    old.freq_b,
                    new.freq_b,
                    old.gain_a,
                    new.gain_a,
                    old.gain_b,
                    new.gain_b,
                    old.pan_a[0],
                    new.pan_a[0],
                    old.pan_b[0],
                    new.pan_b[0],
                    old.pan_a[1],
                    new.pan_a[1],
                    old.pan_b[1],
                    new.pan_b[1],
                )
                st.osc = float(cyc % 1.0)
                st.pulse = float(gp % 1.0)
            if self.hrirs is not None:
                self._place(st, new, dest_l, spatial)
            st.done = min(done + n, r)
        for key in [k for k, s in self.states.items() if s.fading and s.done >= r]:
            del self.states[key]
        if spatial:
            self._convolve(spatial, out_l, out_r)
        elif self._tail is not None:  # the last voices' filters still ringing
            self._convolve([(np.zeros(n), 0)], out_l, out_r)
        return _soft_limit(np.column_stack((out_l, out_r)))

    def _spectrum(self, index: int, nfft: int) -> NDArray[np.complex128]:
        """Both ears' transfer functions of one direction at an FFT size (cached)."""
        assert self.hrirs is not None
        got = self._spectra.get((index, nfft))
        if got is None:
            got = np.fft.rfft(self.hrirs.irs[index], nfft, axis=1)
            self._spectra[(index, nfft)] = got
        return got

    def _place(self, st: _State, v: Voice, mono: NDArray[np.float64], spatial: list[Any]) -> None:
        """Queue ``mono`` for the filters of the voice's direction (a new direction: cross-faded over the call)."""
        h = self.hrirs
        assert h is not None
        az, el = _direction_of(v, self.mapping)
        index = h.nearest(az, el)
        if st.hrir < 0 or index == st.hrir:
            spatial.append((mono, index))
        else:
            # The input moves from the old pair of filters to the new one; the old filters'
            # response to what they already had rings on in the shared tail: no click.
            w = np.arange(1, len(mono) + 1) / len(mono)
            spatial += [(mono * (1.0 - w), st.hrir), (mono * w, index)]
        st.hrir = index

    def _convolve(
        self, spatial: list[tuple[NDArray[np.float64], int]], out_l: NDArray[np.float64], out_r: NDArray[np.float64]
    ) -> None:
        """Add every queued input filtered by its direction's pair to both ears (one overlap-add for all).

        Filtering is linear, so the voices are summed in the frequency domain and transformed
        back once: two inverse FFTs a call whatever the number of voices.
        """
        h = self.hrirs
        assert h is not None
        n, taps = len(out_l), h.taps
        nfft = 1 << (n + taps - 2).bit_length()
        x = np.fft.rfft(np.stack([m for m, _ in spatial]), nfft, axis=1)  # (inputs, bins)
        spectra = np.stack([self._spectrum(i, nfft) for _, i in spatial])  # (inputs, 2, bins)
        y = np.fft.irfft(np.einsum("kb,keb->eb", x, spectra), nfft, axis=1)[:, : n + taps - 1]
        if self._tail is not None:
            y[:, : taps - 1] += self._tail
        out_l += y[0, :n]
        out_r += y[1, :n]
        tail = y[:, n:]
        self._tail = tail.copy() if np.abs(tail).max(initial=0.0) > 1e-9 else None


#: Pan gains that put a voice in the left buffer alone (a mono voice, for binaural rendering).
_MONO = (1.0, 0.0)


def _direction_of(v: Voice, mapping: SoundMapping) -> tuple[float, float]:
    """(azimuth, elevation) in degrees of a voice: its own, or read back from its pan without intrinsics."""
    if v.azimuth is not None and v.elevation is not None:
        return v.azimuth, v.elevation
    # The pan's angle runs 0 (left) .. pi/2 (right) over -pan_azimuth_deg .. +pan_azimuth_deg.
    lr = (v.pan_a[0] + v.pan_b[0], v.pan_a[1] + v.pan_b[1])
    p = math.atan2(lr[1], lr[0]) / (math.pi / 2)
    az = (2.0 * p - 1.0) / max(mapping.pan_width, 1e-6) * mapping.pan_azimuth_deg
    return az, 0.0


class Sonifier:
    """Streams scenes to stereo audio with phase continuity across frames.

    Parameters
    ----------
    mapping : SoundMapping, optional
        The cue mapping (default preset when None).
    samplerate : int
        Samples per second (Hz).
    frame_size : tuple of int, optional
        (width, height) of the frames (px). When omitted, each tree's own frame size is used
        (:attr:`SceneTree.frame_size`, carried by the root of a built or parsed tree).

    Examples
    --------
    >>> s = Sonifier(SoundMapping(), 22050, (640, 480))
    >>> audio = s.push(tree, 1 / 30)  # doctest: +SKIP
    """

    def __init__(
        self, mapping: SoundMapping | None = None, samplerate: int = 22050, frame_size: tuple[int, int] | None = None
    ) -> None:
        if not isinstance(samplerate, (int, np.integer)) or not 4000 <= samplerate <= 192000:
            raise InputError(f"samplerate must be an integer in 4000..192000 Hz, got {samplerate!r}")
        if frame_size is not None:
            w, h = frame_size
            if w <= 0 or h <= 0:
                raise InputError(f"frame_size must be positive (width, height), got {frame_size}")
            frame_size = (int(w), int(h))
        self.mapping = mapping or SoundMapping()
        self.samplerate = int(samplerate)
        self.frame_size = frame_size
        self._seconds = 0.0
        self._samples = 0
        self._bank = VoiceBank(self.mapping, self.samplerate)
        self.chooser = Chooser(self.mapping)
        self.voices_now: dict[tuple[str, int], Voice] = {}  # the voices of the last push, by key

    @property
    def seconds(self) -> float:
        """Total duration (s) pushed so far."""
        return self._seconds

    def push(
        self,
        tree: SceneTree,
        duration_s: float,
        objects: Sequence[SceneObject] = (),
        intrinsics: Any = None,
        gravity: Any = None,
    ) -> NDArray[np.float32]:
        """Audio for one frame of ``duration_s`` seconds.

        ``objects`` are the frame's segmented objects (``SceneResult.segmentation.objects``):
        with them a surface's glide spans its real near and far ends. ``intrinsics`` (the
        frame's) make the pan follow each object's azimuth; with ``gravity`` (the frame's) too,
        pitch follows elevation above the horizon instead of the image row. The voices are chosen frame after
        frame by :attr:`chooser` (:class:`depthgram.sound.choose.Chooser`): a voice belongs to a
        tracked object, and concurrent voices are kept apart.

        The number of samples is chosen so that the total over all pushes is the rounded total
        duration: a sequence's audio lasts exactly as long as the sequence.

        Returns
        -------
        ndarray of float32, shape (n, 2)
            Left and right channels in -1..1.
        """
        if not isinstance(duration_s, (int, float)) or not math.isfinite(duration_s) or duration_s < 0:
            raise InputError(f"frame duration must be a finite number of seconds >= 0, got {duration_s!r}")
        self.voices_now = self.chooser.voices(tree, self._size_of(tree), objects, intrinsics, gravity)
        return self._push_targets(self.voices_now, duration_s)

    def _push_targets(self, targets: dict[tuple[str, int], Voice], duration_s: float) -> NDArray[np.float32]:
        total = round((self._seconds + duration_s) * self.samplerate)
        n = total - self._samples
        self._seconds += duration_s
        if n <= 0:
            return np.zeros((0, 2), np.float32)
        self._samples = total
        return self._render(targets, n).astype(np.float32)

    def _size_of(self, tree: SceneTree) -> tuple[int, int]:
        if self.frame_size is not None:
            return self.frame_size
        size = tree.frame_size
        if size is None:
            raise InputError(
                "Sonifier: the tree's root does not carry the frame size (area W*H, center the middle "
                "pixel); give frame_size=(width, height)"
            )
        return size

    def _render(self, targets: dict[tuple[str, int], Voice], n: int) -> NDArray[np.float64]:
        return self._bank.render(targets, n)


def render_scene(
    tree: SceneTree,
    frame_size: tuple[int, int] | None = None,
    *,
    mapping: SoundMapping | None = None,
    duration_s: float | None = None,
    samplerate: int = 22050,
    objects: Sequence[SceneObject] = (),
) -> NDArray[np.float32]:
    """One scene as a short stereo sound: a scan (left to right by default), then its beeps.

    Every voice starts silent and the sound fades out over the mapping's ramp at the end, so
    the clip can be played on its own. An empty scene gives silence, not an error.

    Parameters
    ----------
    tree : SceneTree
    frame_size : tuple of int, optional
        (width, height) of the frame (px); the tree's own (:attr:`SceneTree.frame_size`) when omitted.
    mapping : SoundMapping, optional
    duration_s : float, optional
        Length of the sound (s). By default :func:`still_seconds`: long enough for every
        voice to be heard twice.
    samplerate : int
        Samples per second (Hz).
    objects : sequence of SceneObject, optional
        The segmented objects, for the real extent of surfaces (see :func:`voices`).

    Returns
    -------
    ndarray of float32, shape (round(duration_s * samplerate), 2)
    """
    s = Sonifier(mapping, samplerate, frame_size)
    # A still is one scene heard whole: its nearest objects, no stream's history to choose by.
    still = voices(tree, s._size_of(tree), s.mapping, objects)
    if duration_s is None:
        duration_s = still_seconds(still, s.mapping)
    if not isinstance(duration_s, (int, float)) or not math.isfinite(duration_s) or duration_s < 0:
        raise InputError(f"duration must be a finite number of seconds >= 0, got {duration_s!r}")
    audio = s._push_targets({v.key: v for v in still}, duration_s)
    r = min(len(audio), max(1, round(s.mapping.ramp_s * samplerate)))
    if r:
        audio[-r:] *= np.linspace(1.0, 0.0, r, dtype=np.float32)[:, None]
    return audio
