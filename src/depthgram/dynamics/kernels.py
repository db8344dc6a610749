"""Compiled kernels of the tracker: the velocity fit, the matching cost, the per-frame step.

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

    Its value is the code in the state table's ``STATUS`` column and its lower-case name the
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
    max_depth_jump_rate: float  # inf with the Kalman filter, which gates jumps itself
    center_tau_s: float
    area_tau_s: float


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


@njit(cache=True)
def fit_rows(
    t: NDArray[np.float64], z: NDArray[np.float64], t_now: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return the slope and fitted depth at ``t_now`` of every row's queue (see :func:`fit_row`)."""
    v = np.empty(t.shape[0])
    zn = np.empty(t.shape[0])
    for i in range(t.shape[0]):
        v[i], zn[i] = fit_row(t[i], z[i], t_now[i])
    return v, zn


@njit(cache=True)
def cost_kernel(
    tc: NDArray[np.float64],
    tc_seen: NDArray[np.float64],
    tz: NDArray[np.float64],
    ta: NDArray[np.float64],
    tb: NDArray[np.float64],
    tl: NDArray[np.float64],
    te: NDArray[np.float64],
    oc: NDArray[np.float64],
    oz: NDArray[np.float64],
    oa: NDArray[np.float64],
    ob: NDArray[np.float64],
    ol: NDArray[np.float64],
    diagonal_px: float,
    dt: float,
    params: CostParams,
) -> NDArray[np.float64]:
    """Compiled body of :func:`match_cost`; ``params`` from :func:`cost_params`.

    ``te`` is each track's time since its last detection and ``dt`` this frame's step (s):
    the gates are rates, so they admit the same physical motion at any frame rate. ``tc_seen``
    is the predicted centre of the part last seen, which differs from ``tc`` while an object
    is partly hidden; the nearer of the two counts.

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
    nt = tc.shape[0]
    no = oc.shape[0]
    cost = np.empty((nt, no))
    for i in range(nt):
        r = center_rate * dt * diagonal_px * (1.0 + growth * max(te[i] - dt, 0.0))
        zg = tz[i] * dz_rate * max(te[i], dt)
        area_t = max(ta[i], 1.0)
        bt_area = (tb[i, 2] - tb[i, 0]) * (tb[i, 3] - tb[i, 1])
        for j in range(no):
            cost[i, j] = FORBIDDEN
            # Cheapest gates first: most pairs are far apart and need no log or sqrt.
            dx = tc[i, 0] - oc[j, 0]
            dy = tc[i, 1] - oc[j, 1]
            sx = tc_seen[i, 0] - oc[j, 0]
            sy = tc_seen[i, 1] - oc[j, 1]
            d2 = min(dx * dx + dy * dy, sx * sx + sy * sy)
            if not d2 <= r * r:
                continue
            dz = abs(oz[j] - tz[i]) / zg
            # NaN depth (no valid pixel) fails the depth gate: comparisons with NaN are False.
            if not dz <= 1.0:
                continue
            da = abs(np.log(max(oa[j], 1.0) / area_t)) / log_ratio
            if not da <= 1.0:
                continue
            ix = min(tb[i, 2], ob[j, 2]) - max(tb[i, 0], ob[j, 0])
            iy = min(tb[i, 3], ob[j, 3]) - max(tb[i, 1], ob[j, 1])
            inter = max(ix, 0.0) * max(iy, 0.0)
            bo_area = (ob[j, 2] - ob[j, 0]) * (ob[j, 3] - ob[j, 1])
            iou = inter / max(bt_area + bo_area - inter, 1.0)
            if iou < min_iou:
                continue
            c = w_c * np.sqrt(d2) / r + w_z * dz + w_a * da + w_iou * (1.0 - iou)
            if tl[i] != ol[j]:
                c += w_label
            cost[i, j] = c
    return cost


# The track state table: one row per live track, these columns. This module owns them (the
# kernels below and depthgram.dynamics.tracker index by these names only); numba's cache
# is per source file, so they live here rather than in a module the kernels would import.
ID = 0  # track id, from 1
HITS = 1  # frames with a detection
MISSED = 2  # frames since the last detection (0: detected this frame)
STATUS = 3  # a Status code
CX, CY = 4, 5  # centre of the object as last detected (px)
VX, VY = 6, 7  # smoothed image velocity of the centre (px/s)
X0, Y0, X1, Y1 = 8, 9, 10, 11  # bbox as last detected, half-open (px)
DEPTH = 12  # depth as last read (mm; see tracker.track_depth)
ZFIT = 13  # fitted depth at the last detection (mm)
AREA = 14  # area as last detected (px)
MAREA = 15  # running depth-compensated area A z^2 (px mm^2), against which splits are judged
LABEL = 16  # depth label as last detected
V = 17  # radial velocity of the queue fit (mm/s; NaN: none yet)
READ = 18  # how the depth was read: 0 mean depth, 1 nearest part of a compound (F_READ)
TSEEN = 19  # time of the last detection (s)
OX, OY = 20, 21  # centre of the part last seen (px); CX, CY while the whole object was in view
NCOL = 22

# Columns of the per-object feature array; F_READ says how its depth was read (0: mean depth,
# 1: nearest part of a compound), see depthgram.dynamics.tracker.track_depth.
F_CX, F_CY, F_Z, F_AREA, F_LABEL, F_X0, F_BEHIND, F_READ = 0, 1, 2, 3, 4, 5, 9, 10
NFEAT = 11


@njit(cache=True)
def mark_behind(f: NDArray[np.float64]) -> None:
    """Set column ``F_BEHIND`` of each object that a nearer object touches or overlaps.

    Boxes within 1 px count as touching, and nearer means by more than 5 % of depth. A loop over
    pairs: a dozen numpy expressions on 30 x 30 pairs cost more in call overhead than the whole
    comparison.
    """
    m = f.shape[0]
    for j in range(m):
        f[j, F_BEHIND] = 0.0
        for i in range(m):
            if i == j or not f[i, F_Z] < 0.95 * f[j, F_Z]:
                continue
            # half-open boxes: x0 <= other x1 means overlapping or adjacent
            if (
                f[j, F_X0] <= f[i, F_X0 + 2]
                and f[i, F_X0] <= f[j, F_X0 + 2]
                and f[j, F_X0 + 1] <= f[i, F_X0 + 3]
                and f[i, F_X0 + 1] <= f[j, F_X0 + 3]
            ):
                f[j, F_BEHIND] = 1.0
                break


@njit(cache=True)
def predict_cost(
    s: NDArray[np.float64],
    n: int,
    f: NDArray[np.float64],
    diagonal_px: float,
    t_now: float,
    dt: float,
    p: CostParams,
) -> NDArray[np.float64]:
    """Predict each track forward by the time since its last detection, then cost all pairs."""
    pc = np.empty((n, 2))
    po = np.empty((n, 2))
    pb = np.empty((n, 4))
    pz = np.empty(n)
    te = np.empty(n)
    for i in range(n):
        el = t_now - s[i, TSEEN]
        te[i] = el
        dx = s[i, VX] * el
        dy = s[i, VY] * el
        pc[i, 0] = s[i, CX] + dx
        pc[i, 1] = s[i, CY] + dy
        po[i, 0] = s[i, OX] + dx
        po[i, 1] = s[i, OY] + dy
        pb[i, 0] = s[i, X0] + dx
        pb[i, 1] = s[i, Y0] + dy
        pb[i, 2] = s[i, X1] + dx
        pb[i, 3] = s[i, Y1] + dy
        if s[i, STATUS] == ENTERING or s[i, STATUS] == LEAVING:
            # The fit skips border frames, so it is stale there, while the mean depth of the
            # visible part drifts as the object crosses the border (a cylinder's flank is
            # deeper than its middle): the last observed depth is the better guess.
            pz[i] = s[i, DEPTH]
        else:
            v = s[i, V] if np.isfinite(s[i, V]) else 0.0
            pz[i] = s[i, ZFIT] + v * el
    return cost_kernel(
        pc, po, pz, s[:n, AREA], pb, s[:n, LABEL], te,
        f[:, 0:2], f[:, F_Z], f[:, F_AREA], f[:, F_X0 : F_X0 + 4], f[:, F_LABEL], diagonal_px, dt, p,
    )  # fmt: skip


@njit(cache=True)
def _crossing_axes(f: NDArray[np.float64], j: int, b: float, width: float, height: float) -> tuple[bool, bool]:
    """Whether object ``j`` can be crossing the left/right and the top/bottom border.

    An object touching exactly one of two opposite borders can be entering or leaving
    through it; one touching both (a wall, a floor) spans the view on that axis and cannot.
    """
    x0, y0, x1, y1 = f[j, F_X0], f[j, F_X0 + 1], f[j, F_X0 + 2], f[j, F_X0 + 3]
    return (x0 <= b) != (x1 >= width - b), (y0 <= b) != (y1 >= height - b)


@njit(cache=True)
def step(
    s: NDArray[np.float64],
    qt: NDArray[np.float64],
    qz: NDArray[np.float64],
    n: int,
    f: NDArray[np.float64],
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
) -> tuple[
    NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], int,
    NDArray[np.float64],
]:  # fmt: skip
    """Advance every track by one frame, in place; new tracks go to rows ``n..``.

    This is the project's own bookkeeping (queues, statuses, split/merge and border tests),
    hand-written in one compiled pass because it runs every frame on a few dozen rows.
    ``p`` holds the settings (:func:`depthgram.dynamics.tracker.step_params`).
    ``dt`` is this frame's time step (s): every rate and time constant is
    scaled by it, so the tracker behaves alike at any frame rate.

    ``dcore`` is each object's depth change over its core since the previous frame (mm, NaN
    where unknown; :func:`depthgram.dynamics.core.core_depth_change`). Where it is known, the
    queue's new entry is the previous depth plus that change, and the whole queue is then
    moved by a constant so that its newest entry is this frame's depth: the slope follows the
    core, the depth stays the object's.

    Returns the track row of each object, the reported velocity and time to collision of
    every row, which rows die this frame, which rows restarted their queue (new tracks too),
    the number of new tracks, and the constant each row's depths were moved by (mm).
    """
    border = p.border_px
    area_rate = p.border_area_rate
    max_jump = p.max_area_jump
    fit_border = p.fit_border_entries
    min_speed = p.min_speed
    min_hits = p.min_hits
    max_missed = p.max_missed
    jump_rate = p.max_depth_jump_rate
    c_tau = p.center_tau_s
    a_tau = p.area_tau_s
    # Exponential smoothing with a time constant: the same weight per second at any rate.
    c_gain = 1.0 - np.exp(-dt / c_tau)
    a_gain = 1.0 - np.exp(-dt / a_tau)
    m = f.shape[0]
    nq = qt.shape[1]
    # Every queue advances one slot; detections fill the newest one below.
    for i in range(n):
        for j in range(nq - 1):
            qt[i, j] = qt[i, j + 1]
            qz[i, j] = qz[i, j + 1]
        qt[i, nq - 1] = t_now
        qz[i, nq - 1] = np.nan
        s[i, MISSED] += 1.0
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
        el = t_now - s[i, TSEEN]  # time since the last detection (s)
        thr = area_rate * el
        has_v = np.isfinite(s[i, V])
        v_old = s[i, V] if has_v else 0.0
        p_depth = s[i, ZFIT] + v_old * el
        zo = f[c, F_Z]
        z_ok = np.isfinite(zo) and zo > 0
        z_new = zo if z_ok else s[i, DEPTH]
        # The core's depth change, chained on the previous depth: in the previous frame's
        # frame of reference, where the track's queue and prediction are.
        chained = z_ok and np.isfinite(dcore[c]) and np.isfinite(s[i, DEPTH]) and s[i, MISSED] == 1
        zq = s[i, DEPTH] + dcore[c] if chained else zo
        # Areas compared at the track's fitted depth, not this frame's mean depth: the area
        # change of an approaching object is then not read as entering, and the biased mean
        # depth of a partly visible object does not hide its area change either.
        # Without a velocity the prediction is "still", wrong for anything moving fast: the
        # area is then compared at this frame's depth.
        z_ref = p_depth if (has_v and np.isfinite(p_depth)) else z_new
        z_ref_of[i] = z_ref
        area = f[c, F_AREA]
        ma_new = area * z_ref * z_ref
        ma_old = s[i, AREA] * s[i, ZFIT] * s[i, ZFIT]
        change = ma_new / ma_old - 1.0 if ma_old > 0 else np.nan
        ma_run = s[i, MAREA]
        jump = max(ma_new / ma_run, ma_run / ma_new) if ma_run > 0 and ma_new > 0 else np.nan
        prev = s[i, STATUS]
        status = VISIBLE
        horiz, vert = _crossing_axes(f, c, border, width, height)
        if horiz or vert:
            # Entering or leaving needs the area AND the extent across the touched border to
            # change: a wall at the border whose area changes because something passes in
            # front of it keeps its extent and stays visible. Sizes compared at the fitted
            # depth, so that approaching is not read as entering.
            scale = z_ref / s[i, ZFIT]
            ew = (f[c, F_X0 + 2] - f[c, F_X0]) / (s[i, X1] - s[i, X0]) * scale - 1.0
            eh = (f[c, F_X0 + 3] - f[c, F_X0 + 1]) / (s[i, Y1] - s[i, Y0]) * scale - 1.0
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
        hidden = f[c, F_BEHIND] > 0 and abs(change) > thr
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
        restart = restart or (valid and not chained and s[i, READ] != f[c, F_READ])
        restarted[i] = restart
        if restart:
            # The mean depth left the predicted path by more than any motion explains: the
            # segment now covers another surface (or the object jolted). Older entries no
            # longer describe the same thing, so the queue restarts from this one.
            for j in range(nq - 1):
                qz[i, j] = np.nan
            s[i, V] = np.nan
        if valid:
            qz[i, nq - 1] = zq
            s[i, READ] = f[c, F_READ]
        if chained:
            off = zo - zq
            offset[i] = off
            for j in range(nq):
                qz[i, j] += off
            s[i, ZFIT] += off
        dcx = (f[c, F_CX] - s[i, CX]) / el
        dcy = (f[c, F_CY] - s[i, CY]) / el
        # While the visible area changes (partial occlusion, entering, leaving, a split) the
        # center of the visible part moves for reasons other than motion: keep the earlier
        # image velocity then, so that an object passing behind another is looked for where
        # it really goes.
        if abs(change) <= thr:
            if s[i, HITS] >= 2:
                s[i, VX] += c_gain * (dcx - s[i, VX])
                s[i, VY] += c_gain * (dcy - s[i, VY])
            else:
                s[i, VX] = dcx
                s[i, VY] = dcy
        if hidden:
            # The visible part of an object going behind (or coming out from behind) a nearer
            # one is off its centre, on the side that is still in view: it moves the other way
            # than the object, or not at all. The centre keeps its predicted path instead, so
            # that the object is looked for where it comes out (measured on `crossing`: the
            # cart's sliver came out 46 px from the sliver it went in as, 2 px beyond the gate).
            s[i, CX] += s[i, VX] * el
            s[i, CY] += s[i, VY] * el
        else:
            s[i, CX] = f[c, F_CX]
            s[i, CY] = f[c, F_CY]
        s[i, OX] = f[c, F_CX]
        s[i, OY] = f[c, F_CY]
        for q in range(4):
            s[i, X0 + q] = f[c, F_X0 + q]
        s[i, DEPTH] = z_new
        s[i, AREA] = area
        # The running area follows entering/leaving objects at once (their area change is
        # real), others slowly so that a one-frame split or merge stands out.
        if status != VISIBLE or not ma_run > 0:
            s[i, MAREA] = ma_new
        else:
            s[i, MAREA] = ma_run + a_gain * (ma_new - ma_run)
        if restart:  # sizes are compared at the new depth from now on
            s[i, MAREA] = area * zo * zo
        s[i, LABEL] = f[c, F_LABEL]
        s[i, STATUS] = status
        s[i, HITS] += 1.0
        s[i, MISSED] = 0.0
        s[i, TSEEN] = t_now
    # Unmatched objects start tracks.
    nn = n
    for c in range(m):
        if obj_row[c] >= 0:
            continue
        i = nn
        nn += 1
        obj_row[c] = i
        zo = f[c, F_Z]
        z_ok = np.isfinite(zo) and zo > 0
        horiz, vert = _crossing_axes(f, c, border, width, height)
        status = ENTERING if (not first and (horiz or vert)) else VISIBLE
        s[i, ID] = next_id + (i - n)
        restarted[i] = True
        s[i, HITS] = 1.0
        s[i, MISSED] = 0.0
        s[i, STATUS] = status
        s[i, CX] = f[c, F_CX]
        s[i, CY] = f[c, F_CY]
        s[i, OX] = f[c, F_CX]
        s[i, OY] = f[c, F_CY]
        s[i, VX] = 0.0
        s[i, VY] = 0.0
        for q in range(4):
            s[i, X0 + q] = f[c, F_X0 + q]
        z0 = zo if z_ok else np.nan
        s[i, DEPTH] = z0
        s[i, ZFIT] = z0
        s[i, AREA] = f[c, F_AREA]
        s[i, MAREA] = f[c, F_AREA] * z0 * z0
        s[i, LABEL] = f[c, F_LABEL]
        s[i, V] = np.nan
        s[i, READ] = f[c, F_READ]
        s[i, TSEEN] = t_now
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
        v, z_now = fit_row(qt[i], qz[i], t_now)
        if np.isfinite(v):
            s[i, V] = v
        if s[i, MISSED] == 0:
            if np.isfinite(z_now):
                s[i, ZFIT] = z_now
            elif np.isfinite(z_ref_of[i]):
                s[i, ZFIT] = z_ref_of[i]
            z_pred = s[i, ZFIT]
            # Back from an occlusion with one fresh entry: the velocity held through the gap
            # (a restart clears it, so a jump never carries an old velocity over).
            vo = v if np.isfinite(v) else s[i, V]
        else:
            # Occluded tracks coast on their held velocity.
            vo = s[i, V]
            z_pred = s[i, ZFIT] + (vo if np.isfinite(vo) else 0.0) * (t_now - s[i, TSEEN])
            s[i, STATUS] = OCCLUDED
            dead[i] = s[i, HITS] < min_hits or s[i, MISSED] > max_missed
        v_out[i] = vo
        ttc[i] = z_pred / -vo if (vo < -min_speed and z_pred > 0) else np.nan
    return obj_row, v_out, ttc, dead, restarted[:nn], nn - n, offset[:nn]


@njit(cache=True)
def estimate(
    s: NDArray[np.float64],
    qt: NDArray[np.float64],
    qz: NDArray[np.float64],
    n: int,
    restarted: NDArray[np.bool_],
    v_queue: NDArray[np.float64],
    ttc_queue: NDArray[np.float64],
    kx: NDArray[np.float64],
    kp: NDArray[np.float64],
    kn: NDArray[np.int64],
    krej: NDArray[np.int64],
    dt: float,
    p: EstimateParams,
    offset: NDArray[np.float64],
    core_dz: NDArray[np.float64],
    still_dz: NDArray[np.float64],
    kw: NDArray[np.float64],
    kwp: NDArray[np.float64],
    kwrej: NDArray[np.int64],
    kwnis: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Radial velocity, time to collision and v_sigma of every live row (mm/s, s, mm/s).

    ``p`` holds the settings (:func:`depthgram.dynamics.tracker.estimate_params`): the Kalman
    filter or the queue's slope, the sensor noise, the process noise, the gates.
    Rows ``n..`` are new tracks. One compiled pass: the same steps in numpy cost some forty
    array expressions per frame, more than the arithmetic on a few dozen rows.

    ``queue``: the kernel's slope, with the standard error that slope has under the sensor
    noise model. ``kalman``: a constant-velocity filter on depth and radial velocity, predicted
    over ``dt`` for every track (occluded ones coast) and updated with each valid depth reading
    within ``innovation_gate`` standard deviations of its prediction; three outliers in a row
    restart it there. Either way a time to collision needs a closing speed of at least
    ``ttc_min_sigmas`` v_sigma. ``offset`` moves each row's filter depth along with its queue
    (see :func:`step`).

    With the camera's own motion known (``kalman`` only): ``still_dz`` is the depth change
    (mm) each detected row would show since the previous frame if it stood still, ``core_dz``
    the change its core shows (mm; NaN where unknown). The radial velocity is then
    ``still_dz / dt`` plus the object's own velocity ``kw`` (mm/s, variance ``kwp``), filtered
    from ``(core_dz - still_dz) / dt`` as a random walk with the same innovation gate
    (``kwrej`` outliers in a row; NaN ``kw``: not started). Its process noise is
    ``own_accel_sigma`` while the readings fit it, and grows up to ``accel_sigma`` with the
    running mean ``kwnis`` of the normalised squared innovations where they do not (an
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
    nn = kx.shape[0]
    nq = qz.shape[1]
    v_out = np.full(nn, np.nan)
    ttc = np.full(nn, np.nan)
    sig = np.full(nn, np.nan)
    q = accel * accel
    for i in range(nn):
        z_new = qz[i, nq - 1]
        meas = s[i, MISSED] == 0 and np.isfinite(z_new)
        zr = z_new if np.isfinite(z_new) else s[i, ZFIT]
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
                kn[i] = 0
                krej[i] = 0
                kx[i, 0] = np.nan
                kx[i, 1] = np.nan
            else:
                kx[i, 0] += dt * kx[i, 1] + offset[i]
                p00, p01, p11 = kp[i, 0, 0], kp[i, 0, 1], kp[i, 1, 1]
                kp[i, 0, 0] = p00 + 2 * dt * p01 + dt * dt * p11 + q * dt**4 / 4
                kp[i, 0, 1] = p01 + dt * p11 + q * dt**3 / 2
                kp[i, 1, 0] = kp[i, 0, 1]
                kp[i, 1, 1] = p11 + q * dt * dt
            if meas:
                start = restarted[i] or kn[i] == 0
                if not start:
                    sv = kp[i, 0, 0] + r
                    y = z_new - kx[i, 0]
                    if y * y > gate_k * gate_k * sv:
                        krej[i] += 1
                        start = krej[i] >= 3  # three outliers in a row: the object did change
                    else:
                        krej[i] = 0
                        k0 = kp[i, 0, 0] / sv
                        k1 = kp[i, 1, 0] / sv
                        kx[i, 0] += k0 * y
                        kx[i, 1] += k1 * y
                        p00, p01, p11 = kp[i, 0, 0], kp[i, 0, 1], kp[i, 1, 1]
                        kp[i, 0, 0] = (1 - k0) * p00
                        kp[i, 0, 1] = (1 - k0) * p01
                        kp[i, 1, 0] = kp[i, 0, 1]
                        kp[i, 1, 1] = p11 - k1 * p01
                        kn[i] += 1
                if start:
                    kx[i, 0] = z_new
                    kx[i, 1] = 0.0
                    kp[i, 0, 0] = r
                    kp[i, 0, 1] = 0.0
                    kp[i, 1, 0] = 0.0
                    kp[i, 1, 1] = v_sigma0 * v_sigma0
                    kn[i] = 1
                    krej[i] = 0
            if i >= n:
                kw[i] = np.nan
                kwp[i] = 0.0
                kwrej[i] = 0
            elif np.isfinite(kw[i]):
                if s[i, STATUS] == ENTERING or s[i, STATUS] == LEAVING:
                    # the visible part changes at the image's edge: its readings change for
                    # reasons the own motion does not model (the simulator's cart entering)
                    kwnis[i] = nis_max
                kwp[i] += qw * qw * min(max(kwnis[i], 1.0), nis_max)
            if s[i, MISSED] == 0 and np.isfinite(still_dz[i]):
                if not np.isfinite(kw[i]):
                    # most of what a camera sees stands still: no own motion until read
                    kw[i] = 0.0
                    kwp[i] = w_sigma0 * w_sigma0
                    kwrej[i] = 0
                    # a new track's own motion is not known yet: it starts fast and settles
                    # as its readings agree (about six readings)
                    kwnis[i] = nis_max
                if np.isfinite(core_dz[i]):
                    y0 = (core_dz[i] - still_dz[i]) / dt
                    rw = r / (dt * dt)
                    y = y0 - kw[i]
                    sw = kwp[i] + rw
                    # a running mean over about three readings; one outlier counts as 25 at most
                    kwnis[i] += 0.3 * (min(y * y / sw, 25.0) - kwnis[i])
                    if y * y <= gate_k * gate_k * sw:
                        gain = kwp[i] / sw
                        kw[i] += gain * y
                        kwp[i] *= 1.0 - gain
                        kwrej[i] = 0
                    else:
                        kwrej[i] += 1
                        if kwrej[i] >= 3:
                            kw[i] = y0
                            kwp[i] = rw
                            kwrej[i] = 0
                # Most of what a camera sees stands still: the own part counts once it is
                # significant (on 7-Scenes within 25 % + 30 mm/s: 0.80 always, 0.85 so).
                own = kw[i] if abs(kw[i]) > own_k * np.sqrt(kwp[i]) else 0.0
                kx[i, 1] = still_dz[i] / dt + own
                kp[i, 0, 1] = 0.0
                kp[i, 1, 0] = 0.0
                kp[i, 1, 1] = kwp[i]
            if kn[i] >= 2:
                v_out[i] = kx[i, 1]
                sig[i] = np.sqrt(kp[i, 1, 1])
                if v_out[i] < -min_speed and kx[i, 0] > 0:
                    ttc[i] = kx[i, 0] / -v_out[i]
        if not -v_out[i] >= ttc_k * sig[i]:
            ttc[i] = np.nan
    return v_out, ttc, sig
