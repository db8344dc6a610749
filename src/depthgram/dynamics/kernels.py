"""Compiled kernels of the tracker: the velocity fit, the matching cost, the per-frame step.

The radial-velocity filters (Kalman and the own motion) are in
:mod:`depthgram.dynamics.estimate`.

They live in one module on purpose: numba's on-disk cache (``cache=True``) is invalidated
per source file, so a kernel inlined into another file's kernel would keep running its
stale compiled copy after an edit. Public, documented entry points are in
:mod:`depthgram.dynamics.flow`, :mod:`depthgram.dynamics.match` and
:mod:`depthgram.dynamics.tracker`.

Hand-written loops because the tracker calls them every frame on a few dozen rows, where
numpy's per-call overhead of some fifty array expressions costs more than the arithmetic.
"""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

#: Cost of a gated (forbidden) pair. Finite, because linear_sum_assignment rejects
#: matrices where a row has no finite entry; pairs at this cost are dropped afterwards.
FORBIDDEN = 1e9


class Status(IntEnum):
    """A track's status this frame.

    Its value is the code in a track record's ``status`` field and its lower-case name the
    :class:`depthgram.scene.tree.Motion` status.
    """

    VISIBLE = 0  # detected, whole in view
    ENTERING = 1  # detected at the image border, growing into view
    LEAVING = 2  # detected at the image border, shrinking out of view
    OCCLUDED = 3  # not detected this frame, alive within max_missed


# Plain ints for the compiled kernels (numba freezes module globals as constants).
VISIBLE, ENTERING, LEAVING, OCCLUDED = (int(x) for x in Status)


class CostParams(NamedTuple):
    """Gates and weights of the matching cost (:func:`cost_kernel`), from a TrackerConfig.

    Built by :func:`depthgram.dynamics.match.cost_params`; the names are the config's fields
    (see :class:`depthgram.dynamics.TrackerConfig` for units) unless said otherwise.
    """

    max_center_rate: float
    gate_growth: float
    max_depth_rate: float
    log_max_area_ratio: float  # log(max_area_ratio)
    min_iou: float
    w_center: float
    w_depth: float
    w_area: float
    w_iou: float
    w_label: float
    accel_sigma: float  # the filter's process noise (mm/s^2): how far a coasting depth may stray
    innovation_gate: float  # standard deviations of that uncertainty a coasting track's depth gate spans


class StepParams(NamedTuple):
    """Settings of :func:`step`, from a TrackerConfig (its fields, same names and units).

    Built by :func:`depthgram.dynamics.tracker.step_params`.
    """

    border_px: float
    border_area_rate: float
    max_area_jump: float
    fit_border_entries: bool
    min_speed: float
    min_hits: int
    max_missed: int
    max_occluded_s: float
    max_depth_jump_rate: float  # inf with the Kalman filter, which gates jumps itself
    center_tau_s: float
    area_tau_s: float


@njit(cache=True)
def fit_row(t: NDArray[np.float64], z: NDArray[np.float64], t_now: float) -> tuple[float, float]:
    """Least-squares slope and fitted depth at ``t_now`` of one queue (see :func:`fit_radial_velocity`).

    Compiled so that the tracker can call it per track without numpy's per-call overhead on arrays
    of four entries.
    """
    n = 0
    st = 0.0
    sz = 0.0
    last = np.nan
    for j in range(t.shape[0]):
        if np.isfinite(z[j]) and np.isfinite(t[j]):
            n += 1
            # Centred on t_now so that large timestamps (Unix seconds) keep full precision.
            st += t[j] - t_now
            sz += z[j]
            last = z[j]
    if n < 2:
        return np.nan, last
    tb = st / n
    zb = sz / n
    num = 0.0
    den = 0.0
    for j in range(t.shape[0]):
        if np.isfinite(z[j]) and np.isfinite(t[j]):
            d = t[j] - t_now - tb
            num += d * (z[j] - zb)
            den += d * d
    if den <= 0.0:
        return np.nan, last
    v = num / den
    return v, zb - v * tb


