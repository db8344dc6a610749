"""Window sums taken in our own order against OpenCV's box filter, and the test that makes them equal.

OpenCV sums a float32 image in float64 and rounds once; where every float64 intermediate is
exact its result is float32 of the exact window sum, and so is ours
(:mod:`depthgram.segmentation.window`). These tests hold OpenCV to that (against whole-number
sums, which are exact whatever the order), the exactness test to hand-worked bounds, and the
fused kernels of the orientation field and the creases to the OpenCV routes they replaced.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from numba import njit
from numpy.typing import NDArray

from depthgram.segmentation.window import bits_range, exact_rows

f32 = np.float32


@njit(cache=True)
def _range_of(v: NDArray[np.float32]) -> tuple[int, int]:
    return bits_range(v)


def _exact(hi: int, lo: int, n: int) -> bool:
    # the test of one band of rows whose largest and smallest nonzero magnitudes are hi and lo
    return _exact_rows(np.array([hi], np.int64), np.array([lo], np.int64), n, 0, 0)


@njit(cache=True)
def _exact_rows(hi: NDArray[np.int64], lo: NDArray[np.int64], n: int, before: int, after: int) -> bool:
    return exact_rows(hi, lo, n, before, after)


def _bits(v: float) -> int:
    return int(np.array([v], f32).view(np.uint32)[0]) & 0x7FFFFFFF


def exact_box(img: NDArray[np.float32], k: int, border: int) -> NDArray[np.float32]:
    """float32 of the exact k x k window sums of a one-channel image (whole numbers inside)."""
    a = np.abs(img[img != 0]).astype(np.float64)
    q = max(math.frexp(float(a.min()))[1] - 1 - 23, -149) if a.size else 0
    n = np.ldexp(img.astype(np.float64), -q)
    assert np.array_equal(n, np.round(n)) and np.abs(n).max(initial=0) < 2.0**56
    r = k // 2
    p = np.pad(n.astype(np.int64), r, mode="edge" if border == cv2.BORDER_REPLICATE else "constant")
    c = np.zeros((p.shape[0] + 1, p.shape[1] + 1), np.int64)
    c[1:, 1:] = p.cumsum(0).cumsum(1)  # whole numbers: exact in any order
    h, w = img.shape
    s = c[k : k + h, k : k + w] - c[:h, k : k + w] - c[k : k + h, :w] + c[:h, :w]
    assert np.abs(s).max(initial=0) < 2**53
    return np.ldexp(s.astype(np.float64), q).astype(f32)


def test_opencv_sums_float32_images_exactly_in_float64() -> None:
    # up to 5 and 2**-20: float32 running sums lose the small ones (a sum past 16 keeps no
    # bit of 2**-20), float64 keeps them; OpenCV's result is the exact sum rounded once, with
    # either border
    rng = np.random.default_rng(3)
    for k, border in ((7, cv2.BORDER_REPLICATE), (3, cv2.BORDER_CONSTANT), (5, cv2.BORDER_REPLICATE)):
        img = np.where(rng.random((31, 37)) < 0.5, f32(1.0), f32(2.0**-20)).astype(f32)
        img *= rng.choice(np.array([1, 3, 5, -1], f32), size=img.shape)
        want = exact_box(img, k, border)
        got = cv2.boxFilter(img, -1, (k, k), normalize=False, borderType=border)
        np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
        # the values do tell float32 from float64 running sums
        r = k // 2
        pad = np.pad(img, r, mode="edge" if border == cv2.BORDER_REPLICATE else "constant")
        acc = np.zeros(img.shape, f32)
        for dy in range(k):
            for dx in range(k):
                acc += pad[dy : dy + img.shape[0], dx : dx + img.shape[1]]
        assert (acc != want).sum() > 10


def test_bits_range_is_the_largest_and_smallest_nonzero_magnitude() -> None:
    rng = np.random.default_rng(1)
    for _ in range(60):
        v = (rng.normal(0, 1, int(rng.integers(1, 40))) * 10.0 ** rng.uniform(-45, 30)).astype(f32)
        v[rng.random(v.size) < 0.3] = 0.0
        hi, lo = _range_of(v)
        a = np.abs(v[v != 0])
        assert hi == (_bits(float(a.max())) if a.size else 0)
        assert lo == (_bits(float(a.min())) if a.size else 0)
    assert _range_of(np.zeros(5, f32)) == (0, 0)
    assert _range_of(np.array([0.0, -2.0, 0.5], f32)) == (_bits(2.0), _bits(0.5))
    # NaN and infinity come out as the largest patterns, which fail the exactness test
    for bad in (np.inf, -np.inf, np.nan):
        hi, _ = _range_of(np.array([1.0, bad, 0.25], f32))
        assert hi >= 0x7F800000 and not _exact(hi, _bits(0.25), 9)


def test_exact_in_float64_at_its_bound() -> None:
    # with the smallest magnitude 2**-d every value is a whole multiple of 2**(-d - 23), and
    # float64 holds such multiples up to 2**(53 - d - 23): n values of at most 1 sum exactly
    # in any order while n <= 2**(30 - d)
    for n in (1, 9, 25, 49, 64, 65):
        for d in range(18, 32):
            assert _exact(_bits(1.0), _bits(2.0**-d), n) == (n <= 2 ** (30 - d)), (n, d)
    # the largest value's mantissa counts: 1.25 * 49 <= 64 < 1.5 * 49 at 24 octaves
    assert _exact(_bits(1.25), _bits(2.0**-24), 49)
    assert not _exact(_bits(1.5), _bits(2.0**-24), 49)
    assert _exact(_bits(1.5), _bits(2.0**-23), 49)
    assert _exact(0, 0, 49)  # all zeros
    # subnormals are whole multiples of 2**-149
    assert _exact(_bits(2.0**-120), _bits(2.0**-149), 49)
    assert not _exact(_bits(2.0**-90), _bits(2.0**-149), 49)
    # sums near float32's largest value are left to OpenCV
    assert not _exact(_bits(2.0**120), _bits(2.0**110), 49)


def test_exact_rows_reads_each_output_rows_band() -> None:
    # output row y reads rows y - 4 to y + 3 (a 7 x 7 window's running column sums)
    h = 20
    hi = np.full(h, _bits(1.0), np.int64)
    lo = np.full(h, _bits(2.0**-10), np.int64)
    assert _exact_rows(hi, lo, 49, 4, 3)
    lo[10] = _bits(2.0**-30)  # 30 octaves below the largest value of its bands ...
    assert not _exact_rows(hi, lo, 49, 4, 3)
    hi[3:18] = _bits(2.0**-12)  # ... but 18 octaves below every value of the bands holding it
    lo[3:10] = lo[11:18] = _bits(2.0**-14)
    assert _exact_rows(hi, lo, 49, 4, 3)
    hi[5] = _bits(1.0)  # row 5 is in the band of output row 9 (rows 5 to 12), as is row 10
    assert not _exact_rows(hi, lo, 49, 4, 3)
    lo[:] = 0  # rows of zeros only
    hi[:] = 0
    assert _exact_rows(hi, lo, 49, 4, 3)


def _kept(rng: np.random.Generator, h: int, w: int, octaves: float) -> NDArray[np.float32]:
    # three planes: the count of kept slopes (1 / 0) and two slope channels with values over
    # `octaves` octaves, zero where not kept
    keep = rng.random((h, w)) < 0.8
    s = rng.choice([-1.0, 1.0], (2, h, w)) * np.exp2(rng.uniform(-octaves, 0, (2, h, w))) * 0.05
    return np.stack([keep.astype(f32), *(np.where(keep, s, 0.0).astype(f32))])


def _ranges(kept: NDArray[np.float32]) -> NDArray[np.int64]:
    h = kept.shape[1]
    out = np.zeros((4, h), np.int64)
    for y in range(h):
        out[0, y], out[1, y] = _range_of(kept[1, y])
        out[2, y], out[3, y] = _range_of(kept[2, y])
    return out


def test_classes_from_window_sums_equal_the_opencv_route() -> None:
    from depthgram.segmentation.orientation import _classify, _classify_window

    rng = np.random.default_rng(7)
    cam = (f32(60.0), f32(58.0), f32(26.0), f32(18.0), f32(math.cos(math.radians(35.0))))
    shapes = [(37, 53), (1, 9), (9, 1), (2, 2), (6, 40), (40, 6), (12, 7)]
    for t in range(40):
        h, w = shapes[t % len(shapes)]
        k = (7, 3, 5, 9)[t % 4]
        kept = _kept(rng, h, w, float(rng.choice([2.0, 12.0, 20.0])))
        inv3 = rng.uniform(0.2, 2.0, (h, w)).astype(f32)
        valid = rng.random((h, w)) < 0.9
        edge = rng.random((h, w)) < 0.05
        img = cv2.merge(list(kept))
        sums = cv2.boxFilter(img, -1, (k, k), normalize=False, borderType=cv2.BORDER_REPLICATE).reshape(h, w, 3)
        for c in range(3):  # OpenCV's sums are the exact ones here
            np.testing.assert_array_equal(sums[:, :, c], exact_box(kept[c], k, cv2.BORDER_REPLICATE))
        want = _classify(np.ascontiguousarray(sums), inv3, valid, edge, *cam)
        got, exact = _classify_window(kept, _ranges(kept), k, inv3, valid, edge, *cam)
        assert exact
        np.testing.assert_array_equal(got, want)
    # slopes over 40 octaves: refused, nothing computed; an even window too
    kept = _kept(rng, 30, 30, 40.0)
    inv3 = np.ones((30, 30), f32)
    ok = np.ones((30, 30), np.bool_)
    assert not _classify_window(kept, _ranges(kept), 7, inv3, ok, ~ok, *cam)[1]
    kept = _kept(rng, 30, 30, 2.0)
    assert not _classify_window(kept, _ranges(kept), 6, inv3, ok, ~ok, *cam)[1]


def test_slopes_give_their_rows_ranges() -> None:
    from depthgram.segmentation._kernels.creases import inverse_depth as _inverse
    from depthgram.segmentation.orientation import _slopes

    rng = np.random.default_rng(2)
    z = (1500 + np.cumsum(rng.normal(0, 30, (30, 41)), axis=1)).astype(f32)
    valid = rng.random(z.shape) < 0.8
    z[~valid] = 0
    _, kept, _, ranges = _slopes(_inverse(z, valid), z, valid, 3, f32(60), f32(58), f32(5.67), f32(0.05))
    np.testing.assert_array_equal(ranges, _ranges(kept))
    assert (ranges[0] > 0).any()


@pytest.mark.parametrize("scene", ["table", "corridor"])
def test_orientation_classes_whichever_route_sums_the_window(scene: str) -> None:
    # a frame's classes from the fused window sums and from OpenCV's (the route the normals
    # take) are the same
    from depthgram.segmentation.orientation import _field
    from depthgram.sensor import simulate

    f = next(iter(simulate(scene, 1, size=(176, 132), seed=1))).frame
    for window in (7, 5):
        args = (f.depth, f.valid, f.intrinsics, window, 35.0, 0.05)
        fused, _ = _field(*args, False)
        via_opencv, normals = _field(*args, True)
        assert normals is not None
        np.testing.assert_array_equal(fused, via_opencv)
        assert len(np.unique(fused)) == 3


def _crease_args(rng: np.random.Generator, h: int, w: int, octaves: float) -> tuple:
    valid = rng.random((h, w)) > 0.15
    inv = np.where(valid, np.exp2(rng.uniform(-octaves, 0, (h, w))) * 4.0, 0.0)
    im = np.ascontiguousarray(np.stack([inv, valid]).astype(f32))  # two planes, as _inverse
    facing = valid & (rng.random((h, w)) > 0.2)
    return im, valid, facing


def test_creases_from_window_sums_equal_the_opencv_route() -> None:
    from depthgram.segmentation._kernels.creases import crease_state_from_sums as _crease_state
    from depthgram.segmentation._kernels.creases import crease_state_window as _crease_state_window
    from depthgram.segmentation.creases import _window_sums

    rng = np.random.default_rng(11)
    c = np.array([1.0, 2e-6, 0.5, 1e-6], f32)
    for t, (h, w, r) in enumerate([(40, 50, 2), (41, 39, 3), (5, 3, 2), (3, 9, 4), (30, 50, 1), (1, 12, 2)] * 3):
        k = 2 * (r // 2) + 1
        im, valid, facing = _crease_args(rng, h, w, (1.0, 6.0, 20.0)[t % 3])
        sums = _window_sums(im, k)
        for ch in range(2):
            np.testing.assert_array_equal(sums[:, :, ch], exact_box(im[ch], k, 0))
        args = (c, f32(0.5 * k * k))
        tail = (f32(0.02), f32(math.sqrt(6.0) / (0.7 * k)))
        state, exact = _crease_state_window(im, valid, facing, *args, k, r, *tail)
        assert exact
        np.testing.assert_array_equal(state, _crease_state(sums, valid, facing, *args, r, *tail))
    # 1 / Z over 40 octaves: refused
    im, valid, facing = _crease_args(rng, 20, 20, 40.0)
    assert not _crease_state_window(im, valid, facing, c, f32(4.5), 3, 2, f32(0.02), f32(1.0))[1]


def test_a_refused_frame_takes_opencvs_route_to_the_same_result(monkeypatch: pytest.MonkeyPatch) -> None:
    # a frame the exactness test refuses (SUN RGB-D's frame read in the wrong units was one)
    # gets its classes, creases and labeller state from OpenCV's sums: the same results where
    # both routes apply
    from depthgram.segmentation import orientation, surfaces
    from depthgram.segmentation._kernels import creases as kernels_creases
    from depthgram.segmentation.noise_model import PROFILES
    from depthgram.sensor import simulate

    f = next(iter(simulate("table", 1, size=(176, 132), seed=0))).frame
    facing = f.valid & (np.arange(176)[None, :] % 3 > 0)
    kw = {"scale_px": 2, "min_angle_deg": 10.0, "focal_px": float(f.intrinsics.fx)}
    sensor = PROFILES["kinect-v1"]
    want = (
        orientation.orientation_classes(f.depth, f.valid, f.intrinsics),
        surfaces.concave_creases(f.depth, f.valid, sensor, **kw),
        surfaces.crease_state(f.depth, f.valid, facing, sensor, **kw),
    )
    calls = []

    def refuse(*args: object) -> tuple[None, bool]:
        calls.append(args)
        return None, False

    for name in ("_classify_window",):
        monkeypatch.setattr(orientation, name, refuse)
    for name in ("crease_state_window",):
        monkeypatch.setattr(kernels_creases, name, refuse)
    got = (
        orientation.orientation_classes(f.depth, f.valid, f.intrinsics),
        surfaces.concave_creases(f.depth, f.valid, sensor, **kw),
        surfaces.crease_state(f.depth, f.valid, facing, sensor, **kw),
    )
    assert len(calls) == 3  # the creases take the state's kernel
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    assert want[1].any() and len(np.unique(want[0])) == 3
