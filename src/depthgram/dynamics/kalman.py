"""A constant-velocity Kalman filter on depth and radial velocity, for many tracks at once.

State per track: depth z (mm) and radial velocity v (mm/s); the process noise is white
acceleration of standard deviation ``accel_sigma`` (mm/s^2) held over each step; the
measurement is the object's depth with a sensor noise that grows with the square of the
depth (time-of-flight and structured light, :func:`depth_sigma`). Every function works on
arrays of tracks (numpy, no per-track Python loop): the tracker updates a few dozen per frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["depth_sigma", "gate", "init", "predict", "update"]

F64 = NDArray[np.float64]


def depth_sigma(z_mm: F64 | float, sigma_1m_mm: float, floor_mm: float) -> F64:
    """Standard deviation of a depth reading (mm): ``floor + sigma_1m * (z / 1 m)^2``."""
    z = np.asarray(z_mm, dtype=np.float64)
    return np.asarray(floor_mm + sigma_1m_mm * (z / 1000.0) ** 2, dtype=np.float64)


def init(x: F64, p: F64, rows: NDArray[np.bool_], z: F64, r: F64, v_sigma0: float) -> None:
    """Start the state of ``rows`` at depth ``z`` (mm), velocity 0 with ``v_sigma0`` (mm/s)."""
    x[rows, 0] = z[rows]
    x[rows, 1] = 0.0
    p[rows] = 0.0
    p[rows, 0, 0] = r[rows]
    p[rows, 1, 1] = v_sigma0 * v_sigma0


def predict(x: F64, p: F64, dt: float, accel_sigma: float) -> None:
    """Advance every state by ``dt`` seconds in place (``F = [[1, dt], [0, 1]]``)."""
    x[:, 0] += dt * x[:, 1]
    p00, p01, p11 = p[:, 0, 0].copy(), p[:, 0, 1].copy(), p[:, 1, 1].copy()
    q = accel_sigma * accel_sigma
    p[:, 0, 0] = p00 + 2 * dt * p01 + dt * dt * p11 + q * dt**4 / 4
    p[:, 0, 1] = p[:, 1, 0] = p01 + dt * p11 + q * dt**3 / 2
    p[:, 1, 1] = p11 + q * dt * dt


def gate(x: F64, p: F64, z: F64, r: F64) -> F64:
    """Normalised innovation ``(z - z_pred) / sqrt(S)`` of each row (dimensionless)."""
    return np.asarray((z - x[:, 0]) / np.sqrt(p[:, 0, 0] + r), dtype=np.float64)


def update(x: F64, p: F64, rows: NDArray[np.bool_], z: F64, r: F64) -> None:
    """Fold the depth measurements ``z`` (mm, variance ``r`` mm^2) of ``rows`` into the state."""
    xs, ps = x[rows], p[rows]
    s = ps[:, 0, 0] + r[rows]
    k0, k1 = ps[:, 0, 0] / s, ps[:, 1, 0] / s
    y = z[rows] - xs[:, 0]
    xs[:, 0] += k0 * y
    xs[:, 1] += k1 * y
    p00, p01, p11 = ps[:, 0, 0].copy(), ps[:, 0, 1].copy(), ps[:, 1, 1].copy()
    ps[:, 0, 0] = (1 - k0) * p00
    ps[:, 0, 1] = ps[:, 1, 0] = (1 - k0) * p01
    ps[:, 1, 1] = p11 - k1 * p01
    x[rows], p[rows] = xs, ps
