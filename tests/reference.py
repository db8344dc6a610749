"""Plain reference implementations that only the tests call.

Each is the straightforward route (numpy, or the package's kernels composed the simple way)
that a fused or compiled step of the package replaced; the tests hold the package to them.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation._kernels.ransac import assign_planes, inliers_counted
from depthgram.segmentation.attributes import Stats, label_stats
from depthgram.segmentation.coplanar import coplanar_groups, near_planes
from depthgram.segmentation.label import ACTIVE, BLOCK, HOLE, label_keyed, relabel
from depthgram.segmentation.label.stats import N_COLUMNS, flush_run
from depthgram.segmentation.orientation import _col_edges_into, _one_sided_col, _one_sided_row, _row_edges_into
from depthgram.segmentation.plane_sums import plane_sums, planes_from_sums
from depthgram.segmentation.ransac import Plane, plane_residual_mask

__all__ = [
    "_jumps",
    "_jumps_cols",
    "_one_sided",
    "_one_sided_cols",
    "best_contact_numpy",
    "best_hypothesis_in_index_order",
    "grid_first_reading",
    "label_stats_bincount",
    "large_pieces_opencv",
    "merge_coplanar",
    "on_support_planes",
    "plane_fits",
    "plane_search_numpy",
    "planes_from_sums_numpy",
    "refine_per_pixel",
    "relabel_small",
    "sensor_ranges",
    "sensor_samples",
    "support_components",
]


def support_components(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    *,
    jump_rel: float,
    bridge: int,
) -> tuple[NDArray[np.int32], int]:
    """Depth-continuous components of the pixels of one orientation class."""
    state = np.where(valid, np.int8(BLOCK), np.int8(HOLE))
    state[classes == cls] = ACTIVE
    return label_keyed(depth_mm, state, tol=0.0, rel=jump_rel, bridge=bridge)


def plane_fits(
    labels: NDArray[np.int32], n: int, depth_mm: NDArray[np.float32], cam: Intrinsics
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Least-squares plane of each label: unit normal toward the sensor, offset (mm), pixel count.

    Inverse depth is exactly affine in the normalised image coordinates for a plane
    (``1/Z = (n . ray) / d``), so the fit is linear: ``1/Z = alpha u' + beta v' + gamma`` from
    one compiled pass of sums, then ``n = -(alpha, beta, gamma) / |.|`` and ``d = 1 / |.|``.
    """
    sums = plane_sums(labels, n, depth_mm, cam.fx, cam.fy, cam.cx, cam.cy)
    return planes_from_sums(sums)


def merge_coplanar(
    labels: NDArray[np.int32],
    n: int,
    depth_mm: NDArray[np.float32],
    cam: Intrinsics,
    *,
    max_angle_deg: float = 10.0,
    max_offset_rel: float = 0.08,
    min_fit_px: int = 1,
) -> tuple[NDArray[np.int32], int]:
    """Join pieces of one plane cut apart by occluders (the floor between two boxes).

    Pieces join when their fitted normals (:func:`plane_fits`) agree within ``max_angle_deg``
    and their plane offsets within ``max_offset_rel``. Pieces under ``min_fit_px`` pixels are
    left alone: a few rows give no reliable plane (a cup's rim would join the table top).
    """
    if n < 2:
        return labels, n
    normal, off, count = plane_fits(labels, n, depth_mm, cam)
    lut, m = coplanar_groups(
        normal, off, count, max_angle_deg=max_angle_deg, max_offset_rel=max_offset_rel, min_fit_px=min_fit_px
    )
    if m == n:
        return labels, n
    return relabel(labels, lut), m


