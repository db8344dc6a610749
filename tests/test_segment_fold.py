"""Issue 28: an object standing on a table is not folded into it as the table's front face.

With a focal length 1.6 times the true one the orientation field classes part of YCB-Video's
boxes as horizontal: in frame 1 their tops join the table, in frame 2 the two box tops join
one plane. The boxes' fronts touched those supports without a depth jump and were folded into
them as front faces (IoU 0.08 and 0.09 in frame 1, 0.45 and 0.51 in frame 2). A front face lies
behind its support's plane continued (1/Z, affine in pixel coordinates whatever the focal
length), and under one piece of it: each box stays its own object.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from depthgram.cli import main
from depthgram.segmentation import evaluate

#: YCB-Video's Xtion (fx, fy, cx, cy), PROVENANCE.md
XTION = (1066.778, 1067.487, 312.987, 241.311)


@pytest.mark.parametrize("frame", ["000001", "000002"])
def test_boxes_on_the_table_are_their_own_objects_with_the_focal_length_x1_6(
    shared_data: Path, tmp_path: Path, frame: str
) -> None:
    folder = shared_data / "ycbv_0000_labelled"
    depth_png = folder / f"{frame}-depth.png"
    if not depth_png.exists():
        pytest.skip(f"{depth_png} not found")
    fx, fy, cx, cy = XTION
    args = ["describe", str(depth_png), "--scale", "0.1", "--quiet", "--stills", "yes"]
    args += ["--intrinsics", str(fx * 1.6), str(fy * 1.6), str(cx), str(cy)]
    args += ["--labels-dir", str(tmp_path), "--json", str(tmp_path / "scene.jsonl")]
    assert main(args) == 0
    labels = cv2.imread(str(tmp_path / depth_png.name), cv2.IMREAD_UNCHANGED).astype(np.int32)
    truth = cv2.imread(str(folder / f"{frame}-label.png"), cv2.IMREAD_UNCHANGED).astype(np.int32)
    depth = cv2.imread(str(depth_png), cv2.IMREAD_UNCHANGED)
    ious = [o.iou for o in evaluate(labels, truth, valid=depth > 0).objects]
    assert len(ious) == 3
    assert min(ious) >= 0.5, ious
