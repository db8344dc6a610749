"""The real recordings in ../shared/data load with the units and figures their PROVENANCE.md states."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.frame import Intrinsics
from depthgram.sources import open_source, read


def test_7scenes_sequence_with_intrinsics(shared_data: Path) -> None:
    root = shared_data / "7scenes_redkitchen_seq"
    src = open_source(root, fps=30)  # reads the depth/ subfolder; intrinsics from the parent
    assert src.kind == "folder" and len(src) == 300
    assert src.intrinsics == Intrinsics(585.0, 585.0, 320.0, 240.0)
    count = 0
    marker_frames = []
    for f in src:
        assert f.size == (640, 480) and f.index == count
        assert f.intrinsics is not None and f.intrinsics.fx == 585.0
        assert f.depth.max() < 10_000  # 65535 never comes out as 65.5 m
        assert 0.057 - 1e-3 <= f.invalid_fraction <= 0.137 + 1e-3  # PROVENANCE: 0.057-0.137
        if f.name in ("frame-000033.depth.png", "frame-000163.depth.png"):
            marker_frames.append(f.index)
        count += 1
    assert count == 300
    assert f.time_s == pytest.approx(299 / 30)
    assert marker_frames == [33, 163]  # natural order keeps file order


def test_7scenes_frame0_and_frame299_figures(shared_data: Path) -> None:
    depth = shared_data / "7scenes_redkitchen_seq" / "depth"
    info0 = open_source(depth / "frame-000000.depth.png").info()
    assert info0.depth_median_mm == 1878 and info0.depth_min_mm == 801 and info0.depth_max_mm == 3493
    assert info0.invalid_fraction == pytest.approx(0.108, abs=5e-4)
    assert info0.intrinsics == Intrinsics(585.0, 585.0, 320.0, 240.0)  # camera-intrinsics.txt in the parent
    info299 = open_source(depth / "frame-000299.depth.png").info()
    assert info299.depth_median_mm == 1630 and info299.depth_max_mm == 2980
    assert info299.invalid_fraction == pytest.approx(0.102, abs=5e-4)


def test_7scenes_65535_marker_is_invalid(shared_data: Path) -> None:
    p = shared_data / "7scenes_redkitchen_seq" / "depth" / "frame-000033.depth.png"
    import cv2

    raw = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    assert (raw == 65535).sum() == 46
    [f] = list(read(p))
    np.testing.assert_array_equal(f.valid, (raw > 0) & (raw != 65535))


def test_tum_with_scale(shared_data: Path) -> None:
    info = open_source(shared_data / "open3d_tum_nyu_sun_singles" / "TUM_depth.png", scale_mm=0.2).info()
    assert info.depth_median_mm == pytest.approx(2415, abs=1)  # 12075 / 5 = 2.42 m
    assert info.depth_min_mm == pytest.approx(1464) and info.depth_max_mm == pytest.approx(9331)
    assert info.invalid_fraction == pytest.approx(0.192, abs=5e-4)


def test_nyu_kinect_disparity(shared_data: Path) -> None:
    info = open_source(shared_data / "open3d_tum_nyu_sun_singles" / "NYU_depth.pgm", encoding="kinect-disparity").info()
    assert info.depth_min_mm == pytest.approx(1390, abs=5) and info.depth_max_mm == pytest.approx(6690, abs=5)
    assert info.depth_median_mm == pytest.approx(3270, abs=5)
    assert info.invalid_fraction == pytest.approx(0.072, abs=5e-4)


def test_nyu_without_encoding_is_not_silently_read_as_mm(shared_data: Path) -> None:
    # auto reads the PGM as big-endian mm: the numbers are absurd for an indoor room, which is
    # why the encoding must be given; check the figures are indeed not the NYU metric range.
    info = open_source(shared_data / "open3d_tum_nyu_sun_singles" / "NYU_depth.pgm").info()
    assert info.depth_max_mm is not None and info.depth_max_mm > 10_000


def test_sun_bit_shift(shared_data: Path) -> None:
    info = open_source(shared_data / "open3d_tum_nyu_sun_singles" / "SUN_depth.png", encoding="sun").info()
    assert (info.depth_min_mm, info.depth_median_mm, info.depth_max_mm) == (1057, 2723, 9870)
    assert info.invalid_fraction == pytest.approx(0.182, abs=5e-4)


def test_azure_kinect_folder_reads_depth_not_ir(shared_data: Path) -> None:
    src = open_source(shared_data / "azure_kinect_tof_mug_single")
    assert len(src) == 1
    info = src.info()
    assert info.size == (640, 576)
    assert (info.depth_min_mm, info.depth_median_mm, info.depth_max_mm) == (165, 1491, 3690)
    assert info.invalid_fraction == pytest.approx(0.235, abs=5e-4)


def test_nvlabs_tabletop_folder(shared_data: Path) -> None:
    src = open_source(shared_data / "nvlabs_ucn_demo_tabletop")
    assert len(src) == 9
    assert src.intrinsics == Intrinsics(612.937, 613.173, 322.549, 248.158)
    frames = list(src)
    assert frames[0].name == "000000-depth.png" and frames[8].name == "000008-depth.png"
    f0 = frames[0]
    assert float(np.median(f0.depth[f0.valid])) == pytest.approx(876, abs=1)
    assert f0.invalid_fraction == pytest.approx(0.079, abs=5e-4)
    assert all(0.020 - 1e-3 <= f.invalid_fraction <= 0.103 + 1e-3 for f in frames)


def test_osd_disparity_folder_is_mm(shared_data: Path) -> None:
    frames = list(read(shared_data / "osd_samples_uoais" / "disparity"))
    assert [f.name for f in frames] == ["learn6.png", "test42.png", "test50.png", "test63.png", "test64.png"]
    learn6 = frames[0]
    assert float(np.median(learn6.depth[learn6.valid])) == pytest.approx(784, abs=1)
    assert learn6.invalid_fraction == pytest.approx(0.225, abs=5e-4)


def test_colour_folder_is_refused(shared_data: Path) -> None:
    with pytest.raises(InputError, match="no depth frames in this folder"):
        open_source(shared_data / "7scenes_redkitchen_seq" / "color")
    with pytest.raises(InputError, match="colour image"):
        list(read(shared_data / "osd_samples_uoais" / "image_color" / "learn6.png"))
