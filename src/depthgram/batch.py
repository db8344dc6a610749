"""Many recordings at once: one task per recording, on local cores or on a Dask cluster.

Each recording gets a folder ``OUT/<name>/`` with ``scenes.jsonl`` (the JSON lines of
``depthgram describe``), ``labels/`` (16-bit PNG label maps) and ``summary.json``, written last
and atomically: a folder with a summary is finished. The summary names the full input (an
existing path made absolute), a hash of the settings and one of the input's files (their names,
sizes and modification times); a re-run skips a folder only when all three match, so swapped
inputs, changed settings or a recording re-recorded in place are processed again (issues 18.1,
32.5).
A recording that fails leaves ``error.txt`` and its error in the returned summary; the
others still finish. A local worker process that dies (killed, out of memory) costs its
recording one retry, in a process of its own; workers end when the parent does.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from depthgram.atomic import atomic_open
from depthgram.errors import InputError

__all__ = ["BatchResult", "input_key", "output_names", "process_recording", "run_batch", "settings_hash"]

#: Marker a worker leaves in a recording's folder while it works on it (its process id).
_RUNNING = ".running"
_GLOB_CHARS = re.compile(r"[*?\[]")

#: How long (s) a Dask scheduler has to answer by default (``batch --connect-timeout``).
CONNECT_TIMEOUT_S = 30.0


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


def input_key(spec: str) -> str:
    """Return the input as every machine must read it: an existing path (or a relative glob) made absolute.

    Other specs (``sim:``, ``realsense:``, a scene name) are returned as they are. A Dask worker
    runs in another folder, so a relative path would name another file there (issue 18.4).
    """
    text = str(spec)
    if text.startswith(("sim:", "realsense:")):
        return text
    base, sep, query = text.partition("?")
    for cand, rest in ((text, ""), (base, sep + query)):
        if cand and Path(cand).exists():
            return str(Path(cand).resolve()) + rest
    if _GLOB_CHARS.search(text) and not os.path.isabs(text):
        return os.path.join(os.getcwd(), text)
    return text


def content_hash(spec: str) -> str:
    """Short hash (hex) of the files an input reads: each one's path, size and modification time.

    A folder counts the files in it and in its ``depth/`` subfolder (a ROS 2 bag's
    ``metadata.yaml`` and storage, a folder's frames and sidecars), a glob the files it
    matches; ``sim:`` and ``realsense:`` inputs have no files (an empty string). Sizes and
    times, not a digest of the bytes: a resumed batch of long recordings would otherwise read
    every one of them again to find it unchanged.
    """
    import glob

    key = input_key(spec)
    if key.startswith(("sim:", "realsense:")):
        return ""
    base = key.partition("?")[0]
    if Path(key).exists():
        base = key
    if Path(base).is_dir():
        # the files a folder source reads: its own (frames, sidecars, a bag's) and its depth/
        # subfolder's; not deeper, so that an --out inside it does not count as a change
        files = sorted(
            str(p) for d in (Path(base), Path(base) / "depth") if d.is_dir() for p in d.iterdir() if p.is_file()
        )
    elif Path(base).exists():
        files = [base]
    else:
        files = sorted(glob.glob(key)) if _GLOB_CHARS.search(key) else []
    rows = []
    for f in files:
        try:
            st = os.stat(f)
        except OSError:  # gone since listed, or a dangling link: the run will say so
            continue
        rows.append((f, st.st_size, st.st_mtime_ns))
    return hashlib.sha256(json.dumps(rows).encode()).hexdigest()[:16]


def settings_hash(config: Mapping[str, Any] | None, source_options: Mapping[str, Any] | None, track: bool) -> str:
    """Short hash (hex) of everything besides the input that changes a recording's outputs."""
    text = json.dumps(
        {"config": dict(config or {}), "source": dict(source_options or {}), "track": bool(track)},
        sort_keys=True,
        default=repr,
    )
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def output_names(inputs: Sequence[str]) -> list[str]:
    """One distinct, file-system-safe folder name per input.

    The base name when it is unique; inputs sharing a base name each get a short hash of their
    full input added (``x-1a2b3c4d``), so a name does not depend on the order of the inputs.
    """
    bases = []
    for spec in inputs:
        base = Path(str(spec).rstrip("/")).name or str(spec)
        bases.append(re.sub(r"[^A-Za-z0-9._-]+", "_", base).strip("._") or "recording")
    names = []
    for spec, base in zip(inputs, bases, strict=True):
        if bases.count(base) == 1:
            names.append(base)
        else:
            names.append(f"{base}-{hashlib.sha256(input_key(spec).encode()).hexdigest()[:8]}")
    seen: dict[str, int] = {}
    for i, name in enumerate(names):  # the same input twice: a counter keeps them apart
        seen[name] = seen.get(name, 0) + 1
        if seen[name] > 1:
            names[i] = f"{name}-{seen[name]}"
    return names


def process_recording(
    spec: str,
    out_dir: str,
    config: Mapping[str, Any] | None = None,
    source_options: Mapping[str, Any] | None = None,
    track: bool = True,
) -> dict[str, Any]:
    """Describe one recording into ``out_dir``; return its summary (also written to summary.json).

    Runs in a worker process or on a Dask worker, so it takes and returns plain data. Outputs
    of an earlier run in ``out_dir`` are replaced; nothing of it is left that could pass for
    this run's (the summary and an old ``error.txt`` go first, label maps are swapped in whole).
    """
    from depthgram.label_maps import label_file_name, write_label_map
    from depthgram.pipeline import Config, Pipeline
    from depthgram.sources import open_source

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for stale in ("summary.json", "error.txt"):
        (out / stale).unlink(missing_ok=True)
    labels_part = out / ".labels.part"
    shutil.rmtree(labels_part, ignore_errors=True)
    labels_part.mkdir()
    t0 = time.perf_counter()
    content = content_hash(spec)  # before reading: a change made while it runs is seen next time
    opts = dict(source_options or {})
    # --trust-intrinsics rides with the reading options (it is said of the camera they give)
    check = not opts.pop("trust_intrinsics", False)
    pipe = Pipeline(Config.from_dict(config or {}), track=track, check_intrinsics=check)
    src = open_source(spec, **opts)
    frames = objects = 0
    with atomic_open(out / "scenes.jsonl") as fh:
        for result in pipe.run(src):
            fh.write(json.dumps(result.to_record()) + "\n")
            name = label_file_name(result.frame.name, result.frame.index)
            # the check describe makes: track ids above 65535 would wrap in a 16-bit PNG
            write_label_map(labels_part / name, result.segmentation.labels, f"{spec} frame {result.frame.index}")
            frames += 1
            objects += len(result.segmentation.objects)
    shutil.rmtree(out / "labels", ignore_errors=True)
    os.replace(labels_part, out / "labels")
    summary = {
        "input": spec,
        "settings": settings_hash(config, source_options, track),
        "content": content,
        "frames": frames,
        "objects": objects,
        "seconds": round(time.perf_counter() - t0, 3),
        "frames_per_s": round(frames / max(time.perf_counter() - t0, 1e-9), 2),
    }
    with atomic_open(out / "summary.json") as fh:  # the marker of a finished recording: written last
        fh.write(json.dumps(summary, indent=1))
    return summary


def _guarded(
    spec: str, out_dir: str, config: Mapping[str, Any], opts: Mapping[str, Any], track: bool
) -> dict[str, Any]:
    """process_recording that turns any failure into a record instead of losing the batch."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    running = out / _RUNNING
    running.write_text(str(os.getpid()), encoding="utf-8")
    try:
        return {"ok": True, **process_recording(spec, out_dir, config, opts, track)}
    except Exception as exc:  # a bad recording must not stop the others
        msg = f"{type(exc).__name__}: {exc}"
        with atomic_open(out / "error.txt") as fh:
            fh.write(msg + "\n\n" + traceback.format_exc())
        return {"ok": False, "input": spec, "error": msg}
    finally:
        running.unlink(missing_ok=True)


def _watch_parent(parent: int) -> None:
    """Worker initialiser: end this worker when the batch's process is gone.

    A worker of a killed parent would otherwise wait for work forever (issue 18.3); polling
    the parent id works wherever ``fork`` or ``spawn`` does, unlike Linux's PR_SET_PDEATHSIG.
    """

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="depthgram-parent-watch", daemon=True).start()


def _run_local(
    args: list[tuple[str, str, dict[str, Any], dict[str, Any], bool]],
    workers: int,
    record: Callable[[int, Mapping[str, Any]], None],
) -> None:
    """Run ``args[i]`` on local processes, calling ``record(i, outcome)`` for each.

    A worker that dies breaks the whole pool: the recordings it was running (their folder holds
    the ``.running`` marker) are retried once, each alone in a fresh process so that a second
    death names its recording; the others go back into a new pool untouched.
    """
    queue = list(range(len(args)))
    suspects: list[int] = []
    while queue:
        pending = list(queue)
        queue = []
        before = len(suspects)
        with ProcessPoolExecutor(
            max_workers=min(workers, len(pending)), initializer=_watch_parent, initargs=(os.getpid(),)
        ) as pool:
            futs: dict[Future[dict[str, Any]], int] = {}
            for n_submitted, i in enumerate(pending):
                try:
                    futs[pool.submit(_guarded, *args[i])] = i
                except BrokenProcessPool:
                    # a worker died while the rest were being handed out (a fast death, a loaded
                    # machine): what was not handed out goes into the next pool untouched
                    queue.extend(pending[n_submitted:])
                    break
            for fut in as_completed(futs):
                i = futs[fut]
                try:
                    outcome = fut.result()
                except BrokenProcessPool:
                    marker = Path(args[i][1]) / _RUNNING
                    (suspects if marker.is_file() else queue).append(i)
                    marker.unlink(missing_ok=True)
                    continue
                record(i, outcome)
        if len(queue) == len(pending) and len(suspects) == before:  # the pool broke before any work
            for i in queue:
                record(i, {"ok": False, "error": "could not start a worker process"})
            queue = []
    for i in suspects:
        with ProcessPoolExecutor(max_workers=1, initializer=_watch_parent, initargs=(os.getpid(),)) as pool:
            try:
                outcome = pool.submit(_guarded, *args[i]).result()
            except BrokenProcessPool:
                (Path(args[i][1]) / _RUNNING).unlink(missing_ok=True)
                outcome = {
                    "ok": False,
                    "error": "the worker process died twice on this recording (killed, or out of memory?)",
                }
                with atomic_open(Path(args[i][1]) / "error.txt") as fh:
                    fh.write(str(outcome["error"]) + "\n")
        record(i, outcome)


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
    connect_timeout_s: float = CONNECT_TIMEOUT_S,
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
    connect_timeout_s : float
        How long (s) ``scheduler`` has to answer as a Dask scheduler before the batch gives up
        with an :class:`~depthgram.errors.InputError` naming it.
    """
    if not connect_timeout_s > 0:
        raise InputError(f"--connect-timeout must be a positive number of seconds, got {connect_timeout_s}")
    root = Path(out_dir).resolve()  # absolute: a Dask worker runs in another folder
    root.mkdir(parents=True, exist_ok=True)
    names = output_names(inputs)
    keys = [input_key(spec) for spec in inputs]
    cfg = dict(config or {})
    opts = dict(source_options or {})
    settings = settings_hash(cfg, opts, track)
    results: dict[int, BatchResult] = {}
    todo: list[int] = []
    for i, (spec, name) in enumerate(zip(inputs, names, strict=True)):
        done = _finished(root / name)
        if (
            done is not None
            and done.get("input") == keys[i]
            and done.get("settings") == settings
            and done.get("content") == content_hash(keys[i])
        ):
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

    args = [(keys[i], str(root / names[i]), cfg, opts, track) for i in todo]
    if todo and scheduler:
        from depthgram._optional import needs_extra

        with needs_extra("dask", "--scheduler (a Dask cluster)"):
            from distributed import Client
            from distributed import as_completed as dask_completed
        with _connected(Client, scheduler, connect_timeout_s) as client:
            futs = {client.submit(_guarded, *a, pure=False): i for a, i in zip(args, todo, strict=True)}
            for fut in dask_completed(list(futs)):  # type: ignore[no-untyped-call]
                i = futs[fut]
                out = fut.result()
                if out.get("ok") and _finished(root / names[i]) is None:
                    # the worker wrote on a disk this machine does not see
                    out = {
                        "ok": False,
                        "error": f"the worker finished, but its outputs are not in {root / names[i]}: "
                        "--out must be a folder every worker and this machine share",
                    }
                record(i, out)
    elif todo:
        n = workers or os.cpu_count() or 1
        if n == 1 or len(todo) == 1:
            for a, i in zip(args, todo, strict=True):
                record(i, _guarded(*a))
        else:
            _run_local(args, n, lambda k, out: record(todo[k], out))
    ordered = [results[i] for i in range(len(inputs))]
    with atomic_open(root / "batch.json") as fh:
        fh.write(json.dumps([asdict(r) for r in ordered], indent=1))
    return ordered


@contextmanager
def _connected(client_type: Any, scheduler: str, timeout_s: float) -> Iterator[Any]:
    """Yield a Dask client of ``scheduler`` made within ``timeout_s``, else raise an InputError naming it.

    ``Client(timeout=...)`` bounds the TCP connection only: a server that accepts and never
    answers (another service on the port) kept it waiting for its handshake for ever (issue
    32.3). So the client is made in a thread of its own and given up on at the deadline; that
    thread is a daemon, so a client that never comes does not keep the process alive.
    """
    made: list[Any] = []
    failed: list[BaseException] = []

    def connect() -> None:
        try:
            # distributed has no type hints: its calls are untyped
            made.append(client_type(scheduler, timeout=f"{timeout_s}s"))
        except BaseException as exc:  # handed to the caller below
            failed.append(exc)

    thread = threading.Thread(target=connect, name="depthgram-dask-connect", daemon=True)
    thread.start()
    thread.join(timeout_s + 1.0)  # Client's own timeout first, when it applies
    if failed:
        exc = failed[0]
        raise InputError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there ({exc})") from None
    if not made:
        raise InputError(
            f"--scheduler {scheduler}: no answer as a Dask scheduler within {timeout_s:g} s "
            "(is something else listening there? a Dask scheduler's default port is 8786; "
            "--connect-timeout S waits longer)"
        )
    with made[0] as client:
        yield client


def _finished(folder: Path) -> dict[str, Any] | None:
    """Return the summary of a finished recording's folder, or None."""
    try:
        done = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return done if isinstance(done, dict) else None
