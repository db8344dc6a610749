"""depthgram describe: one JSON line (or one sentence) per frame."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from depthgram.commands._common import add_pipeline_arguments, pipeline_results

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

NAME = "describe"
HELP = "describe every frame: objects, tree, sentence, motion (JSON lines or text)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_pipeline_arguments(p, stills=True)
    p.add_argument("--json", default=None, metavar="OUT.jsonl", help="write JSON lines here (default: stdout)")
    p.add_argument("--format", choices=["json", "text"], default="json",
                   help="json: one JSON line per frame; text: one sentence per frame")
    p.add_argument("--labels-dir", default=None, metavar="DIR",
                   help="write a 16-bit PNG label map per frame (pixel = object id)")


def label_file_name(frame_name: str, index: int) -> str:
    """Label map file name, after the input frame's file when it has one."""
    stem = Path(frame_name).stem if frame_name and ":" not in frame_name else ""
    return f"{stem or f'{index:06d}'}.png"


def write_label_map(path: Path, labels: NDArray[np.integer], frame_name: str) -> None:
    """Write ``labels`` (object or track id per pixel) as a 16-bit PNG.

    Raises
    ------
    InputError
        When an id does not fit in 16 bits (track ids grow over a long recording and would
        wrap silently), or the file cannot be written.
    """
    import cv2

    from depthgram.errors import InputError

    top = int(labels.max(initial=0))
    if top > 65535:
        raise InputError(f"{frame_name}: object id {top} is above 65535; cannot write a 16-bit PNG label map ({path})")
    from depthgram.atomic import atomic_path

    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), labels.astype("uint16")):
            raise InputError(f"{path}: could not write the label map")


def run(args: argparse.Namespace) -> int:
    labels_dir = Path(args.labels_dir) if args.labels_dir else None
    if labels_dir is not None:
        labels_dir.mkdir(parents=True, exist_ok=True)
    from depthgram.atomic import atomic_open

    # a file output appears only when every frame is written: a failure leaves no look-alike
    with atomic_open(args.json) if args.json else contextlib.nullcontext(sys.stdout) as out:
        _, results = pipeline_results(args, NAME)
        for result in results:
            if args.format == "text":
                out.write(result.sentence + "\n")
            else:
                out.write(json.dumps(result.to_record()) + "\n")
            if labels_dir is not None:
                path = labels_dir / label_file_name(result.frame.name, result.frame.index)
                write_label_map(path, result.segmentation.labels, result.frame.name or f"frame {result.frame.index}")
    return 0
