"""ROS 1 / ROS 2 bags and MCAP written here with rosbags' writers, read back through the sources."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from depthgram.errors import InputError
from depthgram.frame import Intrinsics
from depthgram.sources import open_source, read

T0 = 1_700_000_000  # header stamp seconds of frame 0


def frames_u16(n: int = 3) -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    out = []
    for _ in range(n):
        a = rng.integers(400, 5000, size=(6, 10)).astype(np.uint16)
        a[0, 0] = 0
        out.append(a)
    return out


def image_msg(ts: Typestore, arr: np.ndarray, i: int, encoding: str, pad: int = 0) -> object:
    """sensor_msgs/Image with ``pad`` bytes of row padding, stamped T0 + i/10 s."""
    h, w = arr.shape
    row = arr.astype(arr.dtype.newbyteorder("<")).view(np.uint8).reshape(h, -1)
    data = np.concatenate([row, np.zeros((h, pad), np.uint8)], axis=1).ravel()
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    Image = ts.types["sensor_msgs/msg/Image"]
    extra = {"seq": i} if "seq" in Header.__dataclass_fields__ else {}  # ROS 1 headers carry seq
    header = Header(stamp=Time(sec=T0, nanosec=i * 100_000_000), frame_id="depth", **extra)
    return Image(
        header=header, height=h, width=w, encoding=encoding, is_bigendian=0, step=row.shape[1] + pad, data=data
    )


def camera_info(ts: Typestore, size: tuple[int, int] = (10, 6)) -> object:
    info = ts.types["sensor_msgs/msg/CameraInfo"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    roi = ts.types["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    k = np.array([300.0, 0, 4.5, 0, 310.0, 2.5, 0, 0, 1])
    return info(
        header=Header(stamp=Time(sec=T0, nanosec=0), frame_id="depth"),
        height=size[1],
        width=size[0],
        distortion_model="plumb_bob",
        d=np.zeros(5),
        k=k,
        r=np.eye(3).ravel(),
        p=np.zeros(12),
        binning_x=0,
        binning_y=0,
        roi=roi,
    )


def write_ros2(
    path: Path,
    topics: dict[str, tuple[str, list[np.ndarray]]],
    storage: StoragePlugin,
    with_info: bool = False,
    info_size: tuple[int, int] = (10, 6),
) -> Path:
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer2(path, version=9, storage_plugin=storage) as w:
        for topic, (enc, arrays) in topics.items():
            conn = w.add_connection(topic, "sensor_msgs/msg/Image", typestore=ts)
            for i, a in enumerate(arrays):
                msg = image_msg(ts, a, i, enc, pad=4)
                w.write(conn, (T0 * 10 + i) * 100_000_000, ts.serialize_cdr(msg, "sensor_msgs/msg/Image"))
        if with_info:
            ns = next(iter(topics)).rsplit("/", 1)[0]
            conn = w.add_connection(f"{ns}/camera_info", "sensor_msgs/msg/CameraInfo", typestore=ts)
            w.write(
                conn, T0 * 1_000_000_000, ts.serialize_cdr(camera_info(ts, info_size), "sensor_msgs/msg/CameraInfo")
            )
    return path


def write_ros1(path: Path, topics: dict[str, tuple[str, list[np.ndarray]]]) -> Path:
    ts = get_typestore(Stores.ROS1_NOETIC)
    with Writer1(path) as w:
        for topic, (enc, arrays) in topics.items():
            conn = w.add_connection(topic, "sensor_msgs/msg/Image", typestore=ts)
            for i, a in enumerate(arrays):
                msg = image_msg(ts, a, i, enc)
                w.write(conn, (T0 * 10 + i) * 100_000_000, ts.serialize_ros1(msg, "sensor_msgs/msg/Image"))
    return path


def check_round_trip(spec: Path, arrays: list[np.ndarray], scale: float = 1.0, **kw: object) -> None:
    src = open_source(spec, **kw)  # type: ignore[arg-type]
    assert src.kind == "bag" and len(src) == len(arrays)
    frames = list(src)
    assert len(frames) == len(arrays)
    for i, (f, a) in enumerate(zip(frames, arrays, strict=True)):
        np.testing.assert_allclose(f.depth, a.astype(np.float64) * scale, rtol=1e-6)
        np.testing.assert_array_equal(f.valid, a > 0)
        assert f.index == i
        assert f.time_s == pytest.approx(T0 + 0.1 * i, abs=1e-6)  # from the header, not the log time


def test_ros1_bag_16uc1_round_trip(tmp_path: Path) -> None:
    arrays = frames_u16()
    check_round_trip(write_ros1(tmp_path / "d.bag", {"/camera/depth/image_raw": ("16UC1", arrays)}), arrays)


def test_ros1_bag_32fc1_metres(tmp_path: Path) -> None:
    arrays = [a.astype(np.float32) / 1000 for a in frames_u16()]
    check_round_trip(write_ros1(tmp_path / "m.bag", {"/depth": ("32FC1", arrays)}), arrays, scale=1000)


def test_ros2_sqlite_bag_folder_16uc1_with_camera_info(tmp_path: Path) -> None:
    arrays = frames_u16()
    bag = write_ros2(
        tmp_path / "bag2", {"/cam/depth/image_rect_raw": ("16UC1", arrays)}, StoragePlugin.SQLITE3, with_info=True
    )
    assert (bag / "metadata.yaml").is_file()
    check_round_trip(bag, arrays)
    assert open_source(bag).intrinsics == Intrinsics(300.0, 310.0, 4.5, 2.5)


def test_mcap_32fc1_file_and_folder(tmp_path: Path) -> None:
    arrays = [a.astype(np.float32) / 1000 for a in frames_u16()]
    bag = write_ros2(tmp_path / "bagm", {"/depth/image": ("32FC1", arrays)}, StoragePlugin.MCAP)
    check_round_trip(bag, arrays, scale=1000)
    [mcap] = list(bag.glob("*.mcap"))
    check_round_trip(mcap, arrays, scale=1000)


def test_topic_chosen_when_one_is_depth_like_else_required(tmp_path: Path) -> None:
    d = frames_u16(2)
    c = [np.zeros((6, 10), np.uint16) + 1] * 2
    bag = write_ros1(tmp_path / "two.bag", {"/cam/depth": ("16UC1", d), "/cam/ir": ("16UC1", c)})
    check_round_trip(bag, d)  # only one Image topic has "depth" in its name
    bag3 = write_ros1(tmp_path / "three.bag", {"/a/depth": ("16UC1", d), "/b/depth": ("16UC1", c)})
    with pytest.raises(InputError, match=r"three\.bag: several Image topics \(/a/depth, /b/depth\).*topic="):
        open_source(bag3)
    check_round_trip(bag3, c, topic="/b/depth")
    with pytest.raises(InputError, match=r"no sensor_msgs/Image topic '/c/depth'"):
        open_source(bag3, topic="/c/depth")


def test_bag_without_depth_topic_lists_topics(tmp_path: Path) -> None:
    ts = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / "nodepth.bag"
    with Writer1(path) as w:
        conn = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
        msg = ts.types["std_msgs/msg/String"](data="hi")
        w.write(conn, 1, ts.serialize_ros1(msg, "std_msgs/msg/String"))
    with pytest.raises(InputError, match=r"nodepth\.bag: no sensor_msgs/Image depth topic.*topics: /chatter"):
        open_source(path)


def test_colour_topic_is_refused_with_frame(tmp_path: Path) -> None:
    rgb = [np.zeros((6, 30), np.uint8)]
    bag = write_ros1(tmp_path / "rgb.bag", {"/cam/image": ("rgb8", rgb)})
    with pytest.raises(InputError, match=r"rgb\.bag topic /cam/image \(frame 0\): image encoding 'rgb8' is not depth"):
        list(read(bag))


def test_corrupt_bag(tmp_path: Path) -> None:
    p = tmp_path / "broken.bag"
    p.write_bytes(b"#ROSBAG V2.0\nnot really")
    with pytest.raises(InputError, match=r"broken\.bag: cannot read the bag"):
        open_source(p)


def test_bag_with_mixed_sizes_names_the_frame(tmp_path: Path) -> None:
    arrays = [np.full((6, 10), 900, np.uint16), np.full((4, 10), 900, np.uint16)]
    bag = write_ros1(tmp_path / "mixed.bag", {"/depth": ("16UC1", arrays)})
    with pytest.raises(InputError, match=r"mixed\.bag topic /depth \(frame 1\): image is 10x4 px but frame 0 is 10x6"):
        list(read(bag))


def test_bag_refuses_a_timestamps_file(tmp_path: Path) -> None:
    bag = write_ros1(tmp_path / "d.bag", {"/depth": ("16UC1", frames_u16(1))})
    (tmp_path / "t.txt").write_text("0.0\n")
    with pytest.raises(InputError, match=r"d\.bag: a bag's frame times come from its message headers"):
        open_source(bag, timestamps=tmp_path / "t.txt")


@pytest.mark.parametrize("storage", ["ros1", StoragePlugin.MCAP, StoragePlugin.SQLITE3])
def test_a_damaged_bag_is_an_input_error_naming_the_file(tmp_path: Path, storage: object) -> None:
    # issue 18.5: damage gave rosbags' ReaderError, an AssertionError or sqlite's CorruptError
    arrays = [np.full((30, 40), 1000 + 10 * i, np.uint16) for i in range(12)]
    if storage == "ros1":
        bag = write_ros1(tmp_path / "d.bag", {"/depth": ("16UC1", arrays)})
    else:
        folder = write_ros2(tmp_path / "b", {"/depth": ("16UC1", arrays)}, storage)  # type: ignore[arg-type]
        bag = next(p for p in folder.iterdir() if p.suffix in (".mcap", ".db3"))
    data = bag.read_bytes()
    rng = np.random.default_rng(0)
    damaged = bag.with_name("damaged" + bag.suffix)
    others = []
    for offset in range(0, len(data) - 16, max(1, len(data) // 200)):
        d = bytearray(data)
        d[offset : offset + 16] = rng.integers(0, 256, 16, dtype=np.uint8).tobytes()
        damaged.write_bytes(bytes(d))
        try:
            list(read(damaged))
        except InputError as exc:
            assert str(damaged) in str(exc)
        except Exception as exc:  # the point: nothing else may escape
            others.append((offset, f"{type(exc).__name__}: {exc}"))
    assert others == []


def imu_msg(ts: Typestore, accel: tuple[float, float, float], t_ns: int, frame_id: str) -> object:
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    Vec = ts.types["geometry_msgs/msg/Vector3"]
    Quat = ts.types["geometry_msgs/msg/Quaternion"]
    return ts.types["sensor_msgs/msg/Imu"](
        header=Header(stamp=Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000), frame_id=frame_id),
        orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.full(9, -1.0),
        angular_velocity=Vec(x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=Vec(x=accel[0], y=accel[1], z=accel[2]),
        linear_acceleration_covariance=np.zeros(9),
    )


def static_tf(ts: Typestore, links: list[tuple[str, str, tuple[float, float, float, float]]]) -> object:
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    TS = ts.types["geometry_msgs/msg/TransformStamped"]
    Tf = ts.types["geometry_msgs/msg/Transform"]
    Vec = ts.types["geometry_msgs/msg/Vector3"]
    Quat = ts.types["geometry_msgs/msg/Quaternion"]
    transforms = [
        TS(
            header=Header(stamp=Time(sec=T0, nanosec=0), frame_id=parent),
            child_frame_id=child,
            transform=Tf(translation=Vec(x=0.0, y=0.0, z=0.0), rotation=Quat(x=q[0], y=q[1], z=q[2], w=q[3])),
        )
        for parent, child, q in links
    ]
    return ts.types["tf2_msgs/msg/TFMessage"](transforms=transforms)


def write_imu_bag(
    path: Path,
    accel: tuple[float, float, float],
    imu_frame: str,
    links: list[tuple[str, str, tuple[float, float, float, float]]] | None,
    jitter: float = 0.0,
) -> Path:
    """Depth frames (frame "depth") at 10 Hz with an IMU at 200 Hz reading ``accel`` (+ sway ``jitter``)."""
    ts = get_typestore(Stores.ROS2_HUMBLE)
    rng = np.random.default_rng(5)
    arrays = frames_u16(5)
    with Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        img = w.add_connection("/cam/depth/image_raw", "sensor_msgs/msg/Image", typestore=ts)
        imu = w.add_connection("/cam/imu", "sensor_msgs/msg/Imu", typestore=ts)
        if links is not None:
            tf = w.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=ts)
            w.write(tf, T0 * 1_000_000_000 - 1, ts.serialize_cdr(static_tf(ts, links), "tf2_msgs/msg/TFMessage"))
        for k in range(100):
            t_ns = T0 * 1_000_000_000 + k * 5_000_000
            a = np.asarray(accel) + rng.normal(0, jitter, 3)
            msg = imu_msg(ts, (float(a[0]), float(a[1]), float(a[2])), t_ns, imu_frame)
            w.write(imu, t_ns, ts.serialize_cdr(msg, "sensor_msgs/msg/Imu"))
            if k % 20 == 19:
                i = k // 20
                image = image_msg(ts, arrays[i], i, "16UC1")
                w.write(img, t_ns + 1, ts.serialize_cdr(image, "sensor_msgs/msg/Image"))
    return path


def test_gravity_from_the_imu_in_the_camera_frame(tmp_path: Path) -> None:
    # the camera looks 30 degrees down; the IMU shares the depth image's axes: it reads g upward
    t = np.radians(30.0)
    up = (0.0, -9.81 * np.cos(t), -9.81 * np.sin(t))
    frames = list(read(write_imu_bag(tmp_path / "same.mcap", up, "depth", None, jitter=0.3)))
    assert len(frames) == 5 and all(f.gravity is not None and f.gravity.source == "imu" for f in frames)
    g = frames[-1].gravity
    assert g is not None
    np.testing.assert_allclose(g.vector, (0.0, np.cos(t), np.sin(t)), atol=0.02)
    np.testing.assert_allclose(g.tilt_deg, 30.0, atol=1.0)
    # the user's gravity wins over the IMU
    given = next(iter(read(tmp_path / "same.mcap", tilt_deg=10.0)))
    assert given.gravity is not None and given.gravity.source == "tilt"


def test_gravity_from_an_imu_in_ros_body_axes_through_tf_static(tmp_path: Path) -> None:
    # REP 103 body axes (x forward, y left, z up) under camera_link; the optical frame "depth" is the
    # usual rotation of camera_link (roll -90, yaw -90 degrees). A level camera's IMU reads +g on z.
    optical = (-0.5, 0.5, -0.5, 0.5)
    links = [("camera_link", "depth", optical), ("camera_link", "imu_link", (0.0, 0.0, 0.0, 1.0))]
    frames = list(read(write_imu_bag(tmp_path / "body.mcap", (0.0, 0.0, 9.81), "imu_link", links)))
    g = frames[0].gravity
    assert g is not None
    np.testing.assert_allclose(g.vector, (0.0, 1.0, 0.0), atol=1e-9)  # down is +y in the image


def test_an_imu_without_a_transform_warns_and_gives_no_gravity(tmp_path: Path) -> None:
    bag = write_imu_bag(tmp_path / "lost.mcap", (0.0, 0.0, 9.81), "imu_link", None)
    with pytest.warns(UserWarning, match=r"imu_link.*--gravity X Y Z or --tilt DEG"):
        frames = list(read(bag))
    assert all(f.gravity is None for f in frames) and len(frames) == 5


def test_camera_info_of_another_size_is_scaled_to_the_images(tmp_path: Path) -> None:
    # calibrated at 20 x 12, the images are 10 x 6 (binned 2 x 2): f halves, c = (c + 0.5) / 2 - 0.5
    arrays = frames_u16(2)
    bag = write_ros2(
        tmp_path / "binned", {"/cam/depth/image_raw": ("16UC1", arrays)}, StoragePlugin.SQLITE3, True, (20, 12)
    )
    frames = list(read(bag))
    assert frames[0].intrinsics == Intrinsics(150.0, 155.0, 2.0, 1.0)
    assert frames[0].intrinsics_source == "bag"
