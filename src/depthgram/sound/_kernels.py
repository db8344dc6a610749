"""The voices' oscillators: one fused pass per voice and audio block (numba).

No library kernel combines a wavetable oscillator, a pulse train with raised-cosine beeps
and linear parameter ramps; in numpy it takes some twenty passes over the buffer per voice,
and the beeps are silent most of the time, which a loop can skip. A glide (a surface's tone,
its pitch, loudness and pan following a triangle) is the same kind of loop: as numpy calls it
was some thirty passes over a 256-sample block, each costing its call more than its samples.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def pulse_voice(
    out_l: np.ndarray,
    out_r: np.ndarray,
    table_new: np.ndarray,
    table_old: np.ndarray,
    hann: np.ndarray,
    cross: bool,
    osc: float,
    pulse: float,
    samplerate: float,
    ramp_n: float,
    ramp_done: float,
    duty_max: float,
    scale: float,
    f0: float,
    f1: float,
    r0: float,
    r1: float,
    b0: float,
    b1: float,
    g0: float,
    g1: float,
    l0: float,
    l1: float,
    q0: float,
    q1: float,
) -> tuple[float, float]:
    """Add one beeping voice to ``out_l``/``out_r``; return its (oscillator, pulse) phases.

    Parameters move linearly from the old value (``*0``) to the new (``*1``) over ``ramp_n``
    samples, of which ``ramp_done`` were already played by earlier calls (a ramp longer than one
    audio block spans several): frequency ``f`` (Hz), rate ``r`` (Hz), beep length ``b`` (s), gain
    ``g``, left and right pan ``l``, ``q``. ``cross``: cross-fade from ``table_old`` (a timbre change).
    Phases are in cycles; a negative pulse phase waits for the first beep.
    """
    n_table = table_new.shape[0]
    mask = n_table - 1
    n_hann = hann.shape[0] - 1
    for i in range(out_l.shape[0]):
        w = 1.0 - (i + 1.0 + ramp_done) / ramp_n
        if w < 0.0:
            w = 0.0
        f = f1 + (f0 - f1) * w
        rate = r1 + (r0 - r1) * w
        osc += f / samplerate
        if osc >= 1.0:
            osc -= math.floor(osc)
        pulse += rate / samplerate
        if pulse < 0.0:
            continue
        if pulse >= 1.0:
            pulse -= math.floor(pulse)
        duty = (b1 + (b0 - b1) * w) * rate
        if duty > duty_max:
            duty = duty_max
        x = pulse / duty
        if x >= 1.0:
            continue
        env = hann[min(int(x * n_hann), n_hann)]
        k = int(osc * n_table) & mask
        s = table_new[k]
        if cross:
            s += (table_old[k] - s) * w
        s *= env * (g1 + (g0 - g1) * w) * scale
        out_l[i] += s * (l1 + (l0 - l1) * w)
        out_r[i] += s * (q1 + (q0 - q1) * w)
    return osc, pulse


@njit(cache=True, inline="always")
def _toward(old: float, new: float, w: float) -> float:
    # the value ``w`` of the way back from ``new`` to ``old``; ``new`` itself when they agree, as
    # the numpy ramp returned it (``new + 0 * w`` would turn a -0.0 into +0.0)
    return new if old == new else new + (old - new) * w


@njit(cache=True)
def glide_voice(
    out_l: np.ndarray,
    out_r: np.ndarray,
    table: np.ndarray,
    mono: bool,
    osc: float,
    phase: float,
    samplerate: float,
    period_n: float,
    ramp_n: float,
    ramp_done: float,
    scale: float,
    fa0: float,
    fa1: float,
    fb0: float,
    fb1: float,
    ga0: float,
    ga1: float,
    gb0: float,
    gb1: float,
    la0: float,
    la1: float,
    lb0: float,
    lb1: float,
    ra0: float,
    ra1: float,
    rb0: float,
    rb1: float,
) -> tuple[float, float]:
    """Add one gliding tone to ``out_l``/``out_r``; return its oscillator and glide phases, unwrapped.

    Along the glide's triangle (``phase`` in cycles, one cycle every ``period_n`` samples) the
    parameters move from their near (``*a*``) to their far (``*b*``) values and back: frequency
    ``f`` (Hz), gain ``g``, left and right pan ``l``, ``r``; each moves from its old (``*0``) to
    its new (``*1``) value over ``ramp_n`` samples, ``ramp_done`` of them played by earlier
    calls. ``mono``: the tone goes to ``out_l`` alone, unpanned (binaural rendering filters it).
    The arithmetic is the numpy expression's, in its order, so that a block is the same.
    """
    n_table = table.shape[0]
    mask = n_table - 1
    acc = 0.0
    cyc = osc
    gp = phase
    for i in range(out_l.shape[0]):
        w = 1.0 - (i + 1.0 + ramp_done) / ramp_n
        if w < 0.0:
            w = 0.0
        elif w > 1.0:
            w = 1.0
        gp = phase + (i + 1.0) / period_n
        tri = 1.0 - abs(2.0 * (gp - math.floor(gp)) - 1.0)
        fa, fb = _toward(fa0, fa1, w), _toward(fb0, fb1, w)
        acc += fa * (fb / fa) ** tri
        cyc = osc + acc / samplerate
        ga, gb = _toward(ga0, ga1, w), _toward(gb0, gb1, w)
        wave = table[int(cyc * n_table) & mask] * ((ga * (1 - tri) + gb * tri) * scale)
        if mono:
            out_l[i] += wave
            continue
        la, lb = _toward(la0, la1, w), _toward(lb0, lb1, w)
        ra, rb = _toward(ra0, ra1, w), _toward(rb0, rb1, w)
        out_l[i] += wave * (la * (1 - tri) + lb * tri)
        out_r[i] += wave * (ra * (1 - tri) + rb * tri)
    return cyc, gp
