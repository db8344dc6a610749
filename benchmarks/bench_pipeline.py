"""One table: frames/s per stage and per resolution, the bincount floor, region growing, memory.

Run: ``.venv/bin/python benchmarks/bench_pipeline.py`` or ``depthgram bench pipeline``.
Every stage is timed on one core on the simulator's ``table`` scene at each resolution.
"""

from __future__ import annotations

import argparse
import gc
import itertools
import os
import platform
import resource
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

SIZES = ((176, 132), (640, 480), (1280, 720))


def _best_time(fn: Callable[[], Any], *, budget_s: float, min_reps: int = 3) -> float:
    """Best per-call time (s) over repeated calls within a time budget: the least disturbed run."""
    fn()  # warm-up (caches, numba, lazy imports)
    best = float("inf")
    reps = 0
    t_end = time.perf_counter() + budget_s
    while reps < min_reps or time.perf_counter() < t_end:
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
        reps += 1
    return best


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def stage_rows(*, quick: bool = False) -> list[dict[str, Any]]:
    """Time each stage at each resolution; one row per (size, stage)."""
    from depthgram.act import plan
    from depthgram.dynamics import Tracker
    from depthgram.scene import build_tree, to_sentence
    from depthgram.segmentation import SegmentConfig, region_grow, segment
    from depthgram.sensor import simulate
    from depthgram.sound import Sonifier, SoundMapping

    budget = 0.3 if quick else 1.5
    rows: list[dict[str, Any]] = []
    for w, h in SIZES:
        sim = next(iter(simulate("table", 1, size=(w, h), seed=0)))
        f = sim.frame
        d, v, k = f.depth, f.valid, f.intrinsics
        bins = np.minimum((d / 10.0).astype(np.int64), 1023)
        floor = _best_time(lambda bins=bins: np.bincount(bins.ravel(), minlength=1024), budget_s=budget)
        seg = segment(d, valid=v, intrinsics=k)
        tree = build_tree(seg.objects, (w, h))
        tracker = Tracker()
        tracker.update(seg.objects, 0.0, (w, h))
        clock = iter(range(1, 10**9))
        sonifier = Sonifier(SoundMapping(), 22050, (w, h))
        timings: dict[str, float] = {
            "segment (threshold)": _best_time(
                lambda d=d, v=v, k=k: segment(d, valid=v, intrinsics=k, config=SegmentConfig(method="threshold")),
                budget_s=budget,
            ),
            "segment (slices)": _best_time(
                lambda d=d, v=v, k=k: segment(d, valid=v, intrinsics=k, config=SegmentConfig(method="slices")),
                budget_s=budget,
            ),
            "segment (default)": _best_time(lambda d=d, v=v, k=k: segment(d, valid=v, intrinsics=k), budget_s=budget),
            "region growing": _best_time(lambda d=d, v=v, k=k: region_grow(d, valid=v, intrinsics=k), budget_s=budget),
            "tree + sentence": _best_time(
                lambda seg=seg, w=w, h=h: to_sentence(build_tree(seg.objects, (w, h))), budget_s=budget
            ),
            "tracker update": _best_time(
                lambda seg=seg, tracker=tracker, clock=clock, w=w, h=h: tracker.update(
                    seg.objects, next(clock) / 30.0, (w, h)
                ),
                budget_s=budget,
            ),
            "plan": _best_time(lambda tree=tree, f=f: plan(tree, f), budget_s=budget),
            "sound (1 frame)": _best_time(lambda tree=tree, s=sonifier: s.push(tree, 1 / 30.0), budget_s=budget),
        }
        base = timings["segment (threshold)"]
        for stage, t in timings.items():
            rows.append(
                {
                    "size": f"{w}x{h}",
                    "stage": stage,
                    "ms": t * 1e3,
                    "fps": 1.0 / t,
                    "x_bincount": t / floor,
                    "x_threshold": t / base,
                    "objects": len(seg.objects),
                }
            )
        rows.append(
            {
                "size": f"{w}x{h}",
                "stage": "bincount floor",
                "ms": floor * 1e3,
                "fps": 1 / floor,
                "x_bincount": 1.0,
                "x_threshold": floor / base,
                "objects": len(seg.objects),
            }
        )
    return rows


def memory_row(frames: int) -> dict[str, Any]:
    """Peak RSS before and after streaming ``frames`` 640x480 frames through the whole pipeline."""
    from depthgram.pipeline import Pipeline
    from depthgram.sensor import simulate

    pipe = Pipeline()
    gc.collect()
    before = _rss_mb()
    n = 0
    half_rss = before
    # through Pipeline.run, as users stream: frames are read ahead in a thread
    for _ in pipe.run(sim.frame for sim in simulate("crossing", frames, size=(640, 480), seed=1)):
        n += 1
        if n == frames // 2:
            half_rss = _rss_mb()
    after = _rss_mb()
    stream_gb = frames * 640 * 480 * 2 / 1e9
    return {
        "frames": n,
        "stream_gb_as_uint16": stream_gb,
        "rss_start_mb": before,
        "rss_half_mb": half_rss,
        "rss_end_mb": after,
    }


