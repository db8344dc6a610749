"""The golden cases in CI: every method's labels and objects as stored, within the stated tolerance.

``benchmarks/golden.py`` holds the cases, the stored values and the tolerance (integers identical,
floats to 9 significant digits); this runs its comparison on the simulator's frames always and on
the real recordings where ``../shared/data`` is present.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from benchmarks import golden


def _differences(real: bool) -> tuple[int, list[str]]:
    stored = golden.load()
    checked, out = 0, []
    for key, f, method, sensor in golden.cases():
        if key.startswith("sim:") == real:
            continue
        want = stored.get(key)
        if want is None:
            out.append(f"{key}: no stored values (run benchmarks/golden.py --update)")
            continue
        diff = golden.compare(key, golden.record(f, method, sensor), want)
        out += [f"{key}: {d}" for d in diff]
        checked += 1
    return checked, out


def test_simulated_golden_cases_are_unchanged_within_the_tolerance() -> None:
    checked, diffs = _differences(real=False)
    assert checked == 78
    assert not diffs, "\n".join(diffs)


def test_real_golden_cases_are_unchanged_within_the_tolerance(shared_data: Path) -> None:
    checked, diffs = _differences(real=True)
    assert checked == 114
    assert not diffs, "\n".join(diffs)


def test_the_comparison_sees_a_moved_float_a_moved_pixel_and_last_bits() -> None:
    # the tolerance itself: a float moved in the 8th digit or one label pixel changed is a
    # difference; the same float moved in its last bits is not
    case = golden.Case(
        np.array([[1, 1], [2, 0]], np.int32), None, np.array([[1000.0, 2000.0]]), "(o(#, #),)", np.array([1.5, 2.5e3])
    )
    last_bits = golden.Case(case.labels, None, case.bands * (1 + 4e-16), case.skeleton, case.floats * (1 + 4e-16))
    assert golden.compare("k", last_bits, case) == []
    moved = golden.Case(case.labels, None, case.bands, case.skeleton, case.floats * np.array([1, 1 + 1e-8]))
    want = ["object floats differ beyond 9 significant digits (worst relative 1e-08)"]
    assert golden.compare("k", moved, case) == want
    pixel = case.labels.copy()
    pixel[1, 1] = 2
    got = golden.compare("k", golden.Case(pixel, None, case.bands, case.skeleton, case.floats), case)
    assert got == ["labels: 1 pixels changed (allowed 0)"]
    with pytest.raises(AssertionError):
        assert not golden.compare("k", golden.Case(case.labels, None, case.bands, "(o(#),)", case.floats[:1]), case)
