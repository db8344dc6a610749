"""The default segmentation's two window sums: OpenCV's box filter against the fused kernels.

On the simulated ``table`` frame (seed 0) at 176 x 132 and 320 x 240 (the grid a 640 x 480 frame
is segmented on), thread CPU time, median of repeated calls on the same arguments:

- orientation field, 7 x 7: ``cv2.boxFilter`` of the three kept-slope channels plus
  ``orientation._classify`` (the route a refused frame takes) against
  ``orientation._classify_window`` (the sums taken inside the classes' pass);
- creases, 3 x 3: ``creases._window_sums`` (OpenCV) plus ``_kernels.creases.crease_state_from_sums`` against
  ``_kernels.creases.crease_state_window``;
- each filter alone (OpenCV) and the whole ``orientation_classes`` / ``crease_state`` calls.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/bench_window_sums.py`` (use a fresh
``NUMBA_CACHE_DIR`` after changing a kernel in another module).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import cv2
import numpy as np

from depthgram.segmentation import creases, orientation
from depthgram.segmentation._kernels import creases as kernels
from depthgram.segmentation.noise_model import PROFILES
from depthgram.sensor import simulate


def median_us(fn: Callable[[], object], n: int = 600) -> float:
    """Median thread CPU time (us) of ``n`` calls after a first untimed one."""
    fn()
    ts = []
    for _ in range(n):
        t0 = time.thread_time()
        fn()
        ts.append(time.thread_time() - t0)
    return float(np.median(ts)) * 1e6


def steps(w: int, h: int) -> list[tuple[str, Callable[[], object]]]:
    """The timed calls on the ``table`` frame at ``w`` x ``h``."""
    f32 = np.float32
    f = next(iter(simulate("table", 1, size=(w, h), seed=0))).frame
    z, ok, cam = np.ascontiguousarray(f.depth), np.ascontiguousarray(f.valid), f.intrinsics
    inv = kernels.inverse_depth(z, ok)
    steep = f32(math.tan(math.radians(80.0)))
    inv3, kept, edge, ranges = orientation._slopes(inv, z, ok, 3, f32(cam.fx), f32(cam.fy), steep, f32(0.05))
    c = (f32(cam.fx), f32(cam.fy), f32(cam.cx), f32(cam.cy), f32(math.cos(math.radians(35.0))))
    img = cv2.merge(list(kept))

    def box7() -> np.ndarray:
        return np.asarray(cv2.boxFilter(img, -1, (7, 7), normalize=False, borderType=cv2.BORDER_REPLICATE))

    sums7 = box7()
    k, r = 3, creases.crease_scale_px(w)
    cr = (np.array([1.0, 2e-6, 0.5, 1e-6], f32), f32(0.5 * k * k))
    tail = (f32(r * math.tan(math.radians(20.0)) / cam.fx), f32(math.sqrt(6.0) / (0.7 * k)))
    sums3 = creases._window_sums(inv, k)
    facing = ok.copy()
    sensor = PROFILES["kinect-v1"]
    return [
        ("7x7 OpenCV box filter alone", box7),
        ("7x7 OpenCV + _classify", lambda: orientation._classify(box7(), inv3, ok, edge, *c)),
        ("7x7 _classify alone (sums given)", lambda: orientation._classify(sums7, inv3, ok, edge, *c)),
        ("7x7 _classify_window", lambda: orientation._classify_window(kept, ranges, 7, inv3, ok, edge, *c)),
        ("3x3 OpenCV box filter alone", lambda: creases._window_sums(inv, k)),
        (
            "3x3 OpenCV + _crease_state",
            lambda: kernels.crease_state_from_sums(creases._window_sums(inv, k), ok, facing, *cr, r, *tail),
        ),
        (
            "3x3 _crease_state alone (sums given)",
            lambda: kernels.crease_state_from_sums(sums3, ok, facing, *cr, r, *tail),
        ),
        ("3x3 _crease_state_window", lambda: kernels.crease_state_window(inv, ok, facing, *cr, k, r, *tail)),
        ("orientation_classes (1/Z given)", lambda: orientation.orientation_classes(z, ok, cam, inverse=inv)),
        (
            "crease_state (1/Z given)",
            lambda: creases.crease_state(
                z, ok, facing, sensor, scale_px=r, min_angle_deg=20.0, focal_px=cam.fx, inverse=inv
            ),
        ),
    ]


def main() -> None:
    """Print the table."""
    print(f"{'size':>8} {'step':<44} {'us':>8}")
    for w, h in ((176, 132), (320, 240)):
        for name, fn in steps(w, h):
            print(f"{w}x{h:<4} {name:<44} {median_us(fn):8.1f}", flush=True)


if __name__ == "__main__":
    main()