def batch_scaling(recordings: int = 4, frames: int = 30, size: str = "640x480") -> list[dict[str, Any]]:
    """Wall time of ``depthgram batch`` over ``recordings`` recordings on 1, 2, ... cores.

    The recordings are simulated and written as PNG folders first, outside the timed part: the
    simulator renders a 640x480 frame far slower than depthgram reads one, so batching over
    ``sim:`` inputs would time the simulator. One row per worker count (1 up to the cores
    visible, at most ``recordings``): seconds, frames/s and the speed-up over one worker (ideal:
    the worker count). Each run writes into a fresh folder, so none is skipped as already done.
    """
    import contextlib
    import io
    import tempfile
    from pathlib import Path

    from depthgram.batch import run_batch
    from depthgram.cli import main as cli_main

    rows: list[dict[str, Any]] = []
    base = float("nan")
    with tempfile.TemporaryDirectory(prefix="depthgram-bench-") as tmp:
        inputs = []
        for i in range(recordings):
            folder = Path(tmp) / f"rec{i}"
            with contextlib.redirect_stderr(io.StringIO()):  # its "wrote N frames" lines are not results
                argv = ["simulate", "crossing", "--frames", str(frames), "--size", size]
                code = cli_main([*argv, "--seed", str(i), "--out", str(folder)])
            if code != 0:
                raise RuntimeError(f"depthgram simulate failed with status {code}")
            inputs.append(str(folder))
        for workers in range(1, min(os.cpu_count() or 1, recordings) + 1):
            out = Path(tmp) / f"out{workers}"
            t0 = time.perf_counter()
            results = run_batch(inputs, str(out), workers=workers)
            seconds = time.perf_counter() - t0
            if workers == 1:
                base = seconds
            rows.append(
                {
                    "workers": workers,
                    "seconds": seconds,
                    "fps": recordings * frames / seconds,
                    "speedup": base / seconds,
                    "done": sum(r.status == "done" for r in results),
                }
            )
    return rows


def real_pipeline_row(frames: int = 100) -> dict[str, Any] | None:
    """Time per 640x480 7-Scenes frame: the whole pipeline, and its segmentation alone.

    The pipeline finds the tracker's image motion in a second thread beside the segmentation,
    so three clocks: wall time (what a frame's latency is, inflated by other work on the
    machine), the process's CPU time (all its threads: the work done) and the calling thread's
    CPU time. The segmentation alone in thread CPU time. None when
    ``../shared/data/7scenes_redkitchen_seq`` is not beside the checkout.
    """
    import warnings
    from pathlib import Path

    import depthgram
    from depthgram.pipeline import Pipeline
    from depthgram.segmentation import segment

    folder = (
        Path(os.environ.get("DEPTHGRAM_DATA") or Path(__file__).resolve().parents[1].parent / "shared" / "data")
        / "7scenes_redkitchen_seq"
    )
    if not folder.is_dir():
        return None
    clip = [f for _, f in zip(range(frames), depthgram.read(str(folder), fps=30.0), strict=False)]
    pipe = Pipeline()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for f in clip[:5]:  # warm-up: numba, lazy imports, the sensor estimate
            pipe.process(f)
        pipe.reset()
        whole, wall, cpu, seg = [], [], [], []
        for f in clip:
            t0, w0, c0 = time.thread_time(), time.perf_counter(), time.process_time()
            pipe.process(f)
            t1, w1, c1 = time.thread_time(), time.perf_counter(), time.process_time()
            segment(f, sensor=pipe._sensor_model(f))
            t2 = time.thread_time()
            whole.append(t1 - t0)
            wall.append(w1 - w0)
            cpu.append(c1 - c0)
            seg.append(t2 - t1)
        # a recording streamed by Pipeline.run: each frame described beside the next one's
        # segmentation (throughput; process() above is the latency of one frame at a time)
        pipe.reset()
        streamed = []
        for _ in range(3):
            w0 = time.perf_counter()
            for _r in pipe.run(clip):
                pass
            streamed.append(len(clip) / (time.perf_counter() - w0))
            pipe.reset()
    w, sg, wl, pc = (np.array(x) * 1e3 for x in (whole, seg, wall, cpu))
    return {
        "run_fps": float(np.median(streamed)),
        "frames": len(clip),
        "ms": float(np.median(w)),
        "p95_ms": float(np.percentile(w, 95)),
        "max_ms": float(w.max()),
        "wall_ms": float(np.median(wl)),
        "wall_p95_ms": float(np.percentile(wl, 95)),
        "wall_max_ms": float(wl.max()),
        "cpu_ms": float(np.median(pc)),
        "segment_ms": float(np.median(sg)),
        "fps": 1e3 / float(np.median(wl)),
    }


