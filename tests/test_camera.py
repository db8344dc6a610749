"""The camera told to depthgram: calibration files, profiles, scaling, provenance, gravity."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from depthgram import Pipeline, read
from depthgram.cli import main
from depthgram.errors import InputError
from depthgram.frame import Gravity, Intrinsics, as_gravity
from depthgram.sources.camera import (
    PROFILES,
    IntrinsicsWarning,
    load_camera_file,
    resolve_camera,
)

K = Intrinsics(612.937, 613.173, 322.549, 248.158)
SIZE = (640, 480)


def k_tuple(k: Intrinsics) -> tuple[float, float, float, float]:
    return (k.fx, k.fy, k.cx, k.cy)


def flat(k: Intrinsics) -> list[float]:
    return [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0]


def matrix(k: Intrinsics) -> list[list[float]]:
    return [[k.fx, 0.0, k.cx], [0.0, k.fy, k.cy], [0.0, 0.0, 1.0]]


def test_ros_camera_info_yaml_round_trip(tmp_path: Path) -> None:
    # camera_calibration_parsers' layout, as `cameracalibrator` saves it
    doc = {
        "image_width": SIZE[0],
        "image_height": SIZE[1],
        "camera_name": "depth",
        "camera_matrix": {"rows": 3, "cols": 3, "data": flat(K)},
        "distortion_model": "plumb_bob",
        "distortion_coefficients": {"rows": 1, "cols": 5, "data": [0.0] * 5},
    }
    p = tmp_path / "depth.yaml"
    p.write_text(yaml.safe_dump(doc))
    cam = load_camera_file(p)
    assert_allclose(k_tuple(cam.intrinsics), k_tuple(K))
    assert cam.size == SIZE and cam.source == "file" and cam.origin == str(p)


@pytest.mark.parametrize("key", ["K", "k"])
def test_camera_info_message_dump_round_trip(tmp_path: Path, key: str) -> None:
    p = tmp_path / "info.yml"
    p.write_text(yaml.safe_dump({"height": 480, "width": 640, key: flat(K), "distortion_model": "plumb_bob"}))
    cam = load_camera_file(p)
    assert_allclose(k_tuple(cam.intrinsics), k_tuple(K))
    assert cam.size == SIZE


@pytest.mark.parametrize("suffix", [".yaml", ".xml"])
def test_opencv_filestorage_round_trip(tmp_path: Path, suffix: str) -> None:
    p = tmp_path / f"calib{suffix}"
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", SIZE[0])
    fs.write("image_height", SIZE[1])
    fs.write("camera_matrix", np.array(matrix(K)))
    fs.write("distortion_coefficients", np.zeros((1, 5)))
    fs.release()
    cam = load_camera_file(p)
    assert_allclose(k_tuple(cam.intrinsics), k_tuple(K))
    assert cam.size == SIZE


def test_kalibr_camchain_round_trip(tmp_path: Path) -> None:
    doc = {
        "cam0": {
            "camera_model": "pinhole",
            "intrinsics": list(k_tuple(K)),
            "distortion_model": "radtan",
            "distortion_coeffs": [0.0, 0.0, 0.0, 0.0],
            "resolution": list(SIZE),
            "rostopic": "/camera/depth/image_raw",
        }
    }
    p = tmp_path / "camchain.yaml"
    p.write_text(yaml.safe_dump(doc))
    cam = load_camera_file(p)
    assert_allclose(k_tuple(cam.intrinsics), k_tuple(K))
    assert cam.size == SIZE
    doc["cam0"]["camera_model"] = "omni"
    p.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError, match="pinhole"):
        load_camera_file(p)


def test_open3d_pinhole_json_round_trip(tmp_path: Path) -> None:
    try:
        import open3d as o3d
    except ImportError as exc:  # the Linux wheel needs the system's libusb-1.0
        pytest.skip(f"open3d cannot be imported here: {exc}")
    p = tmp_path / "intrinsic.json"
    pin = o3d.camera.PinholeCameraIntrinsic(SIZE[0], SIZE[1], K.fx, K.fy, K.cx, K.cy)
    assert o3d.io.write_pinhole_camera_intrinsic(str(p), pin)
    cam = load_camera_file(p)
    assert_allclose(k_tuple(cam.intrinsics), k_tuple(K))
    assert cam.size == SIZE


def test_open3d_json_is_column_major(tmp_path: Path) -> None:
    # written by hand in Open3D's order (Eigen, column by column), so no Open3D is needed
    p = tmp_path / "o3d.json"
    p.write_text(json.dumps({"width": 640, "height": 480, "intrinsic_matrix": [500, 0, 0, 0, 501, 0, 320, 240, 1]}))
    assert_allclose(k_tuple(load_camera_file(p).intrinsics), (500, 501, 320, 240))


def azure_calibration(params: list[float]) -> dict[str, object]:
    colour = {"Location": "CALIBRATION_CameraLocationPV0", "Intrinsics": {"ModelParameters": [0.5] * 14}}
    depth = {
        "Location": "CALIBRATION_CameraLocationD0",
        "Intrinsics": {"ModelType": "CALIBRATION_LensDistortionModelBrownConrady", "ModelParameters": params},
        "SensorWidth": 1024,
        "SensorHeight": 1024,
    }
    return {"CalibrationInformation": {"Cameras": [colour, depth], "Metadata": {}}}


def test_azure_kinect_calibration_json_gives_every_depth_mode(tmp_path: Path) -> None:
    p = tmp_path / "calibration.json"
    p.write_text(json.dumps(azure_calibration([0.5, 0.5, 0.5, 0.5, *([0.0] * 10)])))
    cam = load_camera_file(p)
    assert cam.source == "file" and cam.sensor == "azure-kinect"
    # NFOV unbinned: 1024 grid, centre 512 - (192, 180) - 0.5; WFOV binned: 512 grid, no crop
    assert_allclose(k_tuple(cam.for_size((640, 576))), (512.0, 512.0, 319.5, 331.5))
    assert_allclose(k_tuple(cam.for_size((512, 512))), (256.0, 256.0, 255.5, 255.5))
    p.write_text(json.dumps({"CalibrationInformation": {"Cameras": []}}))
    with pytest.raises(InputError, match="CALIBRATION_CameraLocationD0"):
        load_camera_file(p)


def test_the_real_azure_kinect_calibration(shared_data: Path) -> None:
    folder = shared_data / "azure_kinect_tof_mug_single"
    frame = next(iter(read(folder / "depth.png", camera=folder / "calibration.json")))
    assert frame.intrinsics_source == "file" and frame.meta["sensor_profile"] == "azure-kinect"
    # PROVENANCE.md: fx 504.61, fy 504.73, cx 525.28, cy 529.33 on the 1024 grid; NFOV crop (192, 180)
    assert frame.intrinsics is not None
    assert_allclose(k_tuple(frame.intrinsics), (504.61, 504.73, 525.28 - 192.5, 529.33 - 180.5), atol=0.01)


def test_text_matrix_round_trip_and_errors(tmp_path: Path) -> None:
    p = tmp_path / "K.txt"
    np.savetxt(p, np.array(matrix(K)))
    cam = load_camera_file(p)
    assert_allclose(k_tuple(cam.intrinsics), k_tuple(K))
    assert cam.size is None  # for the frames as read
    np.savetxt(p, np.eye(2))
    with pytest.raises(InputError, match=r"K\.txt.*3x3"):
        load_camera_file(p)
    np.savetxt(p, np.array([[500, 0, 320], [0, 500, 240], [0, 0, 2.0]]))
    with pytest.raises(InputError, match="not a camera matrix"):
        load_camera_file(p)


def test_profiles_at_native_size_and_scaled_by_hand() -> None:
    xtion = resolve_camera(camera="xtion")
    assert xtion is not None and xtion.source == "profile" and xtion.sensor == "xtion"
    assert_allclose(k_tuple(xtion.for_size((640, 480))), (570.3422, 570.3422, 319.5, 239.5))
    # half size: f halves; pixel centres: (319.5 + 0.5) / 2 - 0.5 = 159.5
    assert_allclose(k_tuple(xtion.for_size((320, 240))), (285.1711, 285.1711, 159.5, 119.5))
    d435 = resolve_camera(camera="realsense-d435")
    assert d435 is not None and d435.sensor == "realsense-d400"
    assert_allclose(k_tuple(d435.for_size((848, 480))), (427.0, 427.0, 423.5, 239.5))
    # 424x240 is the 848x480 mode halved, not the 1280x720 one (same aspect, both): nearest aspect, largest
    assert_allclose(k_tuple(d435.for_size((424, 240))), (213.5, 213.5, 211.5, 119.5))
    nfov = resolve_camera(camera="azure-kinect-nfov")
    assert nfov is not None and nfov.sensor == "azure-kinect"
    # the binned NFOV mode from the normalised calibration by hand: 512 px grid, crop (96, 90), half a pixel
    cx, cy, fx, fy = 0.5129697918891907, 0.5169235467910767, 0.4927808940410614, 0.49290284514427185
    assert_allclose(k_tuple(nfov.for_size((320, 288))), (fx * 512, fy * 512, cx * 512 - 96.5, cy * 512 - 90.5))
    assert_allclose(k_tuple(nfov.for_size((320, 288))), (252.304, 252.366, 166.140, 174.165), atol=1e-3)
    for name, prof in PROFILES.items():
        for (w, h), k in prof.modes:
            assert 0 < k.cx < w and 0 < k.cy < h, name


def test_profile_of_another_aspect_warns_and_names_the_option() -> None:
    cam = resolve_camera(camera="kinect-v1")
    assert cam is not None
    with pytest.warns(IntrinsicsWarning, match="--intrinsics"):
        k = cam.for_size((640, 360))
    # square pixels kept: the width's scale (1) for both axes, the 360 rows a centred crop of the 480
    assert_allclose(k_tuple(k), (525.0, 525.0, 319.5, 239.5 - 60.0))


def test_calibration_file_scaled_to_the_frames(tmp_path: Path) -> None:
    p = tmp_path / "calib.yaml"
    p.write_text(yaml.safe_dump({"width": 1280, "height": 960, "K": flat(Intrinsics(1000, 1000, 639.5, 479.5))}))
    cam = resolve_camera(camera=p)
    assert cam is not None
    assert_allclose(k_tuple(cam.for_size((640, 480))), (500, 500, 319.5, 239.5))


def test_resolve_errors_and_given_numbers() -> None:
    with pytest.raises(InputError, match=r"neither a calibration file nor a camera profile.*kinect-v1"):
        resolve_camera(camera="kinect-v9")
    with pytest.raises(InputError, match="four numbers"):
        resolve_camera(intrinsics=(1.0, 2.0))
    with pytest.raises(InputError, match="positive focal"):
        resolve_camera(intrinsics=(-1.0, 2.0, 3.0, 4.0))
    both = resolve_camera(intrinsics=(1066.778, 1067.487, 312.987, 241.311), camera="xtion")
    assert both is not None and both.source == "given" and both.sensor == "xtion"
    assert_allclose(k_tuple(both.for_size((320, 240))), (1066.778, 1067.487, 312.987, 241.311))  # as read
    assert resolve_camera() is None


def write_folder(folder: Path, n: int = 2, size: tuple[int, int] = (64, 48)) -> Path:
    folder.mkdir()
    w, h = size
    for i in range(n):
        a = np.full((h, w), 1500, np.uint16)
        a[h // 2 :, :] = 900
        assert cv2.imwrite(str(folder / f"{i:03d}-depth.png"), a)
    return folder


def test_read_puts_the_camera_and_its_source_on_every_frame(tmp_path: Path) -> None:
    folder = write_folder(tmp_path / "seq")
    plain = list(read(folder))
    assert plain[0].intrinsics is None and plain[0].intrinsics_source == ""
    given = list(read(folder, intrinsics=(50.0, 51.0, 31.5, 23.5)))
    assert all(f.intrinsics == Intrinsics(50.0, 51.0, 31.5, 23.5) and f.intrinsics_source == "given" for f in given)
    (folder / "camera.json").write_text(json.dumps({"fx": 40.0, "fy": 40.0, "cx": 31.5, "cy": 23.5}))
    src = read(folder)
    side = next(iter(src))
    assert side.intrinsics_source == "file" and side.meta["intrinsics_from"] == str(folder / "camera.json")
    src = read(folder, camera="kinect-v1")
    prof = next(iter(src))
    # 64x48 is the 640x480 mode at a tenth: f 52.5, c (319.5 + 0.5) / 10 - 0.5
    assert_allclose(k_tuple(prof.intrinsics), (52.5, 52.5, 31.5, 23.5))
    assert prof.intrinsics_source == "profile" and prof.meta["sensor_profile"] == "kinect-v1"
    assert src.info().intrinsics_source == "profile"
    sim = next(iter(read("sim:table?frames=1")))
    assert sim.intrinsics is not None and sim.intrinsics_source == "simulator"


def test_pipeline_warns_on_a_guess_and_says_the_camera_once(tmp_path: Path) -> None:
    folder = write_folder(tmp_path / "seq", n=3)
    with pytest.warns(IntrinsicsWarning, match=r"--intrinsics FX FY CX CY or --camera"):
        results = list(Pipeline().run(read(folder)))
    first = results[0].to_record()
    assert first["camera"]["intrinsics_source"] == "guessed"
    assert_allclose(first["camera"]["intrinsics"]["fx"], 0.8 * 64)  # the segmentation's own guess
    assert all("camera" not in r.to_record() for r in results[1:])
    with warnings.catch_warnings():
        warnings.simplefilter("error", IntrinsicsWarning)
        pipe = Pipeline(camera="xtion", tilt_deg=30.0)
        rec = [r.to_record() for r in pipe.run(read(folder))]
    assert rec[0]["camera"]["intrinsics_source"] == "profile" and rec[0]["camera"]["sensor"] == "xtion"
    assert rec[0]["camera"]["sensor_source"] == "profile"
    assert_allclose(rec[0]["gravity"]["vector"], (0.0, np.cos(np.radians(30)), 0.5), atol=1e-6)
    assert rec[2]["gravity"]["source"] == "tilt"
    frame = next(iter(read(folder, camera="xtion")))
    model = pipe._sensor_model(frame)
    assert model is not None and model.name == "kinect-v1"  # the xtion profile is the Kinect v1 model


def test_gravity_from_vector_and_tilt() -> None:
    g = as_gravity((0.0, 2.0, 0.0))
    assert g is not None and g.vector == (0.0, 1.0, 0.0) and g.source == "given" and g.tilt_deg == 0.0
    down = Gravity.from_tilt(90.0)
    assert_allclose(down.vector, (0.0, 0.0, 1.0), atol=1e-12)
    assert_allclose(Gravity.from_tilt(40.0).tilt_deg, 40.0)
    with pytest.raises(InputError, match="not both"):
        as_gravity((0, 1, 0), 10.0)
    with pytest.raises(InputError, match="non-zero"):
        as_gravity((0, 0, 0))
    with pytest.raises(InputError, match=r"--tilt DEG.*-90 \(up\) to 90"):
        as_gravity(None, 120.0)


def test_cli_describe_and_info_say_the_camera(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = write_folder(tmp_path / "seq")
    assert (
        main(
            ["describe", str(folder), "--quiet", "--intrinsics", "50", "51", "31.5", "23.5", "--gravity", "0", "1", "1"]
        )
        == 0
    )
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert lines[0]["camera"]["intrinsics"] == {"fx": 50.0, "fy": 51.0, "cx": 31.5, "cy": 23.5}
    assert lines[0]["camera"]["intrinsics_source"] == "given"
    assert_allclose(lines[1]["gravity"]["vector"], (0.0, 2**-0.5, 2**-0.5), atol=1e-6)
    assert "camera" not in lines[1]
    calib = tmp_path / "K.txt"
    np.savetxt(calib, np.array(matrix(Intrinsics(50.0, 50.0, 31.5, 23.5))))
    assert main(["info", str(folder), "--camera", str(calib)]) == 0
    out = capsys.readouterr().out
    assert f"fx 50.00  fy 50.00  cx 31.50  cy 23.50 px (file from {calib})" in out
    assert main(["info", str(folder)]) == 0
    captured = capsys.readouterr()
    assert "(guessed: a 64-degree field of view" in captured.out
    assert "give --intrinsics FX FY CX CY or --camera" in captured.out
    assert main(["info", str(folder), "--camera", "nope"]) == 2
    assert "profiles:" in capsys.readouterr().err
