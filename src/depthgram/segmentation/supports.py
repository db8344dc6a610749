"""The supports of each orientation class: floors, table tops and walls, as labelled pieces.

A class's pixels are labelled into depth-continuous pieces (both classes in one pass), pieces on
one plane join, facing pixels lying on a big support's plane join it (noise makes some support
pixels look facing), and supports too small or too flat for their depth go back to the facing
pixels. The result is read through a table (:class:`SupportMap`) when the supports join the
objects' label map (:func:`depthgram.segmentation.core`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from depthgram.frame import Intrinsics
from depthgram.segmentation.config import SegmentConfig
from depthgram.segmentation.coplanar import class_window, join_near
from depthgram.segmentation.label import label_two_classes
from depthgram.segmentation.orientation import FACING
from depthgram.segmentation.plane_sums import planes_from_sums
from depthgram.segmentation.slices import drop_classes, join_pieces, small_supports, support_pieces_lazy

__all__ = ["SupportMap", "label_supports"]


@dataclass
class SupportMap:
    """The supports of one orientation class, read from a label map through a table.

    Pieces ``base + 1 .. base + len(through) - 1`` of ``labels`` are this class's (a map
    labelled for two classes holds the other's too); ``through`` maps piece - base to its
    support 1..n, or 0 for a piece dropped (whose pixels went back to the facing class).
    """

    cls: int  # orientation class
    labels: NDArray[np.int32]  # label map holding the pieces
    base: int  # the pieces' values in `labels` start after this
    size: int  # one more than the largest value of `labels`
    through: NDArray[np.int32]  # (pieces + 1,) piece -> support or 0
    n: int  # supports
    sums: NDArray[np.float64]  # (n + 1, N_COLUMNS) statistics per support (row 0 unused)
    boxes: NDArray[np.int64]  # (n + 1, 4) inclusive boxes per support


Pieces = tuple[NDArray[np.int32], int, int, int, NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]


def label_supports(
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    classes: NDArray[np.int8],
    wanted: list[int],
    cam: Intrinsics,
    cfg: SegmentConfig,
    min_px: int,
) -> list[SupportMap]:
    """Return the supports of each wanted class, in order (:func:`support_class`; ``classes`` updated).

    Parameters are the frame's depth (mm), readings, orientation classes (updated in place), the
    classes wanted (:data:`~depthgram.segmentation.orientation.HORIZONTAL`, ``VERTICAL``), the
    intrinsics, the config and the fewest pixels of a support.

    Both classes' pieces come from one labelling pass. One class's later steps do not change
    the other's pieces: they turn facing pixels into its own class or its own pixels back into
    facing ones, and both are blocking readings to the other class's labeller.
    """
    first: dict[int, Pieces] = {}
    if len(wanted) == 2:
        lab, na, nb, sums, boxes, planes = label_two_classes(
            depth, ok, classes, wanted[0], wanted[1], cam.fx, cam.fy, cam.cx, cam.cy,
            rel=cfg.jump_rel, bridge=cfg.fill_holes_px,
        )  # fmt: skip
        rows = np.arange(na, na + nb + 1)
        rows[0] = 0
        size = na + nb + 1
        first[wanted[0]] = (lab, 0, size, na, sums[: na + 1], boxes[: na + 1], planes[: na + 1])
        first[wanted[1]] = (lab, na, size, nb, sums[rows], boxes[rows], planes[rows])
    return [support_class(depth, ok, classes, cls, cam, cfg, min_px, first.get(cls)) for cls in wanted]


def support_class(
    depth: NDArray[np.float32],
    ok: NDArray[np.bool_],
    classes: NDArray[np.int8],
    cls: int,
    cam: Intrinsics,
    cfg: SegmentConfig,
    min_px: int,
    pieces: Pieces | None = None,
) -> SupportMap:
    """Supports of one orientation class, small or flat ones handed back to the facing pixels.

    Updates ``classes`` in place. ``pieces``: the class's pieces already labelled (label map,
    the value before its first piece, the map's size, and the count, statistics, inclusive
    boxes and plane sums of the pieces); labelled here when None.
    """
    fit_px = max(min_px // 2, 10)
    if pieces is None:
        lab, merge, n, sums, boxes, planes, fit = support_pieces_lazy(
            depth, ok, classes, cls, cam, jump_rel=cfg.jump_rel, bridge=cfg.fill_holes_px, min_fit_px=fit_px,
            min_plane_px=min_px,
        )  # fmt: skip
        n_pieces = merge.size - 1 if merge is not None else n
        base, size = 0, n_pieces + 1
    else:
        lab, base, size, n_pieces, psums, pboxes, pplanes = pieces
        merge, n, sums, boxes, planes, fit = join_pieces(
            n_pieces, psums, pboxes, pplanes, min_fit_px=fit_px, min_plane_px=min_px
        )
    # noise makes some support pixels look facing; those lying on a big support's plane
    # go back to it (an upright object meets that plane only along its base row): only the
    # planes of supports of min_px pixels or more are read
    if n:
        normal, off, count = fit if fit is not None else planes_from_sums(planes, min_px=min_px)
        near = join_near(
            classes, ok, cls, FACING, normal, off, count, boxes, depth, cam, min_px=min_px, tol_rel=cfg.jump_rel / 2
        )
        if near:
            # the class's pixels lie inside its supports' boxes and the margins join_near searched
            win = class_window(boxes, count, depth.shape, min_px=min_px)
            lab, merge, n, sums, boxes, planes, _ = support_pieces_lazy(
                depth, ok, classes, cls, cam, jump_rel=cfg.jump_rel, bridge=cfg.fill_holes_px, min_fit_px=fit_px,
                window=win, min_plane_px=min_px,
            )  # fmt: skip
            n_pieces = merge.size - 1 if merge is not None else n
            base, size = 0, n_pieces + 1
    small, n_small = small_supports(sums, min_px, cfg.min_spread)
    if not n_small:
        through = merge if merge is not None else np.arange(n_pieces + 1, dtype=np.int32)
        return SupportMap(cls, lab, base, size, through, n, sums, boxes)
    # row 0 is never small: the kept rows start with it
    rows = np.nonzero(~small)[0]
    lut = np.zeros(n + 1, dtype=np.int32)
    lut[rows[1:]] = np.arange(1, rows.size, dtype=np.int32)
    # piece -> support -> kept support in one table: the dropped pieces' pixels go back to the
    # facing class now (the next class's steps read it); the map is read through it once, when
    # the supports join the objects' label map
    through = lut[merge] if merge is not None else lut
    drop_classes(lab, through, base, classes, FACING, boxes[small])
    return SupportMap(cls, lab, base, size, through, rows.size - 1, sums[rows], boxes[rows])
