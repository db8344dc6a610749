"""``depthgram info INPUT``: what a depth source holds (frames, size, depth range, rate, intrinsics)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from depthgram.sources import SourceInfo

NAME = "info"
HELP = "Show what a depth source holds: kind, frames, size, depth range (mm), invalid share, rate, intrinsics."

#: Sources with more frames than this get a progress bar on stderr.
_PROGRESS_FROM = 20

#: Frames of a live camera summarised when its spec gives no count.
_LIVE_FRAMES = 30


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``info`` options: INPUT, the reading options every command shares, --json."""
    from depthgram.commands._common import add_output_argument, add_source_arguments

    parser.epilog = "The summary is printed as text unless --json names a file ('-' is standard output)."
    add_source_arguments(parser, input_optional=True)
    add_output_argument(parser, "--json", "the summary as one JSON object", bare_deprecated=True)


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
    if k is None:
        from depthgram.segmentation.orientation import default_intrinsics

        k = default_intrinsics((h, w))
        said = (
            "guessed: a 64-degree field of view, the scene does not show its focal length; "
            "give --intrinsics FX FY CX CY or --camera FILE|PROFILE"
        )
    else:
        origin = getattr(info, "intrinsics_from", "")
        said = (getattr(info, "intrinsics_source", "") or "given") + (f" from {origin}" if origin else "")
        if said.startswith("estimated"):
            said += "; give --intrinsics FX FY CX CY or --camera FILE|PROFILE to be sure"
    lines.append(f"intrinsics  fx {k.fx:.2f}  fy {k.fy:.2f}  cx {k.cx:.2f}  cy {k.cy:.2f} px ({said})")
    gravity = getattr(info, "gravity", None)
    if gravity:
        x, y, z = gravity["vector"]
        lines.append(
            f"gravity     {x:.3f} {y:.3f} {z:.3f} (camera x right, y down, z forward; "
            f"looking {gravity['tilt_deg']:.1f} degrees down; {gravity['source']})"
        )
    sensor = getattr(info, "sensor", None)
    if sensor and sensor.startswith("auto"):
        lines.append(f"sensor      {sensor} (estimated from the first frame; set [segment] sensor to a profile)")
    elif sensor:
        lines.append(f"sensor      {sensor}")
    return "\n".join(lines)


def _with_scene_focal(info: SourceInfo, args: argparse.Namespace) -> SourceInfo:
    """Return ``info`` with the focal length read from the first frame's scene, when it shows it.

    What ``describe`` and the other pipeline commands will use for a source without intrinsics
    (:func:`depthgram.focal_length.estimate_focal_length`), or instead of intrinsics a person
    chose that the scene contradicts (:class:`depthgram.focal_length.FocalCheck`), so that
    ``info`` says the same.
    """
    import dataclasses

    from depthgram.commands._common import open_input
    from depthgram.focal_length import FocalCheck, estimate_focal_length

    src = open_input(args)
    frames = iter(src)
    try:
        first = next(frames, None)
    finally:
        close = getattr(frames, "close", None)
        if close is not None:
            close()
    if first is None:
        return info
    given = info.intrinsics
    if given is not None:
        # intrinsics a person chose, held against the scene as the pipeline holds them
        k, overruled = FocalCheck().read(first.depth, first.valid, given)
        if overruled is None:
            return info
        return dataclasses.replace(
            info,
            intrinsics=k,
            intrinsics_source="estimated",
            intrinsics_from=(
                f"the scene of frame 0, overruling {info.intrinsics_source or 'given'} fx = {given.fx:.0f} px "
                "(--trust-intrinsics keeps them)"
            ),
        )
    found = estimate_focal_length(first.depth, first.valid)
    if found is None:
        return info
    return dataclasses.replace(
        info,
        intrinsics=found.intrinsics,
        intrinsics_source="estimated",
        intrinsics_from=f"the scene of frame 0 (support seen {found.tilt_deg:.0f} degrees from face-on)",
    )


def run(args: argparse.Namespace) -> int:
    """Open the source, stream it once and print the summary."""
    from depthgram.commands._common import Output, open_input, output_target, source_len

    json_to = output_target(args, "json")
    src = open_input(args)
    n = source_len(src)
    if n is None and src.live:
        # a camera streams for ever: summarise a fixed number of its frames
        spec = f"{args.input}{'&' if '?' in args.input else '?'}frames={_LIVE_FRAMES}"
        print(
            f"depthgram info: live camera: summarising its first {_LIVE_FRAMES} frames (add ?frames=N to choose)",
            file=sys.stderr,
        )
        args.input, n = spec, _LIVE_FRAMES
        src = open_input(args)
    # Same rule as the other commands: no bar in logs or pipes.
    info = src.info(progress=(n or 0) > _PROGRESS_FROM and sys.stderr.isatty())
    from depthgram.focal_length import CHECKED_SOURCES

    chosen = info.intrinsics is not None and info.intrinsics_source in CHECKED_SOURCES and not args.trust_intrinsics
    if (info.intrinsics is None or chosen) and not src.live and info.frames:
        info = _with_scene_focal(info, args)
    if json_to is not None:
        with Output(json_to, "--json") as out:
            out.write(json.dumps(info.to_dict()) + "\n")
    else:
        print(format_info(info))
    return 0