def on_support_planes(
    labels: NDArray[np.int32],
    n: int,
    depth_mm: NDArray[np.float32],
    candidates: NDArray[np.bool_],
    cam: Intrinsics,
    *,
    min_px: int,
    tol_rel: float,
) -> NDArray[np.bool_]:
    """Candidate pixels whose depth lies on the fitted plane of a support of >= ``min_px`` pixels.

    Only pixels inside the support's bounding box (grown by a tenth) are tested, so a far
    object that happens to lie on the plane's extension elsewhere is not taken.
    """
    out = np.zeros(labels.shape, bool)
    if n == 0 or not candidates.any():
        return out
    normal, off, _ = plane_fits(labels, n, depth_mm, cam)
    st = label_stats(labels, depth_mm, n)
    assert st.boxes is not None
    return near_planes(normal, off, st.count, st.boxes, depth_mm, candidates, cam, min_px=min_px, tol_rel=tol_rel)


def label_stats_bincount(
    labels: NDArray[np.int32], depth_mm: NDArray[np.floating], n: int, *, metric: bool = False
) -> Stats:
    """The same sums with weighted ``np.bincount`` passes (reference; about 3x slower at 640 x 480)."""
    flat = labels.ravel()
    idx = np.flatnonzero(flat)
    lab = flat[idx]
    z = depth_mm.ravel()[idx].astype(np.float64)
    ys, xs = np.divmod(idx, labels.shape[1])
    m = n + 1
    count = np.bincount(lab, minlength=m).astype(np.float64)
    sz = np.bincount(lab, weights=z, minlength=m)
    szz = np.bincount(lab, weights=z * z, minlength=m)
    sx = np.bincount(lab, weights=xs, minlength=m)
    sy = np.bincount(lab, weights=ys, minlength=m)
    sxz = np.bincount(lab, weights=xs * z, minlength=m) if metric else None
    syz = np.bincount(lab, weights=ys * z, minlength=m) if metric else None
    return Stats(count, sz, szz, sx, sy, sxz, syz)


def relabel_small(labels: NDArray[np.int32], count: NDArray[np.float64], min_px: int) -> NDArray[np.int32]:
    """Drop labels with fewer than ``min_px`` pixels and renumber the rest 1..k in order."""
    keep = count >= min_px
    keep[0] = False
    lut = np.zeros(count.size, dtype=np.int32)
    lut[keep] = np.arange(1, int(keep.sum()) + 1, dtype=np.int32)
    out: NDArray[np.int32] = lut[labels]
    return out


def large_pieces_opencv(mask: NDArray[np.bool_], min_px: int) -> NDArray[np.bool_]:
    """Pixels of the 8-connected pieces of ``mask`` of at least ``min_px`` pixels, by OpenCV."""
    _, lab, stats, _ = cv2.connectedComponentsWithStats(mask.view(np.uint8), connectivity=8)
    keep = stats[:, cv2.CC_STAT_AREA] >= min_px
    keep[0] = False
    out: NDArray[np.bool_] = keep[lab]
    return out


def _fit(u: NDArray[np.float64], v: NDArray[np.float64], inv: NDArray[np.float64]) -> tuple[float, float, float]:
    a = np.stack([u, v, np.ones_like(u)], axis=1)
    coef = np.linalg.lstsq(a, inv, rcond=None)[0]
    return float(coef[0]), float(coef[1]), float(coef[2])


