"""The far limit of segmentation (issue 18.2): absurd depths are counted and left out, the histogram stays bounded."""

from __future__ import annotations

import numpy as np
import pytest

from depthgram.errors import InputError
from depthgram.segmentation import SegmentConfig, segment


def _box_on_wall() -> np.ndarray:
    z = np.full((60, 80), 2000.0, np.float32)  # a wall at 2 m
    z[20:40, 30:50] = 1000.0  # a 20 x 20 box at 1 m
    return z


@pytest.mark.parametrize("method", ["threshold", "surfaces"])
def test_readings_past_the_far_limit_are_counted_and_left_out(method: str) -> None:
    clean = segment(_box_on_wall(), method=method, min_area_px=20)
    z = _box_on_wall()
    z[0, 0] = 1e6  # 1 km: 10^5 bins of 10 mm without a limit
    z[0, 1] = 1e30  # past any integer bin index: an overflow without a limit
    z[0, 2] = np.inf  # ROS REP 117's "too far"
    seg = segment(z, method=method, min_area_px=20)
    assert seg.beyond_far_px == 3
    assert clean.beyond_far_px == 0
    assert sorted(o.area for o in clean.objects) == [400, 4400]
    assert sorted(o.area for o in seg.objects) == [400, 4400 - 3]
    assert seg.labels[0, :3].tolist() == [0, 0, 0]
    assert seg.histogram is not None and seg.histogram.edges[-1] <= 20_000.0


def test_the_far_limit_is_settable() -> None:
    seg = segment(_box_on_wall(), method="threshold", min_area_px=20, far_mm=1500.0)
    assert seg.beyond_far_px == 4800 - 400  # the wall
    assert [o.area for o in seg.objects] == [400]
    # a mask keeps its meaning: a masked-out far reading is not counted
    valid = np.ones((60, 80), bool)
    valid[:, :10] = False
    seg = segment(_box_on_wall(), valid=valid, method="threshold", min_area_px=20, far_mm=1500.0)
    assert seg.beyond_far_px == 4800 - 400 - 600


def test_a_far_limit_that_asks_for_too_many_bins_is_refused() -> None:
    with pytest.raises(InputError, match="far_mm"):
        SegmentConfig(far_mm=1e6, bin_mm=0.1)
    with pytest.raises(InputError, match="far_mm"):
        SegmentConfig(far_mm=float("inf"))
    assert SegmentConfig(far_mm=1e6).far_mm == 1e6
