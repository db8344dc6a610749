"""The README's Python example runs as written (on a simulated recording instead of a bag)."""

from __future__ import annotations

import ast
import re
import warnings
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parents[1] / "README.md"


def test_python_example_runs_as_written(capsys) -> None:
    # executed verbatim: no name injected, no call replaced (it once needed a depth_mm it never
    # loaded, and segment(frame) failed with "got shape ()")
    block = re.search(r"## In Python\n\n```python\n(.*?)```", README.read_text(), re.S)
    assert block, "README lost its Python example"
    from depthgram.frame import GravityWarning

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the example must not trip a units or deprecation warning
        # the simulator's frames carry no gravity (a camera without an IMU): estimated, and said
        warnings.simplefilter("ignore", GravityWarning)
        exec(compile(block.group(1), str(README), "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    objects = ast.literal_eval(lines[0])
    # sim:table: floor, back wall, a table top and four things on it (cup, box, ball, bottle)
    # at about 1 m; the things are the four "object"s nearer than 1.2 m
    assert {"object", "floor"} <= {kind for _, kind, *_ in objects}
    assert sum(kind == "object" and depth < 1200 for _, kind, depth, *_ in objects) == 4
    assert lines[1].startswith("Bkg") and sum(line.startswith("Bkg") for line in lines) == 6


def test_depthgram_segment_is_callable_after_the_stages_are_imported() -> None:
    import depthgram
    import depthgram.pipeline  # imports the segment package, which shadows the lazy name

    depth = np.full((30, 40), 2000.0, np.float32)
    depth[5:15, 5:15] = 700.0
    seg = depthgram.segment(depth, min_area_px=20)
    assert any(abs(o.depth - 700.0) < 1 and o.area == 100 for o in seg.objects)