# This frame's objects as the kernels read them: one record each, all float64, so that the
# tracker fills them as one float block (depthgram.dynamics.tracker._features).
OBJECT_FIELDS: tuple[tuple[str, str], ...] = (
    ("cx", "centre x (px)"),
    ("cy", "centre y (px)"),
    ("z", "depth (mm; tracker.track_depth)"),
    ("area", "area (px)"),
    ("label", "depth label"),
    ("x0", "bbox, half-open (px)"),
    ("y0", "bbox (px)"),
    ("x1", "bbox (px)"),
    ("y1", "bbox (px)"),
    ("behind", "1 where a nearer object touches or overlaps it (mark_behind), else 0"),
    ("read_nearest", "1 where its depth is a compound's nearest part, 0 its mean depth"),
)
OBJECT_DTYPE = np.dtype([(name, np.float64) for name, _ in OBJECT_FIELDS])


# Each track's prediction for this frame, as the matching cost reads it (:func:`cost_kernel`).
PREDICTION_FIELDS: tuple[tuple[str, str], ...] = (
    ("cx", "predicted centre x (px)"),
    ("cy", "predicted centre y (px)"),
    ("sx", "predicted centre of the part last seen, x (px); cx while the whole object was in view"),
    ("sy", "predicted centre of the part last seen, y (px)"),
    ("z", "predicted depth (mm)"),
    ("area", "area as last seen (px)"),
    ("x0", "predicted bbox, half-open (px)"),
    ("y0", "predicted bbox (px)"),
    ("x1", "predicted bbox (px)"),
    ("y1", "predicted bbox (px)"),
    ("label", "depth label as last seen"),
    ("elapsed", "time since the last detection (s)"),
    ("zs", "how far the depth may stray from the prediction by the Kalman filter (mm); NaN: no filter"),
)
PREDICTION_DTYPE = np.dtype([(name, np.float64) for name, _ in PREDICTION_FIELDS])


@njit(cache=True)
def cost_kernel(
    pred: NDArray[np.void],
    objs: NDArray[np.void],
    diagonal_px: float,
    dt: float,
    params: CostParams,
) -> NDArray[np.float64]:
    """Compiled body of :func:`match_cost`: the cost of each track's prediction against each object.

    ``pred`` are :data:`PREDICTION_DTYPE` records, ``objs`` :data:`OBJECT_DTYPE` records (of
    which ``behind`` and ``read_nearest`` are not read), ``params`` from :func:`cost_params`.
    ``elapsed`` is each track's time since its last detection and ``dt`` this frame's step
    (s): the gates are rates, so they admit the same physical motion at any frame rate. The
    predicted centre of the part last seen (``sx``, ``sy``) differs from the centre while an
    object is partly hidden; the nearer of the two counts.

    Hand-written loops because the tracker calls it every frame on matrices of a few dozen
    entries, where numpy's per-call overhead of some twenty array expressions would cost
    more than the arithmetic.
    """
    center_rate = params.max_center_rate
    growth = params.gate_growth
    dz_rate = params.max_depth_rate
    log_ratio = params.log_max_area_ratio
    min_iou = params.min_iou
    w_c, w_z, w_a, w_iou, w_label = params.w_center, params.w_depth, params.w_area, params.w_iou, params.w_label
    nt = pred.shape[0]
    no = objs.shape[0]
    cost = np.empty((nt, no))
    for i in range(nt):
        t = pred[i]
        r = center_rate * dt * diagonal_px * (1.0 + growth * max(t.elapsed - dt, 0.0))
        zg = t.z * dz_rate * max(t.elapsed, dt)
        if t.elapsed > 1.5 * dt and np.isfinite(t.zs):
            # A track coasting with a filter: its depth gate widens with the time missed as far
            # as the filter's predicted depth may stray (``innovation_gate`` of its standard
            # deviations, which grows with the unmodelled acceleration), never below the
            # one-frame gate. The linear widening let a ball hidden behind a box for ten frames
            # (structured light, 640 x 480) take a sliver of the box's side 745 mm nearer than
            # its prediction (4 sigma: 276 mm).
            zg = min(zg, max(t.z * dz_rate * dt, t.zs))
        area_t = max(t.area, 1.0)
        bt_area = (t.x1 - t.x0) * (t.y1 - t.y0)
        for j in range(no):
            o = objs[j]
            cost[i, j] = FORBIDDEN
            # Cheapest gates first: most pairs are far apart and need no log or sqrt.
            dx = t.cx - o.cx
            dy = t.cy - o.cy
            sx = t.sx - o.cx
            sy = t.sy - o.cy
            d2 = min(dx * dx + dy * dy, sx * sx + sy * sy)
            if not d2 <= r * r:
                continue
            dz = abs(o.z - t.z) / zg
            # NaN depth (no valid pixel) fails the depth gate: comparisons with NaN are False.
            if not dz <= 1.0:
                continue
            da = abs(np.log(max(o.area, 1.0) / area_t)) / log_ratio
            if not da <= 1.0:
                continue
            ix = min(t.x1, o.x1) - max(t.x0, o.x0)
            iy = min(t.y1, o.y1) - max(t.y0, o.y0)
            inter = max(ix, 0.0) * max(iy, 0.0)
            bo_area = (o.x1 - o.x0) * (o.y1 - o.y0)
            iou = inter / max(bt_area + bo_area - inter, 1.0)
            if iou < min_iou:
                continue
            c = w_c * np.sqrt(d2) / r + w_z * dz + w_a * da + w_iou * (1.0 - iou)
            if t.label != o.label:
                c += w_label
            cost[i, j] = c
    return cost


