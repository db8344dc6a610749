"""Batch runs: process pool, resumability, failures kept apart, and a real Dask cluster."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from depthgram.batch import output_names, run_batch
from depthgram.cli import main


def _read_all(root: Path, name: str) -> list[dict]:
    return [json.loads(x) for x in (root / name / "scenes.jsonl").read_text().splitlines()]


def test_output_names_are_distinct_and_do_not_depend_on_the_order() -> None:
    names = output_names(["a/x", "b/x", "sim:table?frames=2", "a/x"])
    assert len(set(names)) == 4 and names[2] == "sim_table_frames_2"
    assert all(n.startswith("x-") for n in names[:2])
    assert output_names(["b/x", "a/x"]) == [names[1], names[0]]


def _stack(path: Path, frames: int) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    z = np.full((frames, 24, 32), 2000, np.uint16)
    z[:, 8:16, 10:20] = 1000
    np.save(path, z)
    return str(path)


def test_resume_keys_outputs_by_full_input_and_settings(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # issue 18.1: keyed by base name and order, swapped inputs kept each other's results
    monkeypatch.chdir(tmp_path)
    a, b = _stack(tmp_path / "a" / "x.npy", 1), _stack(tmp_path / "b" / "x.npy", 3)
    frames = {a: 1, b: 3, "a/x.npy": 1, "b/x.npy": 3}
    first = run_batch([a, b], "out", workers=1)
    assert [r.frames for r in first] == [1, 3]
    for order in (["b/x.npy", "a/x.npy"], [b, a]):  # swapped, and relative then absolute
        again = run_batch(order, "out", workers=1)
        assert [r.status for r in again] == ["skipped", "skipped"]
        assert [r.frames for r in again] == [frames[x] for x in order]
        for r in again:
            assert len(_read_all(tmp_path / "out", r.name)) == frames[r.input]
    # changed settings are not skipped
    assert [r.status for r in run_batch([a, b], "out", workers=1, track=False)] == ["done", "done"]
    cfg = {"segment": {"method": "threshold"}}
    assert [r.status for r in run_batch([a], "out", workers=1, config=cfg)] == ["done"]
    assert [r.status for r in run_batch([a], "out", workers=1, config=cfg)] == ["skipped"]
    assert [r.status for r in run_batch([a], "out", workers=1, source_options={"scale_mm": 2.0})] == ["done"]


def _frames(folder: Path, n: int) -> str:
    import cv2

    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    for k in range(n):
        z = np.full((24, 32), 2000, np.uint16)
        z[8:16, 10:20] = 1000
        cv2.imwrite(str(folder / f"f{k}.png"), z)
    return str(folder)


def test_a_later_success_removes_the_old_error_and_stale_labels(tmp_path: Path) -> None:
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "f0.png").write_bytes(b"not a png")
    (r,) = run_batch([str(rec)], tmp_path / "out", workers=1)
    folder = tmp_path / "out" / r.name
    assert r.status == "failed" and (folder / "error.txt").is_file()
    _frames(rec, 3)
    (r,) = run_batch([str(rec)], tmp_path / "out", workers=1)
    assert r.status == "done" and not (folder / "error.txt").exists()
    assert sorted(p.name for p in (folder / "labels").iterdir()) == ["f0.png", "f1.png", "f2.png"]
    _frames(rec, 1)  # fewer frames, other settings: no label map of the old run may stay
    (r,) = run_batch([str(rec)], tmp_path / "out", workers=1, track=False)
    assert sorted(p.name for p in (folder / "labels").iterdir()) == ["f0.png"]
    assert sorted(p.name for p in folder.iterdir()) == ["labels", "scenes.jsonl", "summary.json"]


def _dies_once(real: Any, marker_dir: Path, always: str) -> Any:
    def process(spec: str, out_dir: str, *args: Any) -> Any:
        marker = marker_dir / re.sub(r"\W", "_", spec)
        if always in spec or ("approach" in spec and not marker.exists()):
            marker.touch()
            os.kill(os.getpid(), signal.SIGKILL)  # a worker killed (the OOM killer, a user)
        return real(spec, out_dir, *args)

    return process


def test_a_lost_worker_costs_its_recording_one_retry(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # issue 18.3: one killed worker was a BrokenProcessPool traceback for the whole batch
    from depthgram import batch

    monkeypatch.setattr(batch, "process_recording", _dies_once(batch.process_recording, tmp_path, "crossing"))
    inputs = ["sim:table?frames=2", "sim:approach?frames=2", "sim:crossing?frames=1", "sim:table?frames=1"]
    results = run_batch(inputs, tmp_path / "out", workers=2)
    assert [r.status for r in results] == ["done", "done", "failed", "done"]
    assert [r.frames for r in results] == [2, 2, 0, 1]
    assert results[2].error is not None and "died twice" in results[2].error
    assert len(_read_all(tmp_path / "out", results[1].name)) == 2


def test_workers_end_with_the_parent(tmp_path: Path) -> None:
    # issue 18.3: killing the batch left its workers waiting for work forever
    code = (
        "import sys; from depthgram.batch import run_batch; "
        "run_batch(['sim:crossing?frames=400', 'sim:approach?frames=400'], sys.argv[1], workers=2)"
    )
    import depthgram

    env = {**os.environ, "PYTHONPATH": str(Path(depthgram.__file__).resolve().parents[1])}
    parent = subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "out")], env=env)
    markers = [
        tmp_path / "out" / n / ".running" for n in output_names(["sim:crossing?frames=400", "sim:approach?frames=400"])
    ]
    try:
        deadline = time.monotonic() + 120
        while not all(m.is_file() and m.read_text() for m in markers):
            assert parent.poll() is None and time.monotonic() < deadline, "the workers never started"
            time.sleep(0.2)
        pids = [int(m.read_text()) for m in markers]
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 60
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.2)
    alive = [p for p in pids if _alive(p)]
    for p in alive:
        os.kill(p, signal.SIGKILL)
    assert not alive, "workers outlived their parent"


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_a_bad_scheduler_address_is_a_clear_error(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    code = main(["batch", "sim:table?frames=1", "--out", str(tmp_path / "out"), "--scheduler", "not-an-address"])
    err = capsys.readouterr().err
    assert code == 2 and "not-an-address" in err and "Traceback" not in err


def test_batch_survives_a_bad_recording_and_resumes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png")
    out = tmp_path / "out"
    args = ["batch", "sim:table?frames=2", str(bad), "sim:approach?frames=3", "--out", str(out), "--workers", "2"]
    assert main(args) == 1  # one failed
    summary = json.loads((out / "batch.json").read_text())
    assert [r["status"] for r in summary] == ["done", "failed", "done"]
    assert "bad.png" in summary[1]["error"]
    assert len(_read_all(out, summary[2]["name"])) == 3
    assert (out / summary[0]["name"] / "labels").is_dir()
    capsys.readouterr()
    assert main(args) == 1
    again = json.loads((out / "batch.json").read_text())
    assert [r["status"] for r in again] == ["skipped", "failed", "skipped"]


def test_dask_cluster_gives_the_serial_result(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    inputs = ["sim:crossing?frames=4", "sim:table?frames=1"]
    serial = run_batch(inputs, tmp_path / "serial", workers=1)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        remote = run_batch(inputs, tmp_path / "dask", scheduler=cluster.scheduler_address)
    assert [r.status for r in remote] == ["done", "done"]
    for a, b in zip(serial, remote, strict=True):
        sa, sb = _read_all(tmp_path / "serial", a.name), _read_all(tmp_path / "dask", b.name)
        assert sa == sb


def test_batch_refuses_ids_a_16_bit_label_map_cannot_hold(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # batch wrote labels.astype(uint16) without describe's check: id 65536 became 0 silently.
    from depthgram.dynamics import tracker

    init = tracker.Tracker.__init__

    def late_ids(self: tracker.Tracker, *args: object, **kwargs: object) -> None:
        init(self, *args, **kwargs)  # type: ignore[arg-type]
        self._next_id = 65534  # a long recording: ids 65534, 65535, 65536, ...

    monkeypatch.setattr(tracker.Tracker, "__init__", late_ids)
    (r,) = run_batch(["sim:table?frames=2"], tmp_path / "out", workers=1)
    assert r.status == "failed"
    assert r.error is not None and "above 65535" in r.error and "sim:table?frames=2 frame 0" in r.error


def test_inputs_are_made_absolute_on_the_client(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # issue 18.4: a Dask worker resolved relative paths in its own folder
    from depthgram.batch import input_key

    monkeypatch.chdir(tmp_path)
    _stack(tmp_path / "rec" / "x.npy", 1)
    assert input_key("rec/x.npy") == str(tmp_path / "rec" / "x.npy")
    assert input_key("rec/x.npy?key=depth") == str(tmp_path / "rec" / "x.npy") + "?key=depth"
    assert input_key("rec/*.png") == str(tmp_path / "rec" / "*.png")
    assert input_key("sim:table?frames=2") == "sim:table?frames=2"
    (r,) = run_batch(["rec/x.npy"], "out", workers=1)
    summary = json.loads((tmp_path / "out" / r.name / "summary.json").read_text())
    assert summary["input"] == str(tmp_path / "rec" / "x.npy")


def test_each_frame_of_a_stack_gets_its_own_label_map(tmp_path: Path) -> None:
    # the frames of x.npy are named "x.npy#0", "x.npy#1", ...: all three were written to x.png
    (r,) = run_batch([_stack(tmp_path / "x.npy", 3)], tmp_path / "out", workers=1)
    maps = sorted(p.name for p in (tmp_path / "out" / r.name / "labels").iterdir())
    assert maps == ["x-000000.png", "x-000001.png", "x-000002.png"]
