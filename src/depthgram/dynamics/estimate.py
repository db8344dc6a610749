"""The compiled radial-velocity estimate of the tracker: the Kalman filter and the own motion.

One kernel (:func:`estimate`), run after the tracker's step (:mod:`depthgram.dynamics.kernels`)
on the same track records; in a module of its own because numba's on-disk cache is per source
file and the step and the filters change for different reasons. It calls no kernel of another
file; the status codes it reads are plain ints (numba freezes module globals as constants).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.dynamics.kernels import Status

__all__ = ["OWN_NIS_TAU_S", "EstimateParams", "estimate"]

ENTERING, LEAVING = int(Status.ENTERING), int(Status.LEAVING)


class EstimateParams(NamedTuple):
    """Settings of :func:`estimate`, from a TrackerConfig (its fields, same names and units).

    Built by :func:`depthgram.dynamics.tracker.estimate_params`.
    """

    kalman: bool  # estimator == "kalman" (else the queue's slope)
    depth_sigma_mm: float
    depth_sigma_floor_mm: float
    accel_sigma: float
    innovation_gate: float
    ttc_min_sigmas: float
    min_speed: float
    v_sigma0: float  # velocity uncertainty a (re)started filter begins with (mm/s)
    own_accel_sigma: float
    own_v_sigma0: float  # uncertainty of a new track's own velocity, which starts at 0 (mm/s)
    own_min_sigmas: float  # sigmas from standing still at which an own velocity counts


#: Time constant of the running mean of the own-motion filter's normalised squared innovations (s).
OWN_NIS_TAU_S = 0.1


@njit(cache=True)
def estimate(
    tracks: NDArray[np.void],
    qt: NDArray[np.float64],
    qz: NDArray[np.float64],
    n: int,
    restarted: NDArray[np.bool_],
    v_queue: NDArray[np.float64],
    ttc_queue: NDArray[np.float64],
    dt: float,
    p: EstimateParams,
    offset: NDArray[np.float64],
    core_dz: NDArray[np.float64],
    still_dz: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Radial velocity, time to collision and v_sigma of every live track (mm/s, s, mm/s).

    ``tracks`` are the live :data:`TRACK_DTYPE` records after :func:`step` (their ``kf_*`` and
    ``own_*`` fields are updated here), ``qt`` and ``qz`` their queues.
    ``p`` holds the settings (:func:`depthgram.dynamics.tracker.estimate_params`): the Kalman
    filter or the queue's slope, the sensor noise, the process noise, the gates.
    Tracks ``n..`` are new. One compiled pass: the same steps in numpy cost some forty
    array expressions per frame, more than the arithmetic on a few dozen tracks.

    ``queue``: the kernel's slope, with the standard error that slope has under the sensor
    noise model. ``kalman``: a constant-velocity filter on depth and radial velocity, predicted
    over ``dt`` for every track (occluded ones coast) and updated with each valid depth reading
    within ``innovation_gate`` standard deviations of its prediction; three outliers in a row
    restart it there. Either way a time to collision needs a closing speed of at least
    ``ttc_min_sigmas`` v_sigma. ``offset`` moves each track's filter depth along with its queue
    (see :func:`step`).

    With the camera's own motion known (``kalman`` only): ``still_dz`` is the depth change
    (mm) each detected track would show since the previous frame if it stood still, ``core_dz``
    the change its core shows (mm; NaN where unknown). The radial velocity is then
    ``still_dz / dt`` plus the object's own velocity ``own_v`` (mm/s, variance ``own_var``),
    filtered from ``(core_dz - still_dz) / dt`` as a random walk with the same innovation gate
    (``own_rej`` outliers in a row; NaN ``own_v``: not started). Its process noise is
    ``own_accel_sigma`` while the readings fit it, and grows up to ``accel_sigma`` with the
    running mean ``own_nis`` of the normalised squared innovations where they do not (an
    object that does change speed: the simulator's cart entering the view). The camera's part
    needs no filter: it is read afresh each frame from the whole view, so it follows a
    hand-held camera's shake without lag, and the filter only smooths what the object does
    itself (on 7-Scenes within 25 % + 30 mm/s of the poses' truth: 0.72 without, 0.85 with).
    The depth filter above takes that velocity over, so it coasts on it through frames
    without the camera's motion.
    """
    sig1m = p.depth_sigma_mm
    floor = p.depth_sigma_floor_mm
    accel = p.accel_sigma
    gate_k = p.innovation_gate
    ttc_k = p.ttc_min_sigmas
    min_speed = p.min_speed
    v_sigma0 = p.v_sigma0
    qw = p.own_accel_sigma * dt
    # how far the own filter's process noise may grow when its readings do not fit (variance)
    nis_max = (accel / p.own_accel_sigma) ** 2 if p.own_accel_sigma > 0 else 1.0
    w_sigma0 = p.own_v_sigma0
    own_k = p.own_min_sigmas
    # the running mean's weight of a new reading: a time constant, so that it spans the same
    # time at any frame rate (0.28 at 30 frames/s, about three readings)
    nis_w = 1.0 - np.exp(-dt / OWN_NIS_TAU_S)
    nn = tracks.shape[0]
    nq = qz.shape[1]
    v_out = np.full(nn, np.nan)
    ttc = np.full(nn, np.nan)
    sig = np.full(nn, np.nan)
    q = accel * accel
    for i in range(nn):
        t = tracks[i]
        z_new = qz[i, nq - 1]
        meas = t.missed == 0 and np.isfinite(z_new)
        zr = z_new if np.isfinite(z_new) else t.z_fit
        sz = floor + sig1m * (zr / 1000.0) ** 2
        r = sz * sz
        if not p.kalman:
            cnt = 0
            st = 0.0
            for j in range(nq):
                if np.isfinite(qz[i, j]):
                    cnt += 1
                    st += qt[i, j]
            if cnt >= 2:
                tb = st / cnt
                stt = 0.0
                for j in range(nq):
                    if np.isfinite(qz[i, j]):
                        stt += (qt[i, j] - tb) ** 2
                sig[i] = np.sqrt(r / stt) if stt > 0 else np.nan
            v_out[i] = v_queue[i]
            ttc[i] = ttc_queue[i]
        else:
            if i >= n:
                t.kf_n = 0
                t.kf_rej = 0
                t.kf_z = np.nan
                t.kf_v = np.nan
            else:
                t.kf_z += dt * t.kf_v + offset[i]
                p00, p01, p11 = t.kf_pzz, t.kf_pzv, t.kf_pvv
                t.kf_pzz = p00 + 2 * dt * p01 + dt * dt * p11 + q * dt**4 / 4
                t.kf_pzv = p01 + dt * p11 + q * dt**3 / 2
                t.kf_pvv = p11 + q * dt * dt
            if meas:
                start = restarted[i] or t.kf_n == 0
                if not start:
                    sv = t.kf_pzz + r
                    y = z_new - t.kf_z
                    if y * y > gate_k * gate_k * sv:
                        t.kf_rej += 1
                        # three outliers in a row: the object did change; a velocity one depth
                        # difference gave is no reason to refuse the next reading (which of the
                        # two was wrong is not known): it starts again there
                        start = t.kf_rej >= 3 or t.kf_n == 2
                    else:
                        t.kf_rej = 0
                        k0 = t.kf_pzz / sv
                        k1 = t.kf_pzv / sv
                        t.kf_z += k0 * y
                        t.kf_v += k1 * y
                        p00, p01, p11 = t.kf_pzz, t.kf_pzv, t.kf_pvv
                        t.kf_pzz = (1 - k0) * p00
                        t.kf_pzv = (1 - k0) * p01
                        t.kf_pvv = p11 - k1 * p01
                        t.kf_n += 1
                if start:
                    t.kf_z = z_new
                    t.kf_v = 0.0
                    t.kf_pzz = r
                    t.kf_pzv = 0.0
                    t.kf_pvv = v_sigma0 * v_sigma0
                    t.kf_n = 1
                    t.kf_rej = 0
            if i >= n:
                t.own_v = np.nan
                t.own_var = 0.0
                t.own_rej = 0
            elif np.isfinite(t.own_v):
                if t.status == ENTERING or t.status == LEAVING:
                    # the visible part changes at the image's edge: its readings change for
                    # reasons the own motion does not model (the simulator's cart entering)
                    t.own_nis = nis_max
                t.own_var += qw * qw * min(max(t.own_nis, 1.0), nis_max)
            extra = 0.0  # variance v_sigma adds for an own velocity not yet counted
            reported = t.kf_v  # the filter's velocity, less an own part not counted yet
            # Without the camera's part the velocity is the depth filter's: reported once two
            # depth differences agree, as an own part counts (a new track's core read across two
            # surfaces on its second frame, 190 mm nearer, read -5.7 m/s, a collision 0.4 s
            # away, before a still camera's scene)
            agreed = t.kf_n >= 3
            if t.missed == 0 and np.isfinite(still_dz[i]):
                # Entering or leaving, the visible part changes at the image's edge and its
                # readings with it, for reasons no motion models (the simulator's cart read
                # -2.7 m/s entering the view sideways): they are left out of the own motion.
                edge = t.status == ENTERING or t.status == LEAVING
                if not np.isfinite(t.own_v):
                    t.own_rej = 0
                    if t.kf_n >= 2 and np.isfinite(t.kf_v) and not edge:
                        # the velocity the depth filter knew so far, less the camera's part
                        # now (a camera found moving after standing still)
                        t.own_v = t.kf_v - still_dz[i] / dt
                        t.own_var = t.kf_pvv
                        # as many readings of it as the filter had depth differences: one
                        # difference alone (a core read across two surfaces) does not count yet
                        t.own_n = min(t.kf_n - 1, 2)
                    else:
                        # most of what a camera sees stands still: no own motion until read
                        t.own_v = 0.0
                        t.own_var = w_sigma0 * w_sigma0
                        t.own_n = 0
                    # a new track's own motion is not known yet: it starts fast and settles
                    # as its readings agree (about six readings)
                    t.own_nis = nis_max
                if np.isfinite(core_dz[i]) and not edge:
                    y0 = (core_dz[i] - still_dz[i]) / dt
                    rw = r / (dt * dt)
                    y = y0 - t.own_v
                    sw = t.own_var + rw
                    # one outlier counts as 25 at most
                    t.own_nis += nis_w * (min(y * y / sw, 25.0) - t.own_nis)
                    if y * y <= gate_k * gate_k * sw:
                        gain = t.own_var / sw
                        t.own_v += gain * y
                        t.own_var *= 1.0 - gain
                        t.own_rej = 0
                        t.own_n += 1
                    else:
                        t.own_rej += 1
                        if t.own_rej >= 3:
                            t.own_v = y0
                            t.own_var = rw
                            t.own_rej = 0
                            t.own_n = 1
                # Most of what a camera sees stands still: the own part counts once it is
                # significant (on 7-Scenes within 25 % + 30 mm/s: 0.80 always, 0.85 so) and
                # two readings agree on it: one core read across two surfaces (a track that
                # took over a nearer surface at the image's edge) read -5.2 m/s, a collision
                # 0.4 s away, in a still kitchen. Until then v_sigma covers it.
                counts = t.own_n >= 2 and abs(t.own_v) > own_k * np.sqrt(t.own_var)
                # the depth filter predicts with the own part as filtered; the reading says it
                # only once it counts
                t.kf_v = still_dz[i] / dt + t.own_v
                t.kf_pzv = 0.0
                t.kf_pvv = t.own_var
                reported = t.kf_v
                agreed = True  # the camera's part is read afresh: one frame is enough
                if not counts:
                    extra = t.own_v * t.own_v
                    reported = still_dz[i] / dt
            elif np.isfinite(t.own_v) and t.own_n < 2:
                # the camera's part not read this frame (a repeated frame, a view it cannot
                # follow, a missed detection): the depth filter's velocity holds an own part
                # that one reading alone gave, left out as on the frame it was read (7-Scenes
                # frame 222, a repeat of 221: one core read across two surfaces, -4.4 m/s)
                extra = t.own_v * t.own_v
                reported = t.kf_v - t.own_v
            if t.kf_n >= 2 and agreed:
                v_out[i] = reported
                sig[i] = np.sqrt(t.kf_pvv + extra)
                if v_out[i] < -min_speed and t.kf_z > 0:
                    ttc[i] = t.kf_z / -v_out[i]
        if not -v_out[i] >= ttc_k * sig[i]:
            ttc[i] = np.nan
    return v_out, ttc, sig
