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
