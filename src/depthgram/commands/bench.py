"""depthgram bench: run the stage benchmarks in benchmarks/ and print their tables.

The benchmarks are scripts of the source checkout (they read the real recordings from
``--data``, the ``DEPTHGRAM_DATA`` environment variable or ``../shared/data`` beside it, and are
not part of the wheel): from an installed depthgram, pass ``--dir CHECKOUT/benchmarks``.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
from pathlib import Path

NAME = "bench"
HELP = "run the benchmarks (speed per stage and resolution, Table 1 accuracy, tracking, sound, real accuracy)"

#: Benchmark name -> script in benchmarks/ (each defines main(argv) -> int).
SUITES = {
    "pipeline": "bench_pipeline.py",
    "segmentation": "bench_segmentation.py",
    "table1": "table1.py",
    "scene": "bench_scene.py",
    "tracking": "bench_tracking.py",
    "sound": "bench_sound.py",
    "real": "real.py",
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add this command's options to ``p``."""
    p.add_argument(
        "suites", nargs="*", default=[], metavar="SUITE", help=f"which benchmarks: {', '.join(SUITES)} (default: all)"
    )
    p.add_argument("--quick", action="store_true", help="fewer repetitions (a rough figure in seconds)")
    p.add_argument(
        "--data",
        default=None,
        metavar="DIR",
        help="folder of the real recordings the benchmarks read (default: $DEPTHGRAM_DATA, else ../shared/data "
        "beside the checkout)",
    )
    p.add_argument(
        "--dir",
        default=None,
        metavar="BENCHMARKS",
        help="the benchmarks/ folder of a depthgram checkout (default: the one this depthgram runs from)",
    )


def benchmarks_dir() -> Path | None:
    """Return the benchmarks/ folder of the source checkout this depthgram runs from; None when installed."""
    package = Path(__file__).resolve().parents[1]
    folder = package.parents[1] / "benchmarks"  # src/depthgram -> the checkout's root
    return folder if package.parent.name == "src" and folder.is_dir() else None


def run(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args``; return the exit status."""
    from depthgram.errors import InputError

    unknown = [s for s in args.suites if s not in SUITES]
    if unknown:
        raise InputError(f"unknown benchmark(s) {unknown}; choose from {', '.join(SUITES)}")
    folder = Path(args.dir) if args.dir else benchmarks_dir()
    if folder is None:
        raise InputError(
            f"the benchmarks are scripts of a source checkout, not part of the installed package "
            f"({Path(__file__).resolve().parents[1]}): clone depthgram and run `depthgram bench` there, "
            "or pass --dir CHECKOUT/benchmarks"
        )
    if not folder.is_dir():
        raise InputError(f"--dir {folder}: no such folder (expected a depthgram checkout's benchmarks/)")
    if args.data is not None:
        if not Path(args.data).is_dir():
            raise InputError(f"--data {args.data}: no such folder (expected the real recordings, e.g. ../shared/data)")
        # the scripts read where the recordings are from the environment, as when run on their own
        os.environ["DEPTHGRAM_DATA"] = str(Path(args.data).resolve())
    status = 0
    for name in args.suites or list(SUITES):
        path = folder / SUITES[name]
        if not path.is_file():
            print(f"== {name}: {path.name} missing, skipped", file=sys.stderr)
            status = 1
            continue
        spec = importlib.util.spec_from_file_location(f"depthgram_bench_{name}", path)
        if spec is None or spec.loader is None:
            raise InputError(f"{path}: cannot load benchmark")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod  # dataclasses in the script look their module up there
        spec.loader.exec_module(mod)
        print(f"\n== {name} ({path.name})", flush=True)
        status |= int(mod.main(["--quick"] if args.quick else []) or 0)
    return status
