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

from depthgram.dynamics.kernels import fit_row
from depthgram.errors import InputError

__all__ = ["fit_radial_velocity", "fit_row", "time_to_collision"]


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
    if t.shape != z.shape or t.ndim not in (1, 2):
        raise InputError(f"fit_radial_velocity: times {t.shape} and depths {z.shape} must be equal 1-D or 2-D")
    one = t.ndim == 1
    t2 = np.ascontiguousarray(np.atleast_2d(t))
    z2 = np.ascontiguousarray(np.atleast_2d(z))
    tn = t2[:, -1] if t_now is None else np.asarray(t_now, dtype=np.float64)
    tn = np.ascontiguousarray(np.broadcast_to(tn, t2.shape[:1]))
    v, zn = _fit_rows(t2, z2, tn)
    if one:
        return v[0], zn[0]
    return v, zn


def _fit_rows(
    t: NDArray[np.float64], z: NDArray[np.float64], t_now: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`fit_row` of every row's queue, in numpy: the slope and the fitted depth at ``t_now``."""
    ok = np.isfinite(z) & np.isfinite(t)
    n = ok.sum(axis=1)
    rows = np.arange(z.shape[0])
    # the last valid depth of each row (NaN without one)
    last = np.where(n > 0, z[rows, z.shape[1] - 1 - np.argmax(ok[:, ::-1], axis=1)], np.nan)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        # centred on t_now so that large timestamps (Unix seconds) keep full precision
        dt = np.where(ok, t - t_now[:, None], 0.0)
        zz = np.where(ok, z, 0.0)
        tb = dt.sum(axis=1) / n
        zb = zz.sum(axis=1) / n
        d = np.where(ok, dt - tb[:, None], 0.0)
        num = (d * np.where(ok, zz - zb[:, None], 0.0)).sum(axis=1)
        den = (d * d).sum(axis=1)
        fit = (n >= 2) & (den > 0.0)
        v = np.where(fit, num / den, np.nan)
        return v, np.where(fit, zb - v * tb, last)


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
