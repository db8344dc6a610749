"""Readers on files written here: round trips, units, encodings, sidecars, order, streaming, bad input."""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile

from depthgram.errors import InputError
from depthgram.frame import Intrinsics, depth_to_8bit
from depthgram.sources import SourceConfig, natural_key, open_source, read, read_timestamps

RNG = np.random.default_rng(7)


def mm_image(h: int = 24, w: int = 32, seed: int = 0) -> np.ndarray:
    """uint16 depth in mm with a few zero (invalid) pixels."""
    a = np.random.default_rng(seed).integers(300, 6000, size=(h, w)).astype(np.uint16)
    a[0, :5] = 0
    return a


def write_png(path: Path, a: np.ndarray) -> Path:
    assert cv2.imwrite(str(path), a)
    return path


# --- single files: round trips and units -------------------------------------------------------


def test_png16_round_trip_in_mm(tmp_path: Path) -> None:
    a = mm_image()
    [f] = list(read(write_png(tmp_path / "d.png", a)))
    assert f.depth.dtype == np.float32
    np.testing.assert_array_equal(f.depth, a.astype(np.float32))
    np.testing.assert_array_equal(f.valid, a > 0)
    assert f.size == (32, 24) and f.index == 0 and f.name == "d.png"


def test_uint16_65535_is_invalid_by_default_and_invalid_values_apply(tmp_path: Path) -> None:
    a = mm_image()
    a[3, 3] = 65535
    a[4, 4] = 1234
    [f] = list(read(write_png(tmp_path / "d.png", a), invalid=[1234]))
    assert not f.valid[3, 3] and f.depth[3, 3] == 0
    assert not f.valid[4, 4] and f.depth[4, 4] == 0
    assert f.valid[5, 5] and f.depth[5, 5] == a[5, 5]


def test_tum_scale(tmp_path: Path) -> None:
    a = np.full((8, 8), 12075, np.uint16)  # TUM: 5000 units per metre -> 2415 mm
    [f] = list(read(write_png(tmp_path / "t.png", a), scale_mm=0.2))
    np.testing.assert_allclose(f.depth, 2415.0, rtol=1e-6)


def test_png8_paper_encoding_needs_range(tmp_path: Path) -> None:
    mm = np.linspace(500, 3500, 64, dtype=np.float32).reshape(8, 8)
    mm[0, 0] = 0
    mm[0, 1] = 500.0
    codes = depth_to_8bit(mm, 500, 3500)
    p = write_png(tmp_path / "p8.png", codes)
    with pytest.raises(InputError, match=r"p8\.png.*8-bit.*depth_range_mm"):
        list(read(p))
    [f] = list(read(p, depth_range_mm=(500, 3500)))
    step = 3000 / 254  # one code step, mm
    assert not f.valid[0, 0]
    np.testing.assert_allclose(f.depth[f.valid], mm[f.valid], atol=step / 2 + 1e-3)
    # code 1 is near, code 255 is far: the paper's 0-255 over the stated range
    assert f.depth[0, 1] == pytest.approx(500.0) and f.depth[7, 7] == pytest.approx(3500.0)


def test_tiff_float_metres_and_scale_override(tmp_path: Path) -> None:
    m = RNG.uniform(0.4, 4.0, (12, 16)).astype(np.float32)
    m[2, 2] = np.nan  # NaN is simply an invalid pixel
    p = tmp_path / "d.tif"
    tifffile.imwrite(p, m)
    [f] = list(read(p))
    ok = np.isfinite(m)
    np.testing.assert_allclose(f.depth[ok], m[ok] * 1000, rtol=1e-6)
    assert not f.valid[2, 2] and f.depth[2, 2] == 0
    [g] = list(read(p, scale_mm=1.0))  # float millimetres when told
    np.testing.assert_allclose(g.depth[ok], m[ok], rtol=1e-6)
    [h] = list(read(p, encoding="mm"))  # the same, said as an encoding
    np.testing.assert_allclose(h.depth[ok], m[ok], rtol=1e-6)
    np.save(tmp_path / "int_m.npy", np.array([[1, 2]], np.uint8))
    [k] = list(read(tmp_path / "int_m.npy", encoding="m"))  # integer metres
    np.testing.assert_array_equal(k.depth, [[1000, 2000]])


