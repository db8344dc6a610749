"""Frame-rate independence: fast approaches get a velocity and a time to collision at any rate.

Issue 13, item 0: a clean object closing at walking speed used to get no velocity at all,
because a per-frame relative depth-jump gate restarted its queue on every frame before the
track had a velocity (so its prediction was "standing still"). These sequences are noise
free, so the truth is exact: z(t) = z0 + v t, and the time to collision is z / -v.
"""

from __future__ import annotations

import itertools

import pytest

from depthgram.dynamics import Tracker
from depthgram.segmentation.objects import SceneObject

W, H = 640, 480
FX = 500.0  # px, a 200 mm wide object


def square(z: float) -> SceneObject:
    """A 200 mm square straight ahead at depth ``z`` (mm), as segmentation reports it."""
    side = min(FX * 200.0 / z, 0.9 * H)
    x0, x1 = round(320 - side / 2), round(320 + side / 2)
    y0, y1 = round(240 - side / 2), round(240 + side / 2)
    area = (x1 - x0) * (y1 - y0)
    center = ((x0 + x1 - 1) / 2, (y0 + y1 - 1) / 2)
    return SceneObject(1, "object", 0, z, 5.0, area, area / (W * H), center, (x0, y0, x1, y1))


CASES = list(itertools.product((10.0, 15.0, 30.0, 60.0), (500.0, 1000.0, 1500.0, 2000.0), (1500.0, 3000.0)))


@pytest.mark.parametrize(("fps", "speed", "z0"), CASES)
def test_fast_approach_gets_velocity_and_ttc_within_three_frames(fps: float, speed: float, z0: float) -> None:
    tr = Tracker()
    checked = 0
    for k in itertools.count():
        z = z0 - speed * k / fps
        if z < 400.0:  # the sensor's near limit; the object would fill the view
            break
        m = tr.update([square(z)], k / fps, (W, H)).motions[1]
        assert m.track_id == 1
        if k < 3:  # three frames of first sight to settle
            continue
        assert m.v_radial is not None, f"frame {k}: no velocity"
        assert m.v_radial == pytest.approx(-speed, rel=0.10), f"frame {k}"
        assert m.ttc is not None, f"frame {k}: no time to collision"
        assert m.ttc == pytest.approx(z / speed, rel=0.10), f"frame {k}"
        checked += 1
    assert checked >= 1  # every case leaves at least one frame to check
