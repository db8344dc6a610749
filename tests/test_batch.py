"""Batch runs: process pool, resumability, failures kept apart, and a real Dask cluster."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from depthgram.batch import output_names, run_batch
from depthgram.cli import main


def _read_all(root: Path, name: str) -> list[dict]:
    return [json.loads(x) for x in (root / name / "scenes.jsonl").read_text().splitlines()]


def test_output_names_are_distinct() -> None:
    assert output_names(["a/x", "b/x", "sim:table?frames=2"]) == ["x", "x-2", "sim_table_frames_2"]


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
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
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
