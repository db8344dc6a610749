"""Latency of sonification and action planning: milliseconds per frame.

Run: ``.venv/bin/python benchmarks/bench_sound.py`` (``--quick`` for a shorter run).
Scene: ~10 objects plus two oblique surfaces on a 176x132 frame (the paper's sensor), with
intrinsics for the plan's clearance channel. The target is under 5 ms of audio work per frame.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

W, H = 176, 132


def _median_ms(fn: Callable[[], Any], reps: int) -> tuple[float, float]:
    """(median, best) time per call in ms after one warm-up call."""
    fn()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1000 * float(np.median(times)), 1000 * float(np.min(times))


def _scene(n_objects: int = 10) -> Any:
    from depthgram.scene.tree import Node, SceneTree

    rng = np.random.default_rng(0)
    nodes = [
        Node(
            i + 1,
            "object",
            i,
            float(500 + 300 * i),
            int(rng.integers(50, 2000)),
            (float(rng.uniform(0, W - 1)), float(rng.uniform(0, H - 1))),
            v_radial=-300.0,
            ttc=2.0 + i,
        )
        for i in range(n_objects)
    ]
    nodes += [Node(50, "wall", 2, 1500.0, 3000, (10.0, 60.0)), Node(51, "floor", 3, 1800.0, 4000, (88.0, 120.0))]
    return SceneTree(Node(0, "Bkg", -1, 0.0, W * H, (W / 2, H / 2), children=tuple(nodes)))


def rows(*, quick: bool = False, samplerate: int = 22050) -> list[dict[str, Any]]:
    """Timings per case: name, objects, audio seconds per call, median and best ms per call."""
    from depthgram.act import plan
    from depthgram.frame import Intrinsics, make_frame
    from depthgram.sound import Sonifier, SoundMapping, render_scene

    reps = 20 if quick else 200
    tree = _scene(10)
    out: list[dict[str, Any]] = []
    for preset in ("default", "detailed"):
        m = SoundMapping.preset(preset)
        s = Sonifier(m, samplerate, (W, H))
        med, best = _median_ms(lambda s=s: s.push(tree, 1 / 30), reps)
        out.append({"case": f"Sonifier.push 1/30 s ({preset})", "audio_s": 1 / 30, "median_ms": med, "best_ms": best})
        med, best = _median_ms(
            lambda m=m: render_scene(tree, (W, H), mapping=m, samplerate=samplerate), max(reps // 4, 5)
        )
        out.append({"case": f"render_scene 0.5 s ({preset})", "audio_s": 0.5, "median_ms": med, "best_ms": best})
    depth = np.full((H, W), 3000.0, np.float32)
    depth[30:100, 40:90] = 800.0
    frame = make_frame(depth, intrinsics=Intrinsics(150.0, 150.0, 87.5, 65.5))
    med, best = _median_ms(lambda: plan(tree, frame), reps)
    out.append({"case": "act.plan + channel", "audio_s": 0.0, "median_ms": med, "best_ms": best})
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Print ms per frame for each case; exit 0."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--quick", action="store_true", help="fewer repetitions")
    p.add_argument("--samplerate", type=int, default=22050)
    args = p.parse_args(argv)
    print(f"frame {W}x{H}, 10 objects + wall + floor, samplerate {args.samplerate} Hz")
    print(f"{'case':<36} {'audio s':>8} {'median ms':>10} {'best ms':>8}")
    for r in rows(quick=args.quick, samplerate=args.samplerate):
        print(f"{r['case']:<36} {r['audio_s']:>8.3f} {r['median_ms']:>10.3f} {r['best_ms']:>8.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
