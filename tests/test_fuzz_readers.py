"""Every reader under damage and lying headers: a result or a clear error, never a traceback (issue 32.2).

``benchmarks/fuzz_readers.py`` runs the issue's 1,000 damaged inputs; here a few per reader, and
``hypothesis`` writes ``.npy`` headers and arrays no camera gives.
"""

from __future__ import annotations

import io
import struct
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from benchmarks import fuzz_readers
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

pytest.importorskip("rosbags")
pytest.importorskip("mcap")


def test_seeded_damage_of_every_reader_gives_a_result_or_an_error_naming_the_file() -> None:
    lines: list[str] = []
    counts = fuzz_readers.fuzz(8 * len(fuzz_readers.READERS), seed=32, report=lines.append)
    assert lines == []
    outcomes = Counter(outcome for (_, outcome), n in counts.items() for _ in range(n))
    assert set(outcomes) <= {"ok", "error"} and outcomes["error"] > 0  # the damage was seen


def test_the_harness_reports_a_traceback(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the fuzzing above passes only if a traceback would be counted as one
    import depthgram.cli

    def broken(argv: object) -> int:
        raise KeyError("escaped")

    monkeypatch.setattr(depthgram.cli, "main", broken)
    path = tmp_path / "a.npy"
    np.save(path, np.ones((4, 4), np.uint16))
    outcome, detail = fuzz_readers.run_one(path)
    assert outcome == "traceback" and "KeyError: 'escaped'" in detail


_DESCRS = [
    "<u2",
    ">u2",
    "<f4",
    ">f8",
    "|u1",
    "<i8",
    "|b1",
    "<c16",
    "|O",
    "<U3",
    "|S4",
    "<M8[s]",
    "[('a', '<u2')]",
    "<q",
]


@st.composite
def npy_with_lying_header(draw: st.DrawFn) -> bytes:
    descr = draw(st.sampled_from(_DESCRS))
    shape = draw(st.lists(st.integers(-3, 1 << 40) | st.integers(0, 40), min_size=0, max_size=4))
    fortran = draw(st.booleans())
    text = f"{{'descr': {descr!r}, 'fortran_order': {fortran}, 'shape': {tuple(shape)!r}, }}"
    if descr.startswith("["):
        text = text.replace(repr(descr), descr)
    header = text.encode("latin1")
    header += b" " * (-(10 + len(header) + 1) % 64) + b"\n"
    body = draw(st.binary(max_size=4000))
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header + body


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=npy_with_lying_header())
def test_an_npy_header_that_lies_is_a_clear_error(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "lying.npy"
    path.write_bytes(data)
    outcome, detail = fuzz_readers.run_one(path)
    assert outcome in ("ok", "error"), detail


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    arr=hnp.arrays(
        dtype=hnp.integer_dtypes() | hnp.unsigned_integer_dtypes() | hnp.floating_dtypes(),
        shape=hnp.array_shapes(min_dims=1, max_dims=3, min_side=1, max_side=12),
    ),
    suffix=st.sampled_from([".npy", ".tiff"]),
)
def test_any_numeric_array_gives_a_result_or_a_clear_error(tmp_path: Path, arr: np.ndarray, suffix: str) -> None:
    path = tmp_path / f"any{suffix}"
    if suffix == ".npy":
        np.save(path, arr)
    else:
        import tifffile

        buf = io.BytesIO()
        try:
            tifffile.imwrite(buf, arr)
        except Exception:  # a dtype TIFF cannot hold (float16 big-endian, say): nothing to read
            return
        path.write_bytes(buf.getvalue())
    outcome, detail = fuzz_readers.run_one(path)
    assert outcome in ("ok", "error"), detail


@st.composite
def pgm_with_lying_header(draw: st.DrawFn) -> bytes:
    magic = draw(st.sampled_from([b"P5", b"P2", b"P6", b"P4"]))
    w = draw(st.integers(-2, 1 << 33) | st.integers(0, 50))
    h = draw(st.integers(-2, 1 << 33) | st.integers(0, 50))
    top = draw(st.sampled_from([0, 1, 255, 256, 65535, 65536, 1 << 31]))
    return magic + f"\n{w} {h}\n{top}\n".encode() + draw(st.binary(max_size=3000))


@st.composite
def png_with_lying_header(draw: st.DrawFn) -> bytes:
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    w = draw(st.integers(0, (1 << 31) - 1) | st.integers(0, 40))
    h = draw(st.integers(0, (1 << 31) - 1) | st.integers(0, 40))
    depth, colour = draw(st.sampled_from([(16, 0), (8, 0), (16, 2), (1, 0), (16, 4), (8, 3), (7, 0)]))
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, draw(st.sampled_from([0, 1])))
    idat = zlib.compress(draw(st.binary(max_size=3000)))
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=pgm_with_lying_header() | png_with_lying_header(), suffix=st.sampled_from([".pgm", ".png"]))
def test_an_image_header_that_lies_is_a_clear_error(tmp_path: Path, data: bytes, suffix: str) -> None:
    path = tmp_path / f"lying{suffix}"
    path.write_bytes(data)
    outcome, detail = fuzz_readers.run_one(path)
    assert outcome in ("ok", "error"), detail


def test_a_png_cut_inside_its_header_is_a_clear_error(tmp_path: Path) -> None:
    # found by the fuzzing (seed 7): the size read before decoding unpacked a cut IHDR
    import cv2

    whole = tmp_path / "whole.png"
    assert cv2.imwrite(str(whole), np.full((8, 8), 1000, np.uint16))
    for cut in range(9, 33):
        path = tmp_path / "cut.png"
        path.write_bytes(whole.read_bytes()[:cut])
        outcome, detail = fuzz_readers.run_one(path)
        assert outcome == "error", (cut, detail)


def test_a_bag_message_that_decodes_to_other_fields_is_a_clear_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # found by the fuzzing (seed 7): a damaged definition embedded in the bag gave an Image
    # without its encoding, and image_array's AttributeError escaped
    from depthgram.errors import InputError
    from depthgram.sources import bag

    class NoEncoding:
        header = None

    seeds = fuzz_readers.write_seeds(tmp_path)
    src = bag.BagSource(seeds["ros1"], bag.SourceConfig(), name="b")
    monkeypatch.setattr(type(bag._reader(seeds["ros1"])), "deserialize", lambda self, raw, msgtype: NoEncoding())
    with pytest.raises(InputError, match=r"seed\.bag topic .* \(frame 0\): the message .* is not a readable"):
        list(src)


def test_a_bag_whose_stamps_go_back_names_the_bag_and_the_frame(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # found by the fuzzing (seeds 8-10): the tracker's "tracker frame 1: time_s ... (call
    # reset() between sequences)" named neither the file nor the frame
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from depthgram.cli import main

    ts = get_typestore(Stores.ROS1_NOETIC)
    bag = tmp_path / "back.bag"
    frames = fuzz_readers._depth(n=3)
    with Writer(bag) as w:
        conn = w.add_connection("/camera/depth/image_raw", "sensor_msgs/msg/Image", typestore=ts)
        for k, (i, a) in enumerate(zip((0, 5, 3), frames, strict=True)):
            msg = fuzz_readers._image_msg(ts, a, i)
            w.write(conn, 1_000_000_000 + k, ts.serialize_ros1(msg, "sensor_msgs/msg/Image"))
    assert main(["describe", str(bag), "--quiet", "--json", "/dev/null"]) == 2
    err = capsys.readouterr().err
    assert str(bag) in err and "(frame 2, bag:/camera/depth/image_raw#2)" in err and "Traceback" not in err
