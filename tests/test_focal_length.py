"""The focal length read from the scene: rendered tabletops with known intrinsics, and real ones."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose

from depthgram import Pipeline
from depthgram.focal_length import estimate_focal_length
from depthgram.frame import Frame, Intrinsics
from depthgram.sources.camera import IntrinsicsWarning

#: boxes standing on the table: centre x, centre z (mm, world), width, depth, height (mm), yaw (deg)
BOXES = ((-250.0, 900.0, 160.0, 120.0, 200.0, 30.0), (150.0, 1000.0, 200.0, 90.0, 120.0, -20.0),
         (0.0, 1250.0, 120.0, 120.0, 260.0, 60.0))  # fmt: skip


def render_tabletop(
    f_px: float, tilt_deg: float, size: tuple[int, int] = (640, 480), height_mm: float = 700.0, seed: int = 0
) -> np.ndarray:
    """Depth (mm) of a table top with three yawed boxes, seen by a pinhole camera pitched down."""
    return render_tabletop_truth(f_px, tilt_deg, size, height_mm, seed)[0]


def render_tabletop_truth(
    f_px: float,
    tilt_deg: float,
    size: tuple[int, int] = (640, 480),
    height_mm: float = 700.0,
    seed: int = 0,
    boxes: tuple[tuple[float, ...], ...] = BOXES,
) -> tuple[np.ndarray, np.ndarray]:
    """Depth (mm) and truth (0 table or nothing, k the k-th box) of a table top with yawed boxes.

    World: x right, y down, z ahead; the camera at the origin looks down by ``tilt_deg``; the table
    is the plane y = ``height_mm``. Structured-light-like noise (1 mm + 1.5e-6 z^2), whole mm.
    """
    w, h = size
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    ray = np.stack([(u - (w - 1) / 2) / f_px, (v - (h - 1) / 2) / f_px, np.ones_like(u)], -1)
    t = math.radians(tilt_deg)
    rot = np.array([[1, 0, 0], [0, math.cos(t), math.sin(t)], [0, -math.sin(t), math.cos(t)]])
    d = ray @ rot.T  # world direction of each pixel's ray, z component of ray = 1
    truth = np.zeros((h, w), np.int32)
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(d[..., 1] > 1e-9, height_mm / d[..., 1], np.inf)
        for box_id, (cx, cz, bw, bd, bh, yaw) in enumerate(boxes, start=1):
            a = math.radians(yaw)
            # the ray in the box's own frame (turned about the vertical), from its centre
            c, s = math.cos(a), math.sin(a)
            ox, oz = -(c * cx + s * cz), -(-s * cx + c * cz)
            dx, dz = c * d[..., 0] + s * d[..., 2], -s * d[..., 0] + c * d[..., 2]
            lo = [(-bw / 2 - ox) / dx, (height_mm - bh) / d[..., 1], (-bd / 2 - oz) / dz]
            hi = [(bw / 2 - ox) / dx, height_mm / d[..., 1], (bd / 2 - oz) / dz]
            near = np.maximum.reduce([np.minimum(p, q) for p, q in zip(lo, hi, strict=True)])
            far = np.minimum.reduce([np.maximum(p, q) for p, q in zip(lo, hi, strict=True)])
            hit = (near < far) & (near > 0) & (near < depth)
            depth = np.where(hit, near, depth)
            truth[hit] = box_id
    depth[~np.isfinite(depth) | (depth > 6000)] = 0
    rng = np.random.default_rng(seed)
    noisy = depth + rng.normal(0, 1, depth.shape) * (1.0 + 1.5e-6 * depth**2)
    truth[depth == 0] = 0
    return np.where(depth > 0, np.round(noisy), 0).astype(np.float32), truth


@pytest.mark.parametrize("f_px", [300.0, 580.0, 1050.0])
@pytest.mark.parametrize("tilt_deg", [30.0, 50.0])
def test_the_focal_length_of_a_rendered_tabletop(f_px: float, tilt_deg: float) -> None:
    depth = render_tabletop(f_px, tilt_deg)
    est = estimate_focal_length(depth)
    assert est is not None
    assert_allclose(est.intrinsics.fx, f_px, rtol=0.05)
    assert est.intrinsics.fx == est.intrinsics.fy
    assert (est.intrinsics.cx, est.intrinsics.cy) == (319.5, 239.5)
    # the support's tilt from face-on is 90 degrees less the camera's pitch
    assert_allclose(est.tilt_deg, 90.0 - tilt_deg, atol=4.0)


def test_a_smaller_frame_gives_the_same_field_of_view() -> None:
    # the focal length scales with the frame: 320 x 240 of the same view, half the pixels
    est = estimate_focal_length(render_tabletop(290.0, 40.0, size=(320, 240)))
    assert est is not None
    assert_allclose(est.intrinsics.fx, 290.0, rtol=0.05)


def test_no_estimate_where_the_scene_cannot_tell() -> None:
    # a table seen face-on (camera straight down) or edge-on (level, at the table's height)
    # makes every square surface vote noise: no estimate rather than a wrong one
    assert estimate_focal_length(render_tabletop(580.0, 88.0)) is None
    assert estimate_focal_length(render_tabletop(580.0, 0.0, height_mm=60.0)) is None
    assert estimate_focal_length(np.full((480, 640), 1500.0, np.float32)) is None  # a wall ahead
    assert estimate_focal_length(np.zeros((480, 640), np.float32)) is None  # nothing read
    assert estimate_focal_length(np.full((10, 12), 900.0, np.float32)) is None  # too small to tell


def test_the_pipeline_uses_the_estimate_and_says_so() -> None:
    depths = [render_tabletop(580.0, 45.0, seed=i) for i in range(2)]
    frames = [Frame(d, d > 0, index=i, name=f"f{i}") for i, d in enumerate(depths)]
    with pytest.warns(IntrinsicsWarning, match=r"estimated fx = fy = \d+ px from the scene.*--intrinsics"):
        results = list(Pipeline().run(frames))
    cam = results[0].to_record()["camera"]
    assert cam["intrinsics_source"] == "estimated"
    assert_allclose(cam["intrinsics"]["fx"], 580.0, rtol=0.05)
    assert_allclose((cam["intrinsics"]["cx"], cam["intrinsics"]["cy"]), (319.5, 239.5))
    # given intrinsics within 1.4 times the scene's focal length are not second-guessed
    with warnings.catch_warnings():
        warnings.simplefilter("error", IntrinsicsWarning)
        given = list(Pipeline(intrinsics=Intrinsics(700.0, 700.0, 320.0, 240.0)).run(frames))
    assert given[0].to_record()["camera"]["intrinsics"]["fx"] == 700.0


@pytest.mark.parametrize("factor", [0.6, 1.6])
def test_intrinsics_for_another_camera_are_overruled_by_the_scene(factor: float) -> None:
    # a user's focal length 0.6 or 1.6 times the true one (the colour camera's calibration, a
    # profile of the bare depth camera): the scene's right angles win, with a warning naming
    # the given values and the way to keep them; the principal point given stays
    depths = [render_tabletop(580.0, 45.0, seed=i) for i in range(3)]
    frames = [Frame(d, d > 0, index=i, name=f"f{i}") for i, d in enumerate(depths)]
    wrong = Intrinsics(580.0 * factor, 580.0 * factor, 321.0, 238.0)
    with pytest.warns(IntrinsicsWarning, match=rf"fx = {wrong.fx:.0f}.*disagree with the scene.*--trust-intrinsics"):
        results = list(Pipeline(intrinsics=wrong).run(frames))
    cam = results[0].to_record()["camera"]
    assert cam["intrinsics_source"] == "estimated"
    assert f"overruling given fx = {wrong.fx:.0f} px" in cam["intrinsics_from"]
    for r in results:
        k = r.frame.intrinsics
        assert k is not None and r.frame.intrinsics_source == "estimated"
        assert_allclose((k.fx, k.fy), (580.0, 580.0), rtol=0.05)
        assert (k.cx, k.cy) == (321.0, 238.0)
    # trusted, they are used as given, silently
    with warnings.catch_warnings():
        warnings.simplefilter("error", IntrinsicsWarning)
        kept = list(Pipeline(intrinsics=wrong, check_intrinsics=False).run(frames))
    assert kept[0].to_record()["camera"]["intrinsics"]["fx"] == round(wrong.fx, 3)
    assert all(r.frame.intrinsics == wrong for r in kept)


def test_the_command_line_keeps_trusted_intrinsics(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from depthgram.cli import main

    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(2):
        cv2.imwrite(str(folder / f"{i:03d}.png"), render_tabletop(580.0, 45.0, seed=i).astype(np.uint16))
    fx = ["--intrinsics", "928", "928", "319.5", "239.5"]
    for extra, want in (([], "estimated"), (["--trust-intrinsics"], "given")):
        out = tmp_path / f"scene{len(extra)}.jsonl"
        assert main(["describe", str(folder), *fx, *extra, "--quiet", "--json", str(out)]) == 0
        first = json.loads(out.read_text().splitlines()[0])
        assert first["camera"]["intrinsics_source"] == want
    err = capsys.readouterr().err
    assert err.count("disagree with the scene") == 1
    # batch passes the flag to each recording's pipeline
    for extra, want in (([], "estimated"), (["--trust-intrinsics"], "given")):
        out = tmp_path / f"batch{len(extra)}"
        assert main(["batch", str(folder), "--out", str(out), *fx, *extra, "--quiet", "--workers", "1"]) == 0
        first = json.loads(next(out.glob("*/scenes.jsonl")).read_text().splitlines()[0])
        assert first["camera"]["intrinsics_source"] == want
    capsys.readouterr()
    # info says what describe will use
    for extra, want in (([], "overruling given fx = 928 px"), (["--trust-intrinsics"], "(given)")):
        assert main(["info", str(folder), *fx, *extra]) == 0
        line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("intrinsics"))
        assert want in line, line


def test_info_says_the_focal_length_the_pipeline_will_use(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from depthgram.cli import main

    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(2):
        cv2.imwrite(str(folder / f"{i:03d}.png"), render_tabletop(580.0, 45.0, seed=i).astype(np.uint16))
    assert main(["info", str(folder)]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("intrinsics"))
    fx = float(line.split()[2])
    assert_allclose(fx, 580.0, rtol=0.05)
    assert "estimated from the scene of frame 0" in line and "--intrinsics FX FY CX CY" in line


def test_real_tabletops_without_their_intrinsics(shared_data: Path) -> None:
    # PROVENANCE.md's focal lengths: YCB-Video's Xtion 1066.8 px (registered to colour), the
    # NVlabs RealSense 612.9 px, 7-Scenes' Kinect 585 px; within 15 %, where the guess is 512
    cases = (
        ("ycbv_0000_labelled/000001-depth.png", 0.1, 1066.8),
        ("ycbv_0001_0002_labelled/0002/000001-depth.png", 0.1, 1066.8),
        ("nvlabs_ucn_demo_tabletop/000000-depth.png", 1.0, 612.9),
        ("7scenes_redkitchen_seq/depth/frame-000000.depth.png", 1.0, 585.0),
    )
    for name, scale, fx in cases:
        path = shared_data / name
        if not path.exists():
            pytest.skip(f"{path} not found")
        raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.float32) * scale
        raw[raw > 10_000] = 0
        est = estimate_focal_length(raw)
        assert est is not None, name
        assert_allclose(est.intrinsics.fx, fx, rtol=0.15, err_msg=name)
