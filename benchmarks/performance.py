"""Write ``docs/performance.md``: the project's measured figures, from one run on one machine.

Docstrings and comments carry no figures (the reasons are in ``docs/design-notes.md``); the
figures are here, every one measured by the run that wrote the file, with the machine, its
load and the commit named at the top. The sections come from the other benchmarks, so each
figure can be re-measured alone with the command given in its section:

- segmentation speed per method and size, and on real recordings (``bench_segmentation.py``);
- where the default method's time goes, step by step at 176 x 132 and 640 x 480, and how much of a
  call is inside compiled kernels (``bench_segmentation.py --surfaces-stages``);
- the hand-written labeller against scipy's csgraph and OpenCV (``bench_segmentation.py --profile``);
- compiled kernels against the numpy routes they replaced (this script only);
- every stage of the pipeline per resolution, and the whole pipeline on 7-Scenes (``bench_pipeline.py``);
- Table 1 on the simulator, with the readings behind the defaults (``table1.py --readings --paper``).

Timings are thread CPU time (``time.thread_time``) where the benchmark allows it, so that other
processes on a shared machine do not inflate them, and the best of repeated runs.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/performance.py`` (``--out PATH``, default
``docs/performance.md``; ``--quick`` shorter budgets, 176 x 132 and 640 x 480 only). Takes a few
minutes.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script: the benchmarks package sits beside src/
    sys.path.insert(0, str(ROOT))

from benchmarks import bench_pipeline, bench_segmentation, table1  # noqa: E402


def _table(head: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table; numbers right-aligned."""
    align = ["---:" if rows and isinstance(rows[0][i], (int, float)) else "---" for i in range(len(head))]
    out = ["| " + " | ".join(head) + " |", "| " + " | ".join(align) + " |"]
    for r in rows:
        out.append("| " + " | ".join(_cell(v) for v in r) + " |")
    return "\n".join(out)


def _cell(v: Any) -> str:
    if isinstance(v, float):
        if v != v:
            return "-"
        return f"{v:.3g}" if abs(v) < 10 else f"{v:,.0f}" if abs(v) >= 1000 else f"{v:.1f}"
    return str(v)


def _cpu_best_ms(fn: Callable[[], Any], budget_s: float = 0.5, min_runs: int = 5) -> float:
    """Best thread CPU time per call (ms) over repeated runs."""
    fn()
    best = float("inf")
    t_end = time.perf_counter() + budget_s
    runs = 0
    while runs < min_runs or time.perf_counter() < t_end:
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
        runs += 1
    return best * 1e3