# The state of every live track: one record per track, these fields. This module owns them (the
# kernels below and depthgram.dynamics.tracker read them by name); numba's cache is per source
# file, so they live here rather than in a module the kernels would import.
TRACK_FIELDS: tuple[tuple[str, type, str], ...] = (
    ("id", np.int64, "track id, from 1"),
    ("hits", np.int64, "frames with a detection"),
    ("missed", np.int64, "frames since the last detection (0: detected this frame)"),
    ("status", np.int64, "a Status code"),
    ("cx", np.float64, "centre of the object as last detected, x (px)"),
    ("cy", np.float64, "centre as last detected, y (px)"),
    ("vx", np.float64, "smoothed image velocity of the centre, x (px/s)"),
    ("vy", np.float64, "smoothed image velocity of the centre, y (px/s)"),
    ("x0", np.float64, "bbox as last detected, half-open (px)"),
    ("y0", np.float64, "bbox (px)"),
    ("x1", np.float64, "bbox (px)"),
    ("y1", np.float64, "bbox (px)"),
    ("depth", np.float64, "depth as last read (mm; tracker.track_depth)"),
    ("z_fit", np.float64, "fitted depth at the last detection (mm)"),
    ("area", np.float64, "area as last detected (px)"),
    ("area_run", np.float64, "running depth-compensated area A z^2 against which splits are judged (px mm^2)"),
    ("label", np.int64, "depth label as last detected"),
    ("v", np.float64, "radial velocity of the queue fit (mm/s; NaN: none yet)"),
    ("read_nearest", np.bool_, "the depth is a compound's nearest part (else the mean depth)"),
    ("t_seen", np.float64, "time of the last detection (s)"),
    ("ox", np.float64, "centre of the part last seen, x (px); cx while the whole object was in view"),
    ("oy", np.float64, "centre of the part last seen, y (px)"),
    # the constant-velocity Kalman filter on depth and radial velocity (estimator "kalman")
    ("kf_z", np.float64, "filtered depth (mm; NaN: not started)"),
    ("kf_v", np.float64, "filtered radial velocity (mm/s)"),
    ("kf_pzz", np.float64, "covariance: depth variance (mm^2)"),
    ("kf_pzv", np.float64, "covariance: depth-velocity (mm^2/s)"),
    ("kf_pvv", np.float64, "covariance: velocity variance (mm^2/s^2)"),
    ("kf_n", np.int64, "readings folded in since the filter (re)started"),
    ("kf_rej", np.int64, "outliers rejected in a row"),
    # the object's own radial velocity where the camera's motion is known (estimate)
    ("own_v", np.float64, "own radial velocity, the camera's part taken out (mm/s; NaN: not started)"),
    ("own_var", np.float64, "its variance (mm^2/s^2)"),
    ("own_rej", np.int64, "its outliers rejected in a row"),
    ("own_nis", np.float64, "running mean of its normalised squared innovations"),
    ("own_n", np.int64, "readings folded into the own velocity since it (re)started"),
)
TRACK_DTYPE = np.dtype([(name, kind) for name, kind, _ in TRACK_FIELDS], align=True)


