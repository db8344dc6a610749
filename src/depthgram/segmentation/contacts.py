"""Which facing objects are faces of a support: contacts along an edge without a depth jump.

A box or a table shows the sensor a front face under its top, or a front face beside a side
running away; the orientation classes cut such an object into a facing part and a support part
(:mod:`depthgram.segmentation.slices`). These functions count, in one pass, the pixels where a
facing object meets a support without a depth jump, and say which faces belong to which support.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.label.stats import COUNT, SUM_X, SUM_Y, SUM_Z, SUM_ZZ, label_stats_fused
from depthgram.segmentation.plane_sums import plane_sums_in_boxes, planes_from_sums

__all__ = ["front_faces", "planes_in_pixels", "side_faces", "support_planes"]


def front_faces(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    widths: NDArray[np.float64],
    horizontal_ids: NDArray[np.int32],
    *,
    jump_rel: float,
    min_contact: float = 0.5,
    boxes: NDArray[np.int64] | None = None,
    n_ids: int | None = None,
    face_sums: NDArray[np.float64] | None = None,
    planes: Mapping[int, Sequence[float]] | None = None,
) -> dict[int, int]:
    """Facing objects that are the front face of a horizontal support right above them.

    A table's front edge or a box's front face meets its top along the face's upper edge, at
    the same depth; an object standing on the support meets it along its base instead, and
    its upper edge borders the support farther behind (a depth jump). Facing objects have ids
    ``1..len(widths) - 1`` and bounding-box widths ``widths`` (px, index 0 unused). Returns
    ``{facing id: support id}`` for faces whose upper edge touches the support, without a
    depth jump, over at least ``min_contact`` of the face's width, lying on or behind the
    support's plane continued (an object standing on it rises in front: a can or a box whose
    side the orientation field, with a wrong focal length, partly classes as horizontal), and
    not one of several faces under separate pieces of the support (coplanar tops joined).

    ``boxes`` (inclusive x0, y0, x1, y1 of each of ``horizontal_ids``, holding all its pixels)
    limits the pass to the supports' boxes, with the same counts; ``n_ids``, one past the
    largest id in ``labels``, spares a pass finding it. ``face_sums`` (the statistics table of
    :mod:`depthgram.segmentation.label.stats`, a row per facing id at least) and ``planes``
    (``{support id: (a, b, c)}`` of ``1/Z = a x + b y + c`` in pixels, 1/mm, as
    :func:`support_planes` fits them), when the caller has them, spare a pass computing them:
    the plane test then reads no pixel.
    """
    n_facing = widths.size - 1
    if n_facing == 0 or horizontal_ids.size == 0:
        return {}
    widths = np.asarray(widths, np.float64)
    found = _faces(labels, depth_mm, horizontal_ids, boxes, n_ids, jump_rel, min_contact, widths, widths, False)
    if not found:
        return found
    if boxes is None:
        h, w = labels.shape
        boxes = np.tile(np.array([0, 0, w - 1, h - 1], np.int64), (horizontal_ids.size, 1))
    if planes is None:
        fit = support_planes(labels, depth_mm, horizontal_ids, boxes)
        planes = dict(zip(horizontal_ids.tolist(), fit.tolist(), strict=True))
    if face_sums is None:
        top = int(labels.max(initial=0)) if n_ids is None else n_ids - 1
        face_sums, _ = label_stats_fused(labels, top, depth_mm, np.zeros(labels.shape, np.float32))
    found = _behind_planes(found, face_sums, planes)
    # faces under separate pieces of one support: the tops of several objects joined as one
    # plane (two boxes of one height), not the front of one support: none of them is folded
    # (a support with one face has one piece under it: labelled only under two faces or more)
    if len(found) < 2:
        return found
    row = {s: k for k, s in enumerate(horizontal_ids.tolist())}
    under = list(found.values())
    apart = {s for s in set(under) if under.count(s) > 1 and _pieces_under(labels, found, s, boxes[row[s]]) > 1}
    return {f: s for f, s in found.items() if s not in apart}


def side_faces(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    heights: NDArray[np.float64],
    vertical_ids: NDArray[np.int32],
    mean_depth: NDArray[np.float64],
    *,
    jump_rel: float,
    min_contact: float = 0.5,
    boxes: NDArray[np.int64] | None = None,
    n_ids: int | None = None,
) -> dict[int, int]:
    """Facing objects whose side meets a small vertical support: the front and side of one box.

    A box seen at an angle shows a face toward the sensor and a side running away from it; the
    two meet along a vertical edge at the same depth, at the NEAR end of the side. Facing
    objects have ids ``1..len(heights) - 1`` and bounding-box heights ``heights`` (px, index 0
    unused); ``mean_depth`` (mm) is indexed by id. Returns ``{facing id: support id}`` for faces
    in front of the side's middle touching a support in ``vertical_ids`` side by side, without
    a depth jump, over at least ``min_contact`` of the face's height. (A wall behind the box
    meets the side's far end and lies behind its middle, so it is not taken.) ``boxes`` and
    ``n_ids`` as for :func:`front_faces`.
    """
    n_facing = heights.size - 1
    if n_facing == 0 or vertical_ids.size == 0:
        return {}
    heights = np.asarray(heights, np.float64)
    mean_depth = np.asarray(mean_depth, np.float64)
    return _faces(labels, depth_mm, vertical_ids, boxes, n_ids, jump_rel, min_contact, heights, mean_depth, True)


#: a front face lies on or below its support's plane continued: in 1/Z, at most this fraction
#: in front of it (its mean 1/Z against the plane at its centroid); an object standing on the
#: support rises in front of it
FRONT_MAX_RISE = 0.01


def support_planes(
    labels: NDArray[np.int32], depth_mm: NDArray[np.float32], ids: NDArray[np.int32], boxes: NDArray[np.int64]
) -> NDArray[np.float64]:
    """Least-squares planes ``1/Z = a x + b y + c`` of the labels ``ids`` in pixel coordinates.

    Parameters
    ----------
    labels : ndarray of int32, shape (H, W)
        Label map; every labelled pixel has a reading.
    depth_mm : ndarray of float32, shape (H, W)
        Depth (mm).
    ids : ndarray of int32, shape (K,)
        The labels fitted.
    boxes : ndarray of int64, shape (K, 4)
        Inclusive (x0, y0, x1, y1) of each of ``ids``, holding all its pixels.

    Returns
    -------
    ndarray of float64, shape (K, 3)
        ``(a, b, c)`` per label, 1/Z in 1/mm. A plane's 1/Z is affine in pixel coordinates
        whatever the intrinsics, so no focal length is read: the fit is
        :func:`~depthgram.segmentation.plane_sums.plane_sums_in_boxes` with unit focal lengths.
    """
    which = np.asarray(ids, np.intp)
    if which.size == 0:
        return np.zeros((0, 3), np.float64)
    sums = plane_sums_in_boxes(labels, int(which.max()), which, boxes, depth_mm, 1.0, 1.0, 0.0, 0.0)
    normal, off, _ = planes_from_sums(sums[np.concatenate(([0], which))])
    return np.array(planes_in_pixels(normal[1:].tolist(), off[1:].tolist()), np.float64).reshape(-1, 3)


def planes_in_pixels(
    normal: Sequence[Sequence[float]],
    off: Sequence[float],
    fx: float = 1.0,
    fy: float = 1.0,
    cx: float = 0.0,
    cy: float = 0.0,
) -> list[tuple[float, float, float]]:
    """Planes fitted in normalised image coordinates as ``1/Z = a x + b y + c`` in pixels.

    Parameters
    ----------
    normal, off : sequences of K (nx, ny, nz) and K d (lists: ``ndarray.tolist()``)
        Planes ``n . X + d = 0`` as :func:`~depthgram.segmentation.plane_sums.planes_from_sums`
        gives them from sums taken with ``u' = (x - cx) / fx``, ``v' = (y - cy) / fy``.
    fx, fy, cx, cy : float
        Those coordinates' intrinsics (px); the defaults are pixel coordinates themselves.

    Returns
    -------
    list of (a, b, c)
        Per plane, 1/Z in 1/mm. A least-squares fit is the same whatever affine coordinates it
        was taken in (:func:`support_planes` equals a fit at any focal length converted here).
    """
    out = []
    # X = Z (u', v', 1) on n . X + d = 0: 1/Z = -(n . (u', v', 1)) / d. Python floats: a few
    # planes a frame, for which numpy's calls would cost more than the arithmetic
    for (nx, ny, nz), d in zip(normal, off, strict=True):
        a, b = -nx / (d * fx), -ny / (d * fy)
        out.append((a, b, -nz / d - a * cx - b * cy))
    return out


def _behind_planes(
    found: dict[int, int], sums: NDArray[np.float64], planes: Mapping[int, Sequence[float]]
) -> dict[int, int]:
    """Return the faces of ``found`` lying on or behind their support's plane continued.

    A front face under a support's edge (a table's front, a box's front) lies on or below the
    support's plane (``planes``, the ``(a, b, c)`` of ``1/Z = a x + b y + c`` per support id),
    seen from above: behind it along each ray. An object standing on the
    support lies above it, in front (a larger 1/Z). Each face's statistics row (``sums``) gives
    its pixel count, centroid and the moments of its depth, so no pixel is read: the plane
    being affine, its mean over the face is its value at the centroid.
    """
    kept = {}
    for f, s in found.items():
        a, b, c = planes[s]
        # Python floats: numpy scalars' arithmetic would cost more than the test itself
        r = sums[f].tolist()
        n, szz, sx, sy = r[COUNT], r[SUM_ZZ], r[SUM_X], r[SUM_Y]
        mean = r[SUM_Z] / n
        # the mean of 1/Z by its second-order expansion in depth's spread: on the 122 faces
        # YCB-Video and the golden frames put to the test, within 3e-4 of the exact mean
        # (1/mean alone: up to 0.008 off, a face of 50,000 px over a deep range)
        inverse = (1.0 + max(szz / n - mean * mean, 0.0) / (mean * mean)) / mean
        plane = a * sx / n + b * sy / n + c
        if inverse - plane <= FRONT_MAX_RISE * abs(plane):
            kept[f] = s
    return kept


def _pieces_under(labels: NDArray[np.int32], found: dict[int, int], support: int, box: NDArray[np.int64]) -> int:
    """How many separate (8-connected) pieces of ``support`` the faces folded into it meet above.

    ``box`` (inclusive x0, y0, x1, y1) holds all the support's pixels: the pieces are labelled
    inside it and the row below it, where a face's pixels right under the support lie.
    """
    faces = [f for f, s in found.items() if s == support]
    if len(faces) < 2:
        return 1
    x0, y0, x1, y1 = (int(v) for v in box)
    sub = labels[y0 : min(y1 + 1, labels.shape[0] - 1) + 1, x0 : x1 + 1]
    mask = (sub == support).astype(np.uint8)
    _, piece = cv2.connectedComponents(mask, connectivity=8)
    met = set()
    for f in faces:
        # the support pixels right above the face's pixels: the piece they mostly belong to
        above = piece[:-1][(sub[1:] == f) & (mask[:-1] > 0)]
        if above.size:
            met.add(int(np.bincount(above).argmax()))
    return len(met)


def _faces(
    labels: NDArray[np.int32],
    depth_mm: NDArray[np.float32],
    support_ids: NDArray[np.int32],
    boxes: NDArray[np.int64] | None,
    n_ids: int | None,
    jump_rel: float,
    min_contact: float,
    size: NDArray[np.float64],
    mean_depth: NDArray[np.float64],
    side: bool,
) -> dict[int, int]:
    """:func:`front_faces` (``side`` False, ``mean_depth`` unread) or :func:`side_faces` (``side`` True).

    ``size`` is each facing object's width or height (px); the supports' ``boxes``, when
    given, limit the count to them.
    """
    n_facing = size.size - 1
    n_ids = int(labels.max(initial=0)) + 1 if n_ids is None else n_ids
    rel = np.float32(jump_rel)
    ids = np.asarray(support_ids, np.intp)
    if boxes is None:  # each support read over the whole frame
        h, w = labels.shape
        boxes = np.tile(np.array([0, 0, w - 1, h - 1], np.int64), (ids.size, 1))
    contact = _contacts_in_boxes(labels, depth_mm, ids, np.asarray(boxes, np.int64), n_ids, n_facing, rel, side)
    # the support each facing row touches most (the first of equal ones), kept when that
    # contact (px) reaches min_contact times the face's extent; for a side face only supports
    # whose mean depth lies behind the face's count
    if side:
        n_f, n_s = contact.shape
        contact = np.where(mean_depth[None, :n_s] > mean_depth[:n_f, None], contact, 0)
    best = contact.argmax(axis=1)
    most = contact[np.arange(best.size), best]
    # (a facing row touching nothing has best 0: most is 0 there)
    faces = np.nonzero((most > 0) & (most >= min_contact * size))[0]
    return dict(zip(faces.tolist(), best[faces].tolist(), strict=True))


@njit(cache=True, nogil=True)
def _contacts_in_boxes(
    labels: NDArray[np.int32],
    depth: NDArray[np.float32],
    ids: NDArray[np.intp],
    boxes: NDArray[np.int64],
    n_ids: int,
    n_facing: int,
    rel: np.float32,
    side_by_side: bool,
) -> NDArray[np.int64]:
    # One pass per support inside its box counting (facing id, support id) neighbours without
    # a depth jump: a support pixel right above a facing one (front faces), or with
    # ``side_by_side`` the two next to each other in either order (side faces); every counted
    # pair holds one support pixel, so each pair is met once, under its support. numpy needs
    # masks over the whole frame and np.unique of the pairs. Facing ids are 1..n_facing.
    h, w = labels.shape
    out = np.zeros((n_facing + 1, n_ids), np.int64)
    hit = np.empty(w, np.bool_)
    nf = np.int32(n_facing)
    for k in range(ids.size):
        s = ids[k]
        x0, y0, x1, y1 = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3]
        if not side_by_side:
            # the support above, the facing pixel below it: each row's contacts found by a
            # branch-free loop over row slices (it vectorises), then counted where there are any
            bw = x1 - x0 + 1
            for y in range(y0, min(y1, h - 2) + 1):
                la, lb = labels[y, x0 : x1 + 1], labels[y + 1, x0 : x1 + 1]
                za, zb = depth[y, x0 : x1 + 1], depth[y + 1, x0 : x1 + 1]
                found = False
                for x in range(bw):
                    b = lb[x]
                    c = (la[x] == s) & (b > 0) & (b <= nf) & (abs(za[x] - zb[x]) <= rel * max(za[x], zb[x]))
                    hit[x] = c
                    found |= c
                if found:
                    for x in range(bw):
                        if hit[x]:
                            out[lb[x], s] += 1
            continue
        # side by side, either way round: the support pixel is the left or the right one
        for y in range(y0, y1 + 1):
            for x in range(max(x0 - 1, 0), min(x1, w - 2) + 1):
                a = labels[y, x]
                b = labels[y, x + 1]
                if a == s and 0 < b <= n_facing:
                    f = b
                elif b == s and 0 < a <= n_facing:
                    f = a
                else:
                    continue
                za = depth[y, x]
                zb = depth[y, x + 1]
                if abs(za - zb) <= rel * max(za, zb):
                    out[f, s] += 1
    return out