def plane_search_numpy(
    depth_mm: NDArray[np.float32],
    valid: NDArray[np.bool_],
    *,
    min_area: float = 0.08,
    min_spread: float = 0.15,
    tol_mm: float = 8.0,
    tol_rel: float = 0.012,
    max_planes: int = 3,
    hypotheses: int = 128,
    seed: int = 0,
    search: NDArray[np.bool_] | None = None,
) -> list[Plane]:
    """:func:`depthgram.segmentation.planes.find_planes` with its RANSAC search in numpy.

    LU determinants, every hypothesis scored by broadcasting, numpy masks on the search grid;
    the full-resolution assignment is the package's.
    """
    h, w = depth_mm.shape
    min_px = max(int(min_area * h * w), 3)
    s = max(1, round(math.sqrt(h * w / 3000.0)))
    rng = np.random.default_rng(seed)
    z_sub = np.ascontiguousarray(depth_mm[::s, ::s], dtype=np.float32)
    left = np.ascontiguousarray((valid if search is None else valid & search)[::s, ::s])
    vv, uu = np.mgrid[0:h:s, 0:w:s]
    tol_sub = np.maximum(np.float32(tol_mm), np.float32(tol_rel) * z_sub)
    min_sub = min_px / (s * s)
    found: list[tuple[tuple[float, float, float], NDArray[np.bool_], float]] = []
    for _ in range(max_planes * 2):
        if len(found) >= max_planes:
            break
        idx = np.flatnonzero(left)
        if idx.size < max(min_sub, 3):
            break
        u = uu.ravel()[idx].astype(np.float64)
        v = vv.ravel()[idx].astype(np.float64)
        z = z_sub.ravel()[idx].astype(np.float64)
        tz = tol_sub.ravel()[idx].astype(np.float64)
        n = u.size
        pick = rng.integers(0, n, size=(hypotheses, 3))
        a = np.stack([u[pick], v[pick], np.ones((hypotheses, 3))], axis=2)
        good = np.abs(np.linalg.det(a)) > 1e-6
        if not good.any():
            break
        coefs = np.linalg.solve(a[good], (1000.0 / z)[pick[good]][..., None])[..., 0]
        m = min(n, 2000)
        ev = rng.integers(0, n, size=m) if n > m else np.arange(n)
        inv_all = coefs[:, 0:1] * u[ev] + coefs[:, 1:2] * v[ev] + coefs[:, 2:3]
        score = ((inv_all > 0) & (np.abs(1000.0 - z[ev] * inv_all) <= tz[ev] * inv_all)).sum(axis=1)
        best = coefs[int(np.argmax(score))]
        inv = best[0] * u + best[1] * v + best[2]
        on = (inv > 0) & (np.abs(1000.0 - z * inv) <= tz * inv)
        if on.sum() < min_sub:
            break
        coef = _fit(u[on], v[on], 1000.0 / z[on])
        on_img = plane_residual_mask(z_sub, left, coef, tol_mm=tol_mm, tol_rel=tol_rel, step=s)
        left &= ~on_img
        pieces = large_pieces_opencv(on_img, max(int(min_sub) // 4, 1))
        if int(np.count_nonzero(pieces)) < min_sub:
            continue
        p5, p50, p95 = np.percentile(z_sub[pieces], (5, 50, 95))
        spread = float((p95 - p5) / max(p50, 1e-6))
        if spread < min_spread:
            continue
        found.append((coef, pieces, spread))
    if not found:
        return []
    coefs = np.array([c for c, _, _ in found], np.float64)
    kernel = np.ones((3, 3), np.uint8)
    allowed = np.stack([np.asarray(cv2.dilate(m.view(np.uint8), kernel), np.uint8) for _, m, _ in found])
    which = assign_planes(depth_mm, valid, coefs, allowed, s, float(tol_mm), float(tol_rel))
    masks = [(c, which == k, sp) for k, (c, _, sp) in enumerate(found, start=1)]
    return [Plane(c, m, int(m.sum()), sp) for c, m, sp in masks if m.sum() >= min_px]


def planes_from_sums_numpy(
    sums: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`depthgram.segmentation.planes.planes_from_sums` by numpy's batched solve and norm."""
    m = sums.shape[0]
    ata = np.empty((m, 3, 3))
    ata[:, 0, 0], ata[:, 0, 1], ata[:, 0, 2] = sums[:, 0], sums[:, 1], sums[:, 2]
    ata[:, 1, 0], ata[:, 1, 1], ata[:, 1, 2] = sums[:, 1], sums[:, 3], sums[:, 4]
    ata[:, 2, 0], ata[:, 2, 1], ata[:, 2, 2] = sums[:, 2], sums[:, 4], sums[:, 5]
    atb = sums[:, 6:9].copy()
    ata[0] = np.eye(3)
    atb[0] = (0.0, 0.0, 1.0)
    ata += np.eye(3) * 1e-12
    coef = np.linalg.solve(ata, atb[..., None])[..., 0]
    norm = np.maximum(np.linalg.norm(coef, axis=1), 1e-15)
    return -coef / norm[:, None], 1.0 / norm, sums[:, 5]


@njit(cache=False, nogil=True)
def refine_per_pixel(
    glab: NDArray[np.int32],
    gz: NDArray[np.float32],
    depth: NDArray[np.float32],
    valid: NDArray[np.bool_],
    step: int,
    t0: np.float32,
    t2: np.float32,
    sl: np.float32,
    n_labels: int,
) -> tuple[NDArray[np.int32], NDArray[np.float64], NDArray[np.int32]]:
    """:func:`depthgram.segmentation.coarse.refine_labels`'s kernel pixel by pixel, as it was.

    Each pixel's four candidates tried in turn behind branches, and each run summed with a
    test per pixel: the route the branch-free rows and paired run sums replaced.
    """
    # Hand-written: the choice among a pixel's four grid samples by depth and by the surface
    # labeller's own continuity rule has no library kernel (OpenCV's and scipy's upsampling
    # interpolate values, they do not pick a label). Walked cell by cell, so that no pixel pays
    # an integer division and a cell whose four samples carry one label (most of a frame) only
    # asks whether any of them continues the pixel, nearest first. The statistics table of
    # the new map (label.stats' layout) is gathered in the same pass, run by run.
    h, w = depth.shape
    gh, gw = glab.shape
    out = np.zeros((h, w), np.int32)
    # the samples of the grid rows above and below a band of `step` pixel rows, with a column
    # past the end (label 0) so that every pixel reads four candidates
    lab = np.zeros((2, gw + 1), np.int32)
    zs = np.zeros((2, gw + 1), np.float32)
    tol = np.zeros((2, gw + 1), np.float32)
    per_px = np.zeros((2, gw + 1), np.float32)
    one = np.zeros(gw, np.bool_)
    sums = np.zeros((n_labels + 1, N_COLUMNS), np.float64)
    # label.stats' boxes: each label's first row is set when its first run is added
    box = np.empty((n_labels + 1, 4), np.int32)
    box[:, 0] = w
    box[:, 1] = h
    box[:, 2] = -1
    box[:, 3] = -1
    for i0 in range(gh):
        for r in range(2):
            i = i0 + r
            for j in range(gw):
                v = glab[i, j] if i < gh else 0
                lab[r, j] = v
                z = gz[i, j] if v else np.float32(0.0)
                zs[r, j] = z
                tol[r, j] = t0 + t2 * z * z
                per_px[r, j] = sl * z
        for j in range(gw):
            a = lab[0, j]
            one[j] = (
                a != 0
                and (lab[0, j + 1] == 0 or lab[0, j + 1] == a)
                and (lab[1, j] == 0 or lab[1, j] == a)
                and (lab[1, j + 1] == 0 or lab[1, j + 1] == a)
            )
        for dy0 in range(min(step, h - i0 * step)):
            y = i0 * step + dy0
            gy = (np.float32(dy0), np.float32(step - dy0))
            j0 = 0
            dx0 = 0
            run = 0  # the label of the run being summed, its start and sums
            start = 0
            c = sz = szz = sx = sxz = 0.0
            for x in range(w + 1):
                best = 0
                if x < w and valid[y, x]:
                    z = depth[y, x]
                    best_d = np.float32(np.inf)
                    for k in range(4):
                        r = k >> 1
                        j = j0 + (k & 1)
                        cand = lab[r, j]
                        if cand == 0:
                            continue
                        d = abs(zs[r, j] - z)
                        gap = gy[r] + np.float32(dx0 if (k & 1) == 0 else step - dx0)
                        if d < best_d and d <= tol[r, j] + gap * per_px[r, j]:
                            best = cand
                            best_d = d
                            if one[j0]:
                                break
                    out[y, x] = best
                if best != run:
                    if run:
                        if box[run, 3] < 0:
                            box[run, 1] = y
                        flush_run(sums, box, run, c, sz, szz, sx, sxz, y, start, x - 1, 0.0)
                    run = best
                    start = x
                    c = sz = szz = sx = sxz = 0.0
                if best:
                    zf = np.float64(depth[y, x])
                    c += 1.0
                    sz += zf
                    szz += zf * zf
                    sx += x
                    sxz += x * zf
                dx0 += 1
                if dx0 == step:
                    j0 += 1
                    dx0 = 0
    return out, sums, box


def grid_first_reading(
    depth_mm: NDArray[np.float32], valid: NDArray[np.bool_], step: int
) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """:func:`depthgram.segmentation.coarse.grid_frame`'s samples cell by cell in numpy.

    Each ``step`` x ``step`` cell's first pixel with a reading in raster order (its corner
    first), 0 / False for a cell without one.
    """
    h, w = depth_mm.shape
    gh, gw = -(-h // step), -(-w // step)
    z = np.zeros((gh, gw), np.float32)
    ok = np.zeros((gh, gw), np.bool_)
    for i in range(gh):
        for j in range(gw):
            cell_ok = valid[i * step : (i + 1) * step, j * step : (j + 1) * step].ravel()
            if cell_ok.any():
                k = int(np.argmax(cell_ok))
                z[i, j] = depth_mm[i * step : (i + 1) * step, j * step : (j + 1) * step].ravel()[k]
                ok[i, j] = True
    return z, ok


def best_contact_numpy(contact: NDArray[np.int64], needed: NDArray[np.float64]) -> dict[int, int]:
    """``{facing id: support id}``: the support each facing row of ``contact`` touches most.

    numpy's argmax per row, kept when that contact reaches ``needed[facing id]``: the route
    :func:`depthgram.segmentation.contacts._best_faces` replaced.
    """
    out: dict[int, int] = {}
    if contact.size == 0:
        return out
    best = contact.argmax(axis=1)
    most = contact[np.arange(contact.shape[0]), best]
    for f in np.flatnonzero((most > 0) & (most >= needed)):
        out[int(f)] = int(best[f])
    return out


@njit(cache=True, nogil=True)
def sensor_samples(
    depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The sensor estimate's samples alone, as ``noise_model._triples_span`` takes them without the span.

    Every ``rows``-th row: the depth of each pixel whose two row neighbours also have a reading,
    its first difference z[x+1] - z[x] (absolute) and its second difference
    (z[x-1] - 2 z[x]) + z[x+1], in raster order.
    """
    h, w = depth.shape
    n_rows = (h + rows - 1) // rows
    cap = n_rows * max(w - 2, 0)
    z = np.empty(cap, np.float64)
    d1 = np.empty(cap, np.float64)
    d2 = np.empty(cap, np.float64)
    k = 0
    for y in range(0, h, rows):
        for x in range(1, w - 1):
            if valid[y, x - 1] and valid[y, x] and valid[y, x + 1]:
                a = np.float64(depth[y, x - 1])
                b = np.float64(depth[y, x])
                c = np.float64(depth[y, x + 1])
                z[k] = b
                d1[k] = abs(c - b)
                d2[k] = (a - 2.0 * b) + c
                k += 1
    return z[:k], d1[:k], d2[:k]


def sensor_ranges(depth: NDArray[np.float32], valid: NDArray[np.bool_], rows: int) -> NDArray[np.float64]:
    """Each depth range's row of the sensor estimate (median depth, step, sigma, 1), in numpy.

    The readable route (``noise_model.range_estimates_readable``) that the counted one
    (``noise_model._range_estimates_counted``) is held to.
    """
    from depthgram.segmentation.noise_model import range_estimates_readable

    return range_estimates_readable(depth, valid, rows)


@njit(cache=True, nogil=True)
def best_hypothesis_in_index_order(
    coef: NDArray[np.float64],
    u: NDArray[np.float64],
    v: NDArray[np.float64],
    z: NDArray[np.float64],
    tol: NDArray[np.float64],
    ev: NDArray[np.int64],
) -> int:
    """The RANSAC scoring ``_kernels.ransac.best_hypothesis`` replaced: hypotheses in index order.

    The first hypothesis with the most inliers among the points ``ev`` (``np.argmax`` of the
    scores), each scored by blocks of 256 points and left when it could not pass the best one
    even if all its remaining points were inliers.
    """
    m = ev.size
    ue = np.empty(m, np.float64)
    ve = np.empty(m, np.float64)
    ze = np.empty(m, np.float64)
    te = np.empty(m, np.float64)
    for i in range(m):
        j = ev[i]
        ue[i] = u[j]
        ve[i] = v[j]
        ze[i] = z[j]
        te[i] = tol[j]
    best = -1
    arg = 0
    for k in range(coef.shape[0]):
        a, b, c = coef[k, 0], coef[k, 1], coef[k, 2]
        cnt = 0
        for i0 in range(0, m, 256):
            if cnt + (m - i0) <= best:
                break
            cnt += inliers_counted(a, b, c, ue[i0 : i0 + 256], ve[i0 : i0 + 256], ze[i0 : i0 + 256], te[i0 : i0 + 256])
        if cnt > best:
            best = cnt
            arg = k
    return arg


# The orientation field's row and column passes one at a time, as the tests compare them (the
# field runs them inside `orientation._slopes`).


def _one_sided(inv: NDArray[np.float32], valid: NDArray[np.bool_], step: int) -> NDArray[np.float32]:
    """Return the derivative along rows (per px), the smaller of the forward and backward differences.

    Beside an occlusion edge one of the two differences crosses the edge; the smaller one stays
    on the pixel's own surface, so a floor pixel next to a box keeps the floor's slope. Pixels
    whose neighbours both lack a reading get 0 (no evidence of a slope).
    """
    return _one_sided_rows(np.ascontiguousarray(inv), np.ascontiguousarray(valid), step)


@njit(cache=True, error_model="numpy")
def _one_sided_rows(inv: NDArray[np.float32], valid: NDArray[np.bool_], step: int) -> NDArray[np.float32]:
    h, w = inv.shape
    out = np.zeros((h, w), np.float32)
    for y in range(h):
        _one_sided_row(inv[y], valid[y], step, out[y])
    return out


@njit(cache=True, error_model="numpy")
def _one_sided_cols(inv: NDArray[np.float32], valid: NDArray[np.bool_], step: int) -> NDArray[np.float32]:
    # _one_sided_rows along columns (same arithmetic), a whole row of columns at a time,
    # without the three transposed copies
    h, w = inv.shape
    out = np.zeros((h, w), np.float32)
    for y in range(h):
        _one_sided_col(inv, valid, y, step, out[y])
    return out


def _jumps(z: NDArray[np.float32], valid: NDArray[np.bool_], jump_rel: float) -> NDArray[np.bool_]:
    """Pixels beside an occlusion edge along rows.

    A step is an edge when it exceeds ``jump_rel`` of the depth and is more than twice the
    steps two pixels before and after it: a floor seen at a grazing angle makes large but
    steady steps, an occlusion one isolated step (or two, with a flying pixel between).
    """
    out = np.zeros(z.shape, np.bool_)
    _row_edges_into(np.ascontiguousarray(z), np.ascontiguousarray(valid), np.float32(jump_rel), out)
    return out


@njit(cache=True)
def _jumps_cols(z: NDArray[np.float32], valid: NDArray[np.bool_], rel: np.float32) -> NDArray[np.bool_]:
    # _jumps_rows along columns (same float32 tests)
    out = np.zeros(z.shape, np.bool_)
    _col_edges_into(z, valid, rel, out)
    return out
