"""Time the scene stage: build_tree + to_sentence for 20 objects at 640x480, beside segmentation.

The budget: building the tree and the sentence must add under 10 % to the segmentation time
(the paper's real-time aim; 10 % of 3.3 ms = 0.33 ms when segmentation is not importable).

Run: ``.venv/bin/python benchmarks/bench_scene.py [--repeats N] [--objects N]``
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from collections.abc import Callable, Sequence

import numpy as np

from depthgram.scene import build_tree, parse_sentence, to_sentence
from depthgram.segmentation.objects import SceneObject

W, H = 640, 480
BUDGET_FALLBACK_MS = 0.33


def synthetic_scene(n_objects: int = 20, seed: int = 0) -> tuple[np.ndarray, np.ndarray, list[SceneObject]]:
    """A 640x480 depth image: a floor ramp and ``n_objects`` boxes at distinct depths, with its objects."""
    rng = np.random.default_rng(seed)
    rows = np.arange(H, dtype=np.float32)[:, None]
    depth = np.broadcast_to(6000.0 - 9.0 * rows, (H, W)).astype(np.float32).copy()
    lab = np.zeros((H, W), np.int32)
    lab[H // 2 :, :] = 1
    zs = np.linspace(700.0, 4500.0, n_objects)
    for i in range(n_objects):
        w, h = rng.integers(20, 70, 2)
        x0, y0 = rng.integers(0, W - w), rng.integers(40, H - h)
        depth[y0 : y0 + h, x0 : x0 + w] = zs[i] + rng.normal(0.0, 5.0, (h, w))
        lab[y0 : y0 + h, x0 : x0 + w] = i + 2
    objs = []
    for i in np.unique(lab[lab > 0]).tolist():
        ys, xs = np.nonzero(lab == i)
        d = depth[ys, xs]
        objs.append(
            SceneObject(
                int(i),
                "floor" if i == 1 else "object",
                int(i) - 1,
                float(d.mean()),
                float(d.std()),
                int(d.size),
                d.size / (W * H),
                (float(xs.mean()), float(ys.mean())),
                (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1),
            )
        )
    return depth, lab, objs


def _best_ms(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm caches (lark parser, numba)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def rows(n_objects: int = 20, repeats: int = 50) -> list[dict[str, object]]:
    """Timings (best of ``repeats``, ms) of each step; one dict per step."""
    depth, lab, objs = synthetic_scene(n_objects)
    out: list[dict[str, object]] = []
    seg_ms: float | None = None
    if importlib.util.find_spec("depthgram.segmentation.core") is not None:
        from depthgram.segmentation import segment

        valid = depth > 0
        seg_ms = _best_ms(lambda: segment(depth, valid=valid), max(3, repeats // 10))
        seg = segment(depth, valid=valid)
        out.append({"step": "segment", "objects": len(seg.objects), "ms": seg_ms})
    tree = build_tree(objs, (W, H))
    sentence = to_sentence(tree)
    steps: list[tuple[str, Callable[[], object]]] = [
        ("build_tree", lambda: build_tree(objs, (W, H))),
        ("to_sentence", lambda: to_sentence(tree)),
        ("build_tree+to_sentence", lambda: to_sentence(build_tree(objs, (W, H)))),
        ("build_tree(labels)+to_sentence", lambda: to_sentence(build_tree(objs, (W, H), labels=lab))),
        ("parse_sentence", lambda: parse_sentence(sentence)),
    ]
    budget = 0.1 * seg_ms if seg_ms is not None else BUDGET_FALLBACK_MS
    for name, fn in steps:
        ms = _best_ms(fn, repeats)
        out.append(
            {
                "step": name,
                "objects": len(objs),
                "ms": ms,
                "share_of_segment": None if seg_ms is None else ms / seg_ms,
                "budget_ms": budget,
            }
        )
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Print the timings; exit status 0."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--objects", type=int, default=20)
    p.add_argument("--repeats", type=int, default=50)
    p.add_argument("--quick", action="store_true", help="fewer repeats (10)")
    a = p.parse_args(argv)
    table = rows(a.objects, 10 if a.quick else a.repeats)
    print(f"{'step':34s} {'objects':>7s} {'ms':>9s} {'of segment':>10s} {'budget ms':>9s}")
    for r in table:
        share = r.get("share_of_segment")
        share_s = f"{100 * share:9.1f}%" if isinstance(share, float) else f"{'-':>10s}"
        budget = r.get("budget_ms")
        budget_s = f"{budget:9.3f}" if isinstance(budget, float) else f"{'-':>9s}"
        print(f"{r['step']!s:34s} {r['objects']!s:>7s} {r['ms']:9.3f} {share_s} {budget_s}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
