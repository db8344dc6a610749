"""Damaged inputs for every reader, run through the command line: no traceback, no hang (issue 32.2).

One small valid file per reader (PNG, TIFF, PGM, ``.npy``, ``.npz``, an ``.npy`` stack, a ROS 1
bag, ROS 2 bags in SQLite and MCAP storage, and depthgram's own ``describe --mcap`` output) is
damaged by a seeded mutation (bytes flipped or overwritten, a length field set to all ones, a
cut, bytes inserted, a chunk repeated or zeroed) and handed to ``depthgram info`` and
``depthgram describe`` in this process. Each input must end in a result (status 0) or a clear
error (status 2); anything escaping ``main`` is a traceback, and an input still running after
``--deadline`` seconds a hang. ``tests/test_fuzz_readers.py`` runs a few per reader; this script
the issue's 1,000.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/fuzz_readers.py [--inputs 1000] [--seed 0]``
(prints the outcomes per reader and each traceback or hang with the seed that reproduces it).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from types import FrameType

import numpy as np

#: The readers fuzzed, by the suffix of their seed file.
READERS = (
    "png",
    "tiff",
    "pgm",
    "npy",
    "npz",
    "npy_stack",
    "npz_stack",
    "ros1",
    "ros2_db3",
    "ros2_mcap",
    "depthgram_mcap",
)

_T0 = 1_700_000_000


def _depth(h: int = 24, w: int = 32, n: int = 1, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    z = np.tile(np.linspace(600, 2400, w), (h, 1)) + rng.integers(0, 20, (n, h, w))
    z[:, h // 3 : h // 2, w // 4 : w // 2] = 900  # a box in front of the ramp
    z[:, 0, 0] = 0
    return z.astype(np.uint16)


def _image_msg(ts: object, arr: np.ndarray, i: int) -> object:
    types = ts.types  # type: ignore[attr-defined]
    header_type = types["std_msgs/msg/Header"]
    extra = {"seq": i} if "seq" in header_type.__dataclass_fields__ else {}
    stamp = types["builtin_interfaces/msg/Time"](sec=_T0, nanosec=i * 100_000_000)
    h, w = arr.shape
    return types["sensor_msgs/msg/Image"](
        header=header_type(stamp=stamp, frame_id="depth", **extra),
        height=h,
        width=w,
        encoding="16UC1",
        is_bigendian=0,
        step=2 * w,
        data=arr.astype("<u2").view(np.uint8).ravel(),
    )


def _ros1(path: Path, frames: np.ndarray) -> Path:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as w:
        conn = w.add_connection("/camera/depth/image_raw", "sensor_msgs/msg/Image", typestore=ts)
        for i, a in enumerate(frames):
            w.write(
                conn, (_T0 * 10 + i) * 100_000_000, ts.serialize_ros1(_image_msg(ts, a, i), "sensor_msgs/msg/Image")
            )
    return path


def _ros2(folder: Path, frames: np.ndarray, storage: str) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(folder, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection("/camera/depth/image_raw", "sensor_msgs/msg/Image", typestore=ts)
        for i, a in enumerate(frames):
            w.write(conn, (_T0 * 10 + i) * 100_000_000, ts.serialize_cdr(_image_msg(ts, a, i), "sensor_msgs/msg/Image"))
    # the storage file alone: damaging the folder's metadata.yaml is another reader's concern
    return next(p for p in folder.iterdir() if p.suffix in (".db3", ".mcap"))


def write_seeds(folder: Path) -> dict[str, Path]:
    """Write one small valid input per reader into ``folder``; return them by reader name."""
    os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")  # as main sets it, before OpenCV is loaded
    import cv2
    import tifffile

    from depthgram.cli import main

    one = _depth()[0]
    seeds = {
        "png": folder / "seed.png",
        "tiff": folder / "seed.tiff",
        "pgm": folder / "seed.pgm",
        "npy": folder / "seed.npy",
        "npz": folder / "seed.npz",
        "npy_stack": folder / "stack.npy",
        "npz_stack": folder / "stack.npz",
    }
    cv2.imwrite(str(seeds["png"]), one)
    tifffile.imwrite(seeds["tiff"], one.astype(np.float32) / 1000.0)
    cv2.imwrite(str(seeds["pgm"]), one)
    np.save(seeds["npy"], one)
    np.savez(seeds["npz"], depth=one)
    np.save(seeds["npy_stack"], _depth(n=3))
    np.savez_compressed(seeds["npz_stack"], depth=_depth(n=3))
    seeds["ros1"] = _ros1(folder / "seed.bag", _depth(n=3))
    seeds["ros2_db3"] = _ros2(folder / "ros2_db3", _depth(n=3), "sqlite3")
    seeds["ros2_mcap"] = _ros2(folder / "ros2_mcap", _depth(n=3), "mcap")
    own = folder / "own.mcap"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        if main(["describe", "sim:approach?frames=3&size=48x36", "--quiet", "--mcap", str(own)]) != 0:
            raise RuntimeError("describe --mcap failed: no seed for depthgram's own MCAP")
    seeds["depthgram_mcap"] = own
    return seeds


def mutate(data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    """Return a seeded damage of ``data`` and what it was."""
    n = len(data)
    at = int(rng.integers(0, max(n, 1)))
    kind = str(rng.choice(["flip", "overwrite", "ones", "cut", "insert", "repeat", "zero", "several"]))
    d = bytearray(data)
    if kind == "flip":
        d[at] ^= 1 << int(rng.integers(0, 8))
    elif kind == "overwrite":
        d[at : at + 16] = rng.integers(0, 256, 16, dtype=np.uint8).tobytes()[: len(d[at : at + 16])]
    elif kind == "ones":  # a length or count field that lies: as large as it can be
        d[at : at + 4] = b"\xff" * len(d[at : at + 4])
    elif kind == "cut":
        del d[at:]
    elif kind == "insert":
        d[at:at] = rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8).tobytes()
    elif kind == "repeat":
        d[at:at] = d[at : at + int(rng.integers(1, 256))]
    elif kind == "zero":
        d[at : at + int(rng.integers(1, 256))] = bytes(len(d[at : at + int(rng.integers(1, 256))]))
    else:
        for _ in range(int(rng.integers(2, 20))):
            d[int(rng.integers(0, n))] = int(rng.integers(0, 256))
    return f"{kind}@{at}", bytes(d)


class Hang(Exception):
    """An input still being read at its deadline."""


@contextlib.contextmanager
def _deadline(seconds: float) -> Iterator[None]:
    # SIGALRM interrupts Python code; a compiled loop that never returns to the interpreter is
    # caught by faulthandler, which ends the process with every thread's stack printed
    import faulthandler

    def alarm(signum: int, frame: FrameType | None) -> None:
        raise Hang(f"still running after {seconds:g} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    faulthandler.dump_traceback_later(4 * seconds, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def run_one(path: Path, deadline_s: float = 30.0) -> tuple[str, str]:
    """Hand ``path`` to ``depthgram info`` and ``describe``; return (outcome, detail).

    The outcome is ``ok`` (both gave status 0), ``error`` (a clear error: status 2 with the
    file named), ``unnamed`` (status 2 but the message names no file), ``traceback`` or ``hang``.
    """
    from depthgram.cli import main

    worst = ("ok", "")
    for command in (["info", str(path)], ["describe", str(path), "--quiet", "--json", os.devnull]):
        err = io.StringIO()
        try:
            with (
                _deadline(deadline_s),
                contextlib.redirect_stdout(io.StringIO()),
                contextlib.redirect_stderr(err),
            ):
                status = main(command)
        except Hang as exc:
            return "hang", f"{command[0]}: {exc}"
        except BaseException:  # the point: whatever escapes main is reported
            return "traceback", f"{command[0]}: " + traceback.format_exc(limit=-3)
        if status == 2:
            message = err.getvalue().strip()
            if str(path) not in message:
                return "unnamed", f"{command[0]}: {message!r}"
            worst = ("error", message)
        elif status != 0:
            return "traceback", f"{command[0]}: status {status}: {err.getvalue()[-300:]}"
    return worst


def fuzz(
    inputs: int, seed: int = 0, folder: Path | None = None, report: Callable[[str], None] | None = None
) -> Counter[tuple[str, str]]:
    """Damage ``inputs`` files spread over :data:`READERS`; return the count of (reader, outcome).

    ``report`` receives a line for every traceback, hang or unnamed error, with its seed.
    """
    import warnings

    counts: Counter[tuple[str, str]] = Counter()
    with contextlib.ExitStack() as stack:
        if folder is None:
            folder = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="depthgram-fuzz-")))
        seeds = write_seeds(folder)
        stack.enter_context(warnings.catch_warnings())
        warnings.simplefilter("ignore")
        for i in range(inputs):
            reader = READERS[i % len(READERS)]
            rng = np.random.default_rng([seed, i])
            what, data = mutate(seeds[reader].read_bytes(), rng)
            damaged = seeds[reader].with_name(f"damaged{seeds[reader].suffix}")
            damaged.write_bytes(data)
            outcome, detail = run_one(damaged)
            counts[reader, outcome] += 1
            if outcome not in ("ok", "error") and report is not None:
                report(f"{reader} input {i} (seed {seed}, {what}): {outcome}: {detail}")
    return counts


def main(argv: list[str] | None = None) -> int:
    """Run the fuzzing; print the outcomes per reader; status 1 when any traceback or hang."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--inputs", type=int, default=1000, help="how many damaged inputs (spread over the readers)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--quick", action="store_true", help="100 inputs")
    args = p.parse_args(argv)
    n = 100 if args.quick else args.inputs
    start = time.perf_counter()
    counts = fuzz(n, args.seed, report=lambda line: print(line, flush=True))
    outcomes = ("ok", "error", "unnamed", "traceback", "hang")
    print(f"{'reader':16}" + "".join(f"{o:>10}" for o in outcomes))
    for r in READERS:
        print(f"{r:16}" + "".join(f"{counts[r, o]:>10}" for o in outcomes))
    total = Counter({o: sum(counts[r, o] for r in READERS) for o in outcomes})
    print(f"{'all':16}" + "".join(f"{total[o]:>10}" for o in outcomes))
    print(f"{n} inputs in {time.perf_counter() - start:.0f} s (seed {args.seed})")
    return 1 if total["traceback"] or total["hang"] else 0


if __name__ == "__main__":
    sys.exit(main())
