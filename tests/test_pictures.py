"""The pictures leave the user's matplotlib alone: backend, pyplot and its figure list."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np

SCRIPT = textwrap.dedent(
    """
    import sys
    import matplotlib
    matplotlib.use("svg")  # what a user chose before importing depthgram's pictures
    import numpy as np
    from depthgram.frame import make_frame
    from depthgram.scene import parse_sentence
    from depthgram.segmentation import segment
    from depthgram.views.pictures import draw_histogram, draw_overlay, draw_tracks
    from depthgram.views.tree_plot import draw_tree

    out = sys.argv[1]
    z = np.full((60, 80), 3000.0, np.float32)
    z[10:40, 20:50] = 1000.0
    frame = make_frame(z)
    seg = segment(z, method="threshold")
    draw_overlay(frame, seg, out + "/overlay.png")
    draw_histogram(seg.histogram, out + "/hist.png")
    draw_tracks([0.0, 0.1], {1: [1000.0, 990.0]}, {1: [None, -100.0]}, out + "/tracks.png")
    draw_tree(parse_sentence("Bkg[A=4800,c=(39.5,29.5),z=0.0] -> object#1 o_0[A=900,c=(34.5,24.5),z=1000.0]"),
              out + "/tree.png")
    print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules)
    """
)


def test_pictures_keep_the_users_backend_and_stay_out_of_pyplot(tmp_path: Path) -> None:
    # Importing depthgram.views.pictures used to call matplotlib.use("Agg"), switching the
    # backend of whoever imported it (a notebook's inline backend included).
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(tmp_path)], capture_output=True, text=True, check=False, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["svg", "False"]
    for name in ("overlay", "hist", "tracks", "tree"):
        img = cv2.imread(str(tmp_path / f"{name}.png"))
        assert img is not None and img.shape[0] > 50 and img.shape[1] > 50, name
        assert np.ptp(img) > 0, name  # something was drawn
