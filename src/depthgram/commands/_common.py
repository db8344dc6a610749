"""Arguments shared by the sub-commands that read a source and run the pipeline."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from depthgram.pipeline import Config, SceneResult
    from depthgram.sources import Source


def add_pipeline_arguments(p: argparse.ArgumentParser, *, stills: bool = False) -> None:
    """INPUT, how to read it (with --stills), the settings and --quiet.

    ``stills`` is kept for callers of the time when only some commands had --no-track; every
    command now has --stills (alias --no-track) among the reading options.
    """
    add_source_arguments(p)
    add_config_arguments(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def pipeline_results(args: argparse.Namespace, desc: str) -> tuple[Source, Iterator[SceneResult]]:
    """Open the input, run the configured pipeline over it, with a progress bar."""
    from depthgram.pipeline import Pipeline

    src = open_input(args)
    pipe = Pipeline(load_config(args))
    return src, progress(pipe.run(src), total=source_len(src), desc=desc, quiet=args.quiet)


def add_source_arguments(p: argparse.ArgumentParser) -> None:
    """INPUT and the options that say how to read it."""
    p.add_argument(
        "input",
        metavar="INPUT",
        help="file, folder or glob of depth frames, ROS bag / MCAP, or sim:SCENE (table, corridor, approach, crossing)",
    )
    g = p.add_argument_group("reading the input")
    g.add_argument("--scale", type=float, default=None, metavar="MM_PER_UNIT",
                   help="millimetres per raw unit (0.2 for TUM's 5000 per metre; 1000 for metres)")
    g.add_argument("--invalid", type=float, nargs="+", default=[], metavar="VALUE",
                   help="raw values that mean no reading (0 always does)")
    g.add_argument("--fps", type=float, default=None, metavar="RATE",
                   help="frame rate of a folder of frames without timestamps")
    g.add_argument("--timestamps", default=None, metavar="FILE", help="file with one time (s) per frame")
    g.add_argument("--stills", "--no-track", dest="stills", default=None, nargs="?", const="yes",
                   choices=["yes", "no", "auto"],
                   help="the frames are unrelated still images: no motion (velocity, time to collision, approach "
                        "alarm) is read between them. 'no': one recording, always track; default 'auto' (or the "
                        "config's 'stills'): tracks are dropped between frames with nothing in common")
    g.add_argument("--encoding", default="auto", help="raw encoding: auto, mm, sun, kinect-disparity")
    g.add_argument("--topic", default=None, help="depth Image topic of a ROS bag")
    g.add_argument("--range", type=float, nargs=2, default=None, metavar=("NEAR_MM", "FAR_MM"),
                   dest="depth_range", help="depth range of 8-bit (0-255) depth images")


def add_config_arguments(p: argparse.ArgumentParser) -> None:
    """--config and the most used segmentation setting."""
    p.add_argument("--config", default=None, metavar="TOML", help="pipeline settings (see depthgram config --dump)")
    p.add_argument("--method", default=None, choices=["threshold", "slices", "region"],
                   help="segmentation method (default from the config)")


def open_input(args: argparse.Namespace) -> Source:
    """Open the source named by the arguments."""
    from depthgram.sources import open_source

    kwargs: dict[str, Any] = {
        "scale_mm": args.scale,
        "invalid": tuple(args.invalid),
        "fps": args.fps,
        "timestamps": args.timestamps,
        "encoding": args.encoding,
        "topic": args.topic,
    }
    if args.depth_range is not None:
        kwargs["depth_range_mm"] = tuple(args.depth_range)
    return open_source(args.input, **kwargs)


def load_config(args: argparse.Namespace) -> Config:
    """The pipeline configuration from --config and --method."""
    from depthgram.pipeline import Config

    cfg = Config.load(args.config) if getattr(args, "config", None) else Config()
    if getattr(args, "method", None):
        cfg = cfg.replace(segment={"method": args.method})
    stills = getattr(args, "stills", None)
    if stills is not None:
        cfg = cfg.with_stills({"yes": True, "no": False}.get(stills, "auto"))
    return cfg


def progress(iterable: Any, *, total: int | None, desc: str, quiet: bool = False) -> Any:
    """A tqdm progress bar on standard error; silent with --quiet or when not a terminal."""
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit="frame", disable=quiet or not sys.stderr.isatty(),
                file=sys.stderr)


def source_len(src: object) -> int | None:
    """Frame count when the source knows it."""
    try:
        return len(src)  # type: ignore[arg-type]
    except TypeError:
        return None
