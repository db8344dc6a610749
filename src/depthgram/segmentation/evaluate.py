"""Agreement of a label map with ground-truth instances.

Per ground-truth object: the detected segment of best IoU, its coverage (intersection / true
area, the paper's "Area %") and precision (intersection / detected area); the share found at
IoU >= 0.5; and the counts of Hoover et al. (1996), "An experimental comparison of range image
segmentation algorithms", at tolerance T: correct, over-segmented, under-segmented, missed, noise.
All overlaps come from one ``np.bincount`` over pixel pairs (the contingency table).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from depthgram.errors import InputError

__all__ = ["Evaluation", "ObjectScore", "evaluate"]


@dataclass(frozen=True)
class ObjectScore:
    """Scores of one ground-truth object.

    Attributes
    ----------
    truth_id : int
        Ground-truth instance id.
    area : int
        True area (px) over the evaluated pixels.
    detected : int
        Label of the best-IoU segment, 0 when none overlaps.
    iou, coverage, precision : float
        Of that segment: IoU, intersection / true area, intersection / detected area.
    hoover : str
        ``correct``, ``over``, ``under`` or ``missed``.
    """

    truth_id: int
    area: int
    detected: int
    iou: float
    coverage: float
    precision: float
    hoover: str


@dataclass(frozen=True)
class Evaluation:
    """Scores of one segmentation against ground truth.

    Attributes
    ----------
    objects : tuple of ObjectScore
        One per ground-truth object, in id order.
    found_share : float
        Share of ground-truth objects whose best IoU is >= ``iou_found``.
    area : float
        Area-weighted coverage: sum of best-match intersections / sum of true areas.
    precision : float
        Area-weighted precision: sum of best-match intersections / sum of their detected areas.
    area_assigned : float
        Share of the true area labelled by segments assigned to the right object, each segment
        going to the object it overlaps most: an object seen in disconnected pieces (a wall
        behind a table and below it) counts all its pieces. The paper's "Area %" is read this way
        in ``benchmarks/table1.py``.
    precision_assigned : float
        Share of all labelled pixels that lie in the object their segment is assigned to.
    correct, over, under, missed, noise : int
        Hoover et al. counts at ``tolerance``: ground-truth objects correctly detected,
        over-segmented, under-segmented (merged with others) or missed; detected segments
        matching nothing (noise).
    tolerance : float
        Hoover tolerance T.
    """

    objects: tuple[ObjectScore, ...]
    found_share: float
    area: float
    precision: float
    area_assigned: float
    precision_assigned: float
    correct: int
    over: int
    under: int
    missed: int
    noise: int
    tolerance: float

    def score(self, truth_id: int) -> ObjectScore:
        """Return the scores of one ground-truth object."""
        for s in self.objects:
            if s.truth_id == truth_id:
                return s
        raise KeyError(truth_id)


def evaluate(
    labels: NDArray[np.integer],
    truth_instances: NDArray[np.integer],
    *,
    valid: NDArray[np.bool_] | None = None,
    truth_ids: list[int] | None = None,
    tolerance: float = 0.8,
    iou_found: float = 0.5,
) -> Evaluation:
    """Compare a label map with ground-truth instance ids.

    Parameters
    ----------
    labels : ndarray of int, shape (H, W)
        Detected segment per pixel, 0 = none.
    truth_instances : ndarray of int, shape (H, W)
        Ground-truth instance per pixel, 0 = none.
    valid : ndarray of bool, optional
        Only these pixels are compared (the ones with a reading: a segmentation cannot label
        a pixel without depth).
    truth_ids : list of int, optional
        Ground-truth objects to score; all ids present by default.
    tolerance : float
        Hoover tolerance T in (0.5, 1].
    iou_found : float
        IoU at which an object counts as found.
    """
    lab = np.asarray(labels)
    tru = np.asarray(truth_instances)
    if lab.shape != tru.shape or lab.ndim != 2:
        raise InputError(f"evaluate: labels {lab.shape} and truth {tru.shape} must be 2-D of the same shape")
    if not 0.5 < tolerance <= 1.0:
        raise InputError(f"evaluate: Hoover tolerance must be in (0.5, 1], got {tolerance}")
    if (lab < 0).any() or (tru < 0).any():
        raise InputError("evaluate: labels and truth ids must be >= 0")
    if valid is not None:
        lab = np.where(valid, lab, 0)
        tru = np.where(valid, tru, 0)
    nd = int(lab.max(initial=0)) + 1
    nt = int(tru.max(initial=0)) + 1
    table = np.bincount((tru.astype(np.int64) * nd + lab).ravel(), minlength=nt * nd).reshape(nt, nd)
    true_area = table.sum(axis=1)
    det_area = table.sum(axis=0)
    inter = table[1:, 1:].astype(np.float64)  # rows: truth 1.., cols: detected 1..
    union = true_area[1:, None] + det_area[None, 1:] - inter
    iou = np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)
    ids = [int(i) for i in (truth_ids if truth_ids is not None else np.flatnonzero(true_area[1:] > 0) + 1)]
    t = tolerance
    P = true_area[1:, None].astype(np.float64)
    R = det_area[None, 1:].astype(np.float64)
    big_of_det = inter >= t * R  # detected n lies mostly inside truth m
    big_of_true = inter >= t * P  # truth m lies mostly inside detected n
    correct_pair = big_of_det & big_of_true
    over_t = (np.where(big_of_det, inter, 0).sum(axis=1) >= t * P[:, 0]) & (big_of_det.sum(axis=1) >= 2)
    under_d = (np.where(big_of_true, inter, 0).sum(axis=0) >= t * R[0]) & (big_of_true.sum(axis=0) >= 2)
    under_t = (big_of_true & under_d[None, :]).any(axis=1)
    correct_t = correct_pair.any(axis=1)
    scores = []
    for m in ids:
        r = m - 1
        if r < 0 or r >= inter.shape[0] or true_area[m] == 0:
            scores.append(ObjectScore(m, 0, 0, 0.0, 0.0, 0.0, "missed"))
            continue
        best = int(np.argmax(iou[r])) if inter.shape[1] else -1
        hit = best >= 0 and inter[r, best] > 0
        cls = "correct" if correct_t[r] else "over" if over_t[r] else "under" if under_t[r] else "missed"
        scores.append(
            ObjectScore(
                truth_id=m,
                area=int(true_area[m]),
                detected=best + 1 if hit else 0,
                iou=float(iou[r, best]) if hit else 0.0,
                coverage=float(inter[r, best] / true_area[m]) if hit else 0.0,
                precision=float(inter[r, best] / det_area[best + 1]) if hit else 0.0,
                hoover=cls,
            )
        )
    n = len(scores)
    tot_true = sum(s.area for s in scores)
    tot_inter = sum(s.coverage * s.area for s in scores)
    tot_det = sum(det_area[s.detected] for s in scores if s.detected)
    used = correct_pair.any(axis=0) | big_of_det[[i - 1 for i in ids if 0 < i <= inter.shape[0]]].any(axis=0)
    noise = int(np.count_nonzero(~used & (det_area[1:] > 0) & ~under_d))
    scored = np.zeros(inter.shape[0], bool)
    scored[[i - 1 for i in ids if 0 < i <= inter.shape[0]]] = True
    if inter.size:
        owner = np.argmax(inter, axis=0)
        got = inter[owner, np.arange(inter.shape[1])]
        to_scored = scored[owner] & (got > 0)
        area_assigned = float(got[to_scored].sum() / tot_true) if tot_true else 0.0
        labelled = det_area[1:].sum() - table[0, 1:].sum()  # pixels of segments over some truth
        precision_assigned = float(got.sum() / labelled) if labelled else 0.0
    else:
        area_assigned = precision_assigned = 0.0
    return Evaluation(
        objects=tuple(scores),
        found_share=sum(s.iou >= iou_found for s in scores) / n if n else 0.0,
        area=tot_inter / tot_true if tot_true else 0.0,
        precision=tot_inter / tot_det if tot_det else 0.0,
        area_assigned=area_assigned,
        precision_assigned=precision_assigned,
        correct=sum(s.hoover == "correct" for s in scores),
        over=sum(s.hoover == "over" for s in scores),
        under=sum(s.hoover == "under" for s in scores),
        missed=sum(s.hoover == "missed" for s in scores),
        noise=noise,
        tolerance=t,
    )
