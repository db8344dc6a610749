"""Simulated frames against their own ground truth, scene by scene."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from depthgram.errors import InputError
from depthgram.sensor import SCENES, ToFConfig, simulate
from depthgram.sensor.geometry import cast
from depthgram.sensor.scenes import APPROACH_SPEED_MM_S, build_scene
from depthgram.sensor.tof import ambiguity_range_mm


def _by_name(sim):  # type: ignore[no-untyped-def]
    return {o.name: o for o in sim.truth}


@pytest.mark.parametrize("scene", SCENES)
def test_truth_agrees_with_the_instance_map(scene: str) -> None:
    (sim,) = simulate(scene, 1, seed=3)
    f = sim.frame
    assert f.name == f"sim:{scene}#0" and f.index == 0 and f.time_s == 0.0
    assert f.depth.dtype == np.float32 and sim.true_depth.dtype == np.float32
    assert sim.instances.dtype == np.int32 and sim.instances.shape == (132, 176)
    assert not sim.instances[~f.valid].any()  # invalid pixels belong to nobody
    rows, cols = np.indices(sim.instances.shape)
    ids = {o.id for o in sim.truth}
    assert ids == set(np.unique(sim.instances)) - {0}
    for o in sim.truth:
        mask = sim.instances == o.id
        assert o.area == mask.sum()
        assert o.center_xy == pytest.approx((cols[mask].mean(), rows[mask].mean()))
        assert o.depth == pytest.approx(sim.true_depth[mask].mean(), rel=1e-6)
        on_border = mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any()
        assert o.touches_border == on_border
        assert o.kind in ("object", "floor", "wall", "ceiling")


def test_table_scene_supports_and_sizes() -> None:
    (sim,) = simulate("table", 1)
    t = _by_name(sim)
    assert {"cup", "box", "ball", "bottle", "table", "floor", "back_wall"} <= set(t)
    for name in ("cup", "box", "ball", "bottle"):
        assert t[name].parent == t["table"].id
        assert t[name].kind == "object"
        assert t[name].area > 0.02 * sim.instances.size  # well above 1 % of the frame
        assert not t[name].touches_border
    assert t["table"].parent == t["floor"].id and t["table"].kind == "object"
    assert t["floor"].parent is None and t["back_wall"].kind == "wall"
    # the objects stand out against the wall behind them by more than a metre
    assert t["back_wall"].depth - max(t[n].depth for n in ("cup", "box", "ball", "bottle")) > 1000.0


def test_noise_free_measurement_is_the_rounded_truth() -> None:
    (sim,) = simulate("table", 1, noise=False)
    f = sim.frame
    assert f.valid.all()
    np.testing.assert_allclose(f.depth, sim.true_depth, atol=0.5 + 1e-3)  # whole mm


def test_noisy_measurement_is_close_and_unbiased_at_table_range() -> None:
    (sim,) = simulate("table", 1, seed=11)
    cup = sim.instances == _by_name(sim)["cup"].id
    err = sim.frame.depth[cup] - sim.true_depth[cup]
    assert abs(err.mean()) < 2.0
    # at about 1 m: a = 8000 * 0.8 e, B = 500 e -> sigma = 477 mm/rad * sqrt(2 (B + a) + 200) / (2 a) = 5.3 mm
    assert 3.5 < err.std() < 7.5


@pytest.mark.parametrize("scene", ["table", "approach", "crossing"])
def test_single_frequency_scenes_stay_inside_the_ambiguity_range(scene: str) -> None:
    spec = build_scene(scene, (176, 132))
    assert spec.tof.f_mod2_hz is None
    far = max(cast(spec.camera, spec.bodies, t).distance.max() for t in np.arange(0.0, 4.0, 0.25))
    assert far < ambiguity_range_mm(50e6)


def test_corridor_needs_and_gets_two_frequency_unwrapping() -> None:
    (sim,) = simulate("corridor", 1, noise=False)
    t = _by_name(sim)
    assert {"floor", "left_wall", "right_wall", "ceiling", "box", "person"} <= set(t)
    assert t["left_wall"].kind == "wall" and t["ceiling"].kind == "ceiling"
    end = sim.instances == t["end_wall"].id
    np.testing.assert_allclose(sim.frame.depth[end], 6000.0, atol=1.0)
    # one 50 MHz frequency alone wraps the 6 m end wall into the first 3 m
    (wrapped,) = simulate("corridor", 1, noise=False, tof=ToFConfig())
    assert wrapped.frame.depth[end].max() < ambiguity_range_mm(50e6)
    # with noise, the unwrapping still lands on the right wrap count almost everywhere
    (noisy,) = simulate("corridor", 1, seed=2)
    ok = noisy.frame.valid
    assert np.mean(np.abs(noisy.frame.depth[ok] - noisy.true_depth[ok]) < 500.0) > 0.99


def test_approach_truth_speed_is_the_scripted_speed_and_matches_mean_depth() -> None:
    # truth does not depend on the exposure model: skip the mixed-pixel sub-steps for speed
    sims = list(simulate("approach", 120, fps=30.0, noise=False, tof=ToFConfig(mixed_pixels=False)))
    hand = [_by_name(s)["hand"] for s in sims]
    v = np.array([h.v_radial for h in hand])
    np.testing.assert_allclose(v[:60], -APPROACH_SPEED_MM_S)  # toward the sensor for 2 s
    np.testing.assert_allclose(v[60:], APPROACH_SPEED_MM_S)  # then away
    # the analytic speed agrees with the finite difference of the mean visible depth
    rate = np.diff([h.depth for h in hand]) * 30.0
    steady = np.r_[2:58, 62:118]
    np.testing.assert_allclose(rate[steady], v[steady], rtol=0.03)
    assert hand[0].depth > 1700.0 and hand[59].depth < 700.0
    assert hand[59].area > 8 * hand[0].area  # nearer, bigger


def test_crossing_occludes_the_cart_for_a_few_frames_then_it_reappears() -> None:
    sims = list(simulate("crossing", 80, noise=False, tof=ToFConfig(mixed_pixels=False)))
    seen = np.array([["cart" in _by_name(s), "person" in _by_name(s)] for s in sims])
    cart, person = seen[:, 0], seen[:, 1]
    assert not person[0] and person[1]  # walks in from the left edge
    assert not cart[0] and cart[20]
    hidden = np.flatnonzero(~cart[20:60]) + 20
    assert 2 <= hidden.size <= 6 and np.all(np.diff(hidden) == 1)  # one short gap
    assert cart[hidden[-1] + 1] and person[hidden[0]]
    assert not person[-1] and not cart[-1]  # both have left
    entering = _by_name(sims[2])["person"]
    assert entering.touches_border and entering.center_xy[0] < 10
    assert _by_name(sims[10])["person"].v_radial == pytest.approx(0.0, abs=1e-9)


def test_mixed_pixels_appear_only_on_moving_edges() -> None:
    (sim,) = list(simulate("crossing", 21, noise=False))[-1:]
    off = list(simulate("crossing", 21, noise=False, tof=ToFConfig(mixed_pixels=False)))[-1]
    np.testing.assert_allclose(off.frame.depth, off.true_depth, atol=0.5 + 1e-3)
    mixed = np.abs(sim.frame.depth - sim.true_depth) > 50.0
    assert mixed.sum() > 20
    person = sim.instances == _by_name(sim)["person"].id
    wall = sim.true_depth.max()
    # in-between readings: farther than the person, nearer than the wall
    inner = mixed & person
    assert inner.any() and np.all(sim.frame.depth[inner] > sim.true_depth[inner] + 50)
    assert np.all(sim.frame.depth[mixed] < wall)
    # every mixed pixel lies within two pixels of an instance boundary of the frame's instant
    ids = sim.instances
    boundary = np.zeros(ids.shape, bool)
    boundary[:, 1:] |= ids[:, 1:] != ids[:, :-1]
    boundary[:, :-1] |= ids[:, 1:] != ids[:, :-1]
    assert ndimage.binary_dilation(boundary, iterations=2)[mixed].all()


def test_same_seed_same_frames_other_seed_other_noise() -> None:
    a = list(simulate("crossing", 3, seed=5))
    b = list(simulate("crossing", 3, seed=5))
    c = list(simulate("crossing", 3, seed=6))
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.frame.depth, y.frame.depth)
        np.testing.assert_array_equal(x.instances, y.instances)
        assert x.truth == y.truth
    assert not np.array_equal(a[2].frame.depth, c[2].frame.depth)
    # frame k does not depend on the frames drawn before it
    np.testing.assert_array_equal(a[0].frame.depth, next(iter(simulate("crossing", 1, seed=5))).frame.depth)


def test_other_sizes_keep_the_field_of_view() -> None:
    (big,) = simulate("table", 1, size=(640, 480), noise=False)
    (small,) = simulate("table", 1, noise=False)
    assert big.frame.size == (640, 480)
    k = big.frame.intrinsics
    assert k is not None and k.fx == pytest.approx(320.0 / np.tan(np.radians(20.0)))
    # the same scene: object area fractions agree within a few percent
    for name in ("cup", "box", "ball", "bottle"):
        fb = _by_name(big)[name].area / big.instances.size
        fs = _by_name(small)[name].area / small.instances.size
        assert fb == pytest.approx(fs, rel=0.06)


def test_eight_bit_sensor_gives_codes_of_11_8_mm() -> None:
    (sim,) = simulate("table", 1, tof=ToFConfig(bits=8), noise=False)
    d = sim.frame.depth[sim.frame.valid]
    step = ambiguity_range_mm(50e6) / 254
    np.testing.assert_allclose(d / step, np.rint(d / step), atol=1e-3)
    assert np.max(np.abs(d - sim.true_depth[sim.frame.valid])) <= step / 2 + 0.01


def test_bad_requests_raise_clear_errors() -> None:
    with pytest.raises(InputError, match="known scenes: table, corridor, approach, crossing"):
        simulate("kitchen")
    with pytest.raises(InputError, match="frames"):
        simulate("table", 0)
    with pytest.raises(InputError, match="size"):
        simulate("table", size=(0, 132))
    with pytest.raises(InputError, match="size"):
        simulate("table", size=(100000, 100000))
    with pytest.raises(InputError, match="fps"):
        simulate("table", fps=0.0)


def test_dim_far_pixels_are_invalid_and_belong_to_nobody() -> None:
    # a = 8000 e * 0.8 / (6 m)^2 = 178 e at the end wall: below a 300 e threshold, so invalid;
    # the box at 2.6-2.9 m returns 8000 * 0.7 / 2.9^2 >= 666 e and stays valid.
    cfg = ToFConfig(f_mod2_hz=40e6, min_amplitude_e=300.0)
    (sim,) = simulate("corridor", 1, noise=False, tof=cfg)
    (ref,) = simulate("corridor", 1, noise=False)
    end_id = _by_name(ref)["end_wall"].id
    end = ref.instances == end_id
    assert not sim.frame.valid[end].any() and (sim.frame.depth[end] == 0).all()
    assert not (sim.instances == end_id).any() and "end_wall" not in _by_name(sim)
    assert _by_name(sim)["box"].area == _by_name(ref)["box"].area
    # truth areas count only the valid pixels of each body
    for o in sim.truth:
        assert o.area == np.count_nonzero((ref.instances == o.id) & sim.frame.valid)


def test_eight_bit_code_spans_the_unwrapped_range_with_two_frequencies() -> None:
    cfg = ToFConfig(f_mod2_hz=40e6, bits=8)
    (sim,) = simulate("corridor", 1, noise=False, tof=cfg)
    step = cfg.range_mm / 254  # 14990 mm / 254 = 59 mm
    assert step == pytest.approx(59.0, abs=0.1)
    ok = sim.frame.valid
    assert np.max(np.abs(sim.frame.depth[ok] - sim.true_depth[ok])) <= step / 2 + 0.01


def test_frames_carry_time_and_provenance() -> None:
    sims = list(simulate("approach", 3, fps=12.5, seed=9))
    assert [s.frame.time_s for s in sims] == pytest.approx([0.0, 0.08, 0.16])
    assert [s.frame.name for s in sims] == ["sim:approach#0", "sim:approach#1", "sim:approach#2"]
    assert sims[1].frame.meta == {"scene": "approach", "fps": 12.5, "seed": 9}