def test_tiff_uint16(tmp_path: Path) -> None:
    a = mm_image()
    tifffile.imwrite(tmp_path / "d.tiff", a)
    [f] = list(read(tmp_path / "d.tiff"))
    np.testing.assert_array_equal(f.depth, a)


def test_pgm_round_trip(tmp_path: Path) -> None:
    a = mm_image()
    [f] = list(read(write_png(tmp_path / "d.pgm", a)))
    np.testing.assert_array_equal(f.depth, a)


def test_npy_and_npz_single_and_key(tmp_path: Path) -> None:
    a = mm_image()
    np.save(tmp_path / "d.npy", a)
    [f] = list(read(tmp_path / "d.npy"))
    np.testing.assert_array_equal(f.depth, a)
    b = mm_image(seed=1)
    np.savez(tmp_path / "d.npz", meta=np.arange(3), depth=a, other=b)
    [g] = list(read(tmp_path / "d.npz"))  # first 2-D array
    np.testing.assert_array_equal(g.depth, a)
    [h] = list(read(tmp_path / "d.npz", key="other"))
    np.testing.assert_array_equal(h.depth, b)
    [k] = list(read(f"{tmp_path / 'd.npz'}?key=other"))
    np.testing.assert_array_equal(k.depth, b)
    with pytest.raises(InputError, match=r"no array named 'nope'.*meta, depth, other"):
        list(read(tmp_path / "d.npz", key="nope"))


def test_sun_encoding(tmp_path: Path) -> None:
    mm = np.array([[1057, 2723], [9870, 0]], np.uint16)
    stored = ((mm << np.uint16(3)) | (mm >> np.uint16(13))).astype(np.uint16)  # SUN's shift, inverted
    p = write_png(tmp_path / "sun.png", stored)
    [f] = list(read(p, encoding="sun"))
    np.testing.assert_array_equal(f.depth, mm)
    np.testing.assert_array_equal(f.valid, mm > 0)


def test_kinect_disparity_encoding_little_endian_pgm(tmp_path: Path) -> None:
    d = np.array([[839, 1000], [2047, 1092]], np.uint16)
    # NYU raw PGMs hold little-endian samples; OpenCV reads PGM big-endian, so store swapped.
    p = write_png(tmp_path / "nyu.pgm", d.byteswap())
    [f] = list(read(p, encoding="kinect-disparity"))
    expect_mm = 351.3 / (1092.5 - d.astype(np.float64)) * 1000
    assert f.depth[0, 0] == pytest.approx(expect_mm[0, 0], rel=1e-5)  # 1.3858 m
    assert f.depth[0, 1] == pytest.approx(3798.0, abs=1.0)  # 351.3 / 92.5 m
    assert not f.valid[1, 0]  # 2047: no reading
    assert f.depth[1, 1] == pytest.approx(702600.0, rel=1e-5)  # d just below 1092.5 -> far
    # the same codes stored in native order give the same depth (no swap when max <= 2047)
    np.save(tmp_path / "nyu.npy", d)
    [g] = list(read(tmp_path / "nyu.npy", encoding="kinect-disparity"))
    np.testing.assert_array_equal(g.depth, f.depth)


def test_depth_range_marks_outside_invalid(tmp_path: Path) -> None:
    a = np.array([[100, 600], [2000, 5000]], np.uint16)
    [f] = list(read(write_png(tmp_path / "d.png", a), depth_range_mm=(500, 3000)))
    np.testing.assert_array_equal(f.valid, [[False, True], [True, False]])
    np.testing.assert_array_equal(f.depth, [[0, 600], [2000, 0]])


