"""Frame construction and unit conversion."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from depthgram.frame import DepthError, depth_from_8bit, depth_to_8bit, make_frame


def test_millimetre_png_values_pass_through_and_zero_is_invalid() -> None:
    raw = np.array([[0, 1000], [2500, 65535]], dtype=np.uint16)
    f = make_frame(raw, invalid_values=[65535])
    assert f.depth.dtype == np.float32
    np.testing.assert_array_equal(f.valid, [[False, True], [True, False]])
    np.testing.assert_array_equal(f.depth, [[0, 1000], [2500, 0]])
    assert f.size == (2, 2)
    assert f.invalid_fraction == pytest.approx(0.5)


def test_tum_scale_and_metres() -> None:
    f = make_frame(np.array([[5000, 0]], np.uint16), scale_mm=0.2)
    assert f.depth[0, 0] == pytest.approx(1000.0)
    g = make_frame(np.array([[1.25, np.nan]], np.float32), scale_mm=1000.0)
    assert g.depth[0, 0] == pytest.approx(1250.0)
    assert not g.valid[0, 1] and g.depth[0, 1] == 0


def test_max_range_marks_saturated_pixels_invalid() -> None:
    f = make_frame(np.array([[500, 9000]], np.uint16), max_mm=5000)
    np.testing.assert_array_equal(f.valid, [[True, False]])


def test_colour_image_is_refused_with_a_hint() -> None:
    with pytest.raises(DepthError, match="colour image"):
        make_frame(np.zeros((4, 4, 3), np.uint8), name="rgb.png")


def test_all_invalid_frame_can_be_refused() -> None:
    with pytest.raises(DepthError, match="no valid depth"):
        make_frame(np.zeros((3, 3), np.uint16), name="zero.png", allow_all_invalid=False)


def test_8bit_round_trip_within_one_code_step() -> None:
    near, far = 300.0, 3300.0
    step = (far - near) / 254
    d = np.linspace(near, far, 1000)
    back = depth_from_8bit(depth_to_8bit(d, near, far), near, far)
    assert np.max(np.abs(back - d)) <= step / 2 + 1e-3
    assert depth_to_8bit(np.array([0.0]), near, far)[0] == 0


def test_decimated_frame_keeps_readings_and_rays() -> None:
    from depthgram.errors import InputError
    from depthgram.frame import Intrinsics

    rng = np.random.default_rng(3)
    raw = rng.integers(500, 4000, (480, 640)).astype(np.uint16)
    raw[10, 20] = 0
    k = Intrinsics(525.0, 527.0, 319.5, 239.5)
    f = make_frame(raw, intrinsics=k, name="a.png")
    half = f.decimated(2)
    assert half.size == (320, 240) and half.depth.flags.c_contiguous
    # readings kept as they are (no mean across an outline), invalid ones too
    assert_allclose(half.depth, f.depth[::2, ::2])
    assert not half.valid[5, 10] and not f.valid[10, 20]
    # pixel (i, j) of the result looks along the ray of pixel (2i, 2j)
    hk = half.intrinsics
    assert hk is not None
    for x, y in ((0, 0), (100, 37), (319, 239)):
        assert_allclose(((x - hk.cx) / hk.fx, (y - hk.cy) / hk.fy), ((2 * x - k.cx) / k.fx, (2 * y - k.cy) / k.fy))
    assert f.decimated(1) is f and half.meta["decimated"] == 2
    with pytest.raises(InputError, match=r"a\.png: decimation step must be >= 1"):
        f.decimated(0)
