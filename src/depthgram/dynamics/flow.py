"""Radial range flow from queues of mean depths (paper, section 5, equation 13).

The paper takes ``v = Δdepth / inter-frame time`` over the last two frames and notes that
averaging over three or more makes it more robust at the price of latency. With a queue of
N entries the natural generalisation is the least-squares slope of depth against time over
the valid entries; for two entries it is exactly equation 13. Functions here work on many
tracks at once: one row per track, one column per queue slot.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["fit_radial_velocity", "time_to_collision"]


def fit_radial_velocity(
    times: ArrayLike, depths: ArrayLike, t_now: float | ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Least-squares radial velocity over the valid entries of each queue.

    Parameters
    ----------
    times : array_like, shape (T, N) or (N,)
        Time of each queue entry: seconds, or frame numbers when no period is known.
    depths : array_like, shape (T, N) or (N,)
        Mean depth (mm) of each entry; NaN marks an invalid entry (occluded, entering,
        leaving, split or merged), which is skipped, never read as zero.
    t_now : float or array_like of shape (T,), optional
        Time at which to evaluate the fitted depth; default the last entry's time.

    Returns
    -------
    v : ndarray of float, shape (T,) or ()
        Slope (mm/s, or mm/frame with frame-number times). Positive means receding. NaN when
        fewer than two valid entries exist or they share one time.
    z_now : ndarray of float, shape (T,) or ()
        Fitted depth at ``t_now`` (mm); the last valid depth when the slope is undefined,
        NaN when there is no valid entry.
    """
    t = np.asarray(times, dtype=np.float64)
    z = np.asarray(depths, dtype=np.float64)
    one = t.ndim == 1
    t2 = np.atleast_2d(t)
    z2 = np.atleast_2d(z)
    if t_now is None:
        tn = t2[:, -1]
    else:
        tn = np.broadcast_to(np.asarray(t_now, dtype=np.float64), t2.shape[:1])
    ok = np.isfinite(z2) & np.isfinite(t2)
    w = ok.astype(np.float64)
    n = w.sum(axis=1)
    # Centre on t_now so that large timestamps (Unix seconds) keep full precision.
    tc = np.where(ok, t2 - tn[:, None], 0.0)
    zc = np.where(ok, z2, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        tb = tc.sum(axis=1) / n
        zb = zc.sum(axis=1) / n
        dt = np.where(ok, tc - tb[:, None], 0.0)
        den = (dt * dt).sum(axis=1)
        num = (dt * (zc - zb[:, None])).sum(axis=1)
        good = (n >= 2) & (den > 0)
        v = np.where(good, num / np.where(good, den, 1.0), np.nan)
        z_fit = zb - v * tb
    # Without a slope, the best depth estimate is the most recent valid one.
    last_idx = z2.shape[1] - 1 - np.argmax(ok[:, ::-1], axis=1)
    last_z = np.where(n > 0, z2[np.arange(z2.shape[0]), last_idx], np.nan)
    z_now = np.where(good, z_fit, last_z)
    if one:
        return v[0], z_now[0]
    return v, z_now


def time_to_collision(depth: ArrayLike, v_radial: ArrayLike, min_speed: float) -> NDArray[np.float64]:
    """Time to collision: depth over closing speed, for approaching objects only.

    Parameters
    ----------
    depth : array_like
        Current depth (mm).
    v_radial : array_like
        Radial velocity (mm/s or mm/frame); negative means approaching. NaN gives NaN.
    min_speed : float
        Speed below which the object is still (same unit as ``v_radial``).

    Returns
    -------
    ndarray of float
        ``depth / -v_radial`` (s, or frames) where ``v_radial < -min_speed`` and the depth is
        positive; NaN for receding, still or unknown motion.
    """
    z = np.asarray(depth, dtype=np.float64)
    v = np.asarray(v_radial, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        approaching = (v < -min_speed) & (z > 0)
        return np.where(approaching, z / np.where(approaching, -v, 1.0), np.nan)
