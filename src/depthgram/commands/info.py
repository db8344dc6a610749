"""``depthgram info INPUT``: what a depth source holds (frames, size, depth range, rate, intrinsics)."""

from __future__ import annotations

import argparse
import json
import sys

NAME = "info"
HELP = "Show what a depth source holds: kind, frames, size, depth range (mm), invalid share, rate, intrinsics."

#: Sources with more frames than this get a progress bar on stderr.
_PROGRESS_FROM = 20


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``info`` options."""
    parser.add_argument("input", metavar="INPUT",
                        help="file, folder, glob, .npy/.npz stack, ROS bag/.mcap, or sim:SCENE?frames=N")
    parser.add_argument("--scale", type=float, metavar="MM_PER_UNIT", default=None,
                        help="mm per raw unit (default 1 for integer images, 1000 for float = metres; TUM: 0.2)")
    parser.add_argument("--invalid", type=float, nargs="+", metavar="V", default=[],
                        help="raw values meaning no reading (65535 in uint16 images always is)")
    parser.add_argument("--fps", type=float, metavar="RATE", default=None, help="frame rate (frames/s)")
    parser.add_argument("--timestamps", metavar="FILE", default=None,
                        help="timestamps file: one time (s) per line, or 'index time' pairs")
    parser.add_argument("--encoding", default="auto",
                        choices=["auto", "raw", "mm", "m", "8bit", "sun", "kinect-disparity"],
                        help="sample encoding (mm/m: units whatever the dtype; sun: SUN RGB-D bit shift; "
                        "kinect-disparity: NYU raw PGM)")
    parser.add_argument("--range", type=float, nargs=2, metavar=("NEAR", "FAR"), default=None, dest="depth_range",
                        help="depth range in mm: of the 8-bit codes 1..255, else the valid range")
    parser.add_argument("--topic", default=None, help="bag topic (needed when a bag has several depth topics)")
    parser.add_argument("--key", default=None, help="array name inside an .npz")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def _fmt_mm(v: float | None) -> str:
    return "-" if v is None else f"{v:.0f}"


def format_info(info: object) -> str:
    """Human-readable lines for a :class:`~depthgram.sources.SourceInfo`."""
    from depthgram.sources import SourceInfo

    assert isinstance(info, SourceInfo)
    w, h = info.size
    lines = [
        f"source      {info.path}",
        f"kind        {info.kind}",
        f"frames      {info.frames}",
        f"size        {w} x {h} px",
        f"units       {info.unit}",
        f"depth       min {_fmt_mm(info.depth_min_mm)}  median {_fmt_mm(info.depth_median_mm)}  "
        f"max {_fmt_mm(info.depth_max_mm)} mm (valid pixels)",
        f"invalid     {100 * info.invalid_fraction:.1f} %",
        f"frame rate  {'unknown' if info.fps is None else f'{info.fps:.3g} frames/s'}",
    ]
    if info.duration_s is not None:
        lines.append(f"duration    {info.duration_s:.3f} s")
    k = info.intrinsics
    intr = "unknown" if k is None else f"fx {k.fx:.2f}  fy {k.fy:.2f}  cx {k.cx:.2f}  cy {k.cy:.2f} px"
    lines.append(f"intrinsics  {intr}")
    sensor = getattr(info, "sensor", None)
    if sensor:
        lines.append(f"sensor      {sensor} (estimated from the first frame; set [segment] sensor to a profile)")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Open the source, stream it once and print the summary."""
    from depthgram.sources import open_source

    src = open_source(
        args.input,
        scale_mm=args.scale,
        invalid=tuple(args.invalid),
        fps=args.fps,
        timestamps=args.timestamps,
        depth_range_mm=tuple(args.depth_range) if args.depth_range else None,
        encoding=args.encoding,
        topic=args.topic,
        key=args.key,
    )
    # Same rule as the other commands: no bar in logs or pipes.
    info = src.info(progress=len(src) > _PROGRESS_FROM and sys.stderr.isatty())
    if args.json:
        json.dump(info.to_dict(), sys.stdout)
        sys.stdout.write("\n")
    else:
        print(format_info(info))
    return 0
