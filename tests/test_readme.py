"""The README's Python example runs as written (on a simulated recording instead of a bag)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

README = Path(__file__).resolve().parents[1] / "README.md"


def test_python_example_runs(capsys) -> None:
    block = re.search(r"## In Python\n\n```python\n(.*?)```", README.read_text(), re.S)
    assert block, "README lost its Python example"
    code = block.group(1).replace('read("recording.bag")', 'read("sim:approach?frames=4")')
    depth_mm = np.full((60, 80), 2000.0, np.float32)
    depth_mm[20:40, 30:50] = 900.0
    exec(compile(code, str(README), "exec"), {"depth_mm": depth_mm})
    out = capsys.readouterr().out
    assert "900" in out and out.count("Bkg") == 4


def test_depthgram_segment_is_callable_after_the_stages_are_imported() -> None:
    import depthgram
    import depthgram.pipeline  # imports the segment package, which shadows the lazy name

    depth = np.full((30, 40), 2000.0, np.float32)
    depth[5:15, 5:15] = 700.0
    seg = depthgram.segment(depth, min_area_px=20)
    assert any(abs(o.depth - 700.0) < 1 and o.area == 100 for o in seg.objects)
