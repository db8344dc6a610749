"""Evaluation against ground truth (Hoover et al. 1996 counts) and attribute sums, hand-computed."""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.segmentation import evaluate
from depthgram.segmentation.attributes import label_stats
from reference import label_stats_bincount


def hoover_case() -> tuple[np.ndarray, np.ndarray]:
    truth = np.zeros((40, 40), np.int32)
    labels = np.zeros((40, 40), np.int32)
    truth[0:10, 0:10] = 1  # A: split in two halves -> over-segmented
    labels[0:10, 0:5] = 1
    labels[0:10, 5:10] = 2
    truth[0:10, 20:30] = 2  # B: exact -> correct
    labels[0:10, 20:30] = 5
    truth[20:30, 0:10] = 3  # C and D: one segment over both -> under-segmented
    truth[20:30, 10:20] = 4
    labels[20:30, 0:20] = 3
    truth[30:40, 30:40] = 5  # E: nothing -> missed
    labels[12:16, 30:40] = 4  # over unlabelled truth -> noise
    return labels, truth


def test_hoover_counts_and_scores_by_hand() -> None:
    labels, truth = hoover_case()
    ev = evaluate(labels, truth, tolerance=0.8)
    assert (ev.correct, ev.over, ev.under, ev.missed, ev.noise) == (1, 1, 2, 1, 1)
    assert [s.hoover for s in ev.objects] == ["over", "correct", "under", "under", "missed"]
    a = ev.score(1)
    assert a.iou == pytest.approx(0.5) and a.coverage == pytest.approx(0.5) and a.precision == 1.0
    c = ev.score(3)
    assert c.iou == pytest.approx(0.5) and c.coverage == 1.0 and c.precision == pytest.approx(0.5)
    assert ev.score(5).detected == 0 and ev.score(5).iou == 0.0
    assert ev.found_share == pytest.approx(4 / 5)
    # best single segments: 50 + 100 + 100 + 100 + 0 of 500 true pixels
    assert ev.area == pytest.approx(350 / 500)
    # assigned: labels 1, 2 -> A (100), 3 -> C (100), 5 -> B (100); 400 labelled pixels over truth
    assert ev.area_assigned == pytest.approx(300 / 500)
    assert ev.precision_assigned == pytest.approx(300 / 400)


def test_perfect_segmentation_and_the_valid_mask() -> None:
    _, truth = hoover_case()
    ev = evaluate(truth, truth)
    assert ev.correct == 5 and ev.area == 1.0 and ev.precision == 1.0 and ev.noise == 0
    valid = np.ones(truth.shape, bool)
    valid[0:10, 0:5] = False  # half of A has no reading: a segmentation can only see the rest
    labels = np.where(valid, truth, 0)
    assert evaluate(labels, truth, valid=valid).score(1).coverage == 1.0
    assert evaluate(labels, truth).score(1).coverage == pytest.approx(0.5)


def test_evaluate_rejects_bad_input() -> None:
    with pytest.raises(InputError, match="same shape"):
        evaluate(np.zeros((3, 3), np.int32), np.zeros((3, 4), np.int32))
    with pytest.raises(InputError, match="tolerance"):
        evaluate(np.zeros((3, 3), np.int32), np.zeros((3, 3), np.int32), tolerance=0.3)


def test_compiled_statistics_equal_the_bincount_reference() -> None:
    rng = np.random.default_rng(3)
    labels = rng.integers(0, 6, size=(37, 53)).astype(np.int32)
    depth = rng.uniform(500, 4000, size=labels.shape).astype(np.float32)
    fast = label_stats(labels, depth, 5, metric=True)
    ref = label_stats_bincount(labels, depth, 5, metric=True)
    for name in ("count", "sz", "szz", "sx", "sy", "sxz", "syz"):
        np.testing.assert_allclose(getattr(fast, name)[1:], getattr(ref, name)[1:], rtol=1e-9)
    ys, xs = np.nonzero(labels == 4)
    assert fast.boxes is not None
    assert tuple(fast.boxes[4]) == (xs.min(), ys.min(), xs.max(), ys.max())