# --- folders, globs, order, sidecars, timestamps ----------------------------------------------


def make_folder(folder: Path, n: int, prefix: str = "frame", suffix: str = "png") -> list[np.ndarray]:
    folder.mkdir(parents=True, exist_ok=True)
    frames = []
    for i in range(n):
        a = np.full((6, 8), 1000 + i, np.uint16)
        write_png(folder / f"{prefix}{i}.{suffix}", a)
        frames.append(a)
    return frames


def test_natural_key_order() -> None:
    names = ["frame10.png", "frame2.png", "frame1.png", "Frame3.png"]
    assert sorted(names, key=natural_key) == ["frame1.png", "frame2.png", "Frame3.png", "frame10.png"]


def test_folder_natural_order_with_fps(tmp_path: Path) -> None:
    make_folder(tmp_path / "seq", 12)
    src = open_source(tmp_path / "seq", fps=10)
    assert len(src) == 12 and src.kind == "folder"
    frames = list(src)
    assert [int(f.depth[0, 0]) - 1000 for f in frames] == list(range(12))  # frame2 before frame10
    assert [f.index for f in frames] == list(range(12))
    assert frames[11].time_s == pytest.approx(1.1)


def test_folder_timestamps_file_and_pairs(tmp_path: Path) -> None:
    make_folder(tmp_path / "seq", 3)
    times = [0.0, 0.04, 0.1]
    (tmp_path / "seq" / "timestamps.txt").write_text("# t in s\n" + "\n".join(map(str, times)) + "\n")
    assert [f.time_s for f in read(tmp_path / "seq")] == times  # picked up automatically
    pairs = tmp_path / "pairs.txt"
    pairs.write_text("2 0.5\n0 0.1\n1 0.3\n")
    assert [f.time_s for f in read(tmp_path / "seq", timestamps=pairs)] == [0.1, 0.3, 0.5]
    info = open_source(tmp_path / "seq", timestamps=pairs).info()
    assert info.fps == pytest.approx(5.0) and info.duration_s == pytest.approx(0.4)


def test_depth_subfolder_and_depth_named_files_and_sidecars(tmp_path: Path) -> None:
    make_folder(tmp_path / "rec" / "depth", 2)
    np.savetxt(tmp_path / "rec" / "camera-intrinsics.txt", [[585, 0, 320], [0, 585, 240], [0, 0, 1]])
    src = open_source(tmp_path / "rec")
    assert len(src) == 2 and src.intrinsics == Intrinsics(585, 585, 320, 240)
    assert all(f.intrinsics == Intrinsics(585, 585, 320, 240) for f in src)
    # NVlabs layout: colour and depth side by side, camera_params.json
    mixed = tmp_path / "nv"
    mixed.mkdir()
    for i in range(3):
        write_png(mixed / f"00000{i}-color.png", np.zeros((6, 8, 3), np.uint8))
        write_png(mixed / f"00000{i}-depth.png", np.full((6, 8), 700 + i, np.uint16))
    (mixed / "camera_params.json").write_text(
        json.dumps({"fx": 612.9, "fy": 613.1, "x_offset": 322.5, "y_offset": 248.1})
    )
    frames = list(read(mixed))
    assert [f.depth[0, 0] for f in frames] == [700, 701, 702]
    assert frames[0].intrinsics == Intrinsics(612.9, 613.1, 322.5, 248.1)
    # camera.json (written by `depthgram simulate`) gives fps too; explicit options win
    (tmp_path / "rec" / "depth" / "camera.json").write_text(
        json.dumps({"fx": 100.0, "fy": 101.0, "cx": 3.5, "cy": 2.5, "fps": 15})
    )
    src = open_source(tmp_path / "rec")
    assert src.intrinsics == Intrinsics(100, 101, 3.5, 2.5) and src.fps == 15
    assert [f.time_s for f in src] == [0.0, pytest.approx(1 / 15)]
    assert open_source(tmp_path / "rec", fps=30).fps == 30
    mine = Intrinsics(1, 2, 3, 4)
    assert open_source(tmp_path / "rec", intrinsics=mine).intrinsics == mine


