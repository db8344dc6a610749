"""``depthgram simulate``: write simulated ToF or structured-light frames and their ground truth to a folder.

Layout of ``--out DIR`` for frame k (six digits, zero-padded):

- ``depth/000000.png``: measured depth, 16-bit PNG in millimetres, 0 = invalid;
- ``depth/camera.json``: intrinsics (px), frame rate, unit, scene and seed;
- ``instances/000000.png``: ground-truth instance map, 16-bit PNG;
- ``truth/000000.json``: the frame's index, time and truth objects.
"""

from __future__ import annotations

import argparse
import re
import sys

NAME = "simulate"
HELP = "Simulate depth frames (ToF or structured light) of a named scene with ground truth (PNGs, truth JSON)."

#: Largest image side accepted on the command line (px).
MAX_SIDE = 4096


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the sub-command's arguments."""
    parser.add_argument(
        "scene",
        help="scene name: table, corridor, approach, crossing, ball_wall, touching, arm_down, arm_45, chest_walk, "
        "ball_approach, ball_rush, pass_behind, cross_front",
    )
    parser.add_argument("--frames", type=int, default=1, help="number of frames (default 1)")
    parser.add_argument("--size", default="176x132", help="image size WxH in pixels (default 176x132)")
    parser.add_argument("--out", required=True, help="output folder (created when missing)")
    parser.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    parser.add_argument("--fps", type=float, default=30.0, help="frame rate in frames per second (default 30)")
    parser.add_argument(
        "--bits",
        type=int,
        choices=(8, 16),
        default=16,
        help="sensor quantization: 16 (mm) or 8 (the paper's 0-255 over 3 m); PNGs stay mm",
    )
    parser.add_argument("--no-noise", action="store_true", help="no shot or read noise (no disparity noise)")
    parser.add_argument(
        "--sensor",
        default="tof",
        choices=("tof", "structured-light", "sl"),
        help="tof (default) or structured-light / sl: a Kinect v1 / Xtion-like camera "
        "(1/8 px disparity steps, projector shadows, registration holes)",
    )


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` to (width, height), each 8..4096 px.

    Raises
    ------
    InputError
        When the text is not WxH or a side is out of range.
    """
    from depthgram.errors import InputError

    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not m:
        raise InputError(f"--size: expected WxH in pixels such as 176x132, got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
    if not (8 <= w <= MAX_SIDE and 8 <= h <= MAX_SIDE):
        raise InputError(f"--size: each side must be 8..{MAX_SIDE} pixels, got {w}x{h}")
    return w, h


def run(args: argparse.Namespace) -> int:
    """Simulate and write the frames; return 0."""
    import dataclasses
    import json
    from pathlib import Path

    import cv2
    import numpy as np
    from tqdm import tqdm

    from depthgram.errors import InputError
    from depthgram.sensor import SCENES, simulate
    from depthgram.sensor.scenes import build_scene

    if args.scene not in SCENES:
        raise InputError(f"unknown scene {args.scene!r}; known scenes: {', '.join(SCENES)}")
    if args.frames < 1:
        raise InputError(f"--frames must be >= 1, got {args.frames}")
    size = parse_size(args.size)
    structured = args.sensor != "tof"
    if structured and args.bits != 16:
        raise InputError("--bits applies to the tof sensor only (structured light is read in mm)")
    tof = None if structured else dataclasses.replace(build_scene(args.scene, size).tof, bits=args.bits)
    frames = simulate(
        args.scene,
        args.frames,
        size=size,
        fps=args.fps,
        seed=args.seed,
        tof=tof,
        noise=not args.no_noise,
        sensor=args.sensor,
    )

    out = Path(args.out)
    dirs = {name: out / name for name in ("depth", "instances", "truth")}
    try:
        for d in dirs.values():
            d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot create the output folders ({exc.strerror or exc})") from exc

    def write_png(path: Path, image: np.ndarray) -> None:
        if not cv2.imwrite(str(path), image):
            raise InputError(f"{path}: could not write the PNG (is the folder writable?)")

    def write_text(path: Path, text: str) -> None:
        try:
            path.write_text(text, encoding="utf-8")
        except OSError as exc:
            raise InputError(f"{path}: could not write ({exc.strerror or exc})") from exc

    camera_written = False
    bar = tqdm(
        frames,
        total=args.frames,
        unit="frame",
        desc=f"simulate {args.scene}",
        disable=not sys.stderr.isatty(),
        file=sys.stderr,
    )
    for sim in bar:
        f = sim.frame
        stem = f"{f.index:06d}"
        if not camera_written:
            k = f.intrinsics
            assert k is not None  # the simulator always knows its camera
            camera = {
                "fx": k.fx,
                "fy": k.fy,
                "cx": k.cx,
                "cy": k.cy,
                "fps": float(args.fps),
                "unit": "mm",
                "scene": args.scene,
                "seed": args.seed,
                "bits": args.bits,
                "sensor": f.meta.get("sensor", "tof"),
                "width": size[0],
                "height": size[1],
            }
            write_text(dirs["depth"] / "camera.json", json.dumps(camera, indent=2) + "\n")
            camera_written = True
        write_png(dirs["depth"] / f"{stem}.png", np.rint(f.depth).astype(np.uint16))
        write_png(dirs["instances"] / f"{stem}.png", sim.instances.astype(np.uint16))
        truth = {
            "index": f.index,
            "time_s": f.time_s,
            "name": f.name,
            "objects": [dataclasses.asdict(o) for o in sim.truth],
        }
        write_text(dirs["truth"] / f"{stem}.json", json.dumps(truth, indent=2) + "\n")
    print(f"wrote {args.frames} frame(s) of {args.scene!r} at {size[0]}x{size[1]} to {out}", file=sys.stderr)
    return 0
