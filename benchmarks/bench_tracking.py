"""Cost of one tracker update, and tracking quality on simulated and real sequences.

Run ``python benchmarks/bench_tracking.py`` (``--quick`` for fewer frames, ``--no-quality``
for timing only). Prints microseconds per :meth:`depthgram.dynamics.Tracker.update` for 5,
30 and 100 objects (target: under 200 µs for 30), then, when the simulator and segmentation
are available, velocity error, identity switches and lost tracks on the ``approach`` and
``crossing`` scenes, and the distribution of |v_radial| on the real 7-Scenes sequence.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

import numpy as np

from depthgram.dynamics import Tracker
from depthgram.segment.objects import SceneObject

W, H = 640, 480


def _scene(n: int, frames: int, seed: int) -> list[list[SceneObject]]:
    """``n`` boxes drifting on a grid, depths changing, a few missing each frame."""
    rng = np.random.default_rng(seed)
    g = int(np.ceil(np.sqrt(n)))
    base = np.array([((i % g + 0.5) * W / g, (i // g + 0.5) * H / g) for i in range(n)])
    vel = rng.normal(0, 1.0, (n, 2))
    z0 = rng.uniform(800, 4000, n)
    vz = rng.normal(0, 10, n)
    side = max(4, int(0.4 * min(W, H) / g))
    out = []
    for k in range(frames):
        objs = []
        present = rng.random(n) > 0.03
        for i in np.flatnonzero(present):
            cx, cy = base[i] + vel[i] * k
            z = z0[i] + vz[i] * k + rng.normal(0, 3)
            x0, y0 = int(cx - side / 2), int(cy - side / 2)
            bbox = (x0, y0, x0 + side - 1, y0 + side - 1)
            area = side * side
            obj = SceneObject(int(i) + 1, "object", int(z // 500), float(z), 5.0, area, area / (W * H), (cx, cy), bbox)
            objs.append(obj)
        out.append(objs)
    return out


def timing_rows(counts: Sequence[int] = (5, 30, 100), frames: int = 300, repeats: int = 3) -> list[dict[str, float]]:
    """Microseconds per update for each object count (best of ``repeats`` runs, mean per frame).

    Returns
    -------
    list of dict
        ``objects``, ``us_per_update``, ``tracks_alive`` (at the end).
    """
    rows = []
    for n in counts:
        seq = _scene(n, frames, seed=n)
        best = float("inf")
        alive = 0
        for _ in range(repeats):
            tr = Tracker()
            t0 = time.perf_counter()
            for k, objs in enumerate(seq):
                tr.update(objs, k / 30.0, (W, H))
            best = min(best, (time.perf_counter() - t0) / frames)
            alive = len(tr.tracks)
        rows.append({"objects": float(n), "us_per_update": best * 1e6, "tracks_alive": float(alive)})
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Print the figures; return 0."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="fewer frames")
    p.add_argument("--no-quality", action="store_true", help="timing only")
    args = p.parse_args(argv)
    frames = 60 if args.quick else 300
    print("tracker update cost (synthetic boxes, 30 Hz, 3 % missed detections)")
    for r in timing_rows(frames=frames):
        n, us, alive = int(r["objects"]), r["us_per_update"], int(r["tracks_alive"])
        print(f"  {n:4d} objects: {us:8.1f} µs/update ({alive} tracks)")
    if not args.no_quality:
        try:
            from quality_tracking import quality_report  # type: ignore[import-not-found]
        except ImportError:
            quality_report = None
        if quality_report is not None:
            quality_report(quick=args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