def workers_scaling(frames: int = 300) -> list[dict[str, Any]] | None:
    """Wall time of ``Pipeline.run(workers=N)`` over 7-Scenes frames, N = 1 up to the cores visible.

    The segmentation runs in N worker processes, the rest of the pipeline in this one, so the
    speed-up is bounded by the share of the segmentation and by the cores. Worker start-up is
    included (a user pays it). None when the recording is not beside the checkout.
    """
    import warnings
    from pathlib import Path

    import depthgram
    from depthgram.pipeline import Pipeline

    folder = (
        Path(os.environ.get("DEPTHGRAM_DATA") or Path(__file__).resolve().parents[1].parent / "shared" / "data")
        / "7scenes_redkitchen_seq"
    )
    if not folder.is_dir():
        return None
    rows: list[dict[str, Any]] = []
    base = float("nan")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for f in itertools.islice(depthgram.read(str(folder), fps=30.0), 5):  # page cache, numba in this process
            Pipeline().process(f)
        for workers in range(1, (os.cpu_count() or 1) + 1):
            src = itertools.islice(depthgram.read(str(folder), fps=30.0), frames)
            t0 = time.perf_counter()
            n = sum(1 for _ in Pipeline().run(src, workers=workers))
            seconds = time.perf_counter() - t0
            if workers == 1:
                base = seconds
            rows.append({"workers": workers, "frames": n, "fps": n / seconds, "speedup": base / seconds})
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="shorter timing budget")
    ap.add_argument("--memory-frames", type=int, default=None, help="frames for the memory check")
    a = ap.parse_args(argv)
    print(
        f"machine: {platform.machine()} {platform.processor() or ''}, Python {platform.python_version()}, "
        f"numpy {np.__version__}; one process, best of repeated runs"
    )
    rows = stage_rows(quick=a.quick)
    print(f"{'size':>9} | {'stage':<20} | {'ms/frame':>9} | {'frames/s':>9} | {'x bincount':>10} | {'x threshold':>11}")
    print("-" * 84)
    for r in rows:
        print(
            f"{r['size']:>9} | {r['stage']:<20} | {r['ms']:9.3f} | {r['fps']:9.0f} | {r['x_bincount']:10.1f} | "
            f"{r['x_threshold']:11.2f}"
        )
    real = real_pipeline_row(30 if a.quick else 100)
    if real is None:
        print(
            "\nwhole pipeline on 7-Scenes: skipped (../shared/data/7scenes_redkitchen_seq is not beside the checkout)"
        )
    else:
        print(
            f"\nwhole pipeline (segment, tree, tracks, plan) on {real['frames']} 7-Scenes frames at 640x480: "
            f"wall time median {real['wall_ms']:.1f} ms ({real['fps']:.0f} frames/s; target >= 100), "
            f"p95 {real['wall_p95_ms']:.1f}, max {real['wall_max_ms']:.1f} (load {os.getloadavg()[0]:.1f}); "
            f"CPU of all threads {real['cpu_ms']:.1f} ms, of the calling thread {real['ms']:.1f} ms; "
            f"segmentation alone {real['segment_ms']:.1f} ms (thread CPU); streamed by Pipeline.run "
            f"(each frame described beside the next one's segmentation): {real['run_fps']:.0f} frames/s "
            f"(target >= 100)"
        )
    scaling = workers_scaling(60 if a.quick else 300)
    if scaling is not None:
        print(
            f"\nPipeline.run(workers=N) on 7-Scenes (segmentation in N processes; wall time, worker start-up "
            f"included; load average now {os.getloadavg()[0]:.1f}):"
        )
        for w in scaling:
            print(
                f"  {w['workers']} worker(s): {w['frames']} frames, {w['fps']:5.1f} frames/s, "
                f"speed-up {w['speedup']:.2f}x"
            )
    recs = 2 if a.quick else 4
    frames = 15 if a.quick else 60
    print(
        f"\nbatch scaling ({recs} recordings of {frames} frames at 640x480 written beforehand; wall time, "
        f"load included; load average now {os.getloadavg()[0]:.1f}):"
    )
    for b in batch_scaling(recordings=recs, frames=frames):
        print(
            f"  {b['workers']} worker(s): {b['seconds']:6.2f} s, {b['fps']:5.1f} frames/s, "
            f"speed-up {b['speedup']:.2f}x (ideal {b['workers']}x), {b['done']} of {recs} done"
        )
    m = memory_row(a.memory_frames or (60 if a.quick else 300))
    print(
        f"\nmemory: streamed {m['frames']} frames of 640x480 ({m['stream_gb_as_uint16']:.2f} GB as uint16) through "
        f"the pipeline; peak RSS {m['rss_start_mb']:.0f} MB at start, {m['rss_half_mb']:.0f} MB half-way, "
        f"{m['rss_end_mb']:.0f} MB at the end"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