def test_glob(tmp_path: Path) -> None:
    make_folder(tmp_path, 11, prefix="f")
    make_folder(tmp_path, 2, prefix="g")
    src = open_source(str(tmp_path / "f*.png"))
    assert src.kind == "glob" and len(src) == 11
    assert [int(f.depth[0, 0]) for f in src] == [1000 + i for i in range(11)]


# --- stacks and streaming ----------------------------------------------------------------------


def test_npy_stack_is_a_sequence(tmp_path: Path) -> None:
    stack = np.stack([mm_image(seed=i) for i in range(4)])
    np.save(tmp_path / "s.npy", stack)
    src = open_source(tmp_path / "s.npy", fps=20)
    assert src.kind == "npy-stack" and len(src) == 4
    frames = list(src)
    for i, f in enumerate(frames):
        np.testing.assert_array_equal(f.depth, stack[i])
        assert f.index == i and f.time_s == pytest.approx(i / 20)


@pytest.mark.parametrize("compress", [False, True])
def test_npz_stack_is_streamed(tmp_path: Path, compress: bool) -> None:
    stack = RNG.uniform(0.5, 3.0, (5, 6, 7)).astype(np.float32)
    (np.savez_compressed if compress else np.savez)(tmp_path / "s.npz", depth=stack)
    src = open_source(tmp_path / "s.npz")
    assert src.kind == "npz-stack" and len(src) == 5
    for i, f in enumerate(src):
        np.testing.assert_allclose(f.depth, stack[i] * 1000, rtol=1e-6)


def test_long_npy_stack_streams_with_flat_memory(tmp_path: Path) -> None:
    n, h, w = 2000, 48, 64
    stack = np.lib.format.open_memmap(tmp_path / "long.npy", mode="w+", dtype=np.uint16, shape=(n, h, w))
    stack[:] = np.arange(n, dtype=np.uint16)[:, None, None] + 500
    stack.flush()
    del stack
    stack_bytes = n * h * w * 2  # 12.3 MB
    tracemalloc.start()
    try:
        count, last = 0, 0.0
        for f in read(tmp_path / "long.npy"):
            count += 1
            last = float(f.depth[0, 0])
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert count == n and last == 500 + n - 1
    assert peak < stack_bytes / 20, f"peak {peak} bytes while streaming a {stack_bytes}-byte stack"


# --- configuration -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kw",
    [
        {"scale_mm": 0},
        {"scale_mm": float("nan")},
        {"fps": -1},
        {"encoding": "jpeg"},
        {"depth_range_mm": (3000, 500)},
        {"invalid": ["x"]},
    ],
)
def test_config_refuses_absurd_values(kw: dict[str, object]) -> None:
    with pytest.raises(InputError):
        SourceConfig(**kw)  # type: ignore[arg-type]


# --- bad input: clear errors naming the file and frame -----------------------------------------


def test_missing_path() -> None:
    with pytest.raises(InputError, match=r"no/such/thing\.png: no such file or folder"):
        open_source("no/such/thing.png")


