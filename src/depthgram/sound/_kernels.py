"""The beep-train oscillator: one fused pass per voice (numba).

No library kernel combines a wavetable oscillator, a pulse train with raised-cosine beeps
and linear parameter ramps; in numpy it takes some twenty passes over the buffer per voice,
and the beeps are silent most of the time, which a loop can skip.
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
