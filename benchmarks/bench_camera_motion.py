"""Cost of the camera's motion per frame (:meth:`EgoMotion.update`), this tree against a git revision.

Run ``PYTHONPATH=src .venv/bin/python benchmarks/bench_camera_motion.py --against main``. The
revision's ``src/depthgram/dynamics/camera_motion.py`` is loaded beside this tree's, and both
read the same frames (60 of 7-Scenes at 640 x 480 when ``../shared/data`` is there, 60 of the
simulator's ``pass_behind`` at 640 x 480 with structured light) in interleaved rounds, the
order swapped every round, timed in thread CPU: on a machine shared with other work, wall time
and one-sided runs say more about the neighbours than about the code.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from depthgram.dynamics import camera_motion
from depthgram.frame import Intrinsics

ROOT = Path(__file__).resolve().parents[1]


def _module_at(revision: str, into: Path) -> ModuleType:
    """``camera_motion`` as it is at ``revision``, imported under another name."""
    text = subprocess.run(
        ["git", "show", f"{revision}:src/depthgram/dynamics/camera_motion.py"],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    path = into / "camera_motion_ref.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("camera_motion_ref", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    # dataclasses look their module up while the class is made
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _sequences(frames: int) -> dict[str, tuple[list[NDArray[np.float32]], Intrinsics]]:
    """Depth frames (mm, 0 where invalid) and intrinsics of each timed sequence."""
    import cv2

    from depthgram.frame import make_frame
    from depthgram.sensor import simulate

    out = {}
    data = Path(os.environ.get("DEPTHGRAM_DATA") or ROOT.parent / "shared" / "data") / "7scenes_redkitchen_seq"
    paths = sorted((data / "depth").glob("*.png"))[:frames]
    if paths:
        k7 = Intrinsics(585.0, 585.0, 320.0, 240.0)
        seven = []
        for k, p in enumerate(paths):
            fr = make_frame(cv2.imread(str(p), cv2.IMREAD_UNCHANGED), invalid_values=(65535,), index=k, intrinsics=k7)
            seven.append(np.where(fr.valid, fr.depth, 0).astype(np.float32))
        out["7-Scenes 640x480"] = (seven, k7)
    sim = list(simulate("pass_behind", frames, size=(640, 480), seed=1, sensor="structured-light"))
    out["pass_behind SL 640x480"] = (
        [np.where(s.frame.valid, s.frame.depth, 0).astype(np.float32) for s in sim],
        sim[0].frame.intrinsics,
    )
    return out


def _per_frame(module: ModuleType, frames: list[NDArray[np.float32]], intrinsics: Intrinsics) -> float:
    """Thread CPU time (s) of one ``EgoMotion.update`` per frame, over the sequence."""
    ego = module.EgoMotion()
    total = 0.0
    for z in frames:
        t0 = time.thread_time()
        ego.update(z, intrinsics)
        total += time.thread_time() - t0
    return total / len(frames)


def main(argv: Sequence[str] | None = None) -> int:
    """Print each sequence's cost per frame for the revision and this tree; return 0."""
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument("--against", default="main", help="git revision to compare with (default: main)")
    p.add_argument("--rounds", type=int, default=12, help="interleaved rounds (default: 12)")
    p.add_argument("--frames", type=int, default=60, help="frames per sequence (default: 60)")
    args = p.parse_args(argv)
    seqs = _sequences(args.frames)
    with tempfile.TemporaryDirectory() as tmp:
        ref = _module_at(args.against, Path(tmp))
        variants = {args.against: ref, "this tree": camera_motion}
        for module in variants.values():  # compile and warm up
            for frames, k in seqs.values():
                _per_frame(module, frames[:3], k)
        times: dict[tuple[str, str], list[float]] = {(s, v): [] for s in seqs for v in variants}
        for r in range(args.rounds):
            order = list(variants.items()) if r % 2 == 0 else list(reversed(variants.items()))
            for name, (frames, k) in seqs.items():
                for v, module in order:
                    times[(name, v)].append(_per_frame(module, frames, k))
    print(f"EgoMotion.update, thread CPU per frame, {args.rounds} interleaved rounds of {args.frames} frames")
    for name in seqs:
        a = 1e3 * np.array(times[(name, args.against)])
        b = 1e3 * np.array(times[(name, "this tree")])
        print(
            f"  {name:24s} {args.against}: median {np.median(a):.3f} ms (min {a.min():.3f})  this tree: median "
            f"{np.median(b):.3f} ms (min {b.min():.3f})  paired ratio median {np.median(b / a):.3f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
