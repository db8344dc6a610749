"""The compiled gate of the raised pass (:mod:`depthgram.segmentation.raised`): a support's block plane.

numpy does the same on a few hundred blocks in about eighty calls, whose overhead (100-130 us a
support) was most of the pass on a frame whose supports are bare; the loops below read the
samples once and fit the blocks in a few microseconds.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

#: what :func:`block_gate` says of a support
NOTHING, PLANE, FEW_BLOCKS, FEW_READINGS = 0, 1, 2, 3


@njit(cache=True, nogil=True)
def _fit(
    mu: NDArray[np.float64], mv: NDArray[np.float64], mq: NDArray[np.float64], keep: NDArray[np.bool_]
) -> NDArray[np.float64]:
    # least squares of mq = a mu + b mv + c over the kept blocks: the normal equations' sums in
    # one pass, solved by LAPACK (numba's np.linalg.solve)
    s_uu = s_uv = s_u = s_vv = s_v = s_1 = s_uq = s_vq = s_q = 0.0
    for i in range(mu.size):
        if keep[i]:
            u, v, q = mu[i], mv[i], mq[i]
            s_uu += u * u
            s_uv += u * v
            s_u += u
            s_vv += v * v
            s_v += v
            s_1 += 1.0
            s_uq += u * q
            s_vq += v * q
            s_q += q
    a = np.array([[s_uu, s_uv, s_u], [s_uv, s_vv, s_v], [s_u, s_v, s_1]])
    if abs(np.linalg.det(a)) < 1e-300:  # fewer than three blocks, or all on one line
        return np.zeros(3)
    return np.linalg.solve(a, np.array([s_uq, s_vq, s_q]))


@njit(cache=True, nogil=True)
def _above(
    coef: NDArray[np.float64], mu: NDArray[np.float64], mv: NDArray[np.float64], z: NDArray[np.float64]
) -> NDArray[np.float64]:
    out = np.empty(z.size)
    for i in range(z.size):
        out[i] = 1000.0 / max(coef[0] * mu[i] + coef[1] * mv[i] + coef[2], 1e-12) - z[i]
    return out


@njit(cache=True, nogil=True)
def block_gate(
    labels: NDArray[np.int32],
    sid: int,
    horizontal: NDArray[np.bool_],
    depth: NDArray[np.float32],
    x0: int,
    y0: int,
    x1: int,
    y1: int,
    s: int,
    target_blocks: float,
    min_readings: float,
    sigma_0: float,
    sigma_2: float,
    step_0: float,
    step_2: float,
    k_sigma: float,
    rounds: int,
) -> tuple[int, NDArray[np.float64]]:
    # every s-th pixel of the box (x0, y0, x1, y1, exclusive) on the support and horizontal,
    # averaged over blocks of b x b samples, as raised._block_plane describes (the sensor's
    # sigma and step are sigma_0 + sigma_2 Z^2 and step_0 + step_2 Z^2, mm)
    h, w = y1 - y0, x1 - x0
    gh0, gw0 = (h + s - 1) // s, (w + s - 1) // s
    n_on = 0
    for i in range(gh0):
        for j in range(gw0):
            y, x = y0 + i * s, x0 + j * s
            if labels[y, x] == sid and horizontal[y, x]:
                n_on += 1
    if n_on * s * s < min_readings:
        return FEW_READINGS, np.zeros(3)
    b = max(2, round(math.sqrt(gh0 * gw0 / target_blocks)))
    gh, gw = gh0 // b, gw0 // b
    if gh * gw < 12:
        return FEW_BLOCKS, np.zeros(3)
    # the blocks wholly on the support: their mean 1000/Z (float32 sums, as OpenCV's area resize)
    mq = np.empty(gh * gw)
    mu = np.empty(gh * gw)
    mv = np.empty(gh * gw)
    n = 0
    cell = float(s * b)
    centre = s * (b - 1) / 2.0
    for r in range(gh):
        for c in range(gw):
            full = True
            acc = np.float32(0.0)
            for i in range(r * b, r * b + b):
                y = y0 + i * s
                for j in range(c * b, c * b + b):
                    x = x0 + j * s
                    if labels[y, x] != sid or not horizontal[y, x]:
                        full = False
                        break
                    acc += np.float32(1000.0) / max(depth[y, x], np.float32(1.0))
                if not full:
                    break
            if full:
                mq[n] = acc / np.float32(b * b)
                mu[n] = c * cell + (centre - (w - 1) / 2.0)
                mv[n] = r * cell + (centre - (h - 1) / 2.0)
                n += 1
    if n < 6:
        return NOTHING, np.zeros(3)
    mq, mu, mv = mq[:n], mu[:n], mv[:n]
    z = 1000.0 / mq
    sigma = sigma_0 + sigma_2 * z * z
    limit = (k_sigma / b) * sigma + (step_0 + step_2 * z * z)
    gate = np.maximum(limit, 2.0 * sigma)
    keep = np.ones(n, np.bool_)
    coef = _fit(mu, mv, mq, keep)
    above = _above(coef, mu, mv, z)
    if not np.any(above > gate):
        return NOTHING, coef
    # the upper medians of the residuals and of their deviations, one-sided cut
    mid = np.sort(above)[n // 2]
    spread = 1.4826 * np.sort(np.abs(above - mid))[n // 2]
    keep = above - mid < np.maximum(2.5 * spread, limit)
    for _ in range(rounds):
        if np.count_nonzero(keep) < 3:
            break
        coef = _fit(mu, mv, mq, keep)
        above = _above(coef, mu, mv, z)
        keep = above < limit
    return (PLANE if np.any(above > gate) else NOTHING), coef