def machine() -> list[str]:
    """Lines naming the machine, the software and the commit."""
    import cv2
    import numba
    import scipy

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(
            ["git", "-C", str(ROOT), "describe", "--always", "--dirty"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    return [
        f"- machine: {cpu}, {os.cpu_count()} logical CPUs visible; {platform.platform()}",
        f"- software: Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"numba {numba.__version__}, OpenCV {cv2.__version__}",
        f"- commit: {commit}",
    ]


def kernels_vs_numpy(size: tuple[int, int] = (640, 480)) -> list[tuple[str, float, float]]:
    """(kernel, ms compiled, ms numpy route) on the default segmentation of the ``table`` scene."""
    from scipy import ndimage

    from depthgram.segmentation import segment
    from depthgram.segmentation.label import label_stats_fused, relabel
    from depthgram.segmentation.label.stats import COUNT
    from depthgram.segmentation.plane_sums import plane_sums, plane_sums_in_boxes
    from depthgram.sensor import simulate

    f = next(iter(simulate("table", 1, size=size, seed=0))).frame
    labels = segment(f.depth, valid=f.valid, intrinsics=f.intrinsics).labels.astype(np.int32)
    n = int(labels.max())
    depth = f.depth.astype(np.float32)
    cam = f.intrinsics
    assert cam is not None
    lut = np.arange(n + 1, dtype=np.int32)[::-1].copy()

    def stats_numpy() -> Any:
        flat = labels.ravel()
        idx = np.flatnonzero(flat)
        lab = flat[idx]
        z = depth.ravel()[idx].astype(np.float64)
        ys, xs = np.divmod(idx, labels.shape[1])
        m = n + 1
        out = [np.bincount(lab, minlength=m)]
        out += [np.bincount(lab, weights=wt, minlength=m) for wt in (z, z * z, xs, ys, xs * z, ys * z)]
        return out, ndimage.find_objects(labels, max_label=n)

    # the compiled plane sums read each label's box (every label here); the readable route is
    # plane_sums, nine bincounts
    table, boxes = label_stats_fused(labels, n, depth, labels)
    ids = np.flatnonzero(table[:, COUNT] > 0)
    ids = ids[ids > 0]

    return [
        (
            "statistics table (label.stats) vs 7 bincounts + find_objects",
            _cpu_best_ms(partial(label_stats_fused, labels, n, depth, labels)),
            _cpu_best_ms(stats_numpy),
        ),
        (
            "relabel (label.renumber) vs lut[labels]",
            _cpu_best_ms(partial(relabel, labels, lut)),
            _cpu_best_ms(lambda: lut[labels]),
        ),
        (
            "plane sums (plane_sums_in_boxes) vs 9 bincounts (plane_sums)",
            _cpu_best_ms(
                partial(plane_sums_in_boxes, labels, n, ids, boxes[ids], depth, cam.fx, cam.fy, cam.cx, cam.cy)
            ),
            _cpu_best_ms(partial(plane_sums, labels, n, depth, cam.fx, cam.fy, cam.cx, cam.cy)),
        ),
    ]


def build(quick: bool = False) -> str:
    """The whole of ``docs/performance.md``."""
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    started = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    sizes = ((176, 132), (640, 480)) if quick else bench_segmentation.SIZES
    parts: list[str] = []

    bench_segmentation.CLOCK = time.thread_time
    rows = bench_segmentation.run_bench(sizes, passes=1 if quick else 2)
    parts += [
        "## Segmentation speed",
        "",
        "Simulated `table` scene, one core, thread CPU time, best of repeated runs; `x bincount` is the",
        "time as a multiple of one `np.bincount` over the frame (no method can read every pixel faster).",
        "`in stream` is the default (`surfaces`) given the sensor model, as `Pipeline` passes it to every",
        "frame of a recording (it estimates the model once every 30 frames); `surfaces` estimates it in",
        "every call, as `segment` alone does. Re-measure: `python benchmarks/bench_segmentation.py --cpu`.",
        "",
        _table(
            ["size", "method", "ms", "frames/s", "target frames/s", "x bincount"],
            [(f"{r.size[0]}x{r.size[1]}", r.method, r.ms, r.fps, r.target_fps, r.x_floor) for r in rows],
        ),
        "",
    ]
    real = bench_segmentation.real_rows()
    if real:
        parts += [
            "On the first frame of real recordings (`../shared/data`), same clock:",
            "",
            _table(
                ["recording", "size", "method", "ms", "frames/s", "invalid"],
                [(name, f"{w}x{h}", m, ms, 1e3 / ms, f"{inv:.1%}") for name, (w, h), m, ms, inv in real],
            ),
            "",
        ]

    stage_sizes = ((176, 132), (640, 480))
    staged = [bench_segmentation.surfaces_stages(sz, runs=5 if quick else 20) for sz in stage_sizes]
    plain = {(r.size, r.method): r.ms for r in rows}
    split = []
    for sz, (whole, _, numba_ms) in zip(stage_sizes, staged, strict=True):
        ms = plain.get((sz, "surfaces"), whole)
        split.append(
            f"- {sz[0]}x{sz[1]}: {ms:.2f} ms a call unwrapped (the table above); with a timer around every step "
            f"and kernel {whole:.2f} ms, {numba_ms:.2f} ms of it inside numba kernels, so about "
            f"{max(ms - numba_ms, 0.0):.2f} ms ({max(ms - numba_ms, 0.0) / ms:.0%}) is the Python, numpy and "
            "OpenCV around them."
        )
    names = sorted({k for _, st, _ in staged for k in st}, key=lambda k: -max(st.get(k, 0.0) for _, st, _ in staged))
    parts += [
        "## Where the default method's time goes",
        "",
        *split,
        "",
        "Thread CPU time of each step, median over the runs. Steps nest (`_surface_objects` holds the",
        "steps after it up to `label_stats_fused`); at 640 x 480 `_slices` runs on the 320 x 240 grid and",
        "`to_full_resolution` brings its labels back to every pixel.",
        "Re-measure: `python benchmarks/bench_segmentation.py --surfaces-stages --quick`.",
        "",
        _table(
            ["step", *(f"{w}x{h} ms" for w, h in stage_sizes)],
            [(k, *(st.get(k, "-") for _, st, _ in staged)) for k in names],
        ),
        "",
    ]

    labellers = bench_segmentation.compare_labellers()
    parts += [
        "## Labellers (region-growing connectivity, 640 x 480)",
        "",
        "The hand-written union-find labeller against scipy's csgraph over the explicit 4-neighbour",
        "graph, and OpenCV's binary labeller for scale (it cannot compare depths). Wall time.",
        "Re-measure: `python benchmarks/bench_segmentation.py --profile`.",
        "",
        _table(["labeller", "ms"], list(labellers.items())),
        "",
    ]

    kern = kernels_vs_numpy()
    parts += [
        "## Compiled kernels against the numpy routes they replaced (640 x 480)",
        "",
        "On the label map of the default method on the `table` scene; thread CPU time. Measured by",
        "this script only (`kernels_vs_numpy`).",
        "",
        _table(["kernel", "compiled ms", "numpy ms", "x"], [(k, a, b, b / a) for k, a, b in kern]),
        "",
    ]

    stages = bench_pipeline.stage_rows(quick=quick)
    parts += [
        "## Every stage of the pipeline",
        "",
        "Simulated `table` scene, wall time, best of repeated runs. Re-measure: `depthgram bench pipeline`.",
        "",
        _table(
            ["size", "stage", "ms/frame", "frames/s", "x bincount", "x threshold"],
            [(r["size"], r["stage"], r["ms"], r["fps"], r["x_bincount"], r["x_threshold"]) for r in stages],
        ),
        "",
    ]
    pipe = bench_pipeline.real_pipeline_row(30 if quick else 100)
    if pipe is not None:
        text = (
            f"Whole pipeline (segment, tree, tracks, plan) on {pipe['frames']} 7-Scenes frames at 640 x 480, "
            "wall time (the tracker's image motion runs in a second thread beside the segmentation): "
            f"median {pipe['wall_ms']:.1f} ms ({pipe['fps']:.0f} frames/s), p95 {pipe['wall_p95_ms']:.1f} ms, "
            f"max {pipe['wall_max_ms']:.1f} ms; CPU time of all threads {pipe['cpu_ms']:.1f} ms, of the calling "
            f"thread {pipe['ms']:.1f} ms; segmentation alone {pipe['segment_ms']:.1f} ms (thread CPU). "
            f"Streamed by `Pipeline.run` (each frame's tracks, tree and plan beside the next frame's "
            f"segmentation; median of 3 passes): {pipe['run_fps']:.0f} frames/s."
        )
        parts += [*textwrap.wrap(text, width=100), ""]

    methods = list(table1.METHODS)
    methods += [(n, {"method": "slices", **kw}) for n, kw in table1.READINGS]
    methods += list(table1.PAPER_READINGS)
    t1 = table1.run_table1(size=(176, 132), repeat=1, methods=methods, real=False)
    parts += [
        "## Table 1 on the simulator (176 x 132)",
        "",
        "The paper's Table 1 for this implementation, with the readings behind the defaults of",
        "`SegmentConfig` (docs/design-notes.md): area and precision (%) of the true area labelled by",
        "segments assigned to the right object, share of objects found at IoU >= 0.5, Hoover counts",
        "(correct/over/under/missed at T = 0.8), time as a multiple of the first row (one run, wall time).",
        "Re-measure: `python benchmarks/table1.py --readings --paper --no-real`.",
        "",
        _table(
            ["scene", "method", "objects", "area %", "precision %", "found", "C/O/U/M", "x time", "kinds found"],
            [
                (
                    r.source,
                    r.method,
                    r.objects,
                    100 * r.area,
                    100 * r.precision,
                    r.found,
                    f"{r.correct}/{r.over}/{r.under}/{r.missed}",
                    r.time_ratio,
                    r.kinds_found,
                )
                for r in t1
            ],
        ),
        "",
    ]

    load1 = os.getloadavg()
    head = [
        "# Performance",
        "",
        "Generated by `benchmarks/performance.py`; do not edit by hand. Every figure below was measured",
        f"by one run started {started} that took {time.perf_counter() - t0:.0f} s"
        + (" (`--quick`: shorter budgets, fewer sizes)." if quick else "."),
        "",
        *machine(),
        f"- load average (1, 5, 15 min) at the start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, "
        f"at the end {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}: the machine was shared with other "
        "work, which wall-time figures feel and thread-CPU-time figures mostly do not.",
        "",
        "Figures move from machine to machine and run to run; the reasons behind the design are in",
        "`docs/design-notes.md`.",
        "",
    ]
    return "\n".join(head + parts)


def main(argv: Sequence[str] | None = None) -> int:
    """Measure and write the file; return the exit status."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "performance.md")
    p.add_argument("--quick", action="store_true", help="shorter budgets, 176x132 and 640x480 only")
    args = p.parse_args(argv)
    text = build(quick=args.quick)
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