def test_truncated_png(tmp_path: Path) -> None:
    _, buf = cv2.imencode(".png", mm_image())
    p = tmp_path / "half.png"
    p.write_bytes(buf.tobytes()[: len(buf) // 2])
    with pytest.raises(InputError, match=r"half\.png: cannot decode the image \(truncated"):
        list(read(p))


def test_truncated_tiff_and_garbage_npy(tmp_path: Path) -> None:
    tifffile.imwrite(tmp_path / "d.tif", mm_image())
    data = (tmp_path / "d.tif").read_bytes()
    (tmp_path / "half.tif").write_bytes(data[:100])
    with pytest.raises(InputError, match=r"half\.tif: cannot read the TIFF"):
        list(read(tmp_path / "half.tif"))
    (tmp_path / "bad.npy").write_bytes(b"not an array")
    with pytest.raises(InputError, match=r"bad\.npy: cannot read"):
        list(read(tmp_path / "bad.npy"))


def test_colour_image_given_as_depth(tmp_path: Path) -> None:
    p = write_png(tmp_path / "rgb.png", np.zeros((6, 8, 3), np.uint8))
    with pytest.raises(InputError, match=r"rgb\.png: this is a colour image"):
        list(read(p))


@pytest.mark.parametrize(
    ("arr", "what"),
    [
        (np.ones((4, 4), bool), "bool"),
        (np.ones((4, 4), complex), "complex"),
    ],
)
def test_wrong_dtype(tmp_path: Path, arr: np.ndarray, what: str) -> None:
    np.save(tmp_path / "x.npy", arr)
    with pytest.raises(InputError, match=rf"x\.npy: expected integer or float depth samples, got dtype {what}"):
        list(read(tmp_path / "x.npy"))


def test_object_npy(tmp_path: Path) -> None:
    np.save(tmp_path / "o.npy", np.array([[1, "a"]], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match=r"o\.npy: cannot read the \.npy"):
        list(read(tmp_path / "o.npy"))


def test_empty_folder_and_glob(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("x")
    with pytest.raises(InputError, match=r"empty: no depth frames in this folder"):
        open_source(tmp_path / "empty")
    with pytest.raises(InputError, match=r"nothing\*\.png: the pattern matches no depth frame files"):
        open_source(str(tmp_path / "nothing*.png"))


def test_folder_of_folders_names_the_subfolder_with_depth(tmp_path: Path) -> None:
    # Datasets nest frames (OSD: disparity/ beside image_color/); the error says where to look.
    root = tmp_path / "dataset"
    for sub in ("image_color", "disparity", "notes"):
        (root / sub).mkdir(parents=True)
    cv2.imwrite(str(root / "image_color" / "a.png"), np.zeros((4, 4, 3), np.uint8))
    cv2.imwrite(str(root / "disparity" / "a.png"), np.full((4, 4), 1000, np.uint16))
    (root / "notes" / "readme.txt").write_text("x")
    with pytest.raises(InputError, match=r"no depth frames in this folder") as err:
        open_source(root)
    said = str(err.value)
    assert said.index("disparity") < said.index("image_color")  # the depth-named one first
    assert "notes" not in said
    (tmp_path / "flat").mkdir()
    with pytest.raises(InputError) as err:
        open_source(tmp_path / "flat")
    assert "subfolders" not in str(err.value)


def test_mixed_sizes_name_both_frames(tmp_path: Path) -> None:
    make_folder(tmp_path, 2, prefix="a")
    write_png(tmp_path / "a2.png", np.ones((5, 5), np.uint16))
    with pytest.raises(InputError, match=r"a2\.png \(frame 2\) is 5x5 px but .*a0\.png \(frame 0\) is 8x6 px"):
        list(read(tmp_path))


def test_bad_frame_in_sequence_names_index(tmp_path: Path) -> None:
    make_folder(tmp_path, 3, prefix="a")
    (tmp_path / "a1.png").write_bytes(b"\x89PNG broken")
    with pytest.raises(InputError, match=r"a1\.png \(frame 1\): cannot decode"):
        list(read(tmp_path))


def test_timestamps_wrong_count_and_not_increasing(tmp_path: Path) -> None:
    make_folder(tmp_path / "seq", 3)
    bad = tmp_path / "ts.txt"
    bad.write_text("0.0\n0.1\n")
    with pytest.raises(InputError, match=r"ts\.txt: 2 timestamps for 3 frames"):
        open_source(tmp_path / "seq", timestamps=bad)
    bad.write_text("0.0\n0.2\n0.2\n")
    with pytest.raises(InputError, match=r"ts\.txt: times must strictly increase; frame 2"):
        open_source(tmp_path / "seq", timestamps=bad)
    bad.write_text("0.0\nzero\n0.2\n")
    with pytest.raises(InputError, match=r"ts\.txt line 2"):
        read_timestamps(bad, 3)


def test_nan_is_invalid_not_an_error(tmp_path: Path) -> None:
    m = np.full((4, 4), np.nan, np.float32)
    m[1, 1] = 1.5
    np.save(tmp_path / "n.npy", m)
    [f] = list(read(tmp_path / "n.npy"))
    assert f.valid.sum() == 1 and f.depth[1, 1] == pytest.approx(1500.0)
    info = open_source(tmp_path / "n.npy").info()
    assert info.invalid_fraction == pytest.approx(15 / 16)
    assert info.depth_median_mm == 1500.0


def test_info_streams_exact_figures(tmp_path: Path) -> None:
    a = np.array([[0, 1000, 2000], [3000, 4000, 65535]], np.uint16)
    b = np.array([[500, 0, 0], [0, 0, 6000]], np.uint16)
    write_png(tmp_path / "x0.png", a)
    write_png(tmp_path / "x1.png", b)
    info = open_source(tmp_path, fps=5).info()
    # valid: 1000 2000 3000 4000 500 6000 -> lower median of 6 values = 2000
    assert (info.frames, info.size, info.unit) == (2, (3, 2), "mm")
    assert (info.depth_min_mm, info.depth_median_mm, info.depth_max_mm) == (500, 2000, 6000)
    assert info.invalid_fraction == pytest.approx(6 / 12)
    assert info.fps == 5 and info.duration_s == pytest.approx(0.2)


# --- the simulator as a source -----------------------------------------------------------------


def test_sim_spec_matches_simulate_and_bare_scene_name() -> None:
    sensor = pytest.importorskip("depthgram.sensor", reason="simulator not available")
    direct = [s.frame for s in sensor.simulate("table", 3, size=(48, 36), fps=10, seed=1)]
    src = open_source("sim:table?frames=3&size=48x36&seed=1&fps=10")
    assert src.kind == "sim" and len(src) == 3 and src.fps == 10
    assert src.intrinsics == direct[0].intrinsics  # known before iterating
    got = list(src)
    assert len(got) == 3
    for a, b in zip(got, direct, strict=True):
        np.testing.assert_array_equal(a.depth, b.depth)
        assert a.time_s == pytest.approx(b.time_s) and a.size == (48, 36)
    assert src.intrinsics == direct[0].intrinsics
    bare = open_source("table?frames=2&size=48x36&seed=1&fps=10")  # no file named "table" here
    assert bare.kind == "sim" and len(bare) == 2
    np.testing.assert_array_equal(next(iter(bare)).depth, direct[0].depth)


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("sim:table?frames=0", "frames must be >= 1"),
        ("sim:table?size=176", "bad value '176' for size"),
        ("sim:table?colour=1", "unknown sim option 'colour'"),
        ("sim:?frames=3", "needs a scene name"),
    ],
)
def test_sim_spec_errors(spec: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        open_source(spec)


def test_sim_unknown_scene_is_a_clear_error() -> None:
    pytest.importorskip("depthgram.sensor", reason="simulator not available")
    with pytest.raises(InputError, match="kitchen"):
        open_source("sim:kitchen?frames=1")  # refused at open, not at the first frame


def test_colour_npy_is_one_image_not_a_stack(tmp_path: Path) -> None:
    np.save(tmp_path / "rgb.npy", np.zeros((6, 8, 3), np.uint8))
    with pytest.raises(InputError, match=r"rgb\.npy: this is a colour image"):
        list(read(tmp_path / "rgb.npy"))
    np.save(tmp_path / "grey.npy", np.full((6, 8, 1), 900, np.uint16))
    [f] = list(read(tmp_path / "grey.npy"))
    assert f.size == (8, 6) and f.depth[0, 0] == 900