def new_tracks(n: int) -> NDArray[np.void]:
    """Return ``n`` blank track records: zeros, the filters not started."""
    t = np.zeros(n, TRACK_DTYPE)
    t["kf_z"] = np.nan
    t["kf_v"] = np.nan
    t["own_v"] = np.nan
    t["own_nis"] = 1.0
    return t


@njit(cache=True)
def mark_behind(objs: NDArray[np.void]) -> None:
    """Set field ``behind`` of each object that a nearer object touches or overlaps.

    Boxes within 1 px count as touching, and nearer means by more than 5 % of depth. A loop over
    pairs: a dozen numpy expressions on 30 x 30 pairs cost more in call overhead than the whole
    comparison.
    """
    m = objs.shape[0]
    for j in range(m):
        o = objs[j]
        o.behind = 0.0
        for i in range(m):
            near = objs[i]
            if i == j or not near.z < 0.95 * o.z:
                continue
            # half-open boxes: x0 <= other x1 means overlapping or adjacent
            if o.x0 <= near.x1 and near.x0 <= o.x1 and o.y0 <= near.y1 and near.y0 <= o.y1:
                o.behind = 1.0
                break


@njit(cache=True)
def predict_cost(
    tracks: NDArray[np.void],
    n: int,
    objs: NDArray[np.void],
    diagonal_px: float,
    t_now: float,
    dt: float,
    p: CostParams,
    filter_gate: bool = True,
) -> NDArray[np.float64]:
    """Predict each of the first ``n`` tracks forward by the time since its last detection, then cost all pairs.

    ``filter_gate``: a coasting track's depth gate widens as its filter's depth uncertainty
    (:func:`cost_kernel`); False where the camera moved in the previous frame, whose motion
    the filter of a hidden track does not hold (it filters the object's own part).
    """
    pred = np.empty(n, PREDICTION_DTYPE)
    qa = p.accel_sigma * p.accel_sigma
    gate_k = p.innovation_gate
    for i in range(n):
        t = tracks[i]
        q = pred[i]
        el = t_now - t.t_seen
        q.elapsed = el
        dx = t.vx * el
        dy = t.vy * el
        q.cx = t.cx + dx
        q.cy = t.cy + dy
        q.sx = t.ox + dx
        q.sy = t.oy + dy
        q.x0 = t.x0 + dx
        q.y0 = t.y0 + dy
        q.x1 = t.x1 + dx
        q.y1 = t.y1 + dy
        if t.status == ENTERING or t.status == LEAVING:
            # The fit skips border frames, so it is stale there, while the mean depth of the
            # visible part drifts as the object crosses the border (a cylinder's flank is
            # deeper than its middle): the last observed depth is the better guess.
            q.z = t.depth
        else:
            v = t.v if np.isfinite(t.v) else 0.0
            q.z = t.z_fit + v * el
        q.area = t.area
        q.label = t.label
        # the filter's depth variance predicted over this frame's step (as estimate() does)
        pzz = t.kf_pzz + 2.0 * dt * t.kf_pzv + dt * dt * t.kf_pvv + qa * dt**4 / 4.0
        # the gate's half-width: innovation_gate of that deviation, plus how far the prediction
        # above is from the filter's own (the queue's slope against the filter's velocity)
        kz = t.kf_z + dt * t.kf_v
        ok = filter_gate and t.kf_n >= 2 and pzz >= 0.0 and np.isfinite(kz)
        q.zs = gate_k * np.sqrt(pzz) + abs(q.z - kz) if ok else np.nan
    return cost_kernel(pred, objs, diagonal_px, dt, p)


