"""benchmarks/real.py: the YCB-Video scoring harness on two frames (skipped without ../shared/data)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from benchmarks import real

from depthgram.commands.bench import SUITES, benchmarks_dir
from depthgram.segmentation import segment


@pytest.fixture(scope="module")
def frames(request: pytest.FixtureRequest) -> list[real.LabelledFrame]:
    shared = request.getfixturevalue("shared_data")
    folder = Path(shared) / "ycbv_0000_labelled"
    if not folder.is_dir():
        pytest.skip(f"{folder} absent")
    return real.load_ycbv(folder, frames=[1, 2])


def test_registered_as_bench_suite() -> None:
    assert (benchmarks_dir() / SUITES["real"]).resolve() == Path(real.__file__).resolve()


def test_loader_units_and_truth(frames: list[real.LabelledFrame]) -> None:
    f = frames[0]
    assert f.depth.shape == f.truth.shape == (480, 640)
    assert set(np.unique(f.truth)) == {0, *real.OBJECT_IDS}
    # PROVENANCE.md: objects at 518-605 mm, so the 0.1 mm units were converted to mm
    for k in real.OBJECT_IDS:
        med = float(np.median(f.depth[(f.truth == k) & f.valid]))
        assert 500.0 < med < 620.0
    assert f.intrinsics.fx == pytest.approx(1066.778)


def test_scores_against_known_labelings(frames: list[real.LabelledFrame]) -> None:
    f = frames[0]
    perfect = real.score_frame(f.truth, f)
    assert perfect.found == 3
    np.testing.assert_allclose(perfect.iou, 1.0)
    # one segment covering every valid pixel: recall 1, precision = object share of valid pixels
    whole = real.score_frame(f.valid.astype(np.int32), f)
    n_valid = np.count_nonzero(f.valid)
    expected = [np.count_nonzero((f.truth == k) & f.valid) / n_valid for k in real.OBJECT_IDS]
    np.testing.assert_allclose(whole.recall, 1.0)
    np.testing.assert_allclose(whole.precision, expected)
    np.testing.assert_allclose(whole.iou, expected)
    assert whole.found == 0


def test_plane_dbscan_removes_the_desk(frames: list[real.LabelledFrame]) -> None:
    f = frames[0]
    lab = real.plane_dbscan_labels(f, {"planes": 1, "plane_mm": 10.0, "eps_mm": 10.0, "min_points": 10})
    # the desk is the dominant plane: most background pixels go, most object pixels stay
    background = f.valid & (f.truth == 0)
    objects = f.valid & (f.truth > 0)
    assert np.count_nonzero(lab[background] == 0) > 0.4 * np.count_nonzero(background)
    assert np.count_nonzero(lab[objects] > 0) > 0.8 * np.count_nonzero(objects)
    assert real.score_frame(lab, f).found >= 1


def test_quick_run_two_frames(frames: list[real.LabelledFrame], tmp_path: Path) -> None:
    results = real.run_benchmark(frames, quick=True, out=tmp_path, progress=False)
    names = [r.method for r in results]
    assert names[:2] == ["depthgram default", "depthgram threshold"]
    assert len(results) == 4
    for r in results:
        assert r.scores.iou.shape == (6,)
        assert r.held_out.iou.shape == (3,)
        for a in (r.scores.iou, r.scores.recall, r.scores.precision):
            assert ((a >= 0) & (a <= 1)).all()
    # the harness scores exactly what segment() gives
    direct = real.Scores.join(
        [real.score_frame(segment(f.depth, valid=f.valid, intrinsics=f.intrinsics).labels, f) for f in frames]
    )
    np.testing.assert_allclose(results[0].scores.iou, direct.iou)
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["ycbv_000001.png", "ycbv_000002.png"]
    text = real.table(results, len(frames))
    assert "of 6" in text and "chosen parameters" in text
