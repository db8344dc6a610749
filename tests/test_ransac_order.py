"""RANSAC scoring in the order of the first block's counts (``_kernels.ransac.best_hypothesis``).

The hypotheses are scored on a first block of points, then each in the order of those counts,
and left when they can no longer be chosen; the choice must stay ``np.argmax`` of the full
scores (the first of equal counts), which the scoring in index order
(``reference.best_hypothesis_in_index_order``) gave.
"""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.segmentation._kernels.ransac import best_hypothesis as _best_hypothesis
from reference import best_hypothesis_in_index_order


def _scores(coef: np.ndarray, u: np.ndarray, v: np.ndarray, z: np.ndarray, tol: np.ndarray) -> np.ndarray:
    # the numpy route's test, every hypothesis against every point
    inv = coef[:, :1] * u + coef[:, 1:2] * v + coef[:, 2:3]
    on = (inv > 0) & (np.abs(1000.0 - z * inv) <= tol * inv)
    return on.sum(axis=1)


def _scene(rng: np.random.Generator, n: int) -> tuple[np.ndarray, ...]:
    # grid points on a few planes 1000 / z = a u + b v + c, with noise and outliers
    u = rng.integers(0, 640, n).astype(np.float64)
    v = rng.integers(0, 480, n).astype(np.float64)
    planes = np.column_stack([rng.normal(0, 2e-4, 4), rng.normal(0, 2e-4, 4) + 1e-4, rng.uniform(0.3, 1.5, 4)])
    which = rng.integers(0, 4, n)
    inv = planes[which, 0] * u + planes[which, 1] * v + planes[which, 2]
    inv = np.where(inv > 0.05, inv, 0.5)
    z = np.round(1000.0 / inv * (1 + rng.normal(0, 0.004, n)))
    out = rng.random(n) < 0.1
    z[out] = np.round(rng.uniform(300, 5000, int(out.sum())))
    tol = np.maximum(np.float32(8.0), np.float32(0.012) * z.astype(np.float32)).astype(np.float64)
    return u, v, z, tol, planes


def _hypotheses(rng: np.random.Generator, planes: np.ndarray, k: int) -> np.ndarray:
    # near the true planes, some anywhere, and exact copies of a few rows (equal counts
    # anywhere in the order)
    coef = planes[rng.integers(0, planes.shape[0], k)] * (1 + rng.normal(0, 0.02, (k, 3)))
    wild = rng.random(k) < 0.2
    m = int(wild.sum())
    coef[wild] = np.column_stack([rng.normal(0, 2e-4, m), rng.normal(0, 2e-4, m), rng.uniform(0.3, 1.5, m)])
    dup = rng.integers(0, k, k // 3)
    coef[rng.integers(0, k, k // 3)] = coef[dup]
    return coef


@pytest.mark.parametrize("seed", range(8))
def test_ordered_scoring_picks_numpys_argmax(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for n in (3, 40, 255, 256, 257, 300, 700, 1544, 2000, 3100):
        u, v, z, tol, planes = _scene(rng, n)
        k = int(rng.integers(1, 129))
        coef = _hypotheses(rng, planes, k)
        # every point, or (beyond 2000) 2000 drawn with repeats, as the search scores them
        ev = np.arange(n) if n <= 2000 else rng.integers(0, n, 2000)
        want = int(np.argmax(_scores(coef, u[ev], v[ev], z[ev], tol[ev])))
        assert _best_hypothesis(coef, u, v, z, tol, ev) == want
        assert best_hypothesis_in_index_order(coef, u, v, z, tol, ev) == want


def test_ordered_scoring_keeps_the_first_of_equal_counts() -> None:
    # two planes with 400 points each, the first plane's points all after the first block: its
    # hypothesis (index 0, or later) comes last in the first block's order, the other one is
    # scored first and holds the best count, and the first in index order must still win
    rng = np.random.default_rng(5)
    u = rng.integers(0, 640, 900).astype(np.float64)
    v = rng.integers(0, 480, 900).astype(np.float64)
    p1 = np.array([1e-4, 2e-4, 0.5])
    p2 = np.array([-1e-4, 3e-4, 0.4])
    on2 = np.arange(900) < 400  # the first 400 points (the first block) on the second plane
    on1 = np.arange(900) >= 500  # the last 400 on the first
    inv = np.where(on2, p2[0] * u + p2[1] * v + p2[2], p1[0] * u + p1[1] * v + p1[2])
    z = 1000.0 / inv
    z[~on1 & ~on2] = 20_000.0  # on neither
    tol = np.full(900, 8.0)
    wild = np.array([[0.0, 0.0, 0.01]])
    for coef in (np.vstack([p1, p2]), np.vstack([wild, p1, wild, p2, p1]), np.vstack([p2, p1])):
        counts = _scores(coef, u, v, z, tol)
        assert np.sort(counts)[-2] == counts.max() == 400  # a tie for the most
        want = int(np.argmax(counts))
        assert _best_hypothesis(coef, u, v, z, tol, np.arange(900)) == want
        assert best_hypothesis_in_index_order(coef, u, v, z, tol, np.arange(900)) == want
    # all hypotheses equal: the first
    same = np.repeat(p1[None], 20, axis=0)
    assert _best_hypothesis(same, u, v, z, tol, np.arange(900)) == 0


def test_plane_pieces_percentiles_are_numpys() -> None:
    # a found plane's depth spread: np.percentile(z_sub[pieces], (5, 50, 95)), ties and one or
    # two pixels too
    from depthgram.segmentation.order_stats import percentile32

    rng = np.random.default_rng(9)
    for _ in range(400):
        n = int(rng.integers(1, 900))
        a = np.round(rng.uniform(300, 300 + float(rng.choice([0, 3, 50, 4000])), n)).astype(np.float32)
        want = np.percentile(a, (5, 50, 95))
        assert tuple(want) == tuple(percentile32(a.copy(), q, False) for q in (5.0, 50.0, 95.0))