@njit(cache=True)
def step(
    tracks: NDArray[np.void],
    qt: NDArray[np.float64],
    qz: NDArray[np.float64],
    n: int,
    objs: NDArray[np.void],
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    cost: NDArray[np.float64],
    t_now: float,
    dt: float,
    width: float,
    height: float,
    first: bool,
    next_id: int,
    p: StepParams,
    dcore: NDArray[np.float64],
    dstill: NDArray[np.float64],
) -> tuple[
    NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], int,
    NDArray[np.float64],
]:  # fmt: skip
    """Advance every track by one frame, in place; new tracks go to records ``n..``.

    This is the project's own bookkeeping (queues, statuses, split/merge and border tests),
    hand-written in one compiled pass because it runs every frame on a few dozen tracks.
    ``tracks`` are :data:`TRACK_DTYPE` records (the first ``n`` live), ``qt`` and ``qz`` their
    queues' times (s) and depths (mm, NaN: no valid entry), oldest first; ``objs`` this frame's
    objects (:data:`OBJECT_DTYPE`), ``rows`` and ``cols`` the assignment's pairs, ``cost`` its
    matrix. ``p`` holds the settings (:func:`depthgram.dynamics.tracker.step_params`).
    ``dt`` is this frame's time step (s): every rate and time constant is
    scaled by it, so the tracker behaves alike at any frame rate.

    ``dcore`` is each object's depth change over its core since the previous frame (mm, NaN
    where unknown; :func:`depthgram.dynamics.core_depth.core_depth_change`). Where it is known, the
    queue's new entry is the previous depth plus that change, and the whole queue is then
    moved by a constant so that its newest entry is this frame's depth: the slope follows the
    core, the depth stays the object's. Where the camera stands still (``dstill``, the change
    each object would show standing still, is NaN), a whole object in plain view is read by its
    mean depth instead, and its entry of ``dcore`` is overwritten with that change, in place, so
    that what reads ``dcore`` afterwards (:func:`estimate`) reads the same change.

    Returns the track of each object, the reported velocity and time to collision of
    every track, which tracks die this frame, which restarted their queue (new tracks too),
    the number of new tracks, and the constant each track's depths were moved by (mm).
    """
    border = p.border_px
    area_rate = p.border_area_rate
    max_jump = p.max_area_jump
    fit_border = p.fit_border_entries
    min_speed = p.min_speed
    min_hits = p.min_hits
    max_missed = p.max_missed
    max_occluded_s = p.max_occluded_s
    jump_rate = p.max_depth_jump_rate
    c_tau = p.center_tau_s
    a_tau = p.area_tau_s
    # Exponential smoothing with a time constant: the same weight per second at any rate.
    c_gain = 1.0 - np.exp(-dt / c_tau)
    a_gain = 1.0 - np.exp(-dt / a_tau)
    m = objs.shape[0]
    nq = qt.shape[1]
    # Every queue advances one slot; detections fill the newest one below.
    for i in range(n):
        for j in range(nq - 1):
            qt[i, j] = qt[i, j + 1]
            qz[i, j] = qz[i, j + 1]
        qt[i, nq - 1] = t_now
        qz[i, nq - 1] = np.nan
        t = tracks[i]
        t.missed += 1
    obj_row = np.full(m, -1, np.int64)
    restarted = np.zeros(n + m, np.bool_)
    offset = np.zeros(n + m)
    z_ref_of = np.full(n + m, np.nan)
    for k in range(rows.shape[0]):
        i = rows[k]
        c = cols[k]
        if cost[i, c] >= FORBIDDEN:  # the assignment had to pair it; the gates say no
            continue
        obj_row[c] = i
        t = tracks[i]
        o = objs[c]
        el = t_now - t.t_seen  # time since the last detection (s)
        thr = area_rate * el
        has_v = np.isfinite(t.v)
        v_old = t.v if has_v else 0.0
        p_depth = t.z_fit + v_old * el
        zo = o.z
        z_ok = np.isfinite(zo) and zo > 0
        z_new = zo if z_ok else t.depth
        # The core's depth change, chained on the previous depth: in the previous frame's
        # frame of reference, where the track's queue and prediction are.
        chained = z_ok and np.isfinite(dcore[c]) and np.isfinite(t.depth) and t.missed == 1
        # Areas compared at the track's fitted depth, not this frame's mean depth: the area
        # change of an approaching object is then not read as entering, and the biased mean
        # depth of a partly visible object does not hide its area change either.
        # Without a velocity the prediction is "still", wrong for anything moving fast: the
        # area is then compared at this frame's depth.
        z_ref = p_depth if (has_v and np.isfinite(p_depth)) else z_new
        z_ref_of[i] = z_ref
        area = o.area
        ma_new = area * z_ref * z_ref
        ma_old = t.area * t.z_fit * t.z_fit
        change = ma_new / ma_old - 1.0 if ma_old > 0 else np.nan
        ma_run = t.area_run
        jump = max(ma_new / ma_run, ma_run / ma_new) if ma_run > 0 and ma_new > 0 else np.nan
        prev = t.status
        status = VISIBLE
        # an object touching exactly one of two opposite borders can be entering or leaving
        # through it; one touching both (a wall, a floor) spans the view on that axis and cannot
        horiz = (o.x0 <= border) != (o.x1 >= width - border)
        vert = (o.y0 <= border) != (o.y1 >= height - border)
        if horiz or vert:
            # Entering or leaving needs the area AND the extent across the touched border to
            # change: a wall at the border whose area changes because something passes in
            # front of it keeps its extent and stays visible. Sizes compared at the fitted
            # depth, so that approaching is not read as entering.
            scale = z_ref / t.z_fit
            ew = (o.x1 - o.x0) / (t.x1 - t.x0) * scale - 1.0
            eh = (o.y1 - o.y0) / (t.y1 - t.y0) * scale - 1.0
            ext = max(ew if horiz else -np.inf, eh if vert else -np.inf)
            ext_min = min(ew if horiz else np.inf, eh if vert else np.inf)
            # Hysteresis: an object keeps entering (leaving) while its size does not reverse,
            # so a slow entry is not cut into entering/visible flicker.
            if (change > thr and ext > thr) or (prev == ENTERING and change >= 0 and ext >= 0):
                status = ENTERING
            elif (change < -thr and ext_min < -thr) or (prev == LEAVING and change <= 0 and ext_min <= 0):
                status = LEAVING
        # Partly hidden behind a nearer object while its visible area changes: the mean depth
        # of the visible part is biased, so the entry stays out of the fit (paper, case b).
        hidden = o.behind > 0 and abs(change) > thr
        # A whole object in plain view (inside the image, nothing nearer touching it, its size
        # as before, its depth read as before) shows all of itself in both frames, so its
        # depth change is its own, read over all its pixels. Its core is a part of it, moved
        # back by an image motion that an object growing or shrinking in the image (closing
        # fast) does not have: on `ball_rush` the core read -1.06 m/s where the mean depth
        # read -1.50 m/s, the truth.
        # Not under a moving camera, whose motion moves every pixel of the object: there the
        # mean depth of a segment whose outline the motion changes lost on 7-Scenes' posed
        # truth (within 25 % + 30 mm/s 0.85 -> 0.83).
        inside = o.x0 > border and o.y0 > border and o.x1 < width - border and o.y1 < height - border
        whole = (
            not np.isfinite(dstill[c]) and status == VISIBLE and inside
            and o.behind == 0 and not (jump > max_jump) and t.read_nearest == (o.read_nearest > 0)
        )  # fmt: skip
        if whole and chained:
            # the change the estimate's own-motion filter reads too (see the docstring)
            dcore[c] = zo - t.depth
        chained = chained and not whole
        zq = t.depth + dcore[c] if chained else zo
        valid = z_ok and (chained or (not (jump > max_jump) and (fit_border or status == VISIBLE) and not hidden))
        # Only a track with a velocity has a path to leave: a new track's prediction is "still",
        # and an object closing fast would otherwise restart its queue on every frame and never
        # get a velocity (issue 13: 0 of 21 frames at 1.5 m/s, 30 frames/s).
        restart = valid and has_v and np.isfinite(p_depth) and abs(zq - p_depth) > jump_rate * p_depth * el
        # The segment turned from a plain object into a compound or back (an oblique side
        # came into view or left it): its depth is now read another way (nearest part against
        # mean), so earlier entries measure another surface. Measured on `crossing`: the cart
        # read 500 mm/s on such a frame while standing still in depth.
        # A core reading does not depend on how the depth is read.
        read_nearest = o.read_nearest > 0
        restart = restart or (valid and not chained and t.read_nearest != read_nearest)
        restarted[i] = restart
        if restart:
            # The mean depth left the predicted path by more than any motion explains: the
            # segment now covers another surface (or the object jolted). Older entries no
            # longer describe the same thing, so the queue restarts from this one.
            for j in range(nq - 1):
                qz[i, j] = np.nan
            t.v = np.nan
        if valid:
            qz[i, nq - 1] = zq
            t.read_nearest = read_nearest
        if chained:
            off = zo - zq
            offset[i] = off
            for j in range(nq):
                qz[i, j] += off
            t.z_fit += off
        dcx = (o.cx - t.cx) / el
        dcy = (o.cy - t.cy) / el
        # While the visible area changes (partial occlusion, entering, leaving, a split) the
        # center of the visible part moves for reasons other than motion: keep the earlier
        # image velocity then, so that an object passing behind another is looked for where
        # it really goes.
        if abs(change) <= thr:
            if t.hits >= 2:
                t.vx += c_gain * (dcx - t.vx)
                t.vy += c_gain * (dcy - t.vy)
            else:
                t.vx = dcx
                t.vy = dcy
        if hidden:
            # The visible part of an object going behind (or coming out from behind) a nearer
            # one is off its centre, on the side that is still in view: it moves the other way
            # than the object, or not at all. The centre keeps its predicted path instead, so
            # that the object is looked for where it comes out (measured on `crossing`: the
            # cart's sliver came out 46 px from the sliver it went in as, 2 px beyond the gate).
            t.cx += t.vx * el
            t.cy += t.vy * el
        else:
            t.cx = o.cx
            t.cy = o.cy
        t.ox = o.cx
        t.oy = o.cy
        t.x0 = o.x0
        t.y0 = o.y0
        t.x1 = o.x1
        t.y1 = o.y1
        t.depth = z_new
        t.area = area
        # The running area follows entering/leaving objects at once (their area change is
        # real), others slowly so that a one-frame split or merge stands out.
        if status != VISIBLE or not ma_run > 0:
            t.area_run = ma_new
        else:
            t.area_run = ma_run + a_gain * (ma_new - ma_run)
        if restart:  # sizes are compared at the new depth from now on
            t.area_run = area * zo * zo
        t.label = int(o.label)
        t.status = status
        t.hits += 1
        t.missed = 0
        t.t_seen = t_now
    # Unmatched objects start tracks.
    nn = n
    for c in range(m):
        if obj_row[c] >= 0:
            continue
        i = nn
        nn += 1
        obj_row[c] = i
        t = tracks[i]
        o = objs[c]
        zo = o.z
        z_ok = np.isfinite(zo) and zo > 0
        horiz = (o.x0 <= border) != (o.x1 >= width - border)
        vert = (o.y0 <= border) != (o.y1 >= height - border)
        status = ENTERING if (not first and (horiz or vert)) else VISIBLE
        t.id = next_id + (i - n)
        restarted[i] = True
        t.hits = 1
        t.missed = 0
        t.status = status
        t.cx = o.cx
        t.cy = o.cy
        t.ox = o.cx
        t.oy = o.cy
        t.vx = 0.0
        t.vy = 0.0
        t.x0 = o.x0
        t.y0 = o.y0
        t.x1 = o.x1
        t.y1 = o.y1
        z0 = zo if z_ok else np.nan
        t.depth = z0
        t.z_fit = z0
        t.area = o.area
        t.area_run = o.area * z0 * z0
        t.label = int(o.label)
        t.v = np.nan
        t.read_nearest = o.read_nearest > 0
        t.t_seen = t_now
        for j in range(nq):
            qt[i, j] = np.nan
            qz[i, j] = np.nan
        qt[i, nq - 1] = t_now
        if z_ok and (fit_border or status == VISIBLE):
            qz[i, nq - 1] = zo
    # Range flow of every track.
    v_out = np.empty(nn)
    ttc = np.empty(nn)
    dead = np.zeros(nn, np.bool_)
    for i in range(nn):
        t = tracks[i]
        v, z_now = fit_row(qt[i], qz[i], t_now)
        if np.isfinite(v):
            t.v = v
        if t.missed == 0:
            if np.isfinite(z_now):
                t.z_fit = z_now
            elif np.isfinite(z_ref_of[i]):
                t.z_fit = z_ref_of[i]
            z_pred = t.z_fit
            # Back from an occlusion with one fresh entry: the velocity held through the gap
            # (a restart clears it, so a jump never carries an old velocity over).
            vo = v if np.isfinite(v) else t.v
        else:
            # Occluded tracks coast on their held velocity.
            vo = t.v
            z_pred = t.z_fit + (vo if np.isfinite(vo) else 0.0) * (t_now - t.t_seen)
            t.status = OCCLUDED
            el = t_now - t.t_seen
            # Out of the frame budget, a track whose predicted place lies behind a nearer object
            # stays while its occlusion lasts, up to max_occluded_s: an object that passes
            # behind another comes out again, one that left the view or the scene does not.
            # A track last seen at the image's border may have left the view: no extension.
            kept = (
                t.x0 > border and t.y0 > border and t.x1 < width - border and t.y1 < height - border
                and el <= max_occluded_s
            )  # fmt: skip
            if kept:
                # its box moved by its image velocity meets an object nearer by more than 5 %
                # of depth (boxes within 1 px, as mark_behind); without a depth, nothing
                dx, dy = t.vx * el, t.vy * el
                x0, y0, x1, y1 = t.x0 + dx, t.y0 + dy, t.x1 + dx, t.y1 + dy
                kept = False
                for j in range(objs.shape[0]):
                    ob = objs[j]
                    if ob.z < 0.95 * z_pred and x0 <= ob.x1 and ob.x0 <= x1 and y0 <= ob.y1 and ob.y0 <= y1:
                        kept = True
                        break
            dead[i] = t.hits < min_hits or (t.missed > max_missed and not kept)
        v_out[i] = vo
        ttc[i] = z_pred / -vo if (vo < -min_speed and z_pred > 0) else np.nan
    return obj_row, v_out, ttc, dead, restarted[:nn], nn - n, offset[:nn]


@njit(cache=True)
def keep_tracks(
    tracks: NDArray[np.void], qt: NDArray[np.float64], qz: NDArray[np.float64], n: int, keep: NDArray[np.bool_]
) -> int:
    """Move the first ``n`` tracks where ``keep`` is True, with their queues, to the front in order.

    Returns how many were kept. Compiled because numpy copies records field by field: 27 µs for
    a hundred tracks, more than the whole step.
    """
    k = 0
    for i in range(n):
        if keep[i]:
            if k != i:
                tracks[k] = tracks[i]
                qt[k, :] = qt[i, :]
                qz[k, :] = qz[i, :]
            k += 1
    return k
