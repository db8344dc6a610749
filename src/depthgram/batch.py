"""Many recordings at once: one task per recording, on local cores or on a Dask cluster.

Each recording gets a folder ``OUT/<name>/`` with ``scenes.jsonl`` (the JSON lines of
``depthgram describe``), ``labels/`` (16-bit PNG label maps) and ``summary.json``, written last
and atomically: a folder with a summary is finished, and a re-run skips it (resumable).
A recording that fails leaves ``error.txt`` and its error in the returned summary; the
others still finish.
"""

from __future__ import annotations

import json
import os
import re
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

__all__ = ["BatchResult", "output_names", "process_recording", "run_batch"]


@dataclass(frozen=True)
class BatchResult:
    """Outcome of one recording: ``status`` is ``done``, ``skipped`` (finished before) or ``failed``."""

    input: str
    name: str
    status: str
    frames: int = 0
    objects: int = 0
    seconds: float = 0.0
    error: str | None = None


def output_names(inputs: Sequence[str]) -> list[str]:
    """One distinct, file-system-safe folder name per input (``a``, ``a-2``, ... for repeats)."""
    seen: dict[str, int] = {}
    names = []
    for spec in inputs:
        base = Path(str(spec).rstrip("/")).name or str(spec)
        base = re.sub(r"[^A-Za-z0-9._-]+", "_", base).strip("._") or "recording"
        seen[base] = seen.get(base, 0) + 1
        names.append(base if seen[base] == 1 else f"{base}-{seen[base]}")
    return names


def process_recording(
    spec: str,
    out_dir: str,
    config: Mapping[str, Any] | None = None,
    source_options: Mapping[str, Any] | None = None,
    track: bool = True,
) -> dict[str, Any]:
    """Describe one recording into ``out_dir``; return its summary (also written to summary.json).

    Runs in a worker process or on a Dask worker, so it takes and returns plain data.
    """
    from depthgram.commands.describe import label_file_name, write_label_map
    from depthgram.pipeline import Config, Pipeline
    from depthgram.sources import open_source

    out = Path(out_dir)
    labels_dir = out / "labels"
    labels_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    pipe = Pipeline(Config.from_dict(config or {}), track=track)
    src = open_source(spec, **dict(source_options or {}))
    frames = objects = 0
    tmp = out / "scenes.jsonl.part"
    with open(tmp, "w", encoding="utf-8") as fh:
        for result in pipe.run(src):
            fh.write(json.dumps(result.to_record()) + "\n")
            name = label_file_name(result.frame.name, result.frame.index)
            # the check describe makes: track ids above 65535 would wrap in a 16-bit PNG
            write_label_map(labels_dir / name, result.segmentation.labels, f"{spec} frame {result.frame.index}")
            frames += 1
            objects += len(result.segmentation.objects)
    os.replace(tmp, out / "scenes.jsonl")
    summary = {
        "input": spec,
        "frames": frames,
        "objects": objects,
        "seconds": round(time.perf_counter() - t0, 3),
        "frames_per_s": round(frames / max(time.perf_counter() - t0, 1e-9), 2),
    }
    part = out / "summary.json.part"
    part.write_text(json.dumps(summary, indent=1), encoding="utf-8")
    os.replace(part, out / "summary.json")  # the marker of a finished recording: written last
    return summary


def _guarded(
    spec: str, out_dir: str, config: Mapping[str, Any], opts: Mapping[str, Any], track: bool
) -> dict[str, Any]:
    """process_recording that turns any failure into a record instead of losing the batch."""
    try:
        return {"ok": True, **process_recording(spec, out_dir, config, opts, track)}
    except Exception as exc:  # a bad recording must not stop the others
        msg = f"{type(exc).__name__}: {exc}"
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        (Path(out_dir) / "error.txt").write_text(msg + "\n\n" + traceback.format_exc(), encoding="utf-8")
        return {"ok": False, "input": spec, "error": msg}


def run_batch(
    inputs: Sequence[str],
    out_dir: str | Path,
    *,
    config: Mapping[str, Any] | None = None,
    source_options: Mapping[str, Any] | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    track: bool = True,
    on_done: Callable[[BatchResult], None] | None = None,
) -> list[BatchResult]:
    """Process recordings, one task each; return one :class:`BatchResult` per input, in input order.

    Parameters
    ----------
    inputs : sequence of str
        Recording specs as :func:`depthgram.sources.open_source` takes them.
    out_dir : path
        Output root; each recording writes into ``out_dir/<name>``.
    config : mapping, optional
        :meth:`depthgram.pipeline.Config.to_dict` output.
    workers : int, optional
        Local worker processes (default: all cores). Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask distributed scheduler (``tcp://host:8786``); needs the
        ``dask`` extra.
    on_done : callable, optional
        Called with each result as it finishes (progress display).
    """
    root = Path(out_dir)
    root.mkdir(parents=True, exist_ok=True)
    names = output_names(inputs)
    cfg = dict(config or {})
    opts = dict(source_options or {})
    results: dict[int, BatchResult] = {}
    todo: list[int] = []
    for i, (spec, name) in enumerate(zip(inputs, names, strict=True)):
        summary = root / name / "summary.json"
        if summary.is_file():
            done = json.loads(summary.read_text(encoding="utf-8"))
            results[i] = BatchResult(spec, name, "skipped", done.get("frames", 0), done.get("objects", 0))
            if on_done:
                on_done(results[i])
        else:
            todo.append(i)

    def record(i: int, out: Mapping[str, Any]) -> None:
        if out.get("ok"):
            r = BatchResult(inputs[i], names[i], "done", out["frames"], out["objects"], out["seconds"])
        else:
            r = BatchResult(inputs[i], names[i], "failed", error=str(out.get("error")))
        results[i] = r
        if on_done:
            on_done(r)

    args = [(inputs[i], str(root / names[i]), cfg, opts, track) for i in todo]
    if todo and scheduler:
        from depthgram._optional import needs_extra

        with needs_extra("dask", "--scheduler (a Dask cluster)"):
            from distributed import Client
            from distributed import as_completed as dask_completed
        # distributed has no type hints: its calls are untyped
        with Client(scheduler) as client:  # type: ignore[no-untyped-call]
            futs = {client.submit(_guarded, *a, pure=False): i for a, i in zip(args, todo, strict=True)}
            for fut in dask_completed(list(futs)):  # type: ignore[no-untyped-call]
                record(futs[fut], fut.result())
    elif todo:
        n = workers or os.cpu_count() or 1
        if n == 1 or len(todo) == 1:
            for a, i in zip(args, todo, strict=True):
                record(i, _guarded(*a))
        else:
            with ProcessPoolExecutor(max_workers=min(n, len(todo))) as pool:
                pfuts: dict[Future[dict[str, Any]], int] = {
                    pool.submit(_guarded, *a): i for a, i in zip(args, todo, strict=True)
                }
                for pf in as_completed(pfuts):
                    record(pfuts[pf], pf.result())
    ordered = [results[i] for i in range(len(inputs))]
    (root / "batch.json").write_text(json.dumps([asdict(r) for r in ordered], indent=1), encoding="utf-8")
    return ordered
