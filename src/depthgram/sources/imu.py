"""Gravity from a recording's accelerometer, turned into the depth camera's frame.

An accelerometer at rest reads the specific force, which points up with the size of g: the
direction of gravity is minus the reading. A hand-held or worn camera accelerates too, so the
readings are low-passed (:class:`GravityFilter`, a time constant of half a second: a walking
body's sway averages out, a turn of the camera is followed within a second). The IMU's axes are
not the depth image's: ROS says how they relate in ``/tf_static`` (:class:`StaticFrames`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

__all__ = ["GravityFilter", "StaticFrames"]

#: Low-pass time constant of the accelerometer (s).
TAU_S = 0.5

#: Readings whose size is this far from g (relative) are a knock or a fall, not gravity: skipped.
_G = 9.80665
_OFF_G = 0.5


class GravityFilter:
    """Direction of gravity in the IMU's axes, low-passed from accelerometer readings.

    Parameters
    ----------
    tau_s : float
        Time constant (s) of the exponential low-pass.
    """

    def __init__(self, tau_s: float = TAU_S) -> None:
        self.tau_s = tau_s
        self._mean: NDArray[np.float64] | None = None
        self._t: float | None = None

    def add(self, accel: tuple[float, float, float], t_s: float) -> None:
        """Take one reading: the specific force (m/s^2, any consistent unit) at time ``t_s`` (s)."""
        a = np.asarray(accel, dtype=np.float64)
        size = float(np.linalg.norm(a))
        if not (np.all(np.isfinite(a)) and size > 0):
            return
        # a unit that is not m/s^2 (some drivers give g) still has a steady size: judge by the first ones
        if self._mean is not None and abs(size / float(np.linalg.norm(self._mean)) - 1.0) > _OFF_G:
            return
        if self._mean is None or self._t is None:
            self._mean = a
        else:
            dt = max(0.0, t_s - self._t)
            alpha = 1.0 - math.exp(-dt / self.tau_s) if self.tau_s > 0 else 1.0
            self._mean = self._mean + alpha * (a - self._mean)
        self._t = t_s

    def down(self) -> NDArray[np.float64] | None:
        """Return the unit vector toward the ground in the IMU's axes, or None before any reading."""
        if self._mean is None:
            return None
        n = float(np.linalg.norm(self._mean))
        return None if n == 0 else -self._mean / n


class StaticFrames:
    """Static transforms between named frames (``/tf_static``): only their rotations are needed."""

    def __init__(self) -> None:
        self._parent: dict[str, tuple[str, Rotation]] = {}

    def add(self, parent: str, child: str, quat_xyzw: tuple[float, float, float, float]) -> None:
        """Record that ``child``'s axes are ``quat_xyzw`` (x, y, z, w) in ``parent``'s."""
        q = np.asarray(quat_xyzw, dtype=np.float64)
        if not (np.all(np.isfinite(q)) and np.linalg.norm(q) > 0):
            return
        self._parent[child.lstrip("/")] = (parent.lstrip("/"), Rotation.from_quat(q))

    def _to_root(self, frame: str) -> tuple[str, Rotation]:
        """Return the root of ``frame``'s tree and ``frame``'s axes in it."""
        rot = Rotation.identity()
        seen = {frame}
        while frame in self._parent:
            parent, r = self._parent[frame]
            rot = r * rot
            frame = parent
            if frame in seen:  # a loop in a damaged bag: stop
                break
            seen.add(frame)
        return frame, rot

    def rotation(self, to_frame: str, from_frame: str) -> NDArray[np.float64] | None:
        """Return the 3x3 matrix taking vectors in ``from_frame``'s axes to ``to_frame``'s, or None when unlinked."""
        to_frame, from_frame = to_frame.lstrip("/"), from_frame.lstrip("/")
        if to_frame == from_frame:
            return np.eye(3)
        root_a, a = self._to_root(to_frame)
        root_b, b = self._to_root(from_frame)
        if root_a != root_b:
            return None
        return np.asarray((a.inv() * b).as_matrix(), dtype=np.float64)
